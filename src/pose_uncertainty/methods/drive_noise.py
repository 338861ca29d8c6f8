"""Error models of every drive's odometry: which error acts on which measurement, and how.

A drive's measurements per step (:mod:`pose_uncertainty.core.drives`) are
travels [m] (a wheel, a track, a steering wheel, an omni wheel) and steering
angles [rad]. A :class:`DriveErrorModel` names the error sources; the channel
kinds of the drive decide where each acts:

========================  ==========================  ===================================
source                    acts on                     per step (variance / bias)
========================  ==========================  ===================================
``k`` travel noise        every travel channel        ``k_j |Δs_j|`` (k per metre, as
                                                      ``k_r, k_l`` of Method A)
``encoder``               every travel channel,       ``σ_v²(v) dt²`` with
                          replacing ``k``             ``σ_v² = q²/12 + c²v² + σ_a²``
                                                      (:mod:`.wheel_noise`; Šafránek 2022)
``steer_var``             every angle channel         ``steer_var`` [rad²], white
``steer_bias``            every angle channel         ``+steer_bias`` [rad]
``slip``                  the ICR of a skid-steer     ``χ ~ N(χ̄, chi_var)``,
(:class:`IcrSlip`)        drive (not a measurement)   ``x_ICR ~ N(x̄_ICR, x_icr_var)``
========================  ==========================  ===================================

Per drive: ``differential``, ``skid_steer`` — ``k`` (or ``encoder``) on ``Δs_r, Δs_l``,
``slip`` on the skid-steer's ICR; ``tricycle``, ``two_axle`` — ``k`` on ``ΔS``,
steering on ``ω``; ``ackermann`` — ``k`` on both front wheels, steering on ``ω``;
``synchro`` — ``k`` on ``ΔS``, steering on ``ψ``; ``mdof`` — ``k`` on each wheel's
travel, steering on each wheel's angle; ``omni3`` — ``k`` on ``s_a, s_b, s_c``. A
scalar applies to every channel of its kind; a tuple gives one value per
channel of that kind, in the drive's channel order.

The sign convention: an error is *true minus reported*. The robot reports the
nominal measurements ``u``; it truly moved by ``u + bias + noise``; Method A's
mean is the path of ``u + bias``.

Two regimes (:data:`.particles.REGIMES`)
-------------------------------------------
``"per_step"`` (non-systematic) — independent errors every step with the
variances above. ``"per_run"`` (systematic) — one draw per run, kept for the
whole run: a travel channel's scale error ``ε_j ~ N(0, k_j/L_j)``
(``L_j = Σ|Δs_j|``, so the total travel has variance ``k_j L_j`` at the end of
the run, as per step), the encoder's constant offsets and scale error
(:func:`.wheel_noise.sample_speed_errors`), a steering offset of variance
``steer_var`` and the skid-steer's ``χ``, ``x_ICR`` for the whole run.

Per-step white steering noise averages out over many steps: its effect on the
pose shrinks with the step (the heading variance of a tricycle on a straight
is ``Σ(ΔS/d)² steer_var``, ∝ the step length); per run it does not.

Skid-steer slip
---------------
The ICR model of :class:`~pose_uncertainty.core.drives.SkidSteer` with random
``χ`` and ``x_ICR`` (Martínez et al. 2005; Mandow et al. 2007) moves only the
turn and the sideways slip, both ∝ ``Δs_r − Δs_l``: on a straight the slip has
no effect, in a turn it makes the turn uncertain. Plain differential odometry
(``χ = 1``, ``x_ICR = 0``) on a skid-steer whose ICRs lie outside its tracks
(``χ̄ > 1``) reports turns ``χ̄`` times too large: unbiased on straights, biased
in turns (:func:`plain_odometry_error`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.drives import Drive, SkidSteer
from ..core.kinematics import Method
from ..core.validation import check_choice, check_finite, check_nonnegative
from .particles import REGIMES, DrawCache
from .wheel_noise import WheelErrorSources, sample_speed_errors, speed_variance

__all__ = [
    "Channels",
    "DriveErrorModel",
    "IcrSlip",
    "PerRunSensitivity",
    "channels",
    "errors_from_normals",
    "measurement_cov",
    "measurement_mean",
    "per_run_sensitivity",
    "plain_odometry_error",
    "sample_errors",
    "slip_twist_cov",
]


@dataclass(frozen=True)
class IcrSlip:
    """Random ICR of a skid-steer drive: variances of ``χ`` [1] and ``x_ICR`` [m²] (means: the drive's)."""

    chi_var: float = 0.0
    x_icr_var: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "chi_var", float(check_nonnegative("chi_var", self.chi_var)))
        object.__setattr__(self, "x_icr_var", float(check_nonnegative("x_icr_var", self.x_icr_var)))


@dataclass(frozen=True)
class DriveErrorModel:
    """Error sources of a drive's odometry (module docstring).

    Attributes
    ----------
    k : float or tuple of float — travel variance per metre [m], ≥ 0, of each
        travel channel (one number for all, or one per travel channel)
    steer_var : float or tuple — per-step steering-angle variance [rad²], ≥ 0
    steer_bias : float or tuple — steering-angle bias, true minus reported [rad]
    encoder : WheelErrorSources, optional — Šafránek 2022's encoder, surface and
        additive errors of every travel channel, in place of ``k``
    slip : IcrSlip, optional — random ICR (skid_steer only)
    """

    k: float | tuple[float, ...] = 5e-4
    steer_var: float | tuple[float, ...] = 0.0
    steer_bias: float | tuple[float, ...] = 0.0
    encoder: WheelErrorSources | None = None
    slip: IcrSlip | None = None

    def __post_init__(self) -> None:
        check_nonnegative("k", self.k)
        check_nonnegative("steer_var", self.steer_var)
        check_finite("steer_bias", self.steer_bias)


class Channels(NamedTuple):
    """A model resolved onto a drive's channels, each shape (m,)."""

    travel: NDArray[np.bool_]  # True for travel channels
    k: NDArray[np.float64]  # [m], 0 on angle channels
    angle_var: NDArray[np.float64]  # [rad²], 0 on travel channels
    bias: NDArray[np.float64]  # [rad], 0 on travel channels


def _per_channel(
    name: str, value: float | tuple[float, ...], mask: NDArray, drive: Drive
) -> NDArray:
    """Spread a scalar over the channels in ``mask``, or place one value per such channel."""
    out = np.zeros(mask.size)
    v = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if v.size != 1 and v.size != int(mask.sum()):
        names = [c for c, m in zip(drive.channels, mask, strict=True) if m]
        raise ValueError(
            f"{name} must be one number or one per channel {names} of the {drive.kind} drive "
            f"(allowed: 1 or {len(names)} values), got {v.size} values"
        )
    out[mask] = v
    return out


def channels(drive: Drive, model: DriveErrorModel) -> Channels:
    """Resolve ``model`` onto the channels of ``drive``; ValueError for a mismatch."""
    travel = np.array([k == "travel" for k in drive.kinds])
    if model.slip is not None and not isinstance(drive, SkidSteer):
        raise ValueError(
            f"slip applies to a skid_steer drive only (allowed: skid_steer), got {drive.kind!r}"
        )
    return Channels(
        travel=travel,
        k=_per_channel("k", model.k, travel, drive),
        angle_var=_per_channel("steer_var", model.steer_var, ~travel, drive),
        bias=_per_channel("steer_bias", model.steer_bias, ~travel, drive),
    )


def measurement_mean(drive: Drive, u: ArrayLike, model: DriveErrorModel) -> NDArray[np.float64]:
    """Expected true measurements ``u + bias``, shape of ``u`` (..., N, m)."""
    return np.asarray(u, dtype=np.float64) + channels(drive, model).bias


def _travel_var(u: NDArray, k: NDArray, encoder: WheelErrorSources | None, dt: float) -> NDArray:
    """Per-step variance of each travel channel: ``k|Δs|`` or ``σ_v²(Δs/dt) dt²``."""
    if encoder is None:
        return k * np.abs(u)
    return speed_variance(encoder, u / dt) * dt**2


def measurement_cov(
    drive: Drive, u: ArrayLike, dt: float, model: DriveErrorModel
) -> NDArray[np.float64]:
    """Per-step covariance of the measurement errors (regime ``per_step``), diagonal.

    Parameters
    ----------
    drive : Drive; u : array_like, shape (..., N, m) — nominal measurements
    dt : float [s] — step (used by the encoder sources only); model : DriveErrorModel

    Returns
    -------
    ndarray, shape (..., N, m, m)
    """
    ch = channels(drive, model)
    a = np.asarray(u, dtype=np.float64)
    var = np.where(ch.travel, _travel_var(a, ch.k, model.encoder, dt), ch.angle_var)
    return var[..., :, None] * np.eye(a.shape[-1])


def slip_twist_cov(
    drive: Drive, u: ArrayLike, model: DriveErrorModel
) -> NDArray[np.float64] | None:
    """Per-step twist covariance of the skid-steer slip ``G diag(chi_var, x_icr_var) Gᵀ``, or None.

    ``G = ∂ξ/∂(χ, x_ICR)`` at ``u`` (:meth:`SkidSteer.icr_jacobian`); shape (..., N, 3, 3).
    """
    channels(drive, model)
    if model.slip is None or not isinstance(drive, SkidSteer):
        return None
    G = drive.icr_jacobian(u)
    W = np.array([model.slip.chi_var, model.slip.x_icr_var])
    return (G * W) @ np.swapaxes(G, -1, -2)


class PerRunSensitivity(NamedTuple):
    """Twist errors of the per-run regime: ``δξ_i = T_i ε``, ``ε ~ N(0, diag(var))``."""

    T: NDArray[np.float64]  # (..., N, 3, r) — ∂ξ_i/∂ε
    var: NDArray[np.float64]  # (..., r) — variances of the per-run parameters


def _per_run_columns(
    drive: Drive, u: NDArray, dt: float, model: DriveErrorModel
) -> tuple[list[NDArray], list[NDArray], list[int]]:
    """Per-run parameters: sensitivity columns of the measurements (..., N), variances, channel."""
    ch = channels(drive, model)
    cols, var, chan = [], [], []
    for j, is_travel in enumerate(ch.travel):
        uj = u[..., j]
        if not is_travel:
            cols.append(np.ones_like(uj))  # steering offset
            var.append(np.broadcast_to(ch.angle_var[j], uj.shape[:-1]))
            chan.append(j)
        elif model.encoder is None:
            L = np.abs(uj).sum(axis=-1)  # scale error ε ~ N(0, k/L): total variance k·L
            cols.append(uj)
            var.append(np.where(L > 0, ch.k[j] / np.where(L > 0, L, 1.0), 0.0))
            chan.append(j)
        else:
            e = (
                model.encoder
            )  # offset (u + a) dt with variance (q²/12 + σ_a²) dt², scale ε v dt = ε Δs
            cols += [np.full_like(uj, dt), uj]
            offset_var = e.quantisation_var + e.additive_std**2
            var += [
                np.broadcast_to(offset_var, uj.shape[:-1]),
                np.broadcast_to(e.surface_rel_std**2, uj.shape[:-1]),
            ]
            chan += [j, j]
    return cols, var, chan


def per_run_sensitivity(
    drive: Drive, u: ArrayLike, dt: float, model: DriveErrorModel
) -> PerRunSensitivity:
    """Twist sensitivities of the per-run (systematic) regime for first-order propagation.

    Each per-run parameter ``ε_r`` moves measurement channel ``j(r)`` by
    ``D_ir ε_r`` in step ``i`` (a scale error ``D = Δs``, an offset ``D = 1`` or
    ``dt``); the twist moves by ``∂ξ/∂u D`` and, for the skid-steer slip, by
    ``∂ξ/∂(χ, x_ICR)``. Jacobians at ``u + bias``.

    Parameters
    ----------
    drive : Drive; u : array_like, shape (..., N, m); dt : float [s]; model : DriveErrorModel
    """
    a = np.asarray(u, dtype=np.float64)
    cols, var, chan = _per_run_columns(drive, a, dt, model)
    mean = measurement_mean(drive, a, model)
    J = drive.twist_jacobian(mean)  # (..., N, 3, m)
    T = [J[..., :, j] * c[..., None] for c, j in zip(cols, chan, strict=True)]
    if model.slip is not None and isinstance(drive, SkidSteer):
        G = drive.icr_jacobian(mean)
        T += [G[..., 0], G[..., 1]]
        var += [
            np.broadcast_to(model.slip.chi_var, a.shape[:-2]),
            np.broadcast_to(model.slip.x_icr_var, a.shape[:-2]),
        ]
    return PerRunSensitivity(np.stack(T, axis=-1), np.stack(var, axis=-1))


class SampledErrors(NamedTuple):
    """Errors of ``n`` runs: each channel's measurement errors (n, N) and the skid-steer's ICR, or None."""

    channels: tuple[NDArray[np.float64], ...]  # m arrays (n, N), true minus reported, biases included
    chi: NDArray[np.float64] | None  # (n, N) or (n, 1)
    x_icr: NDArray[np.float64] | None

    @property
    def du(self) -> NDArray[np.float64]:
        """The measurement errors as one array, shape (n, N, m)."""
        return np.stack(self.channels, axis=-1)


def _gaussian_errors(
    ch: Channels, u: NDArray, gauss: list[int], z: NDArray, regime: str, overwrite: bool = True
) -> list[NDArray]:
    """Errors (n, N) of the Gaussian channels from standard normals z (len(gauss), n, N or 1);
    ``overwrite``: the per-step errors are formed in ``z`` itself (else ``z`` is left as it is)."""
    out = []
    for row, j in enumerate(gauss):
        uj = u[:, j]
        if not ch.travel[j]:
            out.append(z[row] * np.sqrt(ch.angle_var[j]) + np.zeros_like(uj))
        elif regime == "per_step":
            scale = np.sqrt(ch.k[j] * np.abs(uj))  # Δs' − Δs ~ N(0, k|Δs|)
            if overwrite:
                z[row] *= scale
                out.append(z[row])
            else:
                out.append(z[row] * scale)
        else:
            L = float(np.abs(uj).sum())  # Δs' − Δs = ε Δs, ε ~ N(0, k/L)
            eps_std = np.sqrt(ch.k[j] / L) if L > 0 else 0.0
            out.append((eps_std * z[row]) * uj)
    return out


def _with_bias(ch: Channels, errors: list[NDArray]) -> tuple[NDArray, ...]:
    # a zero bias is left out (adding 0.0 changes nothing but the sign of a zero)
    return tuple(e + ch.bias[j] if ch.bias[j] != 0.0 else e for j, e in enumerate(errors))


def errors_from_normals(
    drive: Drive, u: ArrayLike, model: DriveErrorModel, z: NDArray[np.float64], regime: str = "per_step"
) -> SampledErrors:
    """The errors of :func:`sample_errors` from standard normals drawn elsewhere (every channel Gaussian).

    For a model without ``encoder`` and ``slip``: ``z`` (m, n, N) per step or (m, n, 1) per run,
    one row per channel in channel order, is what :func:`sample_errors` would draw; the errors
    are computed from it with the same arithmetic (``z`` is used up).

    Parameters
    ----------
    drive : Drive; u : array_like, shape (N, m); model : DriveErrorModel (no encoder, no slip)
    z : ndarray, shape (m, n, N) or (m, n, 1); regime : {"per_step", "per_run"}

    Returns
    -------
    SampledErrors — as :func:`sample_errors`'s (``chi``, ``x_icr`` None)
    """
    check_choice("regime", regime, REGIMES)
    if model.encoder is not None or model.slip is not None:
        raise ValueError("errors_from_normals needs a model without encoder and slip (allowed: k, steer_var, steer_bias)")
    ch = channels(drive, model)
    a = check_finite("u", u)
    width = a.shape[0] if regime == "per_step" else 1
    if z.shape[0] != a.shape[1] or z.shape[2] != width:
        raise ValueError(f"z must have shape ({a.shape[1]}, n, {width}) for this drive and regime, got {z.shape}")
    return SampledErrors(_with_bias(ch, _gaussian_errors(ch, a, list(range(a.shape[1])), z, regime)), None, None)


def sample_errors(
    drive: Drive,
    u: ArrayLike,
    dt: float,
    model: DriveErrorModel,
    n: int,
    rng: np.random.Generator,
    regime: str = "per_step",
    cache: DrawCache | None = None,
) -> SampledErrors:
    """Draw the errors of ``n`` runs of a measurement sequence (biases included).

    Draw order (fixed, so a seed fixes the result): one ``standard_normal`` of
    shape (c, n, N) — (c, n, 1) per run — for the c Gaussian channels in
    channel order; then each encoder channel (:func:`.wheel_noise.sample_speed_errors`);
    then the ICR ``χ``, ``x_ICR``. For the differential drive with ``k`` only this
    is the draw of the differential drive's :func:`.sampling.sample_end_poses` (its front door).

    Parameters
    ----------
    drive : Drive; u : array_like, shape (N, m); dt : float [s]; model : DriveErrorModel
    n : int; rng : numpy.random.Generator; regime : {"per_step", "per_run"}
    cache : DrawCache, optional — the Gaussian channels' standard normals kept for the next call
        from the same stream state (:class:`.particles.DrawCache`; the same errors either way)

    Returns
    -------
    SampledErrors — ``channels``: m arrays (n, N), true minus reported (``du`` stacks
    them, (n, N, m)); ``chi``, ``x_icr`` (n, N) per step or (n, 1) per run, None without slip
    """
    check_choice("regime", regime, REGIMES)
    ch = channels(drive, model)
    a = check_finite("u", u)
    N = a.shape[0]
    gauss = [j for j in range(a.shape[1]) if not ch.travel[j] or model.encoder is None]
    width = N if regime == "per_step" else 1
    shape = (len(gauss), n, width)
    z = rng.standard_normal(shape) if cache is None else cache.normals(rng, shape)
    errors = dict(zip(gauss, _gaussian_errors(ch, a, gauss, z, regime, overwrite=cache is None), strict=True))
    for j in range(a.shape[1]):
        if j not in errors and model.encoder is not None:
            errors[j] = sample_speed_errors(model.encoder, a[:, j] / dt, n, rng, regime) * dt
    du = _with_bias(ch, [errors[j] for j in range(a.shape[1])])
    if model.slip is None or not isinstance(drive, SkidSteer):
        return SampledErrors(du, None, None)
    zs = rng.standard_normal((2, n, width))
    chi = drive.chi + np.sqrt(model.slip.chi_var) * zs[0]
    x_icr = drive.x_icr + np.sqrt(model.slip.x_icr_var) * zs[1]
    return SampledErrors(du, chi, x_icr)


def plain_odometry_error(
    drive: SkidSteer,
    u: ArrayLike,
    start: ArrayLike = (0.0, 0.0, 0.0),
    method: Method = "exact",
) -> NDArray[np.float64]:
    """Dead-reckoning error of plain differential odometry on a skid-steer drive, per pose.

    The robot truly moves by its ICR kinematics (``drive``); the odometry
    integrates the same track travels as a differential drive of the same track
    (``χ = 1``, ``x_ICR = 0``). Returns reported minus true poses, shape (..., N+1, 3):
    zero on straights; in turns the reported turn is ``χ`` times the true one
    (heading error ``(χ − 1)·Δθ_true``, and the position error it drags).
    """
    a = check_finite("u", u)
    true = drive.integrate(a, start, method)
    plain = SkidSteer(drive.track).integrate(a, start, method)
    return plain - true
