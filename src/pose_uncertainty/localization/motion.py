"""The motion model a filter predicts with, and the samplers of the particle filter.

Three models of one step ``k → k+1`` of a :class:`~pose_uncertainty.localization.simulate.SimulatedRun`,
all driven by the same measured wheel travels:

``"wheels"``
    Method A's noise model (Němec 2012 §2.1.2): ``Δs_r' ~ N(Δs_r, k_r|Δs_r|)``,
    ``Δs_l' ~ N(Δs_l, k_l|Δs_l|)``, then the midpoint step. The simulator's
    ``per_step`` truth is drawn from this model (with exact arcs), so it is the
    right model there; the EKF linearises it (:func:`~pose_uncertainty.localization.ekf.ekf_predict_wheels`).
``"velocity"``
    Thrun's velocity model with ``u = (V, ω)`` = measured travels / Δt, six α's
    (:func:`pose_uncertainty.methods.motion_models.sample_velocity`).
``"odometry"``
    Thrun's odometry model with ``u`` = the dead-reckoned odometry poses ``k → k+1``,
    four α's (:func:`pose_uncertainty.methods.motion_models.sample_odometry`).

:func:`velocity_alphas_for_wheels` gives velocity-model constants that match the
wheel-noise variances of forward driving (see there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.noise import check_noise, check_scaling
from ..core.validation import check_choice, check_nonnegative, check_positive
from ..methods import mc_kernel
from ..methods.motion_models import check_alphas, sample_odometry, sample_velocity
from .simulate import SimulatedRun

__all__ = ["MOTION_MODELS", "Motion", "sample_motion", "velocity_alphas_for_wheels", "wheel_draws"]

MOTION_MODELS: tuple[str, ...] = ("wheels", "velocity", "odometry")

Array = NDArray[np.float64]


#: The default wheel error constant k_r = k_l [m] (wheel-travel variance per metre of travel):
#: of a filter's wheel model, of a localization run's truth and of a dead-reckoning run.
K_WHEEL: float = 5e-4


@dataclass(frozen=True)
class Motion:
    """Motion model and its error constants.

    Attributes
    ----------
    model : {"wheels", "velocity", "odometry"}
    k_r, k_l : float [m], ≥ 0 — wheel-noise constants ("wheels")
    alphas : tuple of 6 (velocity) or 4 (odometry) floats ≥ 0; default 0.05 each
    noise : {"normal", "triangular"}; scaling : {"squared", "abs"} — velocity/odometry models
    """

    model: str = "wheels"
    k_r: float = K_WHEEL
    k_l: float = K_WHEEL
    alphas: tuple[float, ...] | None = None
    noise: str = "normal"
    scaling: str = "squared"

    def __post_init__(self) -> None:
        check_choice("motion.model", self.model, MOTION_MODELS)
        object.__setattr__(self, "k_r", float(check_nonnegative("k_r", self.k_r)))
        object.__setattr__(self, "k_l", float(check_nonnegative("k_l", self.k_l)))
        check_noise(self.noise)
        check_scaling(self.scaling)
        if self.model != "wheels":
            n = 6 if self.model == "velocity" else 4
            a = np.full(n, 0.05) if self.alphas is None else check_alphas(self.alphas, n)
            object.__setattr__(self, "alphas", tuple(float(v) for v in a))

    @property
    def alpha_array(self) -> Array:
        """The α's as an array (velocity: 6, odometry: 4)."""
        return np.asarray(self.alphas, dtype=np.float64)


def velocity_alphas_for_wheels(k_r: float, k_l: float, track: float, dt: float) -> tuple[float, ...]:
    """Velocity-model constants (``scaling="abs"``) with the wheel model's variances, forward driving.

    With both wheels rolling forwards, ``Var Δs = (k_r|Δs_r| + k_l|Δs_l|)/4 ≈ k̄|Δs|/2`` and
    ``Var Δθ = (k_r|Δs_r| + k_l|Δs_l|)/b² ≈ 2k̄|Δs|/b²`` (``k̄ = (k_r+k_l)/2``), so with
    ``σ_V² = α1|V|``, ``σ_ω² = α3|V|``: ``α1 = k̄/(2Δt)``, ``α3 = 2k̄/(b²Δt)``; the others 0.
    Approximate: it drops the V–ω correlation ``(k_r|Δs_r| − k_l|Δs_l|)/(2bΔt²)`` and
    rotation in place.
    """
    kbar = (float(check_nonnegative("k_r", k_r)) + float(check_nonnegative("k_l", k_l))) / 2
    b = float(check_positive("track", track))
    step = float(check_positive("dt", dt))
    return (kbar / (2 * step), 0.0, 2 * kbar / (b * b * step), 0.0, 0.0, 0.0)


def wheel_draws(rng: np.random.Generator, n: int) -> Array:
    """The standard normal draws of one step of ``n`` particles under the wheel model, shape (2, n):
    what :func:`sample_motion` draws from ``rng`` (a runner may draw them ahead and pass them)."""
    return rng.standard_normal((2, n))


def _wheel_step(P: Array, sr: float, sl: float, m: Motion, b: float, z: Array,
                trig: Any = np.float64, out: Array | None = None, compiled: bool = False) -> Array:  # fmt: skip
    """``Δs' ~ N(Δs, k|Δs|)`` per wheel and particle, then the midpoint step (as kinematics.step).

    ``z``: the standard normal draws (2, n) (:func:`wheel_draws`), used up in place. ``trig``: the
    float type of ``cos φ, sin φ`` (float32 is several times faster; its rounding, ~10⁻⁷ of the step,
    is far below the wheel noise). ``out``: the (n, 3) array to write, not ``P``. The operations write
    into ``z`` or ``out`` where they can. ``compiled``: float64 only, the same arithmetic in one
    compiled loop (:mod:`~pose_uncertainty.methods.mc_kernel`; its polynomial ``cos``/``sin``
    within 2 ulp), the draws unchanged.
    """
    if compiled and trig is np.float64:
        res = np.empty_like(P) if out is None else out
        mc_kernel.jit_module().wheel_step(
            np.ascontiguousarray(P), np.ascontiguousarray(z), sr, sl, math.sqrt(m.k_r * abs(sr)),
            math.sqrt(m.k_l * abs(sl)), 1.0 / b, res,
        )  # fmt: skip
        return res
    z[0] *= math.sqrt(m.k_r * abs(sr))
    z[0] += sr  # Δs_r'
    z[1] *= math.sqrt(m.k_l * abs(sl))
    z[1] += sl  # Δs_l'
    res = np.empty_like(P) if out is None else out
    ds = np.add(z[0], z[1])
    ds *= 0.5  # Δs = (Δs_r' + Δs_l')/2
    dth = np.subtract(z[0], z[1], out=z[1])
    dth *= 1.0 / b  # Δθ = (Δs_r' − Δs_l')/b
    np.add(P[:, 2], dth, out=res[:, 2])  # θ' = θ + Δθ
    phi = np.multiply(dth, 0.5, out=z[0])
    phi += P[:, 2]  # φ = θ + Δθ/2
    if trig is not np.float64:
        phi = phi.astype(trig)
    t = np.cos(phi)
    c = np.multiply(ds, t)  # Δs cos φ
    np.sin(phi, out=t)
    s = np.multiply(ds, t, out=z[1])  # Δs sin φ (Δθ is no longer needed)
    np.add(P[:, 0], c, out=res[:, 0])  # x' = x + Δs cos φ
    np.add(P[:, 1], s, out=res[:, 1])  # y' = y + Δs sin φ
    return res


def sample_motion(
    particles: Array, motion: Motion, run: SimulatedRun, k: int, rng: np.random.Generator,
    dtype: str = "float64", out: Array | None = None, draws: Array | None = None,
    compiled: bool | None = None,
) -> Array:  # fmt: skip
    """Move every particle by step ``k → k+1`` of ``run`` under ``motion``'s noise.

    Parameters
    ----------
    particles : ndarray, shape (n, 3)
    motion : Motion; run : SimulatedRun; k : int in [0, N)
    rng : numpy.random.Generator
    dtype : {"float64", "float32"} — the wheel model's heading trigonometry (the pose stays float64)
    out : ndarray, shape (n, 3), optional — where to write the moved particles (not ``particles``)
    draws : ndarray, shape (2, n), optional — the wheel model only: its draws
        (:func:`wheel_draws`) taken from ``rng`` beforehand; used up (overwritten)
    compiled : bool, optional — the wheel model in float64 only: move the particles by the compiled
        loop of :mod:`~pose_uncertainty.methods.mc_kernel` (the same draws and arithmetic, its
        ``cos``/``sin`` within 2 ulp) instead of numpy's; default: from
        :data:`~pose_uncertainty.methods.mc_kernel.MIN_PARTICLE_STEPS` particle-steps of the run
        (these particles times the run's steps)

    Returns
    -------
    ndarray, shape (n, 3) — headings unwrapped
    """
    n = particles.shape[0]
    if motion.model == "wheels":
        trig = np.float64 if check_choice("dtype", dtype, ("float64", "float32")) == "float64" else np.float32
        z = wheel_draws(rng, n) if draws is None else draws
        if z.shape != (2, n):
            raise ValueError(f"draws must have shape (2, {n}) (allowed: wheel_draws of the particles), got {z.shape}")
        # numba's start-up costs more than the compiled step saves below MIN_PARTICLE_STEPS
        big = n * run.n_steps >= mc_kernel.MIN_PARTICLE_STEPS if compiled is None else compiled
        return _wheel_step(particles, float(run.ds_r[k]), float(run.ds_l[k]), motion, run.track, z, trig, out, big)
    if draws is not None:
        raise ValueError(f"draws are the wheel model's (allowed: motion.model 'wheels'), got model {motion.model!r}")
    if motion.model == "velocity":
        moved = sample_velocity(particles, run.controls[k], run.dt, motion.alpha_array, n, rng,
                                motion.noise, motion.scaling)  # fmt: skip
    else:
        moved = sample_odometry(particles, run.odometry[k], run.odometry[k + 1], motion.alpha_array, n,
                                rng, motion.noise, motion.scaling)  # fmt: skip
    if out is None:
        return moved
    out[...] = moved
    return out
