"""Render options: one record per setting, the one source of the UI, the CLI and validation.

Every field of :class:`core.render.RenderSettings` (but the render region) has an
:class:`Option` in :data:`OPTIONS`: its name, the values it takes (for a menu, each with a label
and a description), its default, its range and its description. From these records

- the add-on builds its properties (``addon/properties.py``: ``EnumProperty`` items, defaults,
  limits and tooltips), and reads them back into core values;
- the command line builds its flags (``cli.py``: choices, help text, defaults, type checks);
- :func:`validate` checks a ``RenderSettings``, with one message shape for every option:
  ``"mis_heuristic: 'veach' is not one of power, balance, ..."``.

Names: a menu value is lower case in core (``'blackman_harris'``); its Blender identifier is the
same in upper case (``'BLACKMAN_HARRIS'``), which presets and ``.blend`` files store.

Where a core module already lists what exists (``INTEGRATORS``, ``MIS_SETTINGS``,
``LIGHT_SELECTIONS``, ``LIGHT_SAMPLINGS``, ``DISTRIBUTION_METHODS``, the samplers), the menu's
values are that list and this module adds their labels and descriptions; importing it fails if
a value has no text or a text names no value, so the lists cannot drift apart.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .integrators import INTEGRATORS
from .integrators.bdpt import LIGHT_POINTS
from .integrators.common import ROULETTE_SURVIVALS
from .integrators.radiosity import DISPLAYS as RADIOSITY_DISPLAYS
from .lights import LIGHT_SAMPLINGS, LIGHT_SELECTIONS
from .radiosity.solvers import SOLVERS as RADIOSITY_SOLVERS
from .sampling.distributions import DISTRIBUTION_METHODS
from .sampling.mis import MIS_SETTINGS
from .sampling.samplers import available as available_samplers
from .sampling.samplers import sampler_class


def identifier(value):
    """Blender's identifier of a menu value: ``'blackman_harris'`` -> ``'BLACKMAN_HARRIS'``."""
    return value.upper()


def menu_value(text):
    """The core value of a Blender identifier or of command-line text (any case)."""
    return text.lower()


@dataclass(frozen=True)
class Choice:
    """One value of a menu option: ``value`` in core, ``label`` and ``description`` in the UI."""

    value: str
    label: str
    description: str

    @property
    def identifier(self):
        """Blender's identifier of the value (presets and .blend files store it)."""
        return identifier(self.value)


@dataclass(frozen=True)
class Option:
    """One render setting.

    Parameters
    ----------
    name : str
        Field of ``core.render.RenderSettings``.
    kind : type
        ``str`` (a menu of ``choices``), ``int``, ``float`` or ``bool``.
    label : str
        Name shown in the UI.
    description : str
        What the setting does: the UI's tooltip and the CLI's help.
    default : object
    choices : tuple of Choice
        The menu, in the order the UI shows it (``kind`` str only).
    minimum, maximum : float or None
        Closed range of a number.
    prop : str or None
        Name of the add-on's property (default ``name``).
    flag : str or None
        The ``render`` command's flag (default ``--`` + ``name`` with dashes).
    """

    name: str
    kind: type
    label: str
    description: str
    default: object
    choices: tuple = ()
    minimum: float | None = None
    maximum: float | None = None
    prop: str | None = None
    flag: str | None = None

    @property
    def values(self):
        """Core values of a menu, in UI order."""
        return tuple(c.value for c in self.choices)

    @property
    def prop_name(self):
        return self.prop or self.name

    @property
    def flag_name(self):
        return self.flag or "--" + self.name.replace("_", "-")

    def allowed(self):
        """The allowed values as a user reads them: ``'a, b, c'`` or ``'[lo, hi]'``."""
        if self.choices:
            return ", ".join(self.values)
        if self.kind is bool:
            return "True, False"
        lo = "-inf" if self.minimum is None else f"{self.minimum:g}"
        hi = "inf" if self.maximum is None else f"{self.maximum:g}"
        if self.kind is int:
            lo, hi = (str(v) if v is not None else t for v, t in ((self.minimum, lo),
                                                                 (self.maximum, hi)))
        return f"[{lo}, {hi}]"

    def check(self, value):
        """Raise ``ValueError("<name>: <value> is not ...")`` unless ``value`` is allowed."""
        if self.choices:
            if value not in self.values:
                raise ValueError(f"{self.name}: {value!r} is not one of {self.allowed()}")
            return
        is_bool = type(value).__name__ in ("bool", "bool_")
        if self.kind is bool:
            if not is_bool:
                raise ValueError(f"{self.name}: {value!r} is not one of {self.allowed()}")
            return
        wanted = numbers.Integral if self.kind is int else numbers.Real
        # Blender stores floats in single precision: its 0.01 is 0.0099999998.
        slack = 1e-6 if self.kind is float else 0.0
        # NaN fails every comparison; infinity passes only an open end (time_limit: no limit).
        if not (isinstance(value, wanted) and not is_bool and not math.isnan(value)
                and (self.minimum is None or value >= self.minimum - slack * abs(self.minimum))
                and (self.maximum is None or value <= self.maximum + slack * abs(self.maximum))):
            what = "an integer" if self.kind is int else "a number"
            raise ValueError(f"{self.name}: {value!r} is not {what} in {self.allowed()}")

    def why_not(self, text):
        """What is wrong with the number in ``text`` when it is out of range, as a clause for a
        message (``' (it is negative)'``, ``' (it is NaN)'``); ``''`` for anything else."""
        if self.choices or self.kind is bool:
            return ""
        try:
            value = self.kind(text)
        except ValueError:
            return ""

        def bound(b):
            return str(int(b)) if self.kind is int else f"{b:g}"

        if math.isnan(value):
            return " (it is NaN)"
        if self.minimum is not None and value < self.minimum:
            return (" (it is negative)" if value < 0 <= self.minimum
                    else f" (it is below the minimum {bound(self.minimum)})")
        if self.maximum is not None and value > self.maximum:
            return f" (it is above the maximum {bound(self.maximum)})"
        return ""

    def parse(self, text):
        """A value from command-line text, checked (``ValueError`` names the option)."""
        if self.choices:
            value = menu_value(text)
        else:
            try:
                value = self.kind(text)
            except ValueError:
                what = "an integer" if self.kind is int else "a number"
                raise ValueError(f"{self.name}: {text!r} is not {what} in "
                                 f"{self.allowed()}") from None
        self.check(value)
        return value


def _choices(values, texts):
    """Menu of ``values`` (a core module's list) in the order of ``texts`` (value -> label,
    description); raises if either names a value the other lacks."""
    if set(values) != set(texts):
        raise RuntimeError(f"option texts {sorted(texts)} do not match the values "
                           f"{sorted(values)}")
    return tuple(Choice(v, *texts[v]) for v in texts)


def sampler_choices(names=None):
    """Menu of the samplers ``core.sampling.samplers.available()`` lists, each with its class's
    ``label`` and ``description`` (else its docstring's first line). A sampler module that fails
    to import is left out, so one broken sampler cannot stop the add-on or the CLI."""
    out = []
    for name in available_samplers() if names is None else names:
        try:
            cls = sampler_class(name)
        except Exception:  # noqa: BLE001 - a sampler being written must not break the others
            continue
        label = getattr(cls, "label", None) or name.replace("_", " ").title()
        doc = (cls.__doc__ or "").strip().split("\n")[0].strip()
        description = getattr(cls, "description", None) or doc or f"{label} sampler"
        out.append(Choice(name, str(label), str(description).strip().rstrip(".")))
    return tuple(out)


_INTEGRATOR_TEXT = {
    "path": (
        "Path Tracing",
        "Unidirectional path tracing with next-event estimation and multiple importance "
        "sampling. Unbiased and consistent; the reference estimator the others are compared "
        "with"),
    "light": (
        "Light Tracing",
        "Particles traced from the lights, each vertex connected to the camera and splatted onto "
        "the film. Unbiased; good for caustics seen directly (light through glass or off a "
        "mirror onto a diffuse surface), but it cannot find paths the camera sees through a "
        "specular surface (mirrors and glass in view render black). No MIS: one strategy per "
        "path"),
    "bdpt": (
        "Bidirectional",
        "Bidirectional path tracing: a camera subpath and a light subpath, joined by every "
        "connection strategy (s light vertices, t camera vertices) and combined by multiple "
        "importance sampling with the Light Sampling panel's MIS heuristic. Unbiased; robust "
        "for caustics and indirectly lit scenes, where one strategy's noise is another's "
        "strength"),
    "photon": (
        "Photon Mapping",
        "Jensen's two-pass photon mapping: photons from the lights fill a caustic map and a "
        "global map once; camera paths add direct light by light sampling, caustics from the "
        "caustic map, and indirect light by final gathering into the global map. BIASED but "
        "consistent: the density estimate blurs light over its radius, and more samples per "
        "pixel do not remove that blur (more photons and a smaller radius do)"),
    "sppm": (
        "Stochastic Progressive Photon Mapping",
        "Passes of one camera path per pixel (through mirrors and glass to the first rough "
        "surface, direct light by light sampling) and a batch of photons from the lights; "
        "photons within a per-pixel radius give the indirect light, and the radius shrinks "
        "after every pass. BIASED but consistent: the blur of the radius vanishes as passes "
        "grow. Renders light from point lights through mirrors and glass onto diffuse "
        "surfaces, which path tracing cannot find, and BDPT only where that surface is seen "
        "directly (not through a mirror or glass again)"),
    "radiosity": (
        "Radiosity",
        "Finite-element radiosity: diffuse surfaces cut into patches of constant radiosity, "
        "form factors by ray casting, the linear system solved once per render, then shown by "
        "camera rays. BIASED, and not consistent unless the patches shrink: more samples only "
        "antialias a fixed solution. Every material is treated as diffuse (its Base Color)"),
    "mlt": (
        "Metropolis Light Transport",
        "Primary-sample-space Metropolis (Kelemen et al.): Markov chains mutate the path "
        "tracer's random numbers (large steps: all fresh; small steps: each nudged), accept "
        "with min(1, f'/f) and splat Veach's expected values. Consistent, with the brightness "
        "normalisation b estimated from bootstrap paths (its error scales the whole image; "
        "renders with different seeds average to the path tracer's image). Samples are "
        "mutations per pixel. Meant for light through narrow openings, yet on the benchmark's "
        "gap room it lost to path tracing at equal time (its mutations cost more); at low "
        "mutation counts brightness is uneven (blotches)"),
}

_RADIOSITY_SOLVER_TEXT = {
    "jacobi": (
        "Jacobi",
        "Iterate B = E + rho F B with the whole previous solution (gathering). Stores the dense "
        "form-factor matrix: refused above 8,192 patches"),
    "gauss_seidel": (
        "Gauss-Seidel",
        "Jacobi's sweep row by row with the newest values: about half the sweeps. Stores the "
        "dense form-factor matrix: refused above 8,192 patches"),
    "progressive": (
        "Progressive Refinement",
        "Shoot the patch with the most unshot power to all others (Southwell iteration); one "
        "column of form factors at a time, no stored matrix, but slow for large meshes"),
    "hierarchical": (
        "Hierarchical",
        "Hierarchical radiosity (Hanrahan, Salzman & Aupperle 1991): patch pairs linked at the "
        "coarsest level where their form factor is small, so cost grows near linearly with "
        "the patch count; for large meshes"),
}

_RADIOSITY_DISPLAY_TEXT = {
    "gouraud": (
        "Gouraud",
        "Radiosity interpolated across each patch from its corners (the mean of the patches "
        "that meet there). Smooth, but shadows are only as sharp as the mesh"),
    "flat": (
        "Flat",
        "Each patch's own constant radiosity: the mesh shows, as the solver sees it"),
    "final_gather": (
        "Final Gather",
        "One bounce of path tracing into the solution: direct light by next-event estimation "
        "(sharp shadows), indirect light read from the patches where the bounce ray lands. "
        "Noisy per sample, converges to the radiosity solution's one-bounce image"),
}

_MIS_TEXT = {
    "power": (
        "Power Heuristic",
        "Multiple importance sampling of light and BSDF samples with weights p^beta / sum "
        "p^beta (Veach). Unbiased; beta = 2 is the usual choice, cutting noise from both small "
        "lights and broad reflections"),
    "balance": (
        "Balance Heuristic",
        "MIS with weights proportional to each strategy's density (the power heuristic with "
        "beta = 1). Unbiased; provably close to the best weights, a little noisier than power"),
    "maximum": (
        "Maximum Heuristic",
        "MIS where the strategy with the larger density takes the whole sample. Unbiased; "
        "the limit of the power heuristic for large beta"),
    "cutoff": (
        "Cutoff Heuristic",
        "MIS where strategies whose density is below alpha times the largest get weight zero "
        "and the rest share by the balance heuristic. Unbiased"),
    "none": (
        "None (Average)",
        "Both strategies with constant weight 1/2: the unweighted average of light sampling and "
        "BSDF sampling. Unbiased, but without MIS's variance reduction: each strategy's noisy "
        "cases are only halved"),
    "bsdf": (
        "BSDF Sampling Only",
        "No light sampling: direct light only where a BSDF-sampled ray happens to hit an "
        "emitter (weight one). Unbiased for area, mesh, sphere and sun-disk lights, but point, "
        "spot and sharp sun lights can never be hit and render black: a teaching baseline"),
    "light": (
        "Light Sampling Only",
        "Next-event estimation only (weight one); emitters found by rays after a bounce are "
        "dropped where light sampling could have picked them. Unbiased; emitters seen directly "
        "by the camera still show. Noisy for glossy surfaces and huge lights"),
}

_LIGHT_SELECTION_TEXT = {
    "power": (
        "Power",
        "Choose the light to sample in proportion to its estimated emitted power. Unbiased; "
        "best when brighter lights contribute more"),
    "uniform": (
        "Uniform",
        "Choose every light with the same probability: each lamp, each emission material (all "
        "triangles sharing it count as one light, and a triangle inside it is chosen in "
        "proportion to area times radiance) and the world. Unbiased; lights that emit nothing "
        "are skipped"),
    "tree": (
        "Light Tree",
        "Choose the light from each shading point through a tree of light bounds (position, "
        "orientation, power), preferring lights that are near, face the point and are bright; "
        "the sun and the world are chosen by power beside it. Unbiased; best with many lights. "
        "Path tracing only: light tracing and bidirectional paths start on lights chosen by "
        "power"),
}

_LIGHT_SAMPLING_TEXT = {
    "area": (
        "Area",
        "Sample points uniformly over the surface of area lights and emissive triangles. "
        "Unbiased; noisy close to large lights, whose near parts are undersampled"),
    "solid_angle": (
        "Solid Angle",
        "Sample directions uniformly over the solid angle that an emitter subtends: spherical "
        "triangles (Arvo) for emissive triangles, spherical rectangles (Urena et al.) for "
        "square and rectangular area lights. Unbiased; much less noise near large lights. Disk "
        "and ellipse lights, and emitters seen under a tiny or near-hemispherical solid angle, "
        "stay area-sampled"),
}

_DISTRIBUTION_TEXT = {
    "cdf": (
        "CDF Inversion",
        "Discrete choices (which light, which emissive triangle, which component of a mixed "
        "material) by binary search in a cumulative distribution: O(log n) per sample, "
        "preserves the stratification of the sampler's numbers"),
    "alias": (
        "Alias Table",
        "Discrete choices by Walker's alias method (Vose's construction): O(1) per sample after "
        "an O(n) build, but scrambles the stratification of the sampler's numbers"),
}

_ROULETTE_SURVIVAL_TEXT = {
    "square_root": (
        "Square Root",
        "A path survives with probability sqrt(throughput), Cycles' rule: paths end later "
        "than by their throughput, with less noise per sample for a little more work each"),
    "throughput": (
        "Throughput",
        "A path survives with probability equal to its throughput (its largest colour "
        "component), pbrt's and Mitsuba's rule: the shortest paths, the most noise"),
}

_LIGHT_POINTS_TEXT = {
    "light_path": (
        "Light Path's Origin",
        "Every camera vertex of a sample connects to the point on a light that the sample's "
        "light path starts from, as in Veach's bidirectional path tracing: no light sampling "
        "of its own, but the connections of one sample share their point"),
    "fresh": (
        "Fresh Sample",
        "Every camera vertex samples a point on a light of its own, as next-event estimation "
        "does (pbrt's bidirectional path tracer): independent points, one more light sample "
        "per camera vertex"),
}

# The pixel filters core.film.PixelFilter implements and the UI offers (this list is the source).
FILTER_CHOICES = (
    Choice("box", "Box", "Box filter: every sample counts only for the pixel it falls in"),
    Choice("blackman_harris", "Blackman-Harris",
           "Blackman-Harris window, as Cycles' default pixel filter (importance sampled, so "
           "every camera sample has weight one). Cycles doubles the width for this filter: a "
           "width of 1.5 pixels gives a 3 pixel wide footprint"),
)


def _menu(name, label, description, default, choices, **kw):
    return Option(name, str, label, description, default, choices=choices, **kw)


OPTIONS = {o.name: o for o in (
    _menu("integrator", "Integrator",
          "Light transport estimator: which Monte Carlo estimator of the rendering equation "
          "computes each pixel", "path", _choices(INTEGRATORS, _INTEGRATOR_TEXT)),
    _menu("sampler", "Sampler",
          "How the random numbers of each pixel sample are generated: independent, stratified, "
          "low-discrepancy or blue-noise sequences trade the same work for a different error",
          "sobol", sampler_choices()),
    Option("spp", int, "Samples",
           "Number of samples per pixel. The render stops after this many, or earlier when the "
           "time limit runs out", 16, minimum=0, maximum=1 << 24,
           prop="samples"),
    Option("time_limit", float, "Time Limit",
           "Stop rendering after this many seconds, keeping the samples taken so far. Zero "
           "means no limit (render all samples)", 0.0, minimum=0.0, flag="--time"),
    Option("seed", int, "Seed",
           "Seed of the sample streams. The same seed, samples and scene give the same image; "
           "change it to get an independent render of the same scene (e.g. to measure "
           "variance)", 0, minimum=0, maximum=(1 << 31) - 1),
    Option("max_bounces", int, "Total",
           "Maximum number of bounces of a path (transparent ones not counted), as Cycles' "
           "Light Paths > Max Bounces > Total. Cutting paths short loses the light they would "
           "have carried (a bias toward darker images)", 12, minimum=0,
           maximum=1024, flag="--max-depth"),
    Option("diffuse_bounces", int, "Diffuse",
           "Maximum number of diffuse reflection bounces of a path, as Cycles' limit of the "
           "same name (path tracing only). Lower values are biased: they cut the light of "
           "longer diffuse paths", 4, minimum=0, maximum=1024),
    Option("glossy_bounces", int, "Glossy",
           "Maximum number of glossy and mirror reflection bounces of a path, as Cycles' limit "
           "of the same name (path tracing only). Lower values are biased", 4, minimum=0,
           maximum=1024),
    Option("transmission_bounces", int, "Transmission",
           "Maximum number of transmission bounces (through glass) of a path, as Cycles' limit "
           "of the same name (path tracing only). Lower values are biased", 12, minimum=0,
           maximum=1024),
    Option("transparent_max_bounces", int, "Transparent",
           "Maximum number of transparent surfaces (Transparent BSDF, Principled Alpha) a path "
           "or a shadow ray passes straight through, as Cycles' limit of the same name; the "
           "next one blocks it. Light Tracing and Bidirectional count a path's passes on its "
           "camera and light paths and its connection together; Photon Mapping and SPPM a "
           "photon's apart from a camera path's. Does not count toward the other limits", 8, minimum=0,
           maximum=1024, flag="--transparent-bounces"),
    Option("use_russian_roulette", bool, "Russian Roulette",
           "Terminate low-throughput paths at random and reweight the survivors. Unbiased: it "
           "trades a little variance for a lot less work on long paths", True,
           flag="--russian-roulette"),
    Option("rr_min_bounces", int, "Min Bounces",
           "Number of bounces every path survives before Russian roulette may terminate it", 3,
           minimum=0, maximum=1024),
    _menu("rr_survival", "Survival",
          "How Russian roulette turns a path's throughput into its probability of going on. "
          "Both rules are unbiased", "square_root",
          _choices(ROULETTE_SURVIVALS, _ROULETTE_SURVIVAL_TEXT)),
    Option("connection_roulette", float, "Connection Roulette",
           "Bidirectional only: Russian roulette of the connections before their shadow rays. "
           "A connection whose contribution is below this many times the mean of its batch's "
           "survives with probability contribution / (this x mean), and survivors are "
           "divided by that probability. Unbiased: a little more noise for fewer shadow rays "
           "(0.3 skips about a quarter of them in a Cornell box). 0 turns it off", 0.0,
           minimum=0.0, maximum=10.0),
    _menu("light_points", "Direct Light Points",
          "Bidirectional only: where the strategy that joins a camera vertex to a point on a "
          "light (s = 1) takes that point. Both are unbiased and weighted alike; they differ "
          "in cost and in how the noise of a sample's connections is shared", "light_path",
          _choices(LIGHT_POINTS, _LIGHT_POINTS_TEXT)),
    _menu("mis_heuristic", "MIS",
          "How light sampling (next-event estimation) and BSDF sampling are combined for direct "
          "light: a multiple importance sampling heuristic, their plain average, or one "
          "strategy alone. Bidirectional weights all its connection strategies with the same "
          "heuristic. Light tracing has no MIS", "power", _choices(MIS_SETTINGS, _MIS_TEXT),
          flag="--mis"),
    Option("mis_beta", float, "Beta",
           "Exponent of the power heuristic: 1 is the balance heuristic, 2 the usual choice, "
           "large values approach the maximum heuristic", 2.0, minimum=0.01, maximum=100.0),
    Option("mis_alpha", float, "Alpha",
           "Cutoff of the cutoff heuristic: a strategy whose density is below alpha times the "
           "largest one gets weight zero (0 is the balance heuristic, 1 the maximum heuristic)",
           0.1, minimum=0.0, maximum=1.0),
    _menu("light_selection", "Light Selection",
          "How next-event estimation chooses which light to sample", "tree",
          _choices(LIGHT_SELECTIONS, _LIGHT_SELECTION_TEXT)),
    _menu("light_sampling", "Area Lights",
          "Path Tracing only: how next-event estimation samples a point on an area light or "
          "emissive triangle, uniformly by area or uniformly over the solid angle it covers. "
          "Light Tracing and Bidirectional start their light paths on emitters sampled by area",
          "area", _choices(LIGHT_SAMPLINGS, _LIGHT_SAMPLING_TEXT)),
    _menu("distribution", "Discrete Sampling",
          "Data structure for discrete choices (lights, emissive triangles, mixed materials' "
          "components): CDF inversion or an alias table. Its build and sampling times are shown "
          "in the render stats", "cdf", _choices(DISTRIBUTION_METHODS, _DISTRIBUTION_TEXT)),
    _menu("filter_type", "Pixel Filter",
          "Pixel reconstruction filter: how camera samples spread over pixels",
          "blackman_harris", FILTER_CHOICES),
    Option("filter_width", float, "Width",
           "Pixel filter width in pixels (as Cycles' filter width)", 1.5, minimum=0.01,
           maximum=10.0),
    Option("threads", int, "Threads",
           "Worker threads; 0 is one per CPU core (in Blender: Render > Performance > Threads)",
           0, minimum=0, maximum=1024),
    _menu("workers", "Workers",
          "Path Tracing, Light Tracing and Bidirectional: where the work units run. Worker "
          "processes share no Python lock, so they scale with the cores better than threads "
          "(each holds its own copy of the scene). The other integrators, a render on one "
          "thread and the viewport use threads", "processes",
          (Choice("processes", "Processes", "One worker process per thread, kept between "
                  "renders; each prepares the scene once"),
           Choice("threads", "Threads", "Worker threads in this process (no start-up, one "
                  "copy of the scene; they share Python's lock)"))),
    Option("strategy_views", bool, "Strategy Views",
           "Bidirectional only: write two render passes per BDPT strategy (s, t) with s light "
           "and t camera vertices, for paths up to Max Path Length: the strategy's own estimate "
           "(as if it were the only one) and its MIS-weighted share of the image (the weighted "
           "shares of one path length add up to that length's part of Combined)", False,
           prop="use_strategy_views"),
    Option("strategy_max_length", int, "Max Path Length",
           "Longest path, in segments, that gets strategy views: 1 is emitters seen directly, "
           "2 direct light, 3 one indirect bounce, and so on. A path of k segments has k + 1 "
           "strategies, so the number of passes grows quadratically", 3, minimum=1, maximum=8),
    Option("photons", int, "Photons",
           "Photon mapping: photons traced from the lights, per pass for SPPM and once for "
           "Photon Mapping's maps. More photons cost time and memory but give less noise (and "
           "with Photon Mapping, whose maps stay fixed, less blur at a given k)", 100000,
           minimum=1, maximum=1 << 26),
    Option("photon_radius", float, "Radius",
           "Photon mapping: lookup radius in scene units, SPPM's initial one (it shrinks every "
           "pass; 0: 1.25 times the scene's bounding-box diagonal over the image's larger side "
           "in pixels, a blur of a few pixels, or per pixel with Initial Radius) and Photon "
           "Mapping's fixed one (0: 1/100 of the diagonal). A larger radius gathers more photons (less noise) but blurs the light "
           "over a larger disk (more bias)", 0.0, minimum=0.0, maximum=1e6),
    Option("sppm_alpha", float, "Alpha",
           "SPPM: fraction of a pass's photons kept when the radius shrinks (Hachisuka and "
           "Jensen's alpha). Small values shrink the radius fast (bias fades sooner, more "
           "noise); values near 1 keep more photons (less noise, bias fades slower)", 0.7,
           minimum=0.01, maximum=0.99),
    _menu("photon_lookup", "Lookup",
          "Photon Mapping: which photons a density estimate uses. k nearest adapts the radius "
          "to the photon density (sharper where photons crowd, blurrier where they are "
          "sparse); a fixed radius blurs evenly but is noisy where photons are sparse", "knn",
          (Choice("knn", "K Nearest", "The k nearest photons, within the distance to the "
                  "k-th one"),
           Choice("radius", "Fixed Radius", "Every photon within Radius"))),
    Option("photon_k", int, "Nearest Photons",
           "Photon Mapping: photons per k-nearest estimate. More photons: less noise, more "
           "blur (bias)", 50, minimum=1, maximum=10000),
    _menu("photon_kernel", "Kernel",
          "Photon Mapping: weight of a photon by its distance in the density estimate; every "
          "kernel integrates to one, so all are consistent. Uniform counts photons equally; "
          "cone and Epanechnikov weigh near photons more (sharper caustic edges, a little more "
          "noise)", "uniform",
          (Choice("uniform", "Uniform", "Every photon in the disk weighs the same"),
           Choice("cone", "Cone", "Weight falls linearly to zero at the radius (Jensen's "
                  "cone filter)"),
           Choice("epanechnikov", "Epanechnikov", "Weight 1 - (d / r)^2: the kernel of "
                  "least mean integrated squared error"))),
    Option("gather_rays", int, "Gather Rays",
           "Photon Mapping: final-gather rays per camera sample that look up the global map "
           "where they land. More rays: smoother indirect light at more cost per sample; 0 "
           "reads the global map at the visible point itself (fast but blotchy)", 8,
           minimum=0, maximum=256),
    Option("photon_memory", float, "Photon Memory",
           "Photon mapping: largest photon storage in MB (photons of one pass and their "
           "kd-tree). A render whose photons could need more stops with a message before it "
           "starts", 1024.0, minimum=1.0, maximum=1 << 20),
    Option("photon_surface_test", bool, "Surface Test",
           "Photon mapping: count only photons on surfaces like the one looked up (normals "
           "within 37 degrees, close to its tangent plane: a disk-shaped lookup, as Jensen's "
           "photon maps). Removes the blur across corners and edges and between nearby "
           "surfaces (less bias there); changes nothing on flat open surfaces, and on curved "
           "ones only while the radius is large against their curvature", True,
           prop="use_photon_surface_test"),
    Option("sppm_coverage", bool, "Edge Correction",
           "SPPM: divide each lookup by the share of its disk that lies on the surface (16 "
           "short probe rays per pixel and pass) instead of the whole disk. Removes the "
           "darkening where the disk reaches past a surface's edge into empty space; costs the "
           "probe rays", True, prop="use_sppm_coverage"),
    _menu("sppm_radius", "Initial Radius",
          "SPPM with Radius 0: how the initial lookup radius is chosen", "adaptive",
          (Choice("scene", "Scene", "One radius for every pixel: 1.25 scene bounding-box "
                  "diagonals over the image's larger side in pixels"),
           Choice("pixel", "Pixel Footprint", "Each pixel's own radius: 1.5 times the width "
                  "of the pixel at its first visible point (path length times the pixel's "
                  "angle). Sharper near the camera and at silhouettes, noisier where few "
                  "photons land"),
           Choice("adaptive", "Adaptive", "Each pixel's own radius from its first pass: the "
                  "scene radius, halved up to three times where the photons within it show "
                  "structure beyond their noise (a disk reaching into a caustic much brighter "
                  "than its centre). Sharper caustic edges, the scene radius elsewhere; still "
                  "biased but consistent (the radius shrinks from there every pass)"))),
    _menu("radiosity_solver", "Solver",
          "Radiosity only: how the radiosity system B = E + rho F B is solved",
          "gauss_seidel", _choices(RADIOSITY_SOLVERS, _RADIOSITY_SOLVER_TEXT)),
    Option("radiosity_patch_size", float, "Patch Size",
           "Radiosity only: target edge length of a patch in Blender units; every triangle is "
           "cut into equal sub-triangles no longer than this. Smaller patches: less bias, "
           "quadratically more patches", 0.5, minimum=1e-3, maximum=1e4),
    Option("radiosity_samples", int, "Form Factor Samples",
           "Radiosity only: points per patch pair for each form factor (with one visibility ray "
           "each), and per patch for the light it receives directly from lamps. Their noise "
           "stays in the solution as a fixed error", 8, minimum=1, maximum=1024),
    Option("radiosity_adaptive", float, "Adaptive Threshold",
           "Radiosity only, not with the Hierarchical solver: after a solve, split the patches "
           "whose radiosity differs from their corners' by more than this fraction of the "
           "brightest patch into four, and solve again (two rounds at most). 0 keeps the uniform "
           "mesh", 0.0, minimum=0.0, maximum=1.0),
    _menu("radiosity_display", "Display",
          "Radiosity only: how camera rays read the solved radiosity", "gouraud",
          _choices(RADIOSITY_DISPLAYS, _RADIOSITY_DISPLAY_TEXT)),
    Option("radiosity_patches", bool, "Patches Pass",
           "Radiosity only: write a Radiosity Patches pass that shows the mesh, one colour per "
           "patch", False, prop="use_radiosity_patches"),
    Option("mlt_large_step", float, "Large Step Probability",
           "Metropolis only: probability that a mutation draws all of a path's numbers afresh "
           "(a large step, which lets a chain jump anywhere: ergodicity) instead of nudging "
           "each one (a small step, which explores near the current path). Any value keeps "
           "the estimate consistent; 0 relies on small steps alone to leave a region", 0.3,
           minimum=0.0, maximum=1.0),
    Option("mlt_bootstrap", int, "Bootstrap Paths",
           "Metropolis only: uniform paths traced first. Their mean luminance estimates the "
           "normalisation b, which scales the whole image (its standard error is in the render "
           "stats), and the chains start from them, chosen in proportion to their luminance. "
           "More paths: a more accurate b", 100000, minimum=2, maximum=1 << 26),
    Option("mlt_chains", int, "Chains per Batch",
           "Metropolis only: the most Markov chains mutated together as one batch of paths "
           "(four batches run side by side). A render uses enough chains for each to run "
           "about 512 mutations of its sample budget (64 per pixel under a time limit alone), "
           "at least 256 per batch, at most this many, never more than pixels: more chains use "
           "the CPU better, but a chain that runs fewer steps than it needs to forget its start "
           "leaves blotches", 8192,
           minimum=1, maximum=1 << 20),
)}

DEFAULTS = {name: option.default for name, option in OPTIONS.items()}


def validate(settings):
    """Check every option of ``settings`` (a ``RenderSettings``) against :data:`OPTIONS`.

    Raises
    ------
    ValueError
        ``"<option>: <value> is not one of <allowed>"`` for the first value out of its menu or
        range.
    """
    for name, option in OPTIONS.items():
        option.check(getattr(settings, name))
