"""nav2 AMCL's omni motion model, and its alphas fitted to an omnidirectional drive's wheel model.

The counterpart of :mod:`.nav2` (the differential model) for the holonomic drives
:class:`~pose_uncertainty.core.drives.Omni3` and :class:`~pose_uncertainty.core.drives.MultiDof`.

The model, as navigation2 samples it
------------------------------------
``nav2_amcl/src/motion_model/omni_motion_model.cpp`` (ros-navigation/navigation2, from
Player's AMCL by Gerkey & Stoy; ``OmniMotionModel::odometryUpdate``), for the odometry
change ``delta = (Δx, Δy, Δθ)`` between two filter updates (odom frame; ``Δθ`` the
wrapped heading difference of ``amcl_node.cpp``'s ``shouldUpdateFilter``) from an old
odometry heading ``θ_old``, and a particle of heading ``θ``::

    δtrans = √(Δx² + Δy²),   δrot = Δθ
    σtrans  = √(α3 δtrans² + α4 δrot²)
    σrot    = √(α1 δrot²   + α2 δtrans²)
    σstrafe = √(α4 δrot²   + α5 δtrans²)
    β = angle_diff(atan2(Δy, Δx), θ_old) + θ
    δ̂trans = δtrans + N(0, σtrans),  δ̂rot = δrot + N(0, σrot),  δ̂strafe = N(0, σstrafe)
    x += δ̂trans cos β + δ̂strafe sin β
    y += δ̂trans sin β − δ̂strafe cos β
    θ += δ̂rot

(``N(0, σ)`` is ``pf_ran_gaussian(σ)``, a standard deviation.) Unlike the differential
model there is no folding of backward motion, no small-translation rule (``atan2(0, 0) = 0``)
and one rotation only; ``α4`` scales both the travel's and the strafe's variance with the
rotation. AMCL applies it under the same update rule (``update_min_d``, ``update_min_a``).

Its density
-----------
For a particle starting at the origin with heading 0 the bearing ``β`` is fixed, and the
end position is the rotation-and-reflection ``(X, Y) = (δ̂trans cos β + δ̂strafe sin β,
δ̂trans sin β − δ̂strafe cos β)`` of two independent normals (Jacobian 1), so the model is
*Gaussian in the end pose itself*: with ``t = X cos β + Y sin β`` (travel along the bearing)
and ``s = X sin β − Y cos β`` (strafe)::

    p(X, Y, Θ) = N(t; δtrans, σtrans) · N(s; 0, σstrafe) · N(Θ; δrot, σrot)

(the heading compared modulo 2π) — a single preimage and no ``ρ`` Jacobian, where the
differential model is Gaussian only in its noise variables ``(δrot1, δtrans, δrot2)``.
Each variance is linear in the alphas.

The fit
-------
The increments AMCL would see are found on the drive's nominal odometry (its exact
integration) and AMCL's update rule (:func:`.nav2.update_pairs`); for each, ``n_samples``
true motions are drawn from the drive's own wheel-noise model
(:func:`pose_uncertainty.methods.drive_noise.sample_errors`, per step; the drive's twists
integrated exactly, from the pose at the last update); the alphas maximise the omni
model's log-likelihood of all the draws (:func:`.nav2.fit_log_alphas`), started from a
non-negative least-squares fit of the three variances. Coverage as for the differential
model (:func:`.nav2.region_coverage`). The drive ties the strafe to the heading (a wheel's
travel error moves and turns the body at once) where nav2 draws them independently, and
the wheel model's variances grow like the travel where nav2's grow like its square: the
fitted alphas hold for the update thresholds they were fitted at.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.atomic import atomic_write_text
from ..core.drives import DrivePath, MultiDof, Omni3
from ..core.kinematics import integrate_twist, wrap_angle
from ..core.validation import check_choice
from ..methods import drive_noise as dn
from .exports import nav2_amcl_yaml
from .nav2 import OMNI_MODEL, Nav2Fit, fit_log_alphas, motion_kinds, region_coverage, update_pairs

__all__ = [
    "OMNI_MODEL",
    "fit_nav2_omni_alphas",
    "ml_omni_alphas",
    "nav2_omni_deltas",
    "nav2_omni_logpdf",
    "omni_wheel_draws",
    "sample_nav2_omni",
    "write_nav2_omni_yaml",
]

_LOG_2PI = math.log(2 * math.pi)


def nav2_omni_deltas(delta: ArrayLike, theta_old: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """δtrans, δrot and the bearing β (for a particle of heading 0) of odometry changes (module docstring).

    Parameters
    ----------
    delta : array_like, shape (..., 3) — ``(Δx, Δy, Δθ)`` in the odom frame, ``Δθ`` wrapped
    theta_old : array_like, shape (...) — odometry heading at the last update [rad]
    """
    d = np.asarray(delta, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"delta must have shape (..., 3), got shape {d.shape}")
    bearing = wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - np.asarray(theta_old, dtype=np.float64))
    return {"trans": np.hypot(d[..., 0], d[..., 1]), "rot": d[..., 2].copy(), "bearing": bearing}


def _omni_stds(parts: dict[str, NDArray], alphas: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
    """σtrans, σrot, σstrafe (M,) of the increments."""
    a1, a2, a3, a4, a5 = (float(a) for a in np.asarray(alphas, dtype=np.float64))
    t2, r2 = parts["trans"] ** 2, parts["rot"] ** 2
    return np.sqrt(a3 * t2 + a4 * r2), np.sqrt(a1 * r2 + a2 * t2), np.sqrt(a4 * r2 + a5 * t2)


def sample_nav2_omni(
    parts: dict[str, NDArray], alphas: ArrayLike, n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``n`` nav2 omni motions per increment from the origin, heading 0: shape (M, n, 3) (module docstring)."""
    st, sr, ss = (v[:, None] for v in _omni_stds(parts, alphas))
    z = rng.standard_normal((3, parts["trans"].shape[0], n))
    trans = parts["trans"][:, None] + st * z[0]
    rot = parts["rot"][:, None] + sr * z[1]
    strafe = ss * z[2]
    c, s = np.cos(parts["bearing"])[:, None], np.sin(parts["bearing"])[:, None]
    return np.stack([trans * c + strafe * s, trans * s - strafe * c, rot], axis=-1)


def nav2_omni_logpdf(points: ArrayLike, parts: dict[str, NDArray], alphas: ArrayLike) -> NDArray[np.float64]:
    """log density of nav2's omni model at end poses ``points`` (M, n, 3), exact (module docstring)."""
    p = np.asarray(points, dtype=np.float64)
    st, sr, ss = (v[:, None] for v in _omni_stds(parts, alphas))
    c, s = np.cos(parts["bearing"])[:, None], np.sin(parts["bearing"])[:, None]
    e = (p[..., 0] * c + p[..., 1] * s - parts["trans"][:, None],
         p[..., 0] * s - p[..., 1] * c,
         wrap_angle(p[..., 2] - parts["rot"][:, None]))  # fmt: skip
    with np.errstate(divide="ignore"):
        return sum((-0.5 * (x / sd) ** 2 - np.log(sd) for x, sd in zip(e, (st, ss, sr), strict=True)),
                   start=np.full(p.shape[:-1], -1.5 * _LOG_2PI))  # fmt: skip


def omni_wheel_draws(
    path: DrivePath, model: dn.DriveErrorModel, pairs: NDArray[np.intp], n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """True relative motions of the update intervals ``pairs`` (M, 2) under the drive's wheel-noise model.

    Per step errors of :func:`~pose_uncertainty.methods.drive_noise.sample_errors` on the
    path's measurements, the drive's twists integrated exactly from the origin: (M, n, 3).
    The intervals are padded to one length with steps without motion and without errors.
    """
    a, c = pairs[:, 0], pairs[:, 1]
    M, K, m = a.size, int((c - a).max()), path.u.shape[1]
    steps = a[:, None] + np.arange(K)[None, :]
    inside = steps < c[:, None]
    u = np.where(inside[..., None], path.u[np.minimum(steps, path.n_steps - 1)], 0.0)  # (M, K, m)
    err = dn.sample_errors(path.drive, u.reshape(M * K, m), path.dt, model, n, rng, "per_step")
    du = err.du.reshape(n, M, K, m) * inside[None, :, :, None]
    twists = path.drive.twist(u[None] + du)  # (n, M, K, 3)
    return np.swapaxes(integrate_twist(twists, (0.0, 0.0, 0.0), "exact")[..., -1, :], 0, 1)


def _moment_start(draws: NDArray, parts: dict[str, NDArray]) -> NDArray[np.float64]:
    """log alphas where the three variances, by non-negative least squares, match the draws' own."""
    from scipy.optimize import nnls

    c, s = np.cos(parts["bearing"])[:, None], np.sin(parts["bearing"])[:, None]
    v_t = np.mean((draws[..., 0] * c + draws[..., 1] * s - parts["trans"][:, None]) ** 2, axis=1)
    v_s = np.mean((draws[..., 0] * s - draws[..., 1] * c) ** 2, axis=1)
    v_r = np.mean(wrap_angle(draws[..., 2] - parts["rot"][:, None]) ** 2, axis=1)
    t2, r2, z = parts["trans"] ** 2, parts["rot"] ** 2, np.zeros_like(v_t)
    # columns α1…α5: σrot² = α1 r² + α2 t², σtrans² = α3 t² + α4 r², σstrafe² = α4 r² + α5 t²
    A = np.concatenate([np.stack([r2, t2, z, z, z], -1), np.stack([z, z, t2, r2, z], -1),
                        np.stack([z, z, z, r2, t2], -1)])  # fmt: skip
    alphas = nnls(A, np.concatenate([v_r, v_t, v_s]))[0]
    return np.log(np.maximum(alphas, 1e-9 * max(float(alphas.max()), 1e-12)))


def ml_omni_alphas(draws: NDArray, parts: dict[str, NDArray]) -> tuple[float, ...]:
    """Maximum-likelihood alpha1…alpha5 of the omni model for end poses ``draws`` (M, n, 3) of the increments ``parts``.

    Nelder–Mead over ``log α`` (:func:`.nav2.fit_log_alphas`) from the non-negative
    least-squares fit of the three variances to the draws' own.
    """
    return fit_log_alphas(lambda a: nav2_omni_logpdf(draws, parts, a), _moment_start(draws, parts))


def fit_nav2_omni_alphas(
    path: DrivePath,
    model: dn.DriveErrorModel,
    rng: np.random.Generator,
    update_min_d: float = 0.25,
    update_min_a: float = 0.2,
    n_samples: int = 100,
    max_increments: int = 200,
) -> Nav2Fit:
    """Fit nav2's omni alphas (alpha1…alpha5) to an omnidirectional drive's wheel model (module docstring).

    Parameters
    ----------
    path : DrivePath — an :class:`~pose_uncertainty.core.drives.Omni3` or
        :class:`~pose_uncertainty.core.drives.MultiDof` drive and the measurements its
        odometry reads along a drive like the robot's (:func:`~pose_uncertainty.core.drives.follow`
        or the measurements themselves)
    model : DriveErrorModel — the drive's wheel noise (``k`` per travel channel, steering noise)
    rng : numpy.random.Generator — the wheel model's draws, then nav2's (coverage)
    update_min_d : float — AMCL's distance threshold [m]; update_min_a : float — its angle threshold [rad]
    n_samples : int — draws per increment; max_increments : int — at most this many (evenly spaced)

    Returns
    -------
    Nav2Fit — ``model_type`` ``"nav2_amcl::OmniMotionModel"``, five alphas; ``as_dict()`` is what
    :func:`.exports.nav2_amcl_yaml` writes
    """
    check_choice("drive", path.drive.kind, (Omni3.kind, MultiDof.kind))  # the differential's: fit_nav2_alphas
    odom = path.poses
    pairs = update_pairs(odom, update_min_d, update_min_a, max_increments)
    delta = odom[pairs[:, 1]] - odom[pairs[:, 0]]
    delta[:, 2] = wrap_angle(delta[:, 2])
    parts = nav2_omni_deltas(delta, odom[pairs[:, 0], 2])
    draws = omni_wheel_draws(path, model, pairs, n_samples, rng)
    alphas = ml_omni_alphas(draws, parts)
    own = sample_nav2_omni(parts, alphas, n_samples, rng)
    kinds = motion_kinds(parts["trans"], np.abs(parts["rot"]), update_min_d)
    coverage = region_coverage(draws, own, lambda x: nav2_omni_logpdf(x, parts, alphas), kinds)
    return Nav2Fit(alphas, update_min_d, update_min_a, int(pairs.shape[0]), n_samples, coverage, OMNI_MODEL)


def write_nav2_omni_yaml(
    path: DrivePath,
    model: dn.DriveErrorModel,
    dest: str | Path,
    *,
    seed: int = 0,
    update_min_d: float = 0.25,
    update_min_a: float = 0.2,
) -> dict[str, Any]:
    """Fit nav2's omni alphas (:func:`fit_nav2_omni_alphas`) and write ``nav2_amcl.yaml`` to ``dest`` (atomically).

    The omnidirectional drive's counterpart of the ``nav2_amcl.yaml`` that ``robot calibrate``
    writes for a differential drive: ``robot_model_type: "nav2_amcl::OmniMotionModel"`` and
    ``alpha1``…``alpha5`` for AMCL's ``update_min_d`` [m] and ``update_min_a`` [rad].
    Randomness from ``numpy.random.default_rng(seed)``. Returns :meth:`.nav2.Nav2Fit.as_dict`.
    """
    fit = fit_nav2_omni_alphas(path, model, np.random.default_rng(seed), update_min_d, update_min_a).as_dict()
    atomic_write_text(Path(dest), nav2_amcl_yaml(fit))
    return fit
