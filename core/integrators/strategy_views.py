"""What one batch of a bidirectional estimator adds up to, and BDPT's strategy views.

A :class:`Tally` collects the image (one value per camera sample), the light-path splats and,
with strategy views on, one image per strategy ``(s, t)``: its own estimate (as if it were the
only strategy) and its MIS-weighted share of the image (see
:func:`core.integrators.common.strategy_pass_names`).
"""

from __future__ import annotations

import numpy as np

from ..rows import scaled
from .base import BatchOutput, Splats
from .common import add_rows, finite_rows


class Tally:
    """What one batch's strategies add up to: the image (one value per camera sample), the
    light-path splats and, with strategy views of paths up to ``view_length`` segments, one
    image per strategy ``(s, t)``: its own estimate and its MIS-weighted share."""

    def __init__(self, n, view_length):
        self.image = np.zeros((n, 3))
        self.splats = []
        self.view_length = view_length  # 0: no strategy views
        self.camera_layers = {}
        self.splat_layers = {}
        self.transparency = None  # Film > Transparent: see add_transparency

    def add(self, s, t, rows, value, weight):
        """Add strategy ``(s, t)``'s contributions ``value (k, 3)`` with MIS weights
        ``weight (k,)`` to the camera samples ``rows (k,)`` (distinct)."""
        weighted = scaled(value, weight)
        add_rows(self.image, rows, weighted)
        if s + t - 1 <= self.view_length:
            key = f"Strategy s{s} t{t}"
            layers = self.camera_layers
            for name, v in ((key, value), (key + " weighted", weighted)):
                if name not in layers:
                    layers[name] = np.zeros_like(self.image)
                layers[name][rows] += v

    def add_transparency(self, rows, amount):
        """Add ``amount (k,)``, what of the camera samples ``rows (k,)`` reached a transparent
        film's background, to their transparency (:attr:`.base.BatchOutput.transparency`)."""
        if self.transparency is None:
            self.transparency = np.zeros(self.image.shape[0])
        np.add.at(self.transparency, rows, amount)

    def splat(self, s, xy, value, weight):
        """Add strategy ``(s, 1)``'s contributions at film positions ``xy``."""
        weighted = scaled(value, weight)
        self.splats.append(Splats(xy, weighted))
        if s <= self.view_length:
            key = f"Strategy s{s} t1"
            for name, v in ((key, value), (key + " weighted", weighted)):
                self.splat_layers.setdefault(name, []).append(Splats(xy, v))

    def output(self, light_paths):
        """The batch's :class:`BatchOutput`: no NaN, Inf or negative value in the image."""
        image = self.image
        image[~finite_rows(image)] = 0.0
        splats = Splats.join(self.splats)
        return BatchOutput(np.maximum(image, 0.0, out=image),
                           Splats(splats.xy, np.maximum(splats.value, 0.0, out=splats.value)),
                           light_paths,
                           {name: np.where(np.isfinite(v), v, 0.0)
                            for name, v in self.camera_layers.items()},
                           {name: Splats.join(parts) for name, parts in self.splat_layers.items()},
                           self.transparency)

