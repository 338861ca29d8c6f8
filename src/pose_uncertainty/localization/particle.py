"""Particle filter — Monte Carlo localization (Thrun Tables 8.2–8.3; seed 002 §2.7.1.3; deck 004).

Per step: prediction — every particle moved by a draw of the motion model
(:func:`~pose_uncertainty.localization.motion.sample_motion`: wheel noise, velocity or
odometry sampler); correction — log-weights ``ℓ_i += log p(z | x_i)`` from the landmark
sensor or the beam model, normalised stably (:func:`~pose_uncertainty.localization.resampling.normalize_log_weights`);
resampling — only when the effective sample size ``1/Σw²`` falls below
``ess_threshold · n``, by one of the schemes of :mod:`.resampling`.

Random particles (recovery from a kidnapping or a wrong convergence)
--------------------------------------------------------------------
``injection="fixed"``: at every correction ``round(injection_fraction · n)`` particles
are replaced by poses drawn uniformly over the free space (seed 002's simple remedy).
``injection="augmented"`` (Augmented MCL, Thrun Table 8.3): short- and long-term averages
of the measurement likelihood, ``w_slow += α_slow (w_avg − w_slow)``,
``w_fast += α_fast (w_avg − w_fast)`` (kept in logarithms, ``w_avg = Σ w_i p(z|x_i)``;
both start at the first ``w_avg``, as in ROS AMCL — Thrun's start at 0 leaves
``w_slow ≪ w_fast`` for ~1/α_slow corrections, which disables the injection). ``w_avg``
is taken per measurement, ``(Σ w_i p(z|x_i))^{1/m}`` for ``m`` measurements: the number of
landmarks seen changes from step to step and the likelihood of ``m`` measurements
scales like a density to the power ``m``, which would otherwise drive the averages;
each new particle is random with probability ``max(0, 1 − w_fast/w_slow)``. When
particles are injected the filter resamples whatever the ESS (the injected ones and
the survivors then all weigh ``1/n``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..core.kinematics import wrap_angle
from ..core.validation import check_choice, check_positive, check_positive_int
from .measures import mass_region_flags, weighted_mean_cov
from .motion import Motion, sample_motion
from .resampling import (
    SCHEMES,
    _check_threshold,
    effective_sample_size,
    normalize_log_weights,
    resample,
)
from .result import (
    ASSOCIATIONS,
    FilterResult,
    Start,
    StepCallback,
    StepRecorder,
    check_keep,
    landmark_measurements,
)
from .sensors import (
    BeamSensor,
    RangeBearingSensor,
    beam_log_likelihood,
    landmark_log_likelihood,
    landmark_log_likelihood_ml,
)
from .simulate import SimulatedRun
from .world import World, sample_free_poses

__all__ = [
    "INJECTIONS",
    "ParticleFilterConfig",
    "initial_particles",
    "pf_correct",
    "pf_resample",
    "run_particle",
]

INJECTIONS: tuple[str, ...] = ("none", "fixed", "augmented")

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ParticleFilterConfig:
    """Options of the particle filter.

    Attributes
    ----------
    n_particles : int ≥ 1
    motion : Motion — ``"wheels"``, ``"velocity"`` or ``"odometry"``
    resampling : {"multinomial", "stratified", "systematic", "linear_time"}
    ess_threshold : float in (0, 1] — resample when ``ESS < ess_threshold · n`` (1: always)
    injection : {"none", "fixed", "augmented"}
    injection_fraction : float in [0, 1) — ``"fixed"``
    alpha_slow, alpha_fast : float in (0, 1), ``alpha_slow < alpha_fast`` — ``"augmented"``
    association : {"known", "ml"} — true correspondences, or each particle's maximum-likelihood
        association (:func:`~pose_uncertainty.localization.sensors.landmark_log_likelihood_ml`);
        ``wrong_associations`` is then the weighted mean count of wrong ones
    dtype : {"float64", "float32"} — arithmetic of the landmark likelihood
    hdr_resolution : float [m], > 0 — cell of the particle histogram for the region coverage
    workers : int ≥ 1 — threads of the landmark likelihood (results do not depend on it)
    """

    n_particles: int = 2000
    motion: Motion = field(default_factory=Motion)
    resampling: str = "systematic"
    ess_threshold: float = 0.5
    injection: str = "none"
    injection_fraction: float = 0.01
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    association: str = "known"
    dtype: str = "float64"
    hdr_resolution: float = 0.1
    workers: int = 1

    def __post_init__(self) -> None:
        check_positive_int("n_particles", self.n_particles)
        check_choice("resampling", self.resampling, SCHEMES)
        _check_threshold(self.ess_threshold)
        check_choice("injection", self.injection, INJECTIONS)
        f = float(self.injection_fraction)
        if not 0.0 <= f < 1.0:
            raise ValueError(f"injection_fraction must be in [0, 1) (allowed: [0, 1)), got {f}")
        for name in ("alpha_slow", "alpha_fast"):
            a = float(getattr(self, name))
            if not 0.0 < a < 1.0:
                raise ValueError(f"{name} must be in (0, 1) (allowed: (0, 1)), got {a}")
        if not self.alpha_slow < self.alpha_fast:
            raise ValueError(f"alpha_slow must be < alpha_fast (allowed: 0 < alpha_slow < alpha_fast < 1), "
                             f"got {self.alpha_slow} and {self.alpha_fast}")  # fmt: skip
        check_choice("association", self.association, ASSOCIATIONS)
        check_choice("dtype", self.dtype, ("float64", "float32"))
        check_positive("hdr_resolution", self.hdr_resolution)
        check_positive_int("workers", self.workers)


def initial_particles(start: Start, world: World, n: int, rng: np.random.Generator) -> Array:
    """``n`` particles of the initial belief: N(pose, diag(std²)), or uniform over the free space."""
    if start.is_global:
        return sample_free_poses(world, n, rng)
    return np.asarray(start.pose) + rng.standard_normal((n, 3)) * np.asarray(start.std)


def pf_correct(w: Array, loglik: Array) -> tuple[Array, float]:
    """Posterior weights ``∝ w_i p(z|x_i)`` and ``log Σ w_i p(z|x_i)`` (the step's log evidence)."""
    with np.errstate(divide="ignore"):
        return normalize_log_weights(np.log(w) + loglik)


def pf_resample(
    particles: Array, w: Array, rng: np.random.Generator, scheme: str, threshold: float,
    n_inject: int, world: World,
) -> tuple[Array, Array, bool]:  # fmt: skip
    """Resample if ``ESS < threshold · n`` or particles are to be injected; inject ``n_inject``.

    Returns
    -------
    particles : ndarray, shape (n, 3); w : ndarray, shape (n,); resampled : bool
    """
    n = particles.shape[0]
    if n_inject == 0 and effective_sample_size(w) >= threshold * n and threshold < 1.0:
        return particles, w, False
    keep = n - n_inject
    out = np.empty_like(particles)
    if keep:
        out[:keep] = particles[resample(w, rng, scheme, keep)]
    if n_inject:
        out[keep:] = sample_free_poses(world, n_inject, rng)
    return out, np.full(n, 1.0 / n), True


def _n_inject(cfg: ParticleFilterConfig, log_avg: float, slow_fast: list[float], rng: np.random.Generator) -> int:
    """Number of random particles at this correction (updates the augmented-MCL averages in place)."""
    n = cfg.n_particles
    if cfg.injection == "fixed":
        return round(cfg.injection_fraction * n)
    if cfg.injection == "none":
        return 0
    ls, lf = slow_fast
    if ls == -math.inf:  # first correction: both averages start at w_avg (as ROS AMCL)
        ls = lf = log_avg
    # w ← w + α (w_avg − w) in logarithms: log((1 − α) w + α w_avg)
    ls = np.logaddexp(math.log1p(-cfg.alpha_slow) + ls, math.log(cfg.alpha_slow) + log_avg)
    lf = np.logaddexp(math.log1p(-cfg.alpha_fast) + lf, math.log(cfg.alpha_fast) + log_avg)
    slow_fast[:] = [float(ls), float(lf)]
    p = max(0.0, 1.0 - math.exp(lf - ls))
    return int(rng.binomial(n, p)) if p > 0 else 0


def _loglik(
    particles: Array, run: SimulatedRun, world: World, sensor: RangeBearingSensor | BeamSensor,
    k: int, cfg: ParticleFilterConfig, w: Array,
) -> tuple[Array | None, int, int]:  # fmt: skip
    """Log-likelihood of step ``k``'s measurements per particle (None: no measurement)."""
    if isinstance(sensor, BeamSensor):
        if not run.beam_valid[k] or run.beam_z is None or world.grid is None:
            return None, 0, 0
        return beam_log_likelihood(particles, run.beam_z[k], world.grid, sensor), sensor.n_beams, 0
    if cfg.association == "ml":  # every particle associates for itself
        valid = run.landmark_valid[k]
        if not valid.any():
            return None, 0, 0
        ll, idx = landmark_log_likelihood_ml(particles, run.landmark_z[k][valid], world.landmarks, sensor)
        wrong_w = float(w @ (idx != np.flatnonzero(valid)).sum(axis=1))
        return ll, int(valid.sum()), wrong_w  # type: ignore[return-value]
    z, lm, _ = landmark_measurements(run, world, sensor, k, "known", np.zeros(3), np.eye(3))
    if z.shape[0] == 0:
        return None, 0, 0
    ll = landmark_log_likelihood(particles, z, lm, sensor, dtype=cfg.dtype, workers=cfg.workers)
    return ll, z.shape[0], 0


def _particle_region_flags(particles: Array, w: Array, world: World, truth: Array, h: float) -> NDArray[np.bool_]:
    """Truth in the highest-density regions of the particles' weighted (x, y) histogram (cells of ``h``)."""
    x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
    nx, ny = max(1, math.ceil((x1 - x0) / h)), max(1, math.ceil((y1 - y0) / h))
    i = np.floor((particles[:, 0] - x0) / h).astype(np.int64)
    j = np.floor((particles[:, 1] - y0) / h).astype(np.int64)
    ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    hist = np.bincount(i[ok] * ny + j[ok], w[ok], minlength=nx * ny).reshape(nx, ny)
    if not hist.sum() > 0:
        return np.zeros(3, dtype=bool)
    return mass_region_flags(hist, (math.floor((truth[0] - x0) / h), math.floor((truth[1] - y0) / h)))


def run_particle(
    run: SimulatedRun,
    world: World,
    sensor: RangeBearingSensor | BeamSensor,
    rng: np.random.Generator,
    config: ParticleFilterConfig | None = None,
    start: Start | None = None,
    *,
    keep: Sequence[int] = (),
    on_step: StepCallback | None = None,
) -> FilterResult:
    """Monte Carlo localization along a simulated run, with the landmark sensor or the beam model.

    Diagnostics per step: ``ess`` (after the correction), ``resampled`` (0/1),
    ``injected``, ``log_evidence``, ``n_measurements``, ``wrong_associations``.
    Snapshots / ``on_step`` state: ``particles`` (n, 3) and ``weights`` (n,).
    """
    cfg = config or ParticleFilterConfig()
    st = start or Start(pose=tuple(run.true_poses[0]))  # type: ignore[arg-type]
    rec = StepRecorder("particle", run, check_keep(keep, run.n_steps), on_step)
    n = cfg.n_particles
    P = initial_particles(st, world, n, rng)
    w = np.full(n, 1.0 / n)
    slow_fast = [-math.inf, -math.inf]
    for k in range(run.n_steps + 1):
        rec.tic()
        if k > 0:
            P = sample_motion(P, cfg.motion, run, k - 1, rng)
        ll, m, wrong = _loglik(P, run, world, sensor, k, cfg, w)
        ess, res, inj, logev = float(effective_sample_size(w)), False, 0, 0.0
        if ll is not None:
            w, logev = pf_correct(w, ll)
            ess = effective_sample_size(w)
            inj = _n_inject(cfg, logev / max(m, 1), slow_fast, rng)
            P, w, res = pf_resample(P, w, rng, cfg.resampling, cfg.ess_threshold, inj, world)
        rec.toc(k)
        mean, cov = weighted_mean_cov(P, w)
        flags = _particle_region_flags(P, w, world, run.true_poses[k], cfg.hdr_resolution)
        P[:, 2] = wrap_angle(P[:, 2])
        rec.record(k, mean, cov, flags, {"particles": P, "weights": w}, ess=ess, resampled=float(res),
                   injected=inj, log_evidence=logev, n_measurements=m, wrong_associations=wrong)  # fmt: skip
    return rec.result()
