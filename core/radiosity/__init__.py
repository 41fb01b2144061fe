"""Finite-element radiosity: the scene's diffuse surfaces as patches of constant radiosity.

- :mod:`.mesh`: uniform subdivision into two-sided patches; locating hits; Gouraud corners;
- :mod:`.form_factors`: analytic point-to-polygon form factors times Embree visibility;
- :mod:`.sources`: lamps and the world shot directly onto the patches;
- :mod:`.solvers`: Jacobi, Gauss-Seidel, progressive refinement (Southwell);
- :mod:`.hierarchical`: hierarchical radiosity (Hanrahan, Salzman & Aupperle 1991);
- :mod:`.adaptive`: adaptive subdivision where the solved radiosity changes fast;
- :mod:`.system`: one solve of a prepared scene (what the integrator runs).

Radiosity is a biased estimator, and not consistent unless the mesh refines: see
``docs/RADIOSITY.md``.
"""
