"""Guaranteed dead reckoning with bounded wheel errors as zonotopes (Kühn 1998; Girard 2005; Althoff 2008).

A zonotope ``Z = {c + G ξ : ξ ∈ [−1, 1]^m}`` (centre ``c``, generators the columns of ``G``) is
closed under linear maps and Minkowski sums, so a linearised step keeps the *dependency* of the
pose on every past error: interval boxes (:mod:`pose_uncertainty.methods.intervals`) lose it at
every step (the wrapping / dependency effect of Skalka 2011 §2.8's "too pessimistic" intervals),
a zonotope does not (Kühn 1998, "Rigorously computed orbits of dynamical systems without the
wrapping effect").

Conservative linearisation (Althoff, Stursberg & Buss 2008), on the sum form of the midpoint path
-------------------------------------------------------------------------------------------------
With the per-step errors ``(e_s, e_θ)_k = A_k η_k`` of :mod:`~pose_uncertainty.methods.intervals`
and the start box ``p̄_0 + diag(r_0) ξ_0``, the pose after ``n`` steps is
``x_n = x_0 + Σ_{k<n} (Δs_k + e_s,k) cos(φ̄_k + δφ_k)`` (likewise ``y``) with
``δφ_k = δθ_0 + Σ_{j<k} e_θ,j + e_θ,k/2``. Each term is its first-order part plus a remainder::

    (Δs + e_s) cos(φ̄ + δ) = Δs cos φ̄ + e_s cos φ̄ − Δs sin φ̄ δ + ρ,   |ρ| ≤ |e_s|·|δ| + |Δs| δ²/2

(``|cos(φ̄+δ) − cos φ̄| ≤ |δ|`` and ``|cos''| ≤ 1``; the same for ``sin``), with ``|δφ_k| ≤ R_φ,k``
the exact heading radius. The first-order parts are linear in the ``η`` and ``ξ_0``: the generators
of step ``j`` are ``A_j`` mapped by the lever arm of the rest of the path (the covariance method's
lever arm, :mod:`pose_uncertainty.methods.covariance`), computed for all steps at once; the summed
remainders are two more (box) generators. The result encloses every reachable pose, rigorously (up
to the rounding guard of :func:`~pose_uncertainty.methods.intervals.rounding_guard`), with
``m·n + 5`` generators and no order reduction.

The ``(x, y)`` projection is a centrally symmetric polygon (:func:`zonotope_polygon`), its area
:func:`zonotope_area`; :func:`zonotope_contains_xy` tests points against its half-planes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_finite, check_last_axis
from .intervals import bounded_path, rounding_guard

__all__ = [
    "Zonotope",
    "hull_area",
    "polygon_area",
    "support",
    "zonotope_area",
    "zonotope_contains_xy",
    "zonotope_dead_reckoning",
    "zonotope_polygon",
]

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Zonotope:
    """``{center + generators · ξ : ξ ∈ [−1, 1]^m}``.

    Attributes
    ----------
    center : ndarray, shape (d,); generators : ndarray, shape (d, m)
    """

    center: Array
    generators: Array

    @property
    def radius(self) -> Array:
        """Half-widths of the interval hull ``Σ_j |G_ij|``, shape (d,)."""
        return np.asarray(np.abs(self.generators).sum(axis=1), dtype=np.float64)

    def xy(self) -> Zonotope:
        """The projection on the first two components ``(x, y)``."""
        return Zonotope(self.center[:2], self.generators[:2])


def zonotope_dead_reckoning(
    ds: ArrayLike, dtheta: ArrayLike, error_generators: ArrayLike, *,
    start: ArrayLike = (0.0, 0.0, 0.0), start_radius: ArrayLike = (0.0, 0.0, 0.0),
    checkpoints: ArrayLike | None = None,
) -> list[Zonotope]:  # fmt: skip
    """Zonotopes enclosing the pose under bounded per-step errors (module docs), vectorised over steps.

    Parameters
    ----------
    ds, dtheta : array_like, shape (N,) — measured travel [m] and turn [rad] of each step
    error_generators : array_like, shape (N, 2, m) — per-step errors ``A_k`` in ``(Δs, Δθ)``
    start : array_like, shape (3,); start_radius : array_like, shape (3,) — half-widths of the start box
    checkpoints : sequence of int in [0, N], optional — default the end

    Returns
    -------
    list of Zonotope — one per checkpoint ``n``: centre (3,) the nominal pose, generators
    (3, m·n + 5) [m, m, rad]
    """
    b = bounded_path(ds, dtheta, error_generators, start, start_radius, checkpoints)
    A, nom, r0 = b.generators, b.nominal, b.start_radius
    dx, dy = np.diff(nom[:, 0]), np.diff(nom[:, 1])
    # |ρ_k| ≤ |e_s|·|δφ| + |Δs|·δφ²/2, summed over the steps before each checkpoint
    rho = np.concatenate([[0.0], np.cumsum(b.r_s * b.R_phi + 0.5 * np.abs(b.ds) * b.R_phi**2)])
    out = []
    for n in b.checkpoints:  # a few checkpoints; every step's generators at once
        turn = np.stack([-(nom[n, 1] - nom[1 : n + 1, 1]) - 0.5 * dy[:n],
                         (nom[n, 0] - nom[1 : n + 1, 0]) + 0.5 * dx[:n]], -1)  # fmt: skip
        G_steps = np.empty((3, n, A.shape[2]))
        G_steps[0] = np.cos(b.phi[:n, None]) * A[:n, 0] + turn[:, 0, None] * A[:n, 1]
        G_steps[1] = np.sin(b.phi[:n, None]) * A[:n, 0] + turn[:, 1, None] * A[:n, 1]
        G_steps[2] = A[:n, 1]
        G_start = np.diag(r0)
        G_start[0, 2] = -(nom[n, 1] - nom[0, 1]) * r0[2]
        G_start[1, 2] = (nom[n, 0] - nom[0, 0]) * r0[2]
        g = rounding_guard(np.abs(b.start).sum() + r0.sum() + b.travelled[n], n)
        G_rem = np.diag([rho[n] + g, rho[n] + g])
        G = np.concatenate([G_start, G_steps.reshape(3, -1), np.vstack([G_rem, np.zeros((1, 2))])], axis=1)
        G[2, 2] += float(rounding_guard(abs(b.start[2]) + r0[2] + b.turned[n], n))  # the heading's own guard
        out.append(Zonotope(nom[n].copy(), G))
    return out


def support(z: Zonotope, directions: ArrayLike) -> Array:
    """Support function ``h_Z(u) = u·c + Σ_j |u·g_j|`` for directions ``u`` (K, d), shape (K,)."""
    U = check_last_axis("directions", directions, z.center.shape[0]).reshape(-1, z.center.shape[0])
    return np.asarray(U @ z.center + np.abs(U @ z.generators).sum(axis=1), dtype=np.float64)


def _planar_generators(z: Zonotope) -> tuple[Array, Array]:
    """Centre (2,) and the nonzero generators (m, 2) of a planar zonotope."""
    if z.center.shape != (2,):
        raise ValueError(f"zonotope must be planar (allowed: center shape (2,), use .xy()), got {z.center.shape}")
    G = z.generators.T
    return z.center, G[np.any(G != 0, axis=1)]


def zonotope_polygon(z: Zonotope) -> Array:
    """Vertices of a planar zonotope, counter-clockwise, shape (2m, 2) (one point if m = 0).

    Generators turned into the upper half-plane and sorted by angle; from the lowest vertex
    ``c − Σ g`` the boundary adds ``2g`` in that order, then subtracts them.
    """
    c, G = _planar_generators(z)
    if G.shape[0] == 0:
        return c[None].copy()
    flip = (G[:, 1] < 0) | ((G[:, 1] == 0) & (G[:, 0] < 0))
    G = np.where(flip[:, None], -G, G)
    G = G[np.argsort(np.arctan2(G[:, 1], G[:, 0]), kind="stable")]
    steps = np.concatenate([2 * G, -2 * G])
    return c - G.sum(axis=0) + np.concatenate([np.zeros((1, 2)), np.cumsum(steps[:-1], axis=0)])


def polygon_area(vertices: ArrayLike) -> float:
    """Area of a simple polygon by the shoelace formula [m²], vertices (V, 2) in order."""
    v = check_finite("vertices", check_last_axis("vertices", vertices, 2))
    if v.shape[0] < 3:
        return 0.0
    x, y = v[:, 0], v[:, 1]
    return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def zonotope_area(z: Zonotope) -> float:
    """Area of the ``(x, y)`` projection of a zonotope [m²] (``4 Σ_{i<j} |det(g_i, g_j)|``, via its polygon)."""
    zz = z if z.center.shape == (2,) else z.xy()
    return polygon_area(zonotope_polygon(zz))


def zonotope_contains_xy(z: Zonotope, points: ArrayLike) -> NDArray[np.bool_]:
    """Whether points (..., 2) lie in the ``(x, y)`` projection of ``z`` (half-plane test per generator).

    The projection's edges are parallel to its generators: a point is inside when, for the normal
    ``ν_i ⟂ g_i`` of every generator, ``|ν_i·(p − c)| ≤ Σ_j |ν_i·g_j|``.
    """
    c, G = _planar_generators(z if z.center.shape == (2,) else z.xy())
    p = check_finite("points", check_last_axis("points", points, 2))
    if G.shape[0] == 0:
        return np.asarray(np.all(p == c, axis=-1))
    nu = np.stack([-G[:, 1], G[:, 0]], axis=-1)
    nu /= np.linalg.norm(nu, axis=1, keepdims=True)
    h = np.abs(nu @ G.T).sum(axis=1)  # (m,)
    flat = (p - c).reshape(-1, 2)
    inside = np.ones(flat.shape[0], dtype=bool)
    for a in range(0, flat.shape[0], 4096):  # blocks of points bound the (points × normals) temporary
        inside[a : a + 4096] = np.all(np.abs(flat[a : a + 4096] @ nu.T) <= h * (1 + 1e-12) + 1e-15, axis=1)
    return inside.reshape(p.shape[:-1])


def hull_area(points: ArrayLike) -> float:
    """Area of the convex hull of planar points (n, 2) [m²] (0 for fewer than 3 or collinear points)."""
    p = check_finite("points", check_last_axis("points", points, 2)).reshape(-1, 2)
    if p.shape[0] < 3 or np.linalg.matrix_rank(p - p.mean(axis=0), tol=1e-12) < 2:
        return 0.0
    from scipy.spatial import ConvexHull  # imported where used (only the measures need it)

    return float(ConvexHull(p).volume)
