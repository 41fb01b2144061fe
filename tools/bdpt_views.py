"""BDPT's strategies side by side: one image per (s, t), as the lecture's "contributions of
different path lengths" slide (Veach's figure 10.3).

``python -m sampling_lab bdpt-views`` calls :func:`run`: it renders a built-in scene with BDPT
and Strategy Views on, then lays the per-strategy images out in a grid, one row per path length
``k`` (segments) and one column per number of light vertices ``s``, twice: each strategy's own
estimate (as if it were the only strategy: noise shows where it is bad), and its MIS-weighted
share (what it adds to the image: the rows sum to the light of that length). Figures only.
The command writes the figure into ``<output>/images/`` (default ``out/bdpt-views``), laid out as
in ``docs/``, where ``--update-docs`` copies it.
"""

from __future__ import annotations

import os

import numpy as np

from ..core.integrators.common import strategies
from ..core.render import RenderSettings, render
from ..core.scenes import BUILTIN
from ..core.integrators.bounces import uniform_limits

# The figure's folder, in the output folder as in docs/.
DOCS_FOLDER = "images"


def _tonemap(img, scale):
    """Display ``img (h, w, 3)`` with ``scale`` mapped to white, sRGB-encoded, row 0 on top."""
    x = np.clip(np.nan_to_num(img / max(scale, 1e-12)), 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return x[::-1]


def run(scene="glass_caustic", size=(96, 96), spp=64, max_length=4, max_bounces=None,
        output="out/bdpt-views/images", seed=0, progress=None):
    """Render the views and write ``bdpt_views_<scene>.png`` (own estimates and weighted shares)
    into ``output``. Returns the PNG path and the per-strategy image means as a dict."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    w, h = size
    sc = BUILTIN[scene](w, h)
    settings = RenderSettings(integrator="bdpt", spp=spp, seed=seed, strategy_views=True,
                              strategy_max_length=max_length,
                              **uniform_limits(max_length - 2 if max_bounces is None
                                                else max_bounces))
    res = render(sc, settings, progress=progress)
    layers = res.layers()
    combined = res.film.mean()
    scale = float(np.percentile(combined, 99.0))
    pairs = strategies(max_length)
    cols = max_length + 1
    fig, axes = plt.subplots(2 * max_length, cols, figsize=(1.6 * cols, 3.2 * max_length),
                             squeeze=False)
    means = {}
    for ax in axes.ravel():
        ax.axis("off")
    for s, t in pairs:
        k = s + t - 1
        for half, suffix in ((0, ""), (1, " weighted")):
            name = f"Strategy s{s} t{t}{suffix}"
            img = layers[name]
            means[name] = float(img.mean())
            ax = axes[2 * (k - 1) + half, s]
            ax.imshow(_tonemap(img, scale), interpolation="nearest")
            ax.set_title(f"s={s} t={t}" + (" weighted" if half else ""), fontsize=7)
    fig.suptitle(f"BDPT strategies on '{scene}', {spp} spp: own estimate (upper row of each "
                 f"length) and MIS-weighted share (lower row)", fontsize=8)
    fig.tight_layout()
    os.makedirs(output, exist_ok=True)
    path = os.path.join(output, f"bdpt_views_{scene}.png")
    tmp = path + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
    return path, means


if __name__ == "__main__":  # pragma: no cover
    print(run())
