"""What every light family shares: the light-table row builder, the output batches and the
interface a family implements.

A *family* is one kind of emitter (:mod:`.point`, :mod:`.area`, :mod:`.sun`,
:mod:`.environment`, :mod:`.triangles`). :class:`~.sampler.LightSampler` chooses an emitter per
path vertex and hands each family the rows of the batch that chose one of its emitters; the
family fills those rows of the outputs. Every method works on whole arrays of rows (no loop over
rays); the only Python loops are over families and, in :meth:`LightFamily.intersect`, over the
family's lamps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rows import dots, put_rows
from ..scene import Lights

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def dot(a, b):
    """Row-wise dot products of ``(n, 3)`` arrays: ``(n,)`` (:func:`core.rows.dots`)."""
    return dots(a, b)


def batch_rows(a, m):
    """Rows ``m`` of a batch array ``a (n, ...)``, where ``m (k,)`` is sorted and unique (as
    :meth:`~.sampler.LightSampler.families_of` makes them): ``a`` itself when ``m`` is every
    row (one light family: no copy), else a gather (``np.take``, faster than ``a[m]``)."""
    return a if m.size == a.shape[0] else a.take(m, axis=0)


def set_batch_rows(a, m, values):
    """``a[m] = values`` for ``m`` as in :func:`batch_rows` (a plain copy when ``m`` is every
    row, else a row scatter, :func:`core.rows.put_rows`)."""
    if m.size == a.shape[0]:
        a[...] = values
    else:
        put_rows(a, m, values)


def length_and_direction(v):
    """Lengths ``(n,)`` of vectors ``v (n, 3)`` and their unit directions ``(n, 3)`` (zero
    vectors stay zero)."""
    length = np.sqrt(dot(v, v))
    return length, v / np.maximum(length, 1e-300)[:, None]


def unit(v):
    """``v (3,)`` scaled to unit length (straight down for a zero vector)."""
    v = np.asarray(v, np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.array([0.0, 0.0, -1.0])


def light_row(kind, name, visible_camera, position=(0, 0, 0), axis_x=(0, 0, 0),
              axis_y=(0, 0, 0), direction=(0, 0, -1), radius=0.0, angle=0.0, radiance=(0, 0, 0),
              spot_cos_half=-1.0, spot_smooth=np.inf, power=0.0, soft_falloff=False) -> Lights:
    """One row of :class:`core.scene.Lights` (the family constructors fill in their fields)."""
    v3 = lambda a: np.asarray(a, np.float64).reshape(1, 3)  # noqa: E731
    v1 = lambda a: np.asarray([a], np.float64)  # noqa: E731
    return Lights(
        kind=np.asarray([kind], np.int32), position=v3(position), axis_x=v3(axis_x),
        axis_y=v3(axis_y), direction=v3(direction), radius=v1(radius), angle=v1(angle),
        radiance=v3(radiance), spot_cos_half=v1(spot_cos_half), spot_smooth=v1(spot_smooth),
        power=v1(power), visible_camera=np.asarray([bool(visible_camera)]),
        soft_falloff=np.asarray([bool(soft_falloff)]), names=[name],
    )


@dataclass
class LiSamples:
    """Next-event samples of a batch (see :meth:`LightFamily.sample_li`).

    Attributes
    ----------
    wi : (n, 3) float64
        Unit direction from the receiving point toward the light.
    dist : (n,) float64
        Distance to the sampled point (inf for sun and world).
    radiance : (n, 3) float64
        Arriving radiance (for delta lights: intensity / dist^2 or irradiance).
    pdf : (n,) float64
        Solid-angle density times the selection probability (delta lights: the selection
        probability alone); zero marks a failed sample.
    light_normal : (n, 3) float64
        Normal of the sampled emitter point (zero for lamps, sun and world), for ray offsets.
    """

    wi: np.ndarray
    dist: np.ndarray
    radiance: np.ndarray
    pdf: np.ndarray
    light_normal: np.ndarray

    @classmethod
    def empty(cls, n):
        wi = np.zeros((n, 3))
        wi[:, 2] = 1.0
        return cls(wi, np.full(n, np.inf), np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3)))

    def put(self, name, m, values):
        """``field[m] = values`` for the field ``name`` and rows ``m`` as in
        :func:`set_batch_rows`. When ``m`` is every row and ``values`` a fresh array of the
        field's shape and type (writable, owning its data), it becomes the field: no copy."""
        field = getattr(self, name)
        if (m.size == field.shape[0] and isinstance(values, np.ndarray)
                and values.shape == field.shape and values.dtype == field.dtype
                and values.flags.writeable and values.base is None):
            setattr(self, name, values)
        else:
            set_batch_rows(field, m, values)


@dataclass
class LeOrigins:
    """Light-path origins of a batch being filled (see :meth:`LightFamily.sample_le_origin`):
    ``p, normal, w_inf (n, 3)`` and ``pdf (n,)`` as in :class:`~.emission.EmitterPoints`."""

    p: np.ndarray
    normal: np.ndarray
    w_inf: np.ndarray
    pdf: np.ndarray

    @classmethod
    def empty(cls, n):
        return cls(np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n))


@dataclass
class LeDirections:
    """Light-path directions of a batch being filled (see
    :meth:`LightFamily.sample_le_direction`): ``origin, w (n, 3)``, ``pdf, cos_l (n,)``."""

    origin: np.ndarray
    w: np.ndarray
    pdf: np.ndarray
    cos_l: np.ndarray


class LightFamily:
    """The contract of a light family, on the rows ``m (k,)`` of a batch that chose one of its
    emitters (``index[m]`` are their emitter rows in the sampler's table, ``pmf[m]`` or ``sel[m]``
    their selection probabilities). Densities include the selection probability.

    - ``sample_li(m, index, p, u, pmf, out: LiSamples)``: next-event estimation from points
      ``p``: a direction toward the emitter, its distance, arriving radiance and solid-angle pdf.
    - ``pdf_li``: the density ``sample_li`` gives to a direction found by a BSDF-sampled ray
      (families name it after what the ray found: :meth:`.triangles.EmissiveTriangles.pdf_li`,
      :meth:`.environment.World.pdf_li`; lamps report it with their hits).
    - ``intersect(o, d, tmax, camera)``: what rays see of the family's lamps, yielding
      ``(rows, radiance, pdf_li)`` (emissive triangles are scene geometry: Embree finds them).
    - ``sample_le_origin(m, index, u, pmf, out: LeOrigins)`` and
      ``sample_le_direction(m, index, pts, u, out: LeDirections)``: where and in which direction
      a light path leaves (two steps: BDPT's ``s = 1`` strategy needs a point alone).
    - ``pdf_le_origin(m, index, sel, w, out)`` and ``pdf_le_direction(m, index, normal, w, out)``:
      the densities of those two steps for emitter points found by camera paths.
    - ``le(m, index, p, normal, w, receiver, out)``: radiance leaving emitter points along ``w``.
    """

    #: Suns and the world: light paths enter through the scene's disk (see
    #: :class:`~.emission.Emission`), so these families sample no light-path direction.
    infinite = False

    def __init__(self, sampler):
        self.sampler = sampler
        self.lights = sampler.lights  # the lamp table (core.scene.Lights)

    def is_delta(self, li):
        """Whether lamps ``li (k,)`` of this family are delta lights (no ray can hit them)."""
        return np.zeros(li.shape[0], bool)

    def lamp_power(self, li, radius):
        """Estimated power ``(k,)`` of lamps ``li`` in a scene of bounding ``radius``, for light
        selection."""
        return self.lights.power[li]
