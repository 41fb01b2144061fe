"""Solvers of the radiosity system ``B = E + rho (F B)`` (per colour channel).

``B (p, 3)`` is the radiosity of every patch (W / m^2), ``E`` its emitted (plus directly
received lamp) radiosity, ``rho (p, 3)`` its diffuse albedo and ``F (p, p)`` the form factors.

- :func:`jacobi`: ``B <- E + rho F B`` from ``B = E`` (gathering, stored dense matrix);
- :func:`gauss_seidel`: the same sweep row by row with the newest values (stored matrix);
- :func:`southwell`: progressive refinement (Cohen, Chen, Wallace & Greenberg 1988): shoot the
  patch with the most unshot power to every other patch; needs one column of ``F`` at a time,
  computed on demand, never the matrix.

All three stop when the residual ``r = E + rho F B - B`` has ``max |r| <= tol * max E``; then
``|B - B*| <= max |r| / (1 - q)`` with ``q = max_i rho_i sum_j F_ij < 1``
(:func:`error_bound`), which is what "solver tolerance" means in the tests. Progressive
refinement stops on its unshot radiosity ``dB`` instead: its residual is ``rho F dB``, so
``max |dB|`` bounds it.

Every solver takes ``check(fraction) -> bool``, called between steps: progress, and True to
stop (a cancelled render); it then returns what it has with ``cancelled`` set.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SOLVERS = ("jacobi", "gauss_seidel", "progressive", "hierarchical")


@dataclass
class Solution:
    """What a solver found.

    Attributes
    ----------
    B : (p, 3) float64
        Radiosity per patch.
    iterations : int
        Sweeps (Jacobi, Gauss-Seidel) or shots (progressive).
    residual : float
        ``max |E + rho F B - B|`` at the end; for progressive refinement the largest unshot
        radiosity ``max |dB|``, which bounds it (the residual is ``rho F dB``).
    cancelled : bool
    unshot : list of float
        Progressive refinement: total unshot power ``sum_i A_i sum_c dB_ic`` before every shot
        (and at the end).
    """

    B: np.ndarray
    iterations: int = 0
    residual: float = np.inf
    cancelled: bool = False
    unshot: list = field(default_factory=list)


def _progress(residual, start, target):
    """Fraction done of a geometric convergence from ``start`` to ``target``."""
    if residual <= target or start <= target:
        return 1.0
    return float(np.clip(np.log(start / residual) / np.log(start / target), 0.0, 1.0))


def error_bound(F, rho, residual):
    """Bound on ``max |B - B*|`` from a final ``residual``: ``residual / (1 - q)``, ``q`` the
    largest row sum of ``rho F`` (inf if ``q >= 1``)."""
    q = float((np.max(rho, axis=1) * F.sum(axis=1)).max()) if F.size else 0.0
    return residual / (1.0 - q) if q < 1.0 else np.inf


def jacobi(F, rho, E, tol=1e-4, max_iterations=1000, check=None):
    """Jacobi iteration on a dense ``F (p, p)``; ``rho, E (p, 3)``."""
    B = E.copy()
    target = tol * max(float(np.abs(E).max()), 1e-300)
    start = None
    for k in range(1, max_iterations + 1):
        new = E + rho * (F @ B)
        residual = float(np.abs(new - B).max())
        B = new
        start = start or residual
        if residual <= target:
            return Solution(B, k, residual)
        if check is not None and check(_progress(residual, start, target)):
            return Solution(B, k, residual, cancelled=True)
    return Solution(B, max_iterations, residual)


def gauss_seidel(F, rho, E, tol=1e-4, max_iterations=1000, check=None, rows_per_check=256):
    """Gauss-Seidel sweeps (rows in order, newest values) on a dense ``F (p, p)``."""
    B = E.copy()
    p = B.shape[0]
    target = tol * max(float(np.abs(E).max()), 1e-300)
    start = None
    residual = np.inf
    for k in range(1, max_iterations + 1):
        for i in range(p):
            B[i] = E[i] + rho[i] * (F[i] @ B)
            if check is not None and (i + 1) % rows_per_check == 0 and check(
                    _progress(residual, start or residual, target) if start else 0.0):
                return Solution(B, k, residual, cancelled=True)
        residual = float(np.abs(E + rho * (F @ B) - B).max())
        start = start or residual
        if residual <= target:
            return Solution(B, k, residual)
        if check is not None and check(_progress(residual, start, target)):
            return Solution(B, k, residual, cancelled=True)
    return Solution(B, max_iterations, residual)


def southwell(column, area, rho, E, tol=1e-4, max_shots=None, check=None):
    """Progressive refinement: shoot the unshot radiosity of the patch with the most unshot
    power, ``B_j += rho_j F_ji dB_i`` for all ``j``, until ``max dB <= tol * max E``.

    Parameters
    ----------
    column : callable(i) -> (p,) float64
        Column ``F[:, i]`` (form factors of every patch toward ``i``), computed on demand.
    area : (p,) float64
    rho, E : (p, 3) float64
    max_shots : int or None
        Default ``50 p``.
    """
    p = E.shape[0]
    B, dB = E.copy(), E.copy()
    target = tol * max(float(np.abs(E).max()), 1e-300)
    max_shots = 50 * p if max_shots is None else max_shots
    power = area * dB.sum(axis=1)
    unshot = [float(power.sum())]
    start = float(np.abs(dB).max())
    for k in range(max_shots):
        residual = float(np.abs(dB).max())
        if residual <= target:
            return Solution(B, k, residual, unshot=unshot)
        if check is not None and check(_progress(residual, start, target)):
            return Solution(B, k, residual, cancelled=True, unshot=unshot)
        i = int(np.argmax(power))
        shot = dB[i].copy()
        gain = rho * column(i)[:, None] * shot[None, :]
        dB[i] = 0.0
        B += gain
        dB += gain
        power = area * dB.sum(axis=1)
        unshot.append(float(power.sum()))
    return Solution(B, max_shots, float(np.abs(dB).max()), unshot=unshot)
