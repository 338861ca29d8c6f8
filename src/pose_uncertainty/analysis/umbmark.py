"""UMBmark (Borenstein & Feng 1996): systematic odometry errors from the return errors of squares.

Procedure: drive an ``L × L`` square ``n`` times clockwise and ``n`` times
counter-clockwise on the robot's own odometry and measure each run's
return-position error ``ε = (x_abs − x_calc, y_abs − y_calc)`` — true end
position minus odometry's, in the start frame (x along the first leg, y to its
left; :mod:`pose_uncertainty.methods.systematic` simulates exactly this).

Formulas (Borenstein & Feng's, for that convention)::

    x_c.g.,cw = (1/n) Σ ε_x,i,cw   (likewise y, and ccw)      centres of gravity
    r_c.g. = √(x_c.g.² + y_c.g.²),   E_max,syst = max(r_c.g.,cw, r_c.g.,ccw)
    α = (x_c.g.,cw + x_c.g.,ccw) / (−4L)     type A: each commanded π/2 turns π/2 − α
    β = (x_c.g.,cw − x_c.g.,ccw) / (−4L)     type B: each leg curves by β (left for β > 0)
    R = (L/2) / sin(β/2),   E_d = D_R/D_L = (R + b/2)/(R − b/2) = (L + b sin(β/2))/(L − b sin(β/2))
    E_b = b_actual / b_nominal = (π/2) / (π/2 − α)

with ``b`` the nominal track; the corrected odometry uses diameters
``c_R = 2/(1/E_d + 1)``, ``c_L = 2/(E_d + 1)`` times the nominal one and the track
``E_b b``.

Derivation and its accuracy
---------------------------
The heading error at the start of leg ``k`` is ``k(β − α)`` (ccw) or ``k(β + α)``
(cw); each leg ends ``L(δ_k + β/2)`` off to the side, which sums to
``ε_ccw = 2L(β − α)(1, −1)``, ``ε_cw = −2L(α + β)(1, 1)`` to first order. Summing the
legs exactly (a geometric series of rotations) and expanding to second order::

    x_ccw = L[2δ + 2δ² + βδ],   y_ccw = L[−2δ + 4δ² + βδ],   δ = β − α
    x_cw  = L[−2σ + 2σ² + βσ],  y_cw  = L[−2σ − 4σ² − βσ],   σ = α + β

so ``α̂ = α − α² − (3/2)β²`` and ``β̂ = β − (5/2)αβ`` to second order. Wheels of
unequal size also move the robot during a turn in place (an arc of chord
``(b²β/L)·(√2/4)`` per corner, forward on ccw and backward on cw turns); over the
four corners this cancels to first order and adds ``−½(b/L)²β²`` to ``α̂`` and
``−½(b/L)²αβ`` to ``β̂``. So, with ``O(3)`` the third-order terms,

    α̂ = α − α² − (3/2)β² − ½(b/L)²β² + O(3),     β̂ = β − (5/2)αβ − ½(b/L)²αβ + O(3)

and ``Ê_b − E_b ≈ (π/2)/(π/2 − α)² (α̂ − α)``,
``Ê_d − E_d ≈ (b/L)[(β̂ − β) − (E_b − 1)β]`` (the formula takes the nominal track,
the legs curve on the true one). UMBmark's ``E_b`` is thus biased by about
``−(2/π)(3/2)β²``: with ``β`` of a few degrees this is a sizeable part of
``E_b − 1``. Random errors add a bias of order ``k`` (heading noise shortens the
mean travel of the later legs, the mean shift of Method C), negligible while the
heading noise over a lap is small.

Direct fit
----------
:func:`direct_fit`: least squares of the four centre-of-gravity coordinates
against the noiseless square of :func:`~pose_uncertainty.methods.systematic.return_errors_noiseless`
with ``E_d, E_b`` free (Gauss–Newton, vectorised over data sets). No small-angle
approximation: exact on noiseless data. ``E_max,after`` (predicted) is what that
square would still show with the UMBmark-corrected odometry if the direct fit's
``E_d, E_b`` were the truth — the residue of the small-angle derivation.

Confidence intervals from the scatter of the runs
-------------------------------------------------
Every reported quantity ``q`` is a function of the four centre-of-gravity
coordinates ``c = (x_cw, y_cw, x_ccw, y_ccw)``:

* ``delta``: ``se² = g_cwᵀ S_cw g_cw / n_cw + g_ccwᵀ S_ccw g_ccw / n_ccw`` with the
  gradient ``g = ∂q/∂c`` (central differences) and the per-direction sample
  covariances ``S`` of the runs; ``q ± t·se`` with Student's t on the
  Welch–Satterthwaite degrees of freedom (for ``α`` and ``β``, linear in ``c``,
  this is Welch's two-sample t interval; for the rest it is first order). It is
  symmetric, so for a small non-negative ``E_max`` its lower end can dip below 0.
* ``bootstrap``: runs resampled with replacement within each direction,
  ``n_boot`` times, from an explicit ``numpy.random.Generator``; percentile
  intervals. With few runs it undercovers (no t-correction): 85–88 % for a
  nominal 95 % with 5 runs per direction, 88–95 % with 10, ≈ 95 % with 40
  (seeded simulations; the delta intervals cover 93–95 % with 5, 95 % with 10).
  So the delta interval is the one to quote; the bootstrap shows the shape
  (``E_max`` is a maximum of norms, not smooth).

CSV
---
:func:`read_returns_csv`: a header row with ``direction`` (``cw`` or ``ccw``),
``x``, ``y`` (the return-position error ε [m] in the convention above); extra
columns are ignored; at least 2 runs per direction.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_finite, check_positive, check_probability
from ..methods.systematic import DIRECTIONS, WheelGeometry, return_errors_noiseless, umbmark_runs
from .calibration import read_csv_columns

__all__ = [
    "QUANTITIES",
    "RETURNS_COLUMNS",
    "Estimate",
    "UmbmarkResult",
    "centres_of_gravity",
    "direct_fit",
    "e_max_syst",
    "quantities",
    "read_returns_csv",
    "true_quantities",
    "umbmark",
    "umbmark_experiment",
    "umbmark_parameters",
]

#: Quantities of :func:`umbmark`: name → (unit, description).
QUANTITIES: dict[str, tuple[str, str]] = {
    "alpha": ("rad", "type A: turn deficit per commanded 90 deg"),
    "beta": ("rad", "type B: curvature of each leg"),
    "E_d": ("1", "wheel-diameter ratio D_R/D_L (UMBmark)"),
    "E_b": ("1", "track ratio b_actual/b_nominal (UMBmark)"),
    "c_R": ("1", "corrected right diameter / nominal"),
    "c_L": ("1", "corrected left diameter / nominal"),
    "track_corrected": ("m", "corrected track E_b b"),
    "E_max_before": ("m", "E_max,syst of the runs"),
    "E_d_fit": ("1", "D_R/D_L, direct fit"),
    "E_b_fit": ("1", "b_actual/b_nominal, direct fit"),
    "E_max_after_predicted": ("m", "E_max,syst left after the UMBmark correction (direct fit as truth)"),
}
RETURNS_COLUMNS: tuple[str, ...] = ("direction", "x", "y")


# --- the formulas ---------------------------------------------------------------------------


def centres_of_gravity(returns: ArrayLike) -> NDArray[np.float64]:
    """Centre of gravity of return-position errors: shape (..., n, 2) → (..., 2) [m]."""
    r = check_finite("returns", returns)
    if r.ndim < 2 or r.shape[-1] != 2:
        raise ValueError(f"returns must have shape (..., n, 2), got shape {r.shape}")
    return r.mean(axis=-2)


def umbmark_parameters(
    c_cw: ArrayLike, c_ccw: ArrayLike, side: float, track: float
) -> dict[str, NDArray[np.float64]]:
    """α, β, E_d, E_b and the corrected c_R, c_L, track from the centres of gravity (module docstring).

    Parameters
    ----------
    c_cw, c_ccw : array_like, shape (..., 2) — centres of gravity [m]
    side : float [m] — L; track : float [m] — nominal b

    Returns
    -------
    dict of arrays, shape (...): ``alpha``, ``beta`` [rad], ``E_d``, ``E_b``, ``c_R``, ``c_L`` [1],
    ``track_corrected`` [m]. NaN where the errors are too large for the formulas
    (``|α| ≥ π/2`` or ``b|sin(β/2)| ≥ L``).
    """
    cw, ccw = np.asarray(c_cw, dtype=np.float64), np.asarray(c_ccw, dtype=np.float64)
    L, b = float(side), float(track)
    alpha = (cw[..., 0] + ccw[..., 0]) / (-4.0 * L)
    beta = (cw[..., 0] - ccw[..., 0]) / (-4.0 * L)
    with np.errstate(divide="ignore", invalid="ignore"):
        # E_d = (R + b/2)/(R − b/2) with R = (L/2)/sin(β/2), written without R (β = 0 → 1)
        h = b * np.sin(beta / 2.0)
        E_d = np.where(np.abs(h) < L, (L + h) / (L - h), np.nan)
        E_b = np.where(np.abs(alpha) < math.pi / 2, (math.pi / 2) / (math.pi / 2 - alpha), np.nan)
    return {
        "alpha": alpha,
        "beta": beta,
        "E_d": E_d,
        "E_b": E_b,
        "c_R": 2.0 / (1.0 / E_d + 1.0),
        "c_L": 2.0 / (E_d + 1.0),
        "track_corrected": E_b * b,
    }


def e_max_syst(c_cw: ArrayLike, c_ccw: ArrayLike) -> NDArray[np.float64]:
    """``E_max,syst = max(r_c.g.,cw, r_c.g.,ccw)`` [m]; centres shape (..., 2)."""
    cw, ccw = np.asarray(c_cw, dtype=np.float64), np.asarray(c_ccw, dtype=np.float64)
    return np.maximum(np.hypot(cw[..., 0], cw[..., 1]), np.hypot(ccw[..., 0], ccw[..., 1]))


def _model(theta: NDArray, side: float, track: float) -> NDArray:
    """Noiseless centres (x_cw, y_cw, x_ccw, y_ccw) for ``theta = (E_d, E_b)``, shape (..., 4)."""
    E_d, E_b = theta[..., 0], theta[..., 1]
    sr, sl = 2.0 * E_d / (E_d + 1.0), 2.0 / (E_d + 1.0)
    return np.concatenate(
        [return_errors_noiseless(side, d, sr, sl, E_b * track, odometry_track=track) for d in DIRECTIONS],
        axis=-1,
    )


def _solve2(A: NDArray, y: NDArray) -> NDArray:
    """Solve 2×2 systems ``A x = y`` (batched) in closed form; NaN where ``A`` is singular."""
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    scale = np.abs(A).max(axis=(-1, -2)) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_det = np.where(np.abs(det) > 1e-14 * scale, 1.0 / det, np.nan)
        x0 = (A[..., 1, 1] * y[..., 0] - A[..., 0, 1] * y[..., 1]) * inv_det
        x1 = (A[..., 0, 0] * y[..., 1] - A[..., 1, 0] * y[..., 0]) * inv_det
    return np.stack([x0, x1], axis=-1)


def direct_fit(
    c_cw: ArrayLike,
    c_ccw: ArrayLike,
    side: float,
    track: float,
    *,
    max_iter: int = 50,
    tol: float = 1e-10,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Least-squares ``E_d, E_b`` from the centres of gravity on the simulated square (module docstring).

    Gauss–Newton from UMBmark's estimates, the Jacobian by central differences
    (one vectorised model call per iteration), vectorised over data sets; stops
    when every step is below ``tol`` (the finite-difference Jacobian leaves a
    floor near 10⁻¹¹; noiseless data converge quadratically to it).

    Parameters
    ----------
    c_cw, c_ccw : array_like, shape (..., 2) [m]; side, track : float [m]

    Returns
    -------
    E_d, E_b : ndarray, shape (...)
    """
    c = np.concatenate([np.asarray(c_cw, float), np.asarray(c_ccw, float)], axis=-1)
    start = umbmark_parameters(c_cw, c_ccw, side, track)
    theta = np.stack([start["E_d"], start["E_b"]], axis=-1)
    theta = np.where(np.isfinite(theta), theta, 1.0)
    h = 1e-7
    # the point and its four central-difference neighbours, in one model call
    offsets = np.concatenate([np.zeros((1, 2)), h * np.eye(2), -h * np.eye(2)])[:, *([None] * c.ndim)[:-1]]
    for _ in range(max_iter):
        m = _model(theta + offsets, side, track)  # (5, ..., 4)
        r = m[0] - c
        J = np.stack([(m[1] - m[3]) / (2 * h), (m[2] - m[4]) / (2 * h)], axis=-1)  # (..., 4, 2)
        Jt = np.swapaxes(J, -1, -2)
        step = _solve2(Jt @ J, -(Jt @ r[..., None])[..., 0])
        # a wild step on bad data must not leave the valid range of the model (E > 0)
        theta = np.maximum(theta + step, 0.5 * theta)
        if not np.any(np.abs(step) >= tol):  # NaN (a singular system) counts as done
            break
    return theta[..., 0], theta[..., 1]


def quantities(c: ArrayLike, side: float, track: float) -> NDArray[np.float64]:
    """Every quantity of :data:`QUANTITIES`, in that order, from centres ``c = (x_cw, y_cw, x_ccw, y_ccw)``.

    Parameters
    ----------
    c : array_like, shape (..., 4) [m]; side, track : float [m]

    Returns
    -------
    ndarray, shape (..., len(QUANTITIES))
    """
    cc = np.asarray(c, dtype=np.float64)
    cw, ccw = cc[..., :2], cc[..., 2:]
    p = umbmark_parameters(cw, ccw, side, track)
    E_d_fit, E_b_fit = direct_fit(cw, ccw, side, track)
    # the square with the fitted truth and the UMBmark-corrected odometry
    ok = np.isfinite(p["E_d"]) & np.isfinite(p["E_b"])
    odo_r, odo_l = np.where(ok, p["c_R"], 1.0), np.where(ok, p["c_L"], 1.0)
    odo_b = np.where(ok, p["track_corrected"], track)
    sr, sl = 2.0 * E_d_fit / (E_d_fit + 1.0), 2.0 / (E_d_fit + 1.0)
    after = [
        return_errors_noiseless(side, d, sr, sl, E_b_fit * track, odo_r, odo_l, odo_b)
        for d in DIRECTIONS
    ]
    values = {
        **p,
        "E_max_before": e_max_syst(cw, ccw),
        "E_d_fit": E_d_fit,
        "E_b_fit": E_b_fit,
        "E_max_after_predicted": np.where(ok, e_max_syst(after[0], after[1]), np.nan),
    }
    return np.stack([values[name] for name in QUANTITIES], axis=-1)


# --- intervals from the scatter of the runs ---------------------------------------------------


@dataclass(frozen=True)
class Estimate:
    """One quantity with its standard error and two confidence intervals.

    Attributes
    ----------
    value : float; unit : str
    std_error : float — delta method
    df : float — Welch–Satterthwaite degrees of freedom of the delta interval (inf if se = 0)
    delta : (low, high) — ``value ± t_df · std_error``
    bootstrap : (low, high) — percentile interval (NaN when no bootstrap was run)
    """

    value: float
    unit: str
    std_error: float
    df: float
    delta: tuple[float, float]
    bootstrap: tuple[float, float]

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable mapping."""
        return {
            "value": self.value, "unit": self.unit, "std_error": self.std_error, "df": self.df,
            "delta_ci": list(self.delta), "bootstrap_ci": list(self.bootstrap),
        }


def _split(returns: Mapping[str, ArrayLike]) -> tuple[NDArray, NDArray]:
    """Validated (cw, ccw) run arrays, each (n, 2) with n ≥ 2."""
    out = []
    for d in DIRECTIONS:
        if d not in returns:
            raise ValueError(f"returns must have the keys 'cw' and 'ccw', got {sorted(returns)}")
        r = check_finite(f"returns[{d!r}]", returns[d])
        if r.ndim != 2 or r.shape[1] != 2 or r.shape[0] < 2:
            raise ValueError(
                f"returns[{d!r}] must have shape (n, 2) with n >= 2 (allowed: at least 2 runs, "
                f"the scatter gives the intervals), got shape {r.shape}"
            )
        out.append(r)
    return out[0], out[1]


def _probes(c: NDArray, step: float) -> NDArray:
    """The centres ``c ± step·e_j`` for central differences: (8, 4)."""
    return np.concatenate([c + step * np.eye(4), c - step * np.eye(4)])


def _delta(
    grad: NDArray, S_cw: NDArray, S_ccw: NDArray, n_cw: int, n_ccw: int
) -> tuple[NDArray, NDArray]:
    """Standard errors (m,) and Welch–Satterthwaite degrees of freedom (m,) from gradients (m, 4)."""
    v_cw = np.einsum("ma,ab,mb->m", grad[:, :2], S_cw, grad[:, :2]) / n_cw
    v_ccw = np.einsum("ma,ab,mb->m", grad[:, 2:], S_ccw, grad[:, 2:]) / n_ccw
    var = v_cw + v_ccw
    with np.errstate(divide="ignore", invalid="ignore"):
        df = var**2 / (v_cw**2 / (n_cw - 1) + v_ccw**2 / (n_ccw - 1))
    return np.sqrt(var), np.where(var > 0, df, np.inf)


def _resampled_centres(
    cw: NDArray, ccw: NDArray, n_boot: int, rng: np.random.Generator
) -> NDArray:
    """Centres of ``n_boot`` resamples of the runs, with replacement within each direction: (n_boot, 4)."""
    i_cw = rng.integers(0, cw.shape[0], size=(n_boot, cw.shape[0]))
    i_ccw = rng.integers(0, ccw.shape[0], size=(n_boot, ccw.shape[0]))
    return np.concatenate([cw[i_cw].mean(axis=1), ccw[i_ccw].mean(axis=1)], axis=-1)


def _estimates(
    fn: Any,
    names: tuple[str, ...],
    cw: NDArray,
    ccw: NDArray,
    level: float,
    n_boot: int,
    rng: np.random.Generator | None,
) -> dict[str, Estimate]:
    """Values, delta and bootstrap intervals of the quantities ``fn(c)`` (module docstring)."""
    # imported where used: scipy.special takes 0.2 s to import
    from scipy.special import ndtri, stdtrit

    c = np.concatenate([cw.mean(axis=0), ccw.mean(axis=0)])
    step = 1e-7 * max(float(np.abs(c).max()), 1e-3)
    # the estimate, the difference probes and the resamples: one vectorised call
    centres = [c[None], _probes(c, step)]
    boot = n_boot > 0 and rng is not None
    if rng is not None and n_boot > 0:
        centres.append(_resampled_centres(cw, ccw, n_boot, rng))
    vals = np.asarray(fn(np.concatenate(centres)))
    value, grad = vals[0], ((vals[1:5] - vals[5:9]) / (2.0 * step)).T
    se, df = _delta(grad, np.cov(cw.T), np.cov(ccw.T), cw.shape[0], ccw.shape[0])
    q = 0.5 + level / 2.0
    t = np.where(np.isfinite(df), stdtrit(np.where(np.isfinite(df), df, 1.0), q), ndtri(q))
    if boot:
        lo, hi = np.quantile(vals[9:], [(1.0 - level) / 2.0, (1.0 + level) / 2.0], axis=0)
    else:
        lo = hi = np.full(value.shape, np.nan)
    return {
        name: Estimate(
            value=float(value[j]), unit=QUANTITIES.get(name, ("m", ""))[0], std_error=float(se[j]),
            df=float(df[j]), delta=(float(value[j] - t[j] * se[j]), float(value[j] + t[j] * se[j])),
            bootstrap=(float(lo[j]), float(hi[j])),
        )
        for j, name in enumerate(names)
    }


# --- the procedure -------------------------------------------------------------------------


@dataclass(frozen=True)
class UmbmarkResult:
    """UMBmark's estimates from the cw/ccw return errors, with intervals (module docstring).

    Attributes
    ----------
    side, track : float [m] — L and the nominal b
    n_cw, n_ccw : int — runs per direction
    level : float — confidence level; n_boot : int — bootstrap resamples (0: none)
    centre_cw, centre_ccw : (x, y) — centres of gravity [m]
    estimates : dict name → Estimate, the :data:`QUANTITIES`
    after : Estimate or None — E_max,syst measured on runs after the correction
    """

    side: float
    track: float
    n_cw: int
    n_ccw: int
    level: float
    n_boot: int
    centre_cw: tuple[float, float]
    centre_ccw: tuple[float, float]
    estimates: dict[str, Estimate] = field(default_factory=dict)
    after: Estimate | None = None

    def corrected(self) -> WheelGeometry:
        """The corrected odometry geometry (scales c_R, c_L and track E_b b)."""
        e = self.estimates
        return WheelGeometry.from_ratios(self.track, e["E_d"].value, e["E_b"].value)

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable mapping."""
        return {
            "method": "umbmark", "side": self.side, "track": self.track,
            "n_cw": self.n_cw, "n_ccw": self.n_ccw, "level": self.level, "n_boot": self.n_boot,
            "centre_cw": list(self.centre_cw), "centre_ccw": list(self.centre_ccw),
            "estimates": {k: v.as_dict() for k, v in self.estimates.items()},
            "E_max_after_measured": None if self.after is None else self.after.as_dict(),
        }

    def format(self, diameter: float | None = None) -> str:
        """A text report; ``diameter`` [m], the nominal wheel diameter, adds absolute corrected diameters."""
        pct = f"{100 * self.level:g} %"
        (xa, ya), (xb, yb) = self.centre_cw, self.centre_ccw
        lines = [
            (
                f"UMBmark (Borenstein & Feng 1996): square L = {self.side:g} m, nominal track "
                f"b = {self.track:g} m, {self.n_cw} cw + {self.n_ccw} ccw runs"
            ),
            f"centres of gravity [m]: cw ({xa:.6g}, {ya:.6g}), ccw ({xb:.6g}, {yb:.6g})",
            f"{pct} intervals: delta method (Student t, Welch df) | bootstrap ({self.n_boot} resamples)",
            f"{'quantity':<22} {'estimate':>12} {'std error':>10}  {'delta CI':<27} {'bootstrap CI':<27} unit",
        ]
        rows = [*self.estimates.items(), *([("E_max_after_measured", self.after)] if self.after else [])]
        for name, e in rows:
            lines.append(
                f"{name:<22} {e.value:12.6g} {e.std_error:10.3g}  "
                f"[{e.delta[0]:11.6g}, {e.delta[1]:11.6g}]  [{e.bootstrap[0]:11.6g}, {e.bootstrap[1]:11.6g}]  {e.unit}"
            )
        g = self.corrected()
        corr = f"corrected odometry: D_R = {g.scale_r:.6g} D, D_L = {g.scale_l:.6g} D, track = {g.track:.6g} m"
        if diameter is not None:
            d = float(check_positive("diameter", diameter))
            corr += f" (D = {d:g} m: D_R = {g.scale_r * d:.6g} m, D_L = {g.scale_l * d:.6g} m)"
        lines.append(corr)
        est = self.estimates
        tail = (
            f"E_max,syst [m]: before {est['E_max_before'].value:.4g}; after the UMBmark correction "
            f"(predicted) {est['E_max_after_predicted'].value:.4g}"
        )
        if self.after is not None:
            tail += f"; after (measured) {self.after.value:.4g}"
        lines.append(tail)
        return "\n".join(lines)


def _check_settings(side: float, track: float, level: float, n_boot: int, rng: Any) -> None:
    check_positive("side", side)
    check_positive("track", track)
    check_probability("level", level)
    if isinstance(n_boot, bool) or not isinstance(n_boot, int | np.integer) or n_boot < 0:
        raise ValueError(f"n_boot must be an integer >= 0 (allowed: 0 = no bootstrap, 1, 2, ...), got {n_boot!r}")
    if n_boot > 0 and not isinstance(rng, np.random.Generator):
        raise ValueError(
            f"rng must be a numpy.random.Generator for the bootstrap (allowed: a Generator, or "
            f"n_boot=0), got {type(rng).__name__}"
        )


def umbmark(
    returns: Mapping[str, ArrayLike],
    side: float,
    track: float,
    rng: np.random.Generator | None,
    *,
    level: float = 0.95,
    n_boot: int = 2000,
    after: Mapping[str, ArrayLike] | None = None,
) -> UmbmarkResult:
    """UMBmark from the return-position errors of the cw and ccw runs (module docstring).

    Parameters
    ----------
    returns : {"cw": array (n_cw, 2), "ccw": array (n_ccw, 2)} — ε [m], at least 2 runs each
    side : float [m] — L; track : float [m] — the nominal track b
    rng : numpy.random.Generator — for the bootstrap (may be None with ``n_boot=0``)
    level : float in (0, 1); n_boot : int ≥ 0 — bootstrap resamples
    after : like ``returns``, optional — runs after the correction: E_max,syst measured

    Returns
    -------
    UmbmarkResult
    """
    _check_settings(side, track, level, n_boot, rng)
    cw, ccw = _split(returns)
    L, b = float(side), float(track)
    p = umbmark_parameters(cw.mean(axis=0), ccw.mean(axis=0), L, b)
    if not (np.isfinite(p["E_d"]) and np.isfinite(p["E_b"])):
        raise ValueError(
            f"the return errors are too large for UMBmark's formulas: alpha = {float(p['alpha'])!r}, "
            f"beta = {float(p['beta'])!r} rad (allowed: |alpha| < pi/2 and track*|sin(beta/2)| < side)"
        )
    est = _estimates(lambda c: quantities(c, L, b), tuple(QUANTITIES), cw, ccw, level, n_boot, rng)
    measured = None
    if after is not None:
        a_cw, a_ccw = _split(after)
        measured = _estimates(
            lambda c: e_max_syst(c[..., :2], c[..., 2:])[..., None], ("E_max_after_measured",),
            a_cw, a_ccw, level, n_boot, rng,
        )["E_max_after_measured"]
    return UmbmarkResult(
        side=L, track=b, n_cw=cw.shape[0], n_ccw=ccw.shape[0], level=float(level), n_boot=int(n_boot),
        centre_cw=(float(cw[:, 0].mean()), float(cw[:, 1].mean())),
        centre_ccw=(float(ccw[:, 0].mean()), float(ccw[:, 1].mean())),
        estimates=est, after=measured,
    )


def read_returns_csv(path: str | Path) -> dict[str, NDArray[np.float64]]:
    """Return-position errors from a CSV: columns ``direction`` (cw/ccw), ``x``, ``y`` [m].

    Returns ``{"cw": (n_cw, 2), "ccw": (n_ccw, 2)}``. One-line ValueErrors name the
    file, and the line and column where one is at fault: a missing column, text or
    NaN in ``x``/``y``, an unknown direction, fewer than 2 runs in a direction.
    """
    d = read_csv_columns(path, RETURNS_COLUMNS, text=("direction",), min_rows=1)
    bad = [i for i, v in enumerate(d["direction"]) if v not in DIRECTIONS]
    if bad:
        raise ValueError(
            f"{path}: data row {bad[0] + 1}: column 'direction' must be 'cw' or 'ccw', "
            f"got {str(d['direction'][bad[0]])!r}"
        )
    out = {k: np.stack([d["x"], d["y"]], axis=-1)[d["direction"] == k] for k in DIRECTIONS}
    counts = {k: v.shape[0] for k, v in out.items()}
    if min(counts.values()) < 2:
        raise ValueError(
            f"{path}: too few runs: {counts['cw']} cw and {counts['ccw']} ccw (need at least 2 "
            "per direction: the scatter of the runs gives the intervals)"
        )
    return out


# --- the simulated experiment (the pipeline's UMBmark study) ----------------------------------


def true_quantities(side: float, track: float, E_d: float, E_b: float) -> dict[str, float]:
    """What UMBmark should recover from a robot with true ``E_d``, ``E_b`` (nominal track ``track``).

    ``alpha = (π/2)(1 − 1/E_b)`` (a commanded π/2 turn in place turns ``(π/2)/E_b``),
    ``beta = L(c_R − c_L)/(E_b b)`` (the heading change along a leg), ``c_R``, ``c_L``
    (:meth:`WheelGeometry.from_ratios`), ``track_corrected = E_b b``, the direct fit's
    targets ``E_d_fit = E_d``, ``E_b_fit = E_b``, and ``E_max_before``: E_max,syst of
    the noiseless square [m].
    """
    g = WheelGeometry.from_ratios(track, E_d, E_b)
    L = float(check_positive("side", side))
    noiseless = [
        return_errors_noiseless(L, d, g.scale_r, g.scale_l, g.track, odometry_track=track) for d in DIRECTIONS
    ]
    return {
        "alpha": (math.pi / 2) * (1.0 - 1.0 / E_b), "beta": L * (g.scale_r - g.scale_l) / g.track,
        "E_d": float(E_d), "E_b": float(E_b), "c_R": g.scale_r, "c_L": g.scale_l, "track_corrected": g.track,
        "E_d_fit": float(E_d), "E_b_fit": float(E_b),
        "E_max_before": float(e_max_syst(noiseless[0], noiseless[1])),
    }  # fmt: skip


def umbmark_experiment(
    side: float = 4.0,
    track: float = 0.3,
    E_d: float = 1.002,
    E_b: float = 1.01,
    k: float = 1e-7,
    n: int = 5,
    seed: int = 2026,
    level: float = 0.95,
    n_boot: int = 2000,
    speed: float = 0.5,
    angular_speed: float = 1.0,
    dt: float = 0.02,
) -> dict[str, Any]:
    """UMBmark on a simulated robot with known systematic errors, before and after its correction.

    The robot (:mod:`pose_uncertainty.methods.systematic`) has true wheel-diameter ratio
    ``E_d`` and track ``E_b·track``; its odometry assumes the nominal geometry. It drives
    the ``side × side`` square ``n`` times clockwise and ``n`` times counter-clockwise
    (:func:`~pose_uncertainty.methods.systematic.umbmark_runs`, per-step random error
    ``k_r = k_l = k`` [m], exact arcs, generator ``default_rng(seed)``; the default
    ``k = 10⁻⁷`` m, 0.3 mm per metre of travel, leaves the systematic errors dominant, as
    UMBmark assumes); :func:`umbmark`
    estimates the errors from those return errors (bootstrap from ``default_rng([seed, 1])``);
    the robot then drives the squares again with the UMBmark-corrected odometry
    (generator ``default_rng([seed, 2])``), which gives the measured E_max after.

    Parameters
    ----------
    side : float [m]; track : float [m] — nominal b; E_d, E_b : float [1] — the truth
    k : float [m] — random error constant; n : int — runs per direction; seed : int
    level : float — confidence level; n_boot : int — bootstrap resamples
    speed [m/s], angular_speed [rad/s], dt [s] — how the square is driven

    Returns
    -------
    dict: the settings; ``true`` (:func:`true_quantities`); ``before`` and ``after`` —
    ``{"cw": (n, 2), "ccw": (n, 2)}`` return errors [m] and ``centres_before`` /
    ``centres_after`` their centres of gravity; ``corrected`` — the corrected geometry;
    ``umbmark`` — :meth:`UmbmarkResult.as_dict` of the estimate (with the measured
    E_max after); ``recovered`` — one row per quantity: ``quantity``, ``unit``, ``true``,
    ``estimate``, ``std_error``, ``delta_ci``, ``bootstrap_ci``, ``delta_covers``
    (whether the delta interval holds the truth).
    """
    nominal = WheelGeometry(float(check_positive("track", track)))
    true = WheelGeometry.from_ratios(track, E_d, E_b)
    drive = {"k_r": k, "k_l": k, "speed": speed, "angular_speed": angular_speed, "dt": dt}
    before = umbmark_runs(side, true, nominal, n, np.random.default_rng(seed), **drive)
    first = umbmark(before, side, track, np.random.default_rng([seed, 1]), level=level, n_boot=0)
    corrected = first.corrected()
    after = umbmark_runs(side, true, corrected, n, np.random.default_rng([seed, 2]), **drive)
    res = umbmark(before, side, track, np.random.default_rng([seed, 1]), level=level, n_boot=n_boot,
                  after=after)  # fmt: skip
    truth = true_quantities(side, track, E_d, E_b)
    recovered = [
        {"quantity": q, "unit": e.unit, "true": truth[q], "estimate": e.value, "std_error": e.std_error,
         "delta_ci": list(e.delta), "bootstrap_ci": list(e.bootstrap),
         "delta_covers": bool(e.delta[0] <= truth[q] <= e.delta[1])}
        for q, e in res.estimates.items() if q in truth
    ]  # fmt: skip
    return {
        "side": float(side), "track": float(track), "k": float(k), "n": int(n), "level": float(level),
        "true": truth,
        "before": {d: v.tolist() for d, v in before.items()},
        "after": {d: v.tolist() for d, v in after.items()},
        "centres_before": {d: centres_of_gravity(v).tolist() for d, v in before.items()},
        "centres_after": {d: centres_of_gravity(v).tolist() for d, v in after.items()},
        "corrected": {"scale_r": corrected.scale_r, "scale_l": corrected.scale_l, "track": corrected.track},
        "umbmark": res.as_dict(),
        "recovered": recovered,
    }  # fmt: skip
