"""Photons: what the photon-mapping estimators (:mod:`core.integrators.photon`,
:mod:`core.integrators.sppm`) share.

- :mod:`.tracing`: photon tracing from the lights (vectorised over photons, driven by a
  :class:`~core.sampling.stream.SampleStream`), float32 storage with a memory cap;
- :mod:`.lookup`: neighbour queries over photon positions through ``scipy.spatial.cKDTree``;
- :mod:`.grid`: pbrt-v4's uniform grid over query points, the same pairs (benchmarked against
  the kd-tree in ``tools/photons.py``; slower, so unused by the integrators);
- :mod:`.kernels`: density-estimation kernels (uniform, cone, Epanechnikov), normalised in 2-D;
- :mod:`.estimate`: radiance estimates from a photon map (k nearest or fixed radius);
- :mod:`.visible`: camera paths through specular chains to the first non-specular surface;
- :mod:`.passes`: photons and camera paths straight through transparent surfaces (no bounce);
- :mod:`.compatible`: the surface-compatibility test of a lookup (a disk, not a ball);
- :mod:`.coverage`: the share of a lookup disk on its surface (SPPM's edge correction);
- :mod:`.adaptive`: SPPM's adaptive radius (nested disks per pixel, Lepski's rule).
"""

# The stages use the integrators' common stages, and two integrators use these stages: load the
# integrators first, whichever module of either package is imported first.
from .. import integrators  # noqa: E402,F401
