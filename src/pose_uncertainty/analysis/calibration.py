"""Calibration: error constants estimated from observed poses, with confidence intervals.

Wheel-noise constants ``k_r, k_l`` (Method A's model)
------------------------------------------------------
Data: end poses ``p_1 … p_n`` of repeated runs of one known trajectory (a CSV
of measurements, or the Monte Carlo cloud of a run log). Model: the end pose
is Gaussian with mean the noiseless end pose and covariance linear in the
constants,

    Σ(k) = k_r G_r + k_l G_l

where ``G_r, G_l`` are the propagated covariances for unit constants. Two
coordinate choices (``coords``):

* ``"expcoords"`` (default): residuals ``ε_j = log(μ⁻¹ p_j)`` and ``G`` from
  :func:`pose_uncertainty.methods.expcoords.propagate` — the banana-shaped model, which
  stays right where the Cartesian Gaussian fails (see :mod:`accuracy`);
* ``"cartesian"``: residuals ``p_j − μ`` (heading unwrapped) and ``G`` from
  :func:`pose_uncertainty.methods.covariance.propagate` — Method A itself. It is
  biased once the heading spread is large (a quarter of a radian or so),
  because the cloud is not Gaussian in (x, y, θ).

With the scatter ``S = (1/n) Σ_j d_j d_jᵀ`` the log-likelihood is

    ℓ(k) = −(n/2) [tr(Σ(k)⁻¹ S) + log det Σ(k) + 3 log 2π]

maximised over ``k ≥ 0`` (L-BFGS-B on scaled parameters). With
``equal=True`` one constant ``k = k_r = k_l`` is fitted. The data are assumed
to come from the per-step (random-walk) regime; a per-run (systematic) error
gives a rank-2 covariance this model does not describe.

Motion-model constants ``α``
----------------------------
Data: single-step samples ``x_t`` from known start poses and controls. The
sampler's noise draws are recovered exactly by inverting the model
(:func:`pose_uncertainty.methods.motion_models.velocity_inverse`,
:func:`~pose_uncertainty.methods.motion_models.odometry_deltas`): residuals ``V̂ − V``,
``ω̂ − ω``, ``γ̂`` (velocity) or ``δ̂ − δ`` (odometry), each normal with a
variance linear in the α's and in known features of the control (``V², ω²``,
``δrot1², δtrans², …`` — the variances of the *sampler*, evaluated at the
control). Each group is a variance regression ``r ~ N(0, Σ_a α_a f_a)``,
fitted by maximum likelihood. With one control only the sums (e.g.
``α1V² + α2ω²``) are identifiable: give several different controls. For
triangular noise the same estimator is the Gaussian quasi-MLE: consistent
(the variance is still linear in α) but its intervals are then approximate.

Confidence intervals
--------------------
``ci_method="profile"`` (default): the profile-likelihood interval
``{a: 2(ℓ̂ − max_{others} ℓ(a, ·)) ≤ χ²₁(level)}``, clipped at 0;
``"fisher"``: ``â ± z √(I⁻¹)_aa`` from the expected Fisher information
(``I_ab = (n/2) tr(Σ⁻¹G_aΣ⁻¹G_b)``; ``½ Σ f_a f_b / v²`` for the regressions).
Standard errors always come from the Fisher information.

CSV files
---------
Comma-separated with a header row; extra columns are ignored. End poses need
``x, y, theta`` [m, m, rad] (:func:`read_end_poses_csv`); velocity samples
``v, omega, dt, x, y, theta`` and odometry samples ``odo_x0, odo_y0,
odo_theta0, odo_x1, odo_y1, odo_theta1, x, y, theta``, both optionally with
the start pose ``x0, y0, theta0`` (default 0) (:func:`read_motion_samples_csv`).
Errors name the file, the line, the column and the problem.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import wrap_angle
from ..core.stats import chi2_ppf
from ..core.trajectories import Trajectory
from ..core.validation import check_choice, check_finite, check_last_axis, check_probability
from ..methods import covariance as cv
from ..methods import expcoords as ec
from ..methods.motion_models import odometry_deltas, velocity_inverse

__all__ = [
    "CI_METHODS",
    "COORDS",
    "MIN_ROWS",
    "SCALINGS",
    "CalibrationResult",
    "fit_alphas_odometry",
    "fit_alphas_velocity",
    "fit_k",
    "fit_variance_regression",
    "read_csv_columns",
    "read_end_poses_csv",
    "read_motion_samples_csv",
]

COORDS: tuple[str, ...] = ("expcoords", "cartesian")
CI_METHODS: tuple[str, ...] = ("profile", "fisher")
#: Fewest rows a calibration CSV may have (a covariance of 3-D poses from fewer is meaningless).
MIN_ROWS: int = 10


@dataclass(frozen=True)
class CalibrationResult:
    """Maximum-likelihood estimates with confidence intervals.

    Attributes
    ----------
    names : tuple of str — parameter names (``k_r``, ``alpha1``, …)
    estimate, std_error, ci_low, ci_high : tuple of float — per parameter
    level : float — confidence level of the intervals
    ci_method : str — ``"profile"`` or ``"fisher"``
    loglik : float — maximised log-likelihood
    n : int — number of observations
    model : str — what was fitted
    info : dict — extra details (coordinates, trajectory, …)
    """

    names: tuple[str, ...]
    estimate: tuple[float, ...]
    std_error: tuple[float, ...]
    ci_low: tuple[float, ...]
    ci_high: tuple[float, ...]
    level: float
    ci_method: str
    loglik: float
    n: int
    model: str
    info: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable mapping."""
        return {
            "model": self.model,
            "n": self.n,
            "level": self.level,
            "ci_method": self.ci_method,
            "loglik": self.loglik,
            "parameters": {
                name: {
                    "estimate": est,
                    "std_error": se,
                    "ci_low": lo,
                    "ci_high": hi,
                }
                for name, est, se, lo, hi in zip(
                    self.names, self.estimate, self.std_error, self.ci_low, self.ci_high, strict=True
                )
            },
            "info": self.info,
        }

    def format(self) -> str:
        """A small text table."""
        pct = f"{100 * self.level:g} %"
        lines = [
            f"{self.model}: n = {self.n}, log-likelihood = {self.loglik:.6g}, {pct} CI ({self.ci_method})",
            f"{'parameter':<10} {'estimate':>12} {'std error':>12} {'CI low':>12} {'CI high':>12}",
        ]
        for name, est, se, lo, hi in zip(
            self.names, self.estimate, self.std_error, self.ci_low, self.ci_high, strict=True
        ):
            lines.append(f"{name:<10} {est:12.5g} {se:12.5g} {lo:12.5g} {hi:12.5g}")
        return "\n".join(lines)


# --- generic maximum likelihood with profile intervals ------------------------------------------


Objective = Callable[[NDArray], tuple[float, NDArray]]


def _minimise(nll: Objective, x0: NDArray) -> NDArray:
    """argmin over x ≥ 0 of ``nll`` (returns value and gradient; parameters scaled to order 1)."""
    from scipy import optimize  # imported where used: scipy.optimize takes 0.3 s to import

    best = None
    for start in (x0, np.full_like(x0, 1.0)):
        res = optimize.minimize(
            nll, start, jac=True, method="L-BFGS-B", bounds=[(0.0, None)] * x0.size,
            options={"ftol": 1e-15, "gtol": 1e-9, "maxiter": 2000},
        )
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    return np.asarray(best.x, dtype=float)


def _profile_interval(
    nll: Objective, xhat: NDArray, j: int, crit: float, se: float
) -> tuple[float, float]:
    """Profile-likelihood interval of parameter j: where 2(nll_p − nll_min) = crit."""
    from scipy import optimize  # imported where used: scipy.optimize takes 0.3 s to import

    nll_min = nll(xhat)[0]
    others = [i for i in range(xhat.size) if i != j]

    def profile(t: float) -> float:
        if not others:
            return nll(np.array([t]))[0]

        def inner(z: NDArray) -> tuple[float, NDArray]:
            x = np.empty(xhat.size)
            x[j] = t
            x[others] = z
            f, g = nll(x)
            return f, g[others]

        if len(others) == 1:  # one nuisance parameter: bounded Brent (cheaper than L-BFGS-B)
            top = 10.0 * max(1.0, float(np.max(xhat)))
            sres = optimize.minimize_scalar(
                lambda z: inner(np.array([z]))[0], bounds=(0.0, top), method="bounded",
                options={"xatol": 1e-9 * top},
            )
            return float(sres.fun)
        res = optimize.minimize(
            inner, xhat[others], jac=True, method="L-BFGS-B",
            bounds=[(0.0, None)] * len(others), options={"ftol": 1e-15, "gtol": 1e-9},
        )
        return float(res.fun)

    def g(t: float) -> float:
        return 2.0 * (profile(t) - nll_min) - crit

    step = max(se, 1e-6 * max(abs(xhat[j]), 1e-12), 1e-12)
    # lower end
    if xhat[j] <= 0 or g(0.0) <= 0:
        lo = 0.0
    else:
        lo = float(optimize.brentq(g, 0.0, xhat[j], xtol=1e-10 * max(xhat[j], 1e-300)))
    # upper end: expand until the criterion is exceeded
    hi_b = xhat[j] + step
    for _ in range(200):
        if g(hi_b) > 0:
            break
        step *= 2.0
        hi_b = xhat[j] + step
    hi = float(optimize.brentq(g, xhat[j], hi_b, xtol=1e-10 * max(hi_b, 1e-300)))
    return lo, hi


def _finish(
    names: Sequence[str],
    nll: Objective,
    xhat: NDArray,
    fisher: NDArray,
    scale: NDArray,
    level: float,
    ci_method: str,
    n: int,
    model: str,
    info: dict[str, Any],
) -> CalibrationResult:
    """Estimates, Fisher standard errors and intervals in original units (x = θ/scale)."""
    try:
        cov = np.linalg.inv(fisher)
        se_scaled = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        se_scaled = np.full(xhat.size, np.inf)
    from scipy.special import ndtri  # imported where used (0.2 s)

    z = float(ndtri(0.5 + level / 2.0))
    crit = float(chi2_ppf(level, 1))
    lows, highs = [], []
    for j in range(xhat.size):
        if ci_method == "fisher":
            lo, hi = max(0.0, xhat[j] - z * se_scaled[j]), xhat[j] + z * se_scaled[j]
        else:
            lo, hi = _profile_interval(nll, xhat, j, crit, float(se_scaled[j]))
        lows.append(lo * scale[j])
        highs.append(hi * scale[j])
    return CalibrationResult(
        names=tuple(names),
        estimate=tuple(float(v) for v in xhat * scale),
        std_error=tuple(float(v) for v in se_scaled * scale),
        ci_low=tuple(float(v) for v in lows),
        ci_high=tuple(float(v) for v in highs),
        level=level,
        ci_method=ci_method,
        loglik=float(-nll(xhat)[0]),
        n=n,
        model=model,
        info=info,
    )


# --- k_r, k_l from end poses ---------------------------------------------------------------------


def _unit_model(trajectory: Trajectory, coords: str) -> tuple[NDArray, NDArray]:
    """End pose μ and the unit covariances G (2, 3, 3) for (k_r, k_l) = (1, 0), (0, 1)."""
    unit_r, unit_l = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    if coords == "expcoords":
        e = ec.propagate(trajectory, unit_r, unit_l)
        return trajectory.poses[-1], e.covs[:, -1]
    a = cv.propagate(trajectory, unit_r, unit_l)
    return a.poses[0, -1], a.covs[:, -1]


def fit_k(
    end_poses: ArrayLike,
    trajectory: Trajectory,
    *,
    coords: str = "expcoords",
    equal: bool = False,
    level: float = 0.95,
    ci_method: str = "profile",
) -> CalibrationResult:
    """Maximum-likelihood ``k_r, k_l`` from end poses of repeated runs of ``trajectory``.

    Parameters
    ----------
    end_poses : array_like, shape (n, 3) — observed end poses [m, m, rad], n ≥ MIN_ROWS,
        headings unwrapped or within π of the noiseless end heading
    trajectory : Trajectory — the known commanded trajectory
    coords : {"expcoords", "cartesian"} — the model (module docstring)
    equal : bool — fit one constant ``k = k_r = k_l``
    level : float in (0, 1) — confidence level
    ci_method : {"profile", "fisher"}

    Returns
    -------
    CalibrationResult with parameters ``k_r, k_l`` (or ``k``) [m]
    """
    check_choice("coords", coords, COORDS)
    check_choice("ci_method", ci_method, CI_METHODS)
    lvl = float(check_probability("level", level))
    p = _check_end_poses(end_poses)
    mu, G = _unit_model(trajectory, coords)
    d = _end_pose_residuals(p, mu, coords)
    n = d.shape[0]
    S = d.T @ d / n
    if equal:
        G = G.sum(axis=0)[None]
    # moment start: match the trace of S
    tr_g = np.array([np.trace(g) for g in G])
    k0 = np.trace(S) / tr_g.sum()
    scale = np.full(G.shape[0], k0 if k0 > 0 else 1e-6)
    Gs = G * scale[:, None, None]
    nll = _gaussian_nll(Gs, S, n)
    xhat = _minimise(nll, np.ones(G.shape[0]))
    fisher = _gaussian_fisher(xhat, Gs, n)
    names = ("k",) if equal else ("k_r", "k_l")
    info = {"coords": coords, "trajectory": trajectory.name, "end_pose": [float(v) for v in mu]}
    return _finish(names, nll, xhat, fisher, scale, lvl, ci_method, n, f"k ({coords})", info)


def _check_end_poses(end_poses: ArrayLike) -> NDArray:
    """End poses (n, 3), finite, with n ≥ :data:`MIN_ROWS`."""
    p = check_last_axis("end_poses", end_poses, 3)
    if p.ndim != 2 or p.shape[0] < MIN_ROWS:
        raise ValueError(
            f"end_poses must have shape (n, 3) with n >= {MIN_ROWS} (allowed: at least "
            f"{MIN_ROWS} runs), got shape {p.shape}"
        )
    check_finite("end_poses", p)
    return p


def _end_pose_residuals(p: NDArray, mu: NDArray, coords: str) -> NDArray:
    """Residuals (n, 3) of end poses ``p`` from the model's end pose ``mu``, in ``coords``."""
    if coords == "expcoords":
        return ec.coordinates(p, mu)
    d = p - mu
    # headings: the residual nearest to the noiseless heading
    d[:, 2] = np.mod(d[:, 2] + np.pi, 2 * np.pi) - np.pi
    return d


def _gaussian_nll(Gs: NDArray, S: NDArray, n: int) -> Objective:
    """Negative log-likelihood of ``n`` zero-mean residuals of scatter ``S`` (3, 3).

    The model covariance is ``Σ = Σ_a x_a Gs_a``; returns value and gradient in ``x``.
    """

    def nll(x: NDArray) -> tuple[float, NDArray]:
        # −ℓ = (n/2)[tr(Σ⁻¹S) + log det Σ + 3 log 2π];  ∂/∂x_a = (n/2)[tr(Σ⁻¹G_a) − tr(Σ⁻¹SΣ⁻¹G_a)]
        Sig = np.tensordot(x, Gs, axes=1)
        sign, logdet = np.linalg.slogdet(Sig)
        if sign <= 0:
            return 1e300, -np.ones_like(x)  # singular: push the constants up
        Si = np.linalg.inv(Sig)
        M = Si - Si @ S @ Si
        f = 0.5 * n * (float(np.trace(Si @ S)) + logdet + 3 * math.log(2 * math.pi))
        return f, 0.5 * n * np.einsum("ij,aji->a", M, Gs)

    return nll


def _gaussian_fisher(xhat: NDArray, Gs: NDArray, n: int) -> NDArray:
    """Fisher information at ``xhat``: ``(n/2) tr(Σ⁻¹G_a Σ⁻¹G_b)`` with ``Σ = Σ_a x_a Gs_a``."""
    Sig = np.tensordot(xhat, Gs, axes=1)
    Si = np.linalg.inv(Sig)
    return np.array([[0.5 * n * np.trace(Si @ a @ Si @ b) for b in Gs] for a in Gs])


# --- variance regressions: motion-model alphas -----------------------------------------------------


def fit_variance_regression(
    residuals: ArrayLike,
    features: ArrayLike,
    names: Sequence[str],
    *,
    level: float = 0.95,
    ci_method: str = "profile",
    model: str = "variance regression",
) -> CalibrationResult:
    """MLE of ``α ≥ 0`` in ``r_i ~ N(0, Σ_a α_a F_ia)``.

    Parameters
    ----------
    residuals : array_like, shape (m,)
    features : array_like, shape (m, p) — nonnegative
    names : p parameter names
    level, ci_method : as :func:`fit_k`

    Returns
    -------
    CalibrationResult
    """
    from scipy import optimize  # imported where used: scipy.optimize takes 0.3 s to import

    check_choice("ci_method", ci_method, CI_METHODS)
    lvl = float(check_probability("level", level))
    r = check_finite("residuals", residuals).ravel()
    F = check_finite("features", features)
    if F.ndim != 2 or F.shape[0] != r.size or F.shape[1] != len(names):
        raise ValueError(
            f"features must have shape (m, p) = ({r.size}, {len(names)}), got shape {F.shape}"
        )
    # method-of-moments start: nonnegative least squares of r² on F
    a0, _ = optimize.nnls(F, r**2)
    col = np.abs(F).mean(axis=0)
    if np.any(col == 0):
        bad = [names[int(i)] for i in np.flatnonzero(col == 0)]
        raise ValueError(
            f"the data do not identify {', '.join(bad)} (allowed: controls for which each "
            "constant's feature is nonzero in some sample)"
        )
    typical = float(np.mean(r**2) / np.mean(F.sum(axis=1)))
    scale = np.where(a0 > 0, a0, typical if typical > 0 else 1.0)
    Fs = F * scale
    r2 = r**2
    floor = 1e-12 * max(float(np.mean(r2)), 1e-300)  # a zero variance: likelihood ~ 0, finite

    def nll(x: NDArray) -> tuple[float, NDArray]:
        # −ℓ = ½ Σ [r²/v + log v + log 2π],  v = F x;  ∂/∂x_a = ½ Σ F_a (1/v − r²/v²)
        v = np.maximum(Fs @ x, floor)
        f = float(0.5 * np.sum(r2 / v + np.log(v) + math.log(2 * math.pi)))
        return f, 0.5 * Fs.T @ ((1.0 - r2 / v) / v)

    xhat = _minimise(nll, a0 / scale)
    v = np.maximum(Fs @ xhat, floor)
    fisher = 0.5 * (Fs / v[:, None]).T @ (Fs / v[:, None])
    return _finish(names, nll, xhat, fisher, scale, lvl, ci_method, r.size, model, {})


#: Variance features of the α fits: squared (``α V²``) or absolute (``α|V|``) control components.
SCALINGS: tuple[str, ...] = ("squared", "abs")


def _power(a: NDArray, scaling: str) -> NDArray:
    """A variance feature of one control component: ``a²`` (``"squared"``) or ``|a|`` (``"abs"``)."""
    return a * a if scaling == "squared" else np.abs(a)


def _features(a: NDArray, b: NDArray, scaling: str) -> NDArray:
    """The two features (m, 2) of a noise whose variance is ``α a² + α' b²`` (or ``|a|, |b|``)."""
    return np.stack([_power(a, scaling), _power(b, scaling)], axis=-1)


def _per_sample(name: str, value: ArrayLike, m: int, k: int) -> NDArray:
    """``value`` of shape (m, k) or (k,), checked and broadcast to one row per sample."""
    return np.broadcast_to(check_last_axis(name, value, k), (m, k))


def _single_step_fit(
    model: str,
    groups: Sequence[tuple[str, NDArray, NDArray, tuple[str, ...]]],
    level: float,
    ci_method: str,
) -> dict[str, CalibrationResult]:
    """One variance regression per noise group ``(key, residuals, features, α names)`` of ``model``."""
    return {
        key: fit_variance_regression(
            r, F, names, level=level, ci_method=ci_method, model=f"{model}, {key} noise"
        )
        for key, r, F, names in groups
    }


def fit_alphas_velocity(
    samples: ArrayLike,
    controls: ArrayLike,
    dt: ArrayLike,
    starts: ArrayLike = (0.0, 0.0, 0.0),
    *,
    scaling: str = "squared",
    level: float = 0.95,
    ci_method: str = "profile",
) -> dict[str, CalibrationResult]:
    """MLE of the velocity model's ``α1 … α6`` from single-step samples.

    Parameters
    ----------
    samples : array_like, shape (m, 3) — end poses ``x_t``
    controls : array_like, shape (m, 2) or (2,) — ``(V, ω)`` of each sample [m/s, rad/s]
    dt : float or array_like, shape (m,) [s]
    starts : array_like, shape (m, 3) or (3,) — start poses
    scaling : {"squared", "abs"} — variance ``α V² + …`` or ``α|V| + …``

    Returns
    -------
    dict: ``"V"`` (α1, α2), ``"omega"`` (α3, α4), ``"gamma"`` (α5, α6)
    """
    check_choice("scaling", scaling, SCALINGS)
    x = check_last_axis("samples", samples, 3)
    m = x.shape[0]
    u = _per_sample("controls", controls, m, 2)
    dts = np.broadcast_to(check_finite("dt", dt), (m,))
    x0 = _per_sample("starts", starts, m, 3)
    V_hat = np.empty(m)
    w_hat = np.empty(m)
    g_hat = np.empty(m)
    for d in np.unique(dts):  # velocity_inverse takes a scalar dt
        sel = dts == d
        V_hat[sel], w_hat[sel], g_hat[sel] = velocity_inverse(x[sel], x0[sel], float(d))
    F = _features(u[:, 0], u[:, 1], scaling)
    groups = (
        ("V", V_hat - u[:, 0], F, ("alpha1", "alpha2")),
        ("omega", w_hat - u[:, 1], F, ("alpha3", "alpha4")),
        ("gamma", g_hat, F, ("alpha5", "alpha6")),
    )
    return _single_step_fit("velocity model", groups, level, ci_method)


def fit_alphas_odometry(
    samples: ArrayLike,
    odom_prev: ArrayLike,
    odom_next: ArrayLike,
    starts: ArrayLike = (0.0, 0.0, 0.0),
    *,
    scaling: str = "squared",
    level: float = 0.95,
    ci_method: str = "profile",
) -> dict[str, CalibrationResult]:
    """MLE of the odometry model's ``α1 … α4`` from single-step samples.

    ``α1, α2`` are fitted from the residuals of both rotations together
    (variances ``α1 δrot² + α2 δtrans²``), ``α3, α4`` from the translation
    (``α3 δtrans² + α4 (δrot1² + δrot2²)``), with the sampler's variances
    (evaluated at the odometry ``δ``).

    Parameters
    ----------
    samples : array_like, shape (m, 3)
    odom_prev, odom_next : array_like, shape (m, 3) or (3,) — odometry poses ``x̄, x̄'``
    starts : array_like, shape (m, 3) or (3,)

    Returns
    -------
    dict: ``"rotation"`` (α1, α2), ``"translation"`` (α3, α4)
    """
    check_choice("scaling", scaling, SCALINGS)
    x = check_last_axis("samples", samples, 3)
    m = x.shape[0]
    op = _per_sample("odom_prev", odom_prev, m, 3)
    on = _per_sample("odom_next", odom_next, m, 3)
    x0 = _per_sample("starts", starts, m, 3)
    r1, tr, r2 = odometry_deltas(op, on)
    h1, ht, h2 = odometry_deltas(x0, x, ref_rot1=r1)
    # the sampler draws δ̂ = δ − noise: residuals δ − δ̂ are the noise draws
    res_rot = np.concatenate([wrap_angle(r1 - h1), wrap_angle(r2 - h2)])
    F_rot = np.concatenate([_features(r1, tr, scaling), _features(r2, tr, scaling)])
    F_tr = np.stack([_power(tr, scaling), _power(r1, scaling) + _power(r2, scaling)], axis=-1)
    groups = (
        ("rotation", res_rot, F_rot, ("alpha1", "alpha2")),
        ("translation", tr - ht, F_tr, ("alpha3", "alpha4")),
    )
    return _single_step_fit("odometry model", groups, level, ci_method)


# --- CSV ----------------------------------------------------------------------------------------

END_POSE_COLUMNS: tuple[str, ...] = ("x", "y", "theta")
VELOCITY_COLUMNS: tuple[str, ...] = ("v", "omega", "dt", "x", "y", "theta")
ODOMETRY_COLUMNS: tuple[str, ...] = (
    "odo_x0", "odo_y0", "odo_theta0", "odo_x1", "odo_y1", "odo_theta1", "x", "y", "theta",
)
START_COLUMNS: tuple[str, ...] = ("x0", "y0", "theta0")


def read_csv_columns(
    path: str | Path,
    required: Sequence[str],
    optional: Sequence[str] = (),
    *,
    text: Sequence[str] = (),
    min_rows: int = MIN_ROWS,
) -> dict[str, NDArray[Any]]:
    """Read columns from a CSV with a header; ValueError naming file, line, column, problem.

    Columns are numeric (finite floats) except those named in ``text``, which are
    returned as stripped, lower-cased strings. Header names are matched
    case-insensitively; blank lines are skipped; at least ``min_rows`` data rows.
    """
    p = Path(path)
    rows = _read_csv_rows(p, required)
    columns = _wanted_columns(p, rows[0], required, optional)
    data = _parse_columns(p, rows[1:], columns, text)
    n = len(data[columns[0][0]])
    if n < min_rows:
        raise ValueError(f"{p}: too few data rows: {n} (need at least {min_rows})")
    return {c: np.asarray(v) for c, v in data.items()}


def _read_csv_rows(p: Path, required: Sequence[str]) -> list[list[str]]:
    """All rows of the CSV file ``p``, the first a non-blank header; ValueError naming the file."""
    try:
        with p.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise ValueError(f"{p}: no such file") from None
    except IsADirectoryError:
        raise ValueError(f"{p}: is a directory, not a CSV file") from None
    except UnicodeDecodeError:
        raise ValueError(f"{p}: not a text CSV file (cannot decode as UTF-8)") from None
    except csv.Error as exc:
        raise ValueError(f"{p}: not a valid CSV file ({exc})") from None
    if not rows or not any(c.strip() for c in rows[0]):
        raise ValueError(f"{p}: empty file (expected a header row with columns {', '.join(required)})")
    return rows


def _wanted_columns(
    p: Path, header_row: Sequence[str], required: Sequence[str], optional: Sequence[str]
) -> list[tuple[str, int]]:
    """(name, field index) of each wanted column: the required ones, then the optional group if present.

    Header names are matched case-insensitively; a missing required column or a
    partly present optional group is a ValueError naming the file.
    """
    header = [c.strip().lower() for c in header_row]
    missing = [c for c in required if c not in header]
    if missing:
        raise ValueError(
            f"{p}: missing column(s) {', '.join(repr(c) for c in missing)} in the header "
            f"(required: {', '.join(required)}; found: {', '.join(header)})"
        )
    present_opt = [c for c in optional if c in header]
    if present_opt and len(present_opt) != len(optional):
        absent = [c for c in optional if c not in header]
        raise ValueError(
            f"{p}: incomplete optional column group — has {', '.join(present_opt)} but not "
            f"{', '.join(absent)} (give all of {', '.join(optional)} or none)"
        )
    return [(c, header.index(c)) for c in list(required) + present_opt]


def _parse_columns(
    p: Path, data_rows: Sequence[Sequence[str]], columns: list[tuple[str, int]], text: Sequence[str]
) -> dict[str, list[Any]]:
    """Values of the ``(name, field index)`` columns over the data rows (line 2 on, blanks skipped).

    ValueError naming file, line and column for a short row or a bad value.
    """
    data: dict[str, list[Any]] = {c: [] for c, _ in columns}
    for line_no, row in enumerate(data_rows, start=2):
        if not row or not any(c.strip() for c in row):
            continue  # blank line
        for c, i in columns:
            if i >= len(row):
                raise ValueError(f"{p}: line {line_no}: column {c!r} is missing (row has {len(row)} fields)")
            data[c].append(_parse_field(p, line_no, c, row[i].strip(), c in text))
    return data


def _parse_field(p: Path, line_no: int, c: str, field_: str, is_text: bool) -> Any:
    """One stripped field: lower-cased text, or a finite float."""
    if is_text:
        return field_.lower()
    try:
        val = float(field_)
    except ValueError:
        raise ValueError(f"{p}: line {line_no}: column {c!r}: not a number: {field_!r}") from None
    if not math.isfinite(val):
        raise ValueError(f"{p}: line {line_no}: column {c!r}: not finite: {field_!r}")
    return val


def read_end_poses_csv(path: str | Path) -> NDArray[np.float64]:
    """End poses from a CSV with columns ``x, y, theta``; shape (n, 3), n ≥ :data:`MIN_ROWS`."""
    d = read_csv_columns(path, END_POSE_COLUMNS)
    return np.stack([d["x"], d["y"], d["theta"]], axis=-1)


def read_motion_samples_csv(path: str | Path, model: str) -> dict[str, NDArray[np.float64]]:
    """Single-step samples for the α fit from a CSV (columns in the module docstring).

    Returns a dict: ``samples`` (m, 3), ``starts`` (m, 3), and ``controls``
    (m, 2) and ``dt`` (m,) for ``model="velocity"``, or ``odom_prev``,
    ``odom_next`` (m, 3) for ``"odometry"``.
    """
    check_choice("model", model, ("velocity", "odometry"))
    required = VELOCITY_COLUMNS if model == "velocity" else ODOMETRY_COLUMNS
    d = read_csv_columns(path, required, START_COLUMNS)
    m = d["x"].size
    out = {
        "samples": np.stack([d["x"], d["y"], d["theta"]], -1),
        "starts": (
            np.stack([d["x0"], d["y0"], d["theta0"]], -1) if "x0" in d else np.zeros((m, 3))
        ),
    }
    if model == "velocity":
        if np.any(d["dt"] <= 0):
            line = int(np.flatnonzero(d["dt"] <= 0)[0]) + 2
            raise ValueError(f"{path}: data row {line - 1}: column 'dt' must be > 0")
        out["controls"] = np.stack([d["v"], d["omega"]], -1)
        out["dt"] = d["dt"]
    else:
        out["odom_prev"] = np.stack([d["odo_x0"], d["odo_y0"], d["odo_theta0"]], -1)
        out["odom_next"] = np.stack([d["odo_x1"], d["odo_y1"], d["odo_theta1"]], -1)
    return out
