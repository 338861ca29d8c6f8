"""Random errors: the wheel error constants ``k_r, k_l`` by maximum likelihood under Method A.

Model of a segment's residual
-----------------------------
The residual ``r_j = z_j − g_j`` of segment ``j`` (:mod:`.segments`) is Gaussian with
zero mean and covariance linear in four non-negative parameters
``ψ = (k_r, k_l, σ_p², σ_θ²)``::

    Σ_j(ψ) = k_r G_r,j + k_l G_l,j + σ_p² P_j + σ_θ² H_j

* ``G_r, G_l`` — Method A (:func:`..methods.covariance.propagate_travels`) along the
  segment's wheel travels for unit constants: the wheels' random walk, growing with the
  distance driven;
* ``P_j = (w_a + w_c) diag(1, 1, 0)`` — independent position noise ``σ_p`` [m] per axis
  of each ground-truth sample, the interpolation factors ``w`` of the segment's two
  ends (:mod:`.segments`); isotropic, so the start frame's rotation leaves it unchanged;
* ``H_j = w_a l lᵀ + w_c e₃e₃ᵀ``, ``l = (d_y, −d_x, −1)`` with ``d`` the displacement
  in the start frame — heading noise ``σ_θ`` [rad] of the start sample rotates the
  whole displacement (``∂(R(−θ_a)(p_c − p_a))/∂θ_a = (d_y, −d_x)``) and enters the
  heading change with a minus sign; that of the end sample only the heading.

Segments are independent (:mod:`.segments`), so the log-likelihood is
``ℓ(ψ) = −½ Σ_j [r_jᵀ Σ_j⁻¹ r_j + log det Σ_j + 3 log 2π]``, maximised over ``ψ ≥ 0``
(L-BFGS-B on parameters scaled to order 1, analytic gradient
``∂ℓ/∂ψ_a = −½ Σ_j tr((Σ_j⁻¹ − Σ_j⁻¹ r_j r_jᵀ Σ_j⁻¹) M_a,j)``). With the ground
truth's noise given, ``σ_p, σ_θ`` are fixed and only ``k_r, k_l`` are fitted.

Confidence intervals
--------------------
Profile likelihood: the 95 % interval of ``ψ_a`` is
``{t ≥ 0 : 2(ℓ̂ − max_{others} ℓ(ψ_a = t, ·)) ≤ χ²₁(0.95)}``, the other parameters
re-fitted at each ``t`` (Brent's root finder on each side; the lower end is 0 when the
likelihood at 0 is within the bound — the ground truth's variances often are, when the
wheels' noise dominates). Invariant to reparametrisation, and right at the boundary
where a Wald interval is not. Standard errors come from the expected Fisher
information ``I_ab = ½ Σ_j tr(Σ_j⁻¹ M_a Σ_j⁻¹ M_b)``, ``se = √(I⁻¹)_aa``.

Goodness of fit on held-out segments
------------------------------------
:func:`held_out_check`: NEES ``ε_j = r_jᵀ Σ_j⁻¹ r_j`` (mean 3 for a right model; the
band is ``χ²_{3J}(0.025, 0.975)/J``) and coverage of the 95 % error ellipses: the
fraction of segments whose position residual lies inside the (x, y) ellipse of
``Σ_j`` at 95 % (``r_xyᵀ Σ_xy⁻¹ r_xy ≤ χ²₂(0.95)``), with its Wilson interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.stats import chi2_ppf, wilson_interval
from ..methods import covariance as cv
from .segments import Segments

__all__ = ["NOISE_NAMES", "NoiseFit", "fit_noise", "held_out_check", "model_covariances", "noise_matrices"]

#: Parameters of the noise model and their units.
NOISE_NAMES: dict[str, str] = {"k_r": "m", "k_l": "m", "truth_var_position": "m^2", "truth_var_heading": "rad^2"}


def noise_matrices(seg: Segments, radius_l: float, radius_r: float, track: float) -> NDArray[np.float64]:
    """``M = (G_r, G_l, P, H)``, shape (4, J, 3, 3) (module docstring)."""
    ds_l, ds_r = radius_l * seg.dphi_l, radius_r * seg.dphi_r
    unit_r = np.array([[1.0], [0.0]])
    unit_l = np.array([[0.0], [1.0]])
    _, covs = cv.propagate_travels(ds_r, ds_l, track, unit_r, unit_l)  # (2, J, K+1, 3, 3)
    G = covs[:, :, -1]
    J = len(seg)
    P = (seg.w_start + seg.w_end)[:, None, None] * np.diag([1.0, 1.0, 0.0])
    lever = np.stack([seg.z[:, 1], -seg.z[:, 0], -np.ones(J)], axis=-1)
    e3 = np.zeros((J, 3))
    e3[:, 2] = 1.0
    H = seg.w_start[:, None, None] * lever[:, :, None] * lever[:, None, :]
    H = H + seg.w_end[:, None, None] * e3[:, :, None] * e3[:, None, :]
    return np.concatenate([G, P[None], H[None]], axis=0)


def model_covariances(psi: NDArray[np.float64], M: NDArray[np.float64]) -> NDArray[np.float64]:
    """``Σ_j = Σ_a ψ_a M_a,j``, shape (J, 3, 3)."""
    return np.tensordot(np.asarray(psi, dtype=np.float64), M, axes=1)


@dataclass(frozen=True)
class NoiseFit:
    """The fitted ``ψ`` with standard errors and 95 % intervals (module docstring).

    ``estimate``, ``std_error``, ``ci`` are keyed by :data:`NOISE_NAMES`; ``fitted`` says
    which were fitted (the truth's variances may be given); ``loglik``, ``n_segments``.
    """

    estimate: dict[str, float]
    std_error: dict[str, float]
    ci: dict[str, tuple[float, float]]
    fitted: tuple[str, ...]
    loglik: float
    n_segments: int
    level: float

    @property
    def psi(self) -> NDArray[np.float64]:
        return np.array([self.estimate[k] for k in NOISE_NAMES])

    def as_dict(self) -> dict[str, Any]:
        return {
            name: {"value": self.estimate[name], "std_error": self.std_error[name],
                   "ci95": list(self.ci[name]), "unit": unit, "fitted": name in self.fitted}
            for name, unit in NOISE_NAMES.items()
        }  # fmt: skip


def _inv_det3(S: NDArray) -> tuple[NDArray, NDArray]:
    """Inverses and determinants of symmetric 3 × 3 matrices (J, 3, 3), by the adjugate."""
    a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 0, 2]
    d, e, f = S[:, 1, 1], S[:, 1, 2], S[:, 2, 2]
    A, B, C = d * f - e * e, c * e - b * f, b * e - c * d
    D, E, F = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * A + b * B + c * C
    adj = np.stack([np.stack([A, B, C], -1), np.stack([B, D, E], -1), np.stack([C, E, F], -1)], -2)
    return adj / det[:, None, None], det


def _objective(x: NDArray, Ms: NDArray, fixed: NDArray, rrT: NDArray) -> tuple[float, NDArray, NDArray]:
    """−ℓ, its gradient and the expected Fisher information in the scaled parameters ``x``.

    ``Ms`` (p, J, 3, 3) are the scaled matrices, ``fixed`` (J, 3, 3) the given part of Σ.
    """
    S = np.tensordot(x, Ms, axes=1) + fixed
    Si, det = _inv_det3(S)
    if np.any(det <= 0):
        return math.inf, np.zeros_like(x), np.eye(x.size)
    # −ℓ = ½ Σ_j [tr(Σ⁻¹ r rᵀ) + log det Σ + 3 log 2π]
    f = 0.5 * float(np.sum(np.einsum("jab,jba->j", Si, rrT) + np.log(det)) + S.shape[0] * 3 * math.log(2 * math.pi))
    D = Si - Si @ rrT @ Si
    A = np.einsum("jab,pjbc->pjac", Si, Ms)  # Σ⁻¹ M_a
    # ∂(−ℓ)/∂x_a = ½ Σ tr(D M_a);  I_ab = ½ Σ tr(Σ⁻¹M_a Σ⁻¹M_b)
    return f, 0.5 * np.einsum("jxy,ajyx->a", D, Ms), 0.5 * np.einsum("pjxy,qjyx->pq", A, A)


_FLOOR = 1e-9  # lower bound of the scaled parameters (a zero variance makes Σ singular)


def _scoring(x0: NDArray, free: NDArray[np.bool_], args: tuple[Any, ...], max_iter: int = 100) -> tuple[NDArray, float]:
    """Minimise −ℓ over the ``free`` scaled parameters ≥ floor: projected Fisher scoring.

    Each step solves ``I Δ = −∇`` on the parameters not held at the floor by a gradient
    pushing them below it, and halves the step until −ℓ does not increase.
    """
    x = np.maximum(np.asarray(x0, dtype=np.float64), _FLOOR)
    f, g, info = _objective(x, *args)
    for _ in range(max_iter):
        act = free & ~((x <= _FLOOR * 1.0000001) & (g > 0))
        if not act.any():
            break
        step = np.zeros_like(x)
        step[act] = -np.linalg.solve(info[np.ix_(act, act)], g[act])
        t, done = 1.0, False
        while True:
            xn = np.maximum(x + t * step, _FLOOR)
            fn, gn, In = _objective(xn, *args)
            if fn <= f + 1e-13 * abs(f):
                break
            t *= 0.5
            if t < 1e-8:
                done = True
                break
        if done:
            break
        converged = f - fn < 1e-10 * max(1.0, abs(f))
        x, f, g, info = xn, fn, gn, In
        if converged:
            break
    return x, f


def _profile_bounds(
    xhat: NDArray, k: int, args: tuple[Any, ...], nll_min: float, crit: float, se: float
) -> tuple[float, float]:
    """Profile-likelihood interval of scaled parameter ``k`` (module docstring)."""
    from scipy import optimize  # imported where used: scipy.optimize takes 0.3 s to import

    free = np.ones(xhat.size, dtype=bool)
    free[k] = False
    warm = {"x": xhat.copy()}

    def excess(t: float) -> float:
        x0 = warm["x"].copy()
        x0[k] = t
        x, f = _scoring(x0, free, args)
        warm["x"] = x
        return 2.0 * (f - nll_min) - crit

    x_k = float(xhat[k])
    lo = _FLOOR
    if x_k > 2 * _FLOOR and excess(_FLOOR) > 0:
        warm["x"] = xhat.copy()
        lo = float(optimize.brentq(excess, _FLOOR, x_k, xtol=1e-5 * x_k))
    warm["x"] = xhat.copy()
    step = max(se if math.isfinite(se) else x_k, 0.1 * x_k, 1e-6)
    hi = x_k + step
    for _ in range(60):
        if excess(hi) > 0:
            break
        step *= 2.0
        hi = x_k + step
    hi = float(optimize.brentq(excess, x_k, hi, xtol=1e-5 * hi))
    return (0.0 if lo <= _FLOOR else lo), hi


def fit_noise(
    r: NDArray[np.float64],
    M: NDArray[np.float64],
    truth_std: tuple[float, float] | None = None,
    level: float = 0.95,
    intervals: bool = True,
) -> NoiseFit:
    """Maximum-likelihood ``ψ`` from residuals ``r`` (J, 3) and matrices ``M`` (4, J, 3, 3).

    ``intervals=False`` skips the profile-likelihood intervals (reported as NaN).
    """
    J = r.shape[0]
    if J < 8:
        raise ValueError(f"too few independent segments to fit the noise: {J} (need at least 8)")
    rrT = r[:, :, None] * r[:, None, :]
    idx = [0, 1] if truth_std is not None else [0, 1, 2, 3]
    given = np.zeros(4)
    if truth_std is not None:
        given[2], given[3] = truth_std[0] ** 2, truth_std[1] ** 2
    fixed = model_covariances(given, M)
    # a moment start: the traces of the residual scatter against the model's
    tr_r = float(np.einsum("jaa->", rrT))
    tr_G = np.einsum("ajbb->a", M)
    scale = tr_r / np.maximum(tr_G * len(idx), 1e-300)
    args = (M[idx] * scale[idx, None, None, None], fixed, rrT)
    free = np.ones(len(idx), dtype=bool)
    fits = [_scoring(np.full(len(idx), v), free, args) for v in (1.0, 0.1)]
    xhat, fmin = min(fits, key=lambda xf: xf[1])
    psi = given.copy()
    psi[idx] = xhat * scale[idx]
    try:
        cov = np.linalg.inv(_objective(xhat, *args)[2])
        se_fit = np.sqrt(np.maximum(np.diag(cov), 0.0)) * scale[idx]
    except np.linalg.LinAlgError:
        se_fit = np.full(len(idx), np.inf)
    best_fun = fmin
    names = list(NOISE_NAMES)
    crit = float(chi2_ppf(level, 1))
    est, se, ci = {}, {}, {}
    for a, name in enumerate(names):
        est[name] = float(psi[a])
        if a in idx:
            k = idx.index(a)
            se[name] = float(se_fit[k])
            if intervals:
                lo, hi = _profile_bounds(xhat, k, args, best_fun, crit, float(se_fit[k] / scale[a]))
                ci[name] = (lo * float(scale[a]), hi * float(scale[a]))
            else:
                ci[name] = (math.nan, math.nan)
        else:
            se[name], ci[name] = 0.0, (float(psi[a]), float(psi[a]))
    return NoiseFit(est, se, ci, tuple(names[a] for a in idx), -float(best_fun), J, level)


def held_out_check(r: NDArray[np.float64], Sigma: NDArray[np.float64], level: float = 0.95) -> dict[str, Any]:
    """NEES and 95 % ellipse coverage of residuals ``r`` (J, 3) under covariances (J, 3, 3)."""
    from scipy.stats import chi2  # imported where used (0.3 s)

    J = r.shape[0]
    nees = np.einsum("ja,jab,jb->j", r, np.linalg.inv(Sigma), r)
    d2 = np.einsum("ja,jab,jb->j", r[:, :2], np.linalg.inv(Sigma[:, :2, :2]), r[:, :2])
    inside = int(np.count_nonzero(d2 <= float(chi2_ppf(level, 2))))
    lo, hi = chi2.ppf([0.025, 0.975], 3 * J) / J
    w_lo, w_hi = wilson_interval(inside, J, 0.95)
    return {
        "n_segments": J,
        "nees_mean": float(nees.mean()),
        "nees_expected": 3.0,
        "nees_band95": [float(lo), float(hi)],
        "nees_ok": bool(lo <= nees.mean() <= hi),
        "ellipse_level": level,
        "ellipse_coverage": inside / J,
        "ellipse_coverage_ci95": [w_lo, w_hi],
        "ellipse_ok": bool(w_lo <= level <= w_hi),
    }
