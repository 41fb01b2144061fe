"""Light tracing: particles from the lights, connected to the camera and splatted on the film.

What it estimates
    The same pixel measurement as :mod:`.path`, from the other end. Each sample traces one
    light subpath (emitter chosen as next-event estimation chooses it, a point on it, a
    direction by its emission profile; then BSDF sampling in importance mode, straight through
    transparent surfaces, which are no vertices) and connects every non-delta vertex to the
    pinhole with a shadow ray (through transparent surfaces, dimmed by them; the path's passes
    and the connection's at most the Transparent limit, :mod:`.transparent_passes`); the
    contribution lands at the film
    position where the vertex projects, weighted by the pixel filter (BDPT's ``t = 1``
    strategies, unweighted). Emitters seen directly come from the camera ray of the sample
    (BDPT's ``s = 0, t = 2``), so that the sky and sun disks seen directly count too.
Bias and consistency
    Unbiased for paths of up to ``max_bounces + 1`` scattering vertices, as the path tracer,
    except for the approximations of :mod:`core.lights.emission` (sphere lights do not light
    points inside them).
Render region
    One light path per camera sample of the region's pixels, and only splats that reach a
    region pixel are connected and kept, divided by the light paths traced: unbiased, at the
    region's share of the time, but with ``region / frame`` as many light paths behind each
    pixel as a full render of the same ``spp`` (so a noisier region); see :mod:`.bdpt`.
When to use it
    Caustics seen directly: light focused by glass or mirrors onto a diffuse surface the camera
    sees.
When it fails
    Anything the camera sees through a mirror or glass (a specular surface between the camera
    and the last diffuse vertex cannot be connected to a pinhole), and large scenes where few
    particles land in view. Use BDPT to combine it with path tracing.
"""

from __future__ import annotations

from .bidir import Bidirectional


class LightTracer(Bidirectional):
    """Light tracing: one light path and one camera ray per sample (see the module docstring).

    Each strategy stands alone (weight one): ``s = 0, t = 2`` for emitters the camera ray
    sees, ``t = 1`` for every light vertex the pinhole sees.
    """

    # As many paths per unit as the path tracer's, walked in one chunk (nothing is stored per
    # vertex): the costs per call (the Sobol sampler's set-up per draw, the bookkeeping of every
    # vertex) are spread over 8 x as many paths as in the chunks of 8 k before (units of 16 k;
    # docs/BENCHMARKS.md, fifth round). The splats are the same; only the order in which a
    # pixel sums them changes (tests/core/test_light_speed_paths.py).
    unit_paths = 1 << 16
    chunk_paths = None
    weighs = False
    stores_light_subpaths = False

    def camera_depth(self, depth):
        """The camera ray only: emitters seen directly."""
        return 1


# One work unit without a render loop (tests, one-off use); a render builds LightTracer once.
