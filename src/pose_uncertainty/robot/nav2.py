"""nav2 AMCL's differential motion model, and its alphas fitted to the calibrated wheel model.

The fit's machinery (AMCL's update intervals, the maximum likelihood over ``log α``, the
coverage of a 95 % highest-density region) is shared with nav2's omni model (:mod:`.nav2_omni`).

The model, as navigation2 samples it
------------------------------------
``nav2_amcl/src/motion_model/differential_motion_model.cpp`` (ros-navigation/navigation2,
after Thrun, Burgard & Fox 2005, ``sample_motion_model_odometry``), for the odometry
change ``delta = (Δx, Δy, Δθ)`` between two filter updates (odom frame, ``Δθ`` the
wrapped heading difference) from an old odometry heading ``θ_old``::

    δrot1  = 0                                 if √(Δx² + Δy²) < 0.01
           = angle_diff(atan2(Δy, Δx), θ_old)  otherwise
    δtrans = √(Δx² + Δy²)
    δrot2  = angle_diff(Δθ, δrot1)
    n1 = min(|angle_diff(δrot1, 0)|, |angle_diff(δrot1, π)|)   (backward motion is treated
    n2 = min(|angle_diff(δrot2, 0)|, |angle_diff(δrot2, π)|)    like forward motion)
    δ̂rot1  = angle_diff(δrot1, N(0, √(α1 n1² + α2 δtrans²)))
    δ̂trans = δtrans − N(0, √(α3 δtrans² + α4 n1² + α4 n2²))
    δ̂rot2  = angle_diff(δrot2, N(0, √(α1 n2² + α2 δtrans²)))
    x += δ̂trans cos(θ + δ̂rot1),  y += δ̂trans sin(θ + δ̂rot1),  θ += δ̂rot1 + δ̂rot2

(``N(0, σ)`` is ``pf_ran_gaussian(σ)``, a standard deviation.) AMCL applies it only when
the odometry has moved far enough since the last update (``amcl_node.cpp``,
``shouldUpdateFilter``): ``|Δx| > update_min_d or |Δy| > update_min_d or |Δθ| > update_min_a``.

Its density
-----------
A particle starting at the origin with heading 0 ends at ``(X, Y, Θ)`` through two
preimages: ``δ̂trans = +ρ, δ̂rot1 = atan2(Y, X)`` or ``δ̂trans = −ρ, δ̂rot1 = atan2(Y, X) + π``
(``ρ = √(X² + Y²)``; a negative sampled translation drives backwards), with
``δ̂rot2 = Θ − δ̂rot1``. The density is the sum over both of the product of the three
normal densities of the noise draws, divided by ``ρ`` (the polar Jacobian, which does
not depend on the alphas and drops out of the fit).

The fit
-------
The increments AMCL would see are found on the recorded drive (the calibrated odometry
and AMCL's update rule); for each, ``n_samples`` true motions are drawn from the
calibrated wheel model (per wheel sample ``Δs + N(0, k|Δs|)``, exact arcs, an explicit
``numpy.random.Generator``); the alphas maximise the nav2 log-likelihood of all the
draws (L-BFGS-B over ``log α``). The wheel model's variances grow like ``k |Δs|`` while
nav2's grow like ``α δ²``, so the fitted alphas hold for the update thresholds they
were fitted at (they scale roughly like ``1/update_min_d``).

Coverage: for each increment, the nav2 model's 95 % highest-density region (its density
threshold the 5 % quantile of the densities of its own samples) and the fraction of the
wheel model's draws inside it; 0.95 if the two distributions were the same.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import integrate, wrap_angle

__all__ = [
    "DIFFERENTIAL_MODEL",
    "MOTION_CLASSES",
    "OMNI_MODEL",
    "Nav2Fit",
    "amcl_update_indices",
    "fit_log_alphas",
    "fit_nav2_alphas",
    "motion_kinds",
    "nav2_deltas",
    "nav2_logpdf",
    "region_coverage",
    "sample_nav2",
    "update_pairs",
    "wheel_model_draws",
]

#: nav2's plugin name of the differential motion model (``robot_model_type``).
DIFFERENTIAL_MODEL = "nav2_amcl::DifferentialMotionModel"
#: nav2's plugin name of the omni motion model (:mod:`.nav2_omni`).
OMNI_MODEL = "nav2_amcl::OmniMotionModel"

#: Kinds of update increments, for the coverage report.
MOTION_CLASSES: tuple[str, ...] = ("translation", "rotation", "mixed")
_SMALL_TRANS = 0.01  # m: nav2's rule, below it δrot1 = 0
_LOG_2PI = math.log(2 * math.pi)


def _angle_diff(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """nav2's ``angleutils::angle_diff(a, b)``: ``a − b`` wrapped to (−π, π]."""
    return wrap_angle(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))


def nav2_deltas(delta: ArrayLike, theta_old: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """δrot1, δtrans, δrot2 and the folded rotations n1, n2 of odometry changes (module docstring).

    Parameters
    ----------
    delta : array_like, shape (..., 3) — ``(Δx, Δy, Δθ)`` in the odom frame
    theta_old : array_like, shape (...) — odometry heading at the last update [rad]
    """
    d = np.asarray(delta, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise ValueError(f"delta must have shape (..., 3), got shape {d.shape}")
    trans = np.hypot(d[..., 0], d[..., 1])
    rot1 = np.where(trans < _SMALL_TRANS, 0.0, _angle_diff(np.arctan2(d[..., 1], d[..., 0]), theta_old))
    rot2 = _angle_diff(d[..., 2], rot1)
    fold = [np.minimum(np.abs(_angle_diff(r, 0.0)), np.abs(_angle_diff(r, math.pi))) for r in (rot1, rot2)]
    return {"rot1": rot1, "trans": trans, "rot2": rot2, "n1": fold[0], "n2": fold[1]}


def _stds(dl: dict[str, NDArray], alphas: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
    a1, a2, a3, a4 = (float(a) for a in np.asarray(alphas, dtype=np.float64))
    t2 = dl["trans"] ** 2
    s1 = np.sqrt(a1 * dl["n1"] ** 2 + a2 * t2)
    st = np.sqrt(a3 * t2 + a4 * dl["n1"] ** 2 + a4 * dl["n2"] ** 2)
    s2 = np.sqrt(a1 * dl["n2"] ** 2 + a2 * t2)
    return s1, st, s2


def sample_nav2(
    dl: dict[str, NDArray], alphas: ArrayLike, n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``n`` nav2 motions per increment from the origin: shape (M, n, 3) (module docstring)."""
    s1, st, s2 = _stds(dl, alphas)
    M = dl["trans"].shape[0]
    z = rng.standard_normal((3, M, n))
    r1 = _angle_diff(dl["rot1"][:, None], s1[:, None] * z[0])
    tr = dl["trans"][:, None] - st[:, None] * z[1]
    r2 = _angle_diff(dl["rot2"][:, None], s2[:, None] * z[2])
    return np.stack([tr * np.cos(r1), tr * np.sin(r1), r1 + r2], axis=-1)


def _log_normal(x: NDArray, s: NDArray) -> NDArray:
    with np.errstate(divide="ignore"):
        return -0.5 * (x / s) ** 2 - np.log(s) - 0.5 * _LOG_2PI


def nav2_logpdf(points: ArrayLike, dl: dict[str, NDArray], alphas: ArrayLike) -> NDArray[np.float64]:
    """log density of nav2's model at end poses ``points`` (M, n, 3) (module docstring).

    Without the ``−log ρ`` Jacobian; for increments under nav2's 0.01 m rule (turns in
    place) the density of ``(X, Θ)`` instead (:func:`_in_place_logpdf`).
    """
    p = np.asarray(points, dtype=np.float64)
    s1, st, s2 = (v[:, None] for v in _stds(dl, alphas))
    rho = np.hypot(p[..., 0], p[..., 1])
    phi = np.arctan2(p[..., 1], p[..., 0])
    branches = []
    for sign, shift in ((1.0, 0.0), (-1.0, math.pi)):
        rot1_hat = phi + shift
        e1 = _angle_diff(dl["rot1"][:, None], rot1_hat)
        et = dl["trans"][:, None] - sign * rho
        e2 = _angle_diff(dl["rot2"][:, None], p[..., 2] - rot1_hat)
        branches.append(_log_normal(e1, s1) + _log_normal(et, st) + _log_normal(e2, s2))
    full = np.logaddexp(branches[0], branches[1])
    in_place = (dl["trans"] < _SMALL_TRANS)[:, None]
    return np.where(in_place, _in_place_logpdf(p, dl, s1, st, s2), full)


def _in_place_logpdf(p: NDArray, dl: dict[str, NDArray], s1: NDArray, st: NDArray, s2: NDArray) -> NDArray:
    """Turns in place (δrot1 = 0): the density of the travel along the start heading and the heading.

    There ``X ≈ δ̂trans`` and ``Θ = δ̂rot1 + δ̂rot2 ~ N(δrot2, s1² + s2²)``; the direction of
    the sub-centimetre displacement, which the wheel model and nav2 scatter differently
    and which does not matter to a filter, is left out (marginalised).
    """
    et = dl["trans"][:, None] - p[..., 0]
    eth = _angle_diff(dl["rot2"][:, None], p[..., 2])
    return _log_normal(et, st) + _log_normal(eth, np.sqrt(s1**2 + s2**2))


def amcl_update_indices(odom: NDArray[np.float64], update_min_d: float, update_min_a: float) -> NDArray[np.intp]:
    """Indices of the odometry poses (n, 3) at which AMCL updates, the first pose included."""
    keep = [0]
    ref = odom[0]
    for i in range(1, odom.shape[0]):
        d = odom[i] - ref
        if abs(d[0]) > update_min_d or abs(d[1]) > update_min_d or abs(math.remainder(d[2], 2 * math.pi)) > update_min_a:
            keep.append(i)
            ref = odom[i]
    return np.asarray(keep, dtype=np.intp)


def wheel_model_draws(
    ds_l: NDArray, ds_r: NDArray, track: float, k_r: float, k_l: float, n: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """True relative motions under the wheel model: travels (M, K) → draws (M, n, 3)."""
    shape = (ds_l.shape[0], n, ds_l.shape[1])
    z = rng.standard_normal((2, *shape))
    tl = ds_l[:, None, :] + z[0] * np.sqrt(k_l * np.abs(ds_l))[:, None, :]
    tr = ds_r[:, None, :] + z[1] * np.sqrt(k_r * np.abs(ds_r))[:, None, :]
    return integrate((tr + tl) / 2.0, (tr - tl) / track, method="exact")[..., -1, :]


@dataclass(frozen=True)
class Nav2Fit:
    """Fitted alphas with the settings they hold for and the coverage of the wheel model."""

    alphas: tuple[float, ...]
    update_min_d: float
    update_min_a: float
    n_increments: int
    n_samples: int
    coverage: dict[str, Any]
    #: nav2's ``robot_model_type``: four alphas for the differential model, five for the omni model
    model_type: str = DIFFERENTIAL_MODEL

    def as_dict(self) -> dict[str, Any]:
        """The alphas as ``alpha1``…, ``robot_model_type``, the thresholds, the coverage and ``holds_for``."""
        return {
            "robot_model_type": self.model_type,
            **{f"alpha{i + 1}": a for i, a in enumerate(self.alphas)},
            "update_min_d": self.update_min_d, "update_min_a": self.update_min_a,
            "n_increments": self.n_increments, "n_samples": self.n_samples, "coverage": self.coverage,
            "holds_for": (
                f"AMCL updates at update_min_d = {self.update_min_d:g} m, update_min_a = "
                f"{self.update_min_a:g} rad on a drive like the recorded one; the wheel model's "
                "variance grows like |ds| and nav2's like delta^2, so other thresholds need a new fit"
            ),
        }  # fmt: skip


def _increments(
    phi_l: NDArray, phi_r: NDArray, radius_l: float, radius_r: float, track: float, idx: NDArray
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Padded per-step travels (M, K) of each update interval, its odom delta (M, 3) and old heading."""
    ds_l_all, ds_r_all = radius_l * np.diff(phi_l), radius_r * np.diff(phi_r)
    odom = integrate((ds_r_all + ds_l_all) / 2.0, (ds_r_all - ds_l_all) / track, method="exact")
    a, c = idx[:-1], idx[1:]
    K = int((c - a).max())
    steps = a[:, None] + np.arange(K)[None, :]
    inside = steps < c[:, None]
    steps = np.minimum(steps, ds_l_all.size - 1)
    dl, dr = np.where(inside, ds_l_all[steps], 0.0), np.where(inside, ds_r_all[steps], 0.0)
    delta = odom[c] - odom[a]
    delta[:, 2] = wrap_angle(delta[:, 2])
    return dl, dr, delta, odom[a, 2]


def motion_kinds(trans: NDArray, turn: NDArray, update_min_d: float) -> NDArray:
    """:data:`MOTION_CLASSES` of increments: travel under a fifth of ``update_min_d`` is a
    rotation, a turn under 0.05 rad a translation, the rest mixed."""
    small = trans < 0.2 * update_min_d
    straight = turn < 0.05
    return np.where(small, "rotation", np.where(straight, "translation", "mixed"))


def update_pairs(odom: NDArray[np.float64], update_min_d: float, update_min_a: float, max_increments: int) -> NDArray[np.intp]:
    """(start, end) odometry indices (M, 2) of AMCL's update intervals, at most ``max_increments`` (evenly spaced)."""
    idx = amcl_update_indices(odom, update_min_d, update_min_a)
    if idx.size < 5:
        raise ValueError(f"the drive gives only {idx.size - 1} AMCL updates (need at least 4)")
    if idx.size - 1 > max_increments:
        pick = np.unique(np.linspace(0, idx.size - 2, max_increments).round().astype(int))
        return np.stack([idx[pick], idx[pick + 1]], axis=-1)
    return np.stack([idx[:-1], idx[1:]], axis=-1)


def fit_log_alphas(logpdf: Callable[[NDArray], NDArray], x0: ArrayLike) -> tuple[float, ...]:
    """Maximum likelihood: the alphas maximising the mean of ``logpdf(alphas)`` (Nelder–Mead over ``log α`` from ``x0``)."""
    from scipy import optimize  # imported where used: scipy.optimize takes 0.3 s to import

    def nll(log_a: NDArray) -> float:
        v = logpdf(np.exp(log_a))
        return -float(np.mean(v)) if np.all(np.isfinite(v)) else 1e300

    x = np.asarray(x0, dtype=np.float64)
    res = optimize.minimize(nll, x, method="Nelder-Mead",
                            options={"xatol": 1e-3, "fatol": 1e-7, "maxiter": 150 * x.size})  # fmt: skip
    return tuple(float(a) for a in np.exp(res.x))


def fit_nav2_alphas(
    phi_l: NDArray,
    phi_r: NDArray,
    geometry: tuple[float, float, float],
    k: tuple[float, float],
    rng: np.random.Generator,
    update_min_d: float = 0.25,
    update_min_a: float = 0.2,
    n_samples: int = 100,
    max_increments: int = 200,
) -> Nav2Fit:
    """Fit nav2's alphas to the calibrated wheel model on the recorded drive (module docstring).

    Parameters
    ----------
    phi_l, phi_r : (n,) — recorded cumulative wheel angles [rad]
    geometry : (r_l, r_r, b) [m] — calibrated; k : (k_r, k_l) [m] — calibrated
    rng : numpy.random.Generator — the wheel model's draws, then nav2's (coverage)
    update_min_d [m], update_min_a [rad] — AMCL's thresholds
    n_samples : draws per increment; max_increments : at most this many (evenly spaced)
    """
    rl, rr, b = geometry
    ds_l_all, ds_r_all = rl * np.diff(phi_l), rr * np.diff(phi_r)
    odom = integrate((ds_r_all + ds_l_all) / 2.0, (ds_r_all - ds_l_all) / b, method="exact")
    pairs = update_pairs(odom, update_min_d, update_min_a, max_increments)
    dls, drs, deltas, th0 = [], [], [], []
    for a, c in pairs:
        dl_, dr_, de, t0 = _increments(phi_l, phi_r, rl, rr, b, np.array([a, c]))
        dls.append(dl_[0])
        drs.append(dr_[0])
        deltas.append(de[0])
        th0.append(t0[0])
    K = max(x.size for x in dls)
    dl = np.stack([np.pad(x, (0, K - x.size)) for x in dls])
    dr = np.stack([np.pad(x, (0, K - x.size)) for x in drs])
    delta, theta_old = np.stack(deltas), np.array(th0)
    # the odometry delta in the frame of the old pose = the motion from the origin
    draws = wheel_model_draws(dl, dr, b, k[0], k[1], n_samples, rng)
    parts = nav2_deltas(delta, theta_old)

    # start: the wheel model's variances matched at increments of the thresholds' size,
    # k|Δs| against α δ² (straight: heading and travel; in place: heading and travel)
    ks = max(k[0] + k[1], 1e-12)
    d, a = update_min_d, update_min_a
    x0 = np.log([ks / (2 * b * a), ks / (2 * b * b * d), ks / (4 * d), ks * b / (8 * a)])
    alphas = fit_log_alphas(lambda a: nav2_logpdf(draws, parts, a), x0)
    coverage = _coverage(draws, parts, alphas, rng, motion_kinds(parts["trans"], parts["n1"] + parts["n2"], update_min_d))
    return Nav2Fit(alphas, update_min_d, update_min_a, int(pairs.shape[0]), n_samples, coverage)


def _coverage(
    draws: NDArray, parts: dict[str, NDArray], alphas: ArrayLike, rng: np.random.Generator, kinds: NDArray
) -> dict[str, Any]:
    """Fraction of wheel-model draws inside nav2's 95 % highest-density region, overall and by class."""
    own = sample_nav2(parts, alphas, draws.shape[1], rng)
    # the ρ Jacobian matters for a density threshold: log p = log-normal part − log ρ
    in_place = (parts["trans"] < _SMALL_TRANS)[:, None]

    def logp(x: NDArray) -> NDArray:
        jac = np.log(np.maximum(np.hypot(x[..., 0], x[..., 1]), 1e-300))
        return nav2_logpdf(x, parts, alphas) - np.where(in_place, 0.0, jac)

    return region_coverage(draws, own, logp, kinds)


def region_coverage(draws: NDArray, own: NDArray, logp: Callable[[NDArray], NDArray], kinds: NDArray) -> dict[str, Any]:
    """Fraction of ``draws`` (M, n, 3) inside a model's 95 % highest-density region, overall and by class.

    The region of increment ``m``: ``logp ≥`` the 5 % quantile of ``logp`` of the model's own
    samples ``own`` (M, n', 3); ``kinds`` (M,) the increments' :data:`MOTION_CLASSES`.
    """
    tau = np.quantile(logp(own), 0.05, axis=1)
    inside = logp(draws) >= tau[:, None]
    per = inside.mean(axis=1)
    out: dict[str, Any] = {"level": 0.95, "overall": float(per.mean()), "n_draws": int(inside.size)}
    for c in MOTION_CLASSES:
        m = kinds == c
        out[c] = {"increments": int(m.sum()), "coverage": float(per[m].mean()) if m.any() else None}
    return out
