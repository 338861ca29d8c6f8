"""Particle filter — Monte Carlo localization (Thrun Tables 8.2–8.3; Skalka 2011 §2.7.1.3; Kulich 2014).

Per step: prediction — every particle moved by a draw of the motion model
(:func:`~pose_uncertainty.localization.motion.sample_motion`: wheel noise, velocity or
odometry sampler); correction — log-weights ``ℓ_i += log p(z | x_i)`` from the landmark
sensor or the beam model, normalised stably (:func:`~pose_uncertainty.localization.resampling.normalize_log_weights`);
resampling — only when the effective sample size ``1/Σw²`` falls below
``ess_threshold · n``, by one of the schemes of :mod:`.resampling`.

Random particles (recovery from a kidnapping or a wrong convergence)
--------------------------------------------------------------------
``injection="fixed"``: at every correction ``round(injection_fraction · n)`` particles
are replaced by poses drawn uniformly over the free space (the simple remedy of Skalka 2011 §2.7.1.3).
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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ..core.kinematics import wrap_angle
from ..core.validation import check_choice, check_positive, check_positive_int
from ..methods import mc_kernel
from .dynamic import distance_filter
from .evaluation import region_flags_of_mass, weighted_mean_cov
from .motion import Motion, sample_motion, wheel_draws
from .resampling import (
    SCHEMES,
    _check_threshold,
    _counts_from_below,
    _cumulative,
    _ess,
    _strata_below,
    _systematic_below,
    normalize_log_weights,
    pointers,
    select,
)
from .result import (
    ASSOCIATIONS,
    FilterResult,
    Start,
    StepCallback,
    StepRecorder,
    check_keep,
)
from .sensors import (
    BeamSensor,
    LandmarkLikelihood,
    RangeBearingSensor,
    beam_log_likelihood,
    beam_probability,
    chunks,
    expected_ranges,
    landmark_log_likelihood_ml,
    run_ahead,
    run_blocks,
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
#: Schemes with one pointer per stratum [i/n, (i+1)/n): resampled by copies per particle.
_STRATA: tuple[str, ...] = ("systematic", "stratified")

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
    workers : int ≥ 1 — threads of a step: the blocks of particles and the next step's wheel
        draws (:func:`_thread_plan`); the results do not depend on it
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
    n_inject: int, world: World, workers: int = 1,
) -> tuple[Array, Array, bool]:  # fmt: skip
    """Resample if ``ESS < threshold · n`` or particles are to be injected; inject ``n_inject``.

    Systematic and stratified pointers: the copies of each particle (the count of pointers below
    each cumulative weight, found from its stratum: O(n)), then ``numpy.repeat``; the other schemes:
    binary search of each pointer, then the copy. Either runs in the blocks of
    :func:`~pose_uncertainty.localization.sensors.chunks` on ``workers`` threads and gives
    :func:`~pose_uncertainty.localization.resampling.select`'s particles, whatever ``workers``.

    Returns
    -------
    particles : ndarray, shape (n, 3); w : ndarray, shape (n,); resampled : bool
    """
    n = particles.shape[0]
    if n_inject == 0 and _ess(w) >= threshold * n and threshold < 1.0:
        return particles, w, False
    keep = n - n_inject
    if keep == n and scheme in _STRATA and workers == 1:  # one block: the copies are the new array
        return np.repeat(particles, _strata_counts(w, keep, rng, scheme), axis=0), np.full(n, 1.0 / n), True
    out = np.empty_like(particles)
    if keep and scheme in _STRATA:
        _repeat_blocks(particles, _cumulative(w), _strata_below_of(keep, rng, scheme), out[:keep], workers)
    elif keep:
        q, T = _cumulative(w), pointers(keep, rng, scheme)
        blocks = chunks(keep)

        def pick(c: int) -> None:
            a, b = blocks[c]
            np.take(particles, select(q, T[a:b]), axis=0, out=out[a:b])

        run_blocks(pick, len(blocks), workers)
    if n_inject:
        out[keep:] = sample_free_poses(world, n_inject, rng)
    return out, np.full(n, 1.0 / n), True


def _strata_below_of(keep: int, rng: np.random.Generator, scheme: str) -> Callable[[Array], NDArray[np.intp]]:
    """The count of ``keep`` new pointers of a stratified or systematic scheme below given values (draws them).

    Systematic: the one uniform of ``pointers(keep, rng, "systematic")``, its pointers never built.
    """
    if scheme == "systematic":
        return _systematic_below(keep, rng.random())
    return _strata_below(pointers(keep, rng, scheme), scheme)


def _strata_counts(w: Array, keep: int, rng: np.random.Generator, scheme: str) -> NDArray[np.intp]:
    """Copies of each particle when ``keep`` particles are drawn by a stratified or systematic scheme."""
    return _counts_from_below(_strata_below_of(keep, rng, scheme)(_cumulative(w)), keep)


def _repeat_blocks(
    particles: Array, q: Array, below: Callable[[Array], NDArray[np.intp]], out: Array, workers: int
) -> None:
    """``out`` (n, 3) = each particle repeated ``C(q_j) − C(q_{j−1})`` times, by blocks of particles.

    Block ``[a, b)`` counts below ``q_{a−1} … q_{b−1}`` itself and writes its copies at
    ``out[C(q_{a−1}) : C(q_{b−1})]`` (``C(q_{N−1}) = n``: select's guard), so the blocks need no
    other's result.
    """
    N, n = q.size, out.shape[0]
    blocks = chunks(N)

    def part(c: int) -> None:
        a, b = blocks[c]
        C = below(q[max(a - 1, 0) : b])
        if b == N:
            C[-1] = n
        if a:  # C holds C(q_{a−1}) first
            start, counts = int(C[0]), C[1:] - C[:-1]
        else:
            start, counts = 0, _counts_from_below(C, int(C[-1]))
        out[start : int(C[-1])] = np.repeat(particles[a:b], counts, axis=0)

    run_blocks(part, len(blocks), workers)


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


#: A step's measurement model on a block of particles: writes the log-likelihood into its second
#: argument, returns the wrong associations per particle (or None).
BlockModel = Callable[[Array, Array], Array | None]


def _measurement_model(
    run: SimulatedRun, world: World, sensor: RangeBearingSensor | BeamSensor, k: int, cfg: ParticleFilterConfig,
) -> tuple[BlockModel, int] | None:  # fmt: skip
    """Step ``k``'s measurements prepared for blocks of particles, and their number (None: no measurement)."""
    if isinstance(sensor, BeamSensor):
        grid, zb = world.grid, run.beam_z
        if not run.beam_valid[k] or zb is None or grid is None:
            return None

        def beams(P: Array, out: Array) -> None:
            out[...] = beam_log_likelihood(P, zb[k], grid, sensor)

        return beams, sensor.n_beams
    valid = run.landmark_valid[k]
    if not valid.any():
        return None
    if cfg.association == "ml":  # every particle associates for itself
        zk, ids = run.landmark_z[k][valid], np.flatnonzero(valid)

        def ml(P: Array, out: Array) -> Array:
            out[...], idx = landmark_log_likelihood_ml(P, zk, world.landmarks, sensor)
            return (idx != ids).sum(axis=1).astype(np.float64)

        return ml, int(valid.sum())
    # the true correspondences (result.landmark_measurements "known"), from the run's own valid arrays
    z, lm = run.landmark_z[k][valid], world.landmarks[valid]
    lik = LandmarkLikelihood.trusted(z, lm, sensor, cfg.dtype)

    def known(P: Array, out: Array) -> None:
        lik(P, out)

    return known, z.shape[0]


def _predict_and_weigh(
    P: Array, model: tuple[BlockModel, int] | None, run: SimulatedRun, k: int, cfg: ParticleFilterConfig,
    gens: Sequence[np.random.Generator], draws: Sequence[Array] | None = None,
) -> tuple[Array, Array | None, Array | None]:  # fmt: skip
    """Move the particles by step ``k−1 → k`` and evaluate step ``k``'s likelihood, block by block.

    Block ``c`` of :func:`~pose_uncertainty.localization.sensors.chunks` draws its motion from its
    own generator ``gens[c]`` (spawned once per run from the filter's), so the result does not
    depend on ``cfg.workers``, the threads the blocks run on; ``draws``: the wheel model's draws of
    each block for this step, drawn ahead (:func:`_draw_ahead`).

    Returns
    -------
    particles (n, 3); log-likelihood (n,) or None; wrong associations per particle (n,) or None
    """
    n = P.shape[0]
    blocks = chunks(n)
    out = np.empty_like(P) if k > 0 else P
    ll = np.empty(n) if model is not None else None
    wrong = np.zeros(n) if model is not None and cfg.association == "ml" else None
    compiled = n * run.n_steps >= mc_kernel.MIN_PARTICLE_STEPS  # the whole filter's particle-steps

    def block(c: int) -> None:
        a, b = blocks[c]
        if k > 0:
            sample_motion(P[a:b], cfg.motion, run, k - 1, gens[c], cfg.dtype, out=out[a:b],
                          draws=None if draws is None else draws[c], compiled=compiled)  # fmt: skip
        if model is not None and ll is not None:
            wr = model[0](out[a:b], ll[a:b])
            if wr is not None and wrong is not None:
                wrong[a:b] = wr

    if k > 0 or model is not None:
        run_blocks(block, len(blocks), cfg.workers)
    return out, ll, wrong


def _filtered_beams(P: Array, w: Array, z: Array, world: World, sensor: BeamSensor,
                    threshold: float) -> tuple[Array, int]:  # fmt: skip
    """The beam model's log-likelihood of the beams the distance filter keeps under ``(P, w)``, and their number."""
    assert world.grid is not None
    zs = expected_ranges(world.grid, P, sensor)
    keep = distance_filter(z, zs, w, sensor, threshold)
    with np.errstate(divide="ignore"):
        ll = np.log(beam_probability(z[keep], zs[:, keep], sensor)).sum(axis=-1)
    return np.asarray(ll, dtype=np.float64), int(keep.sum())


def _thread_plan(cfg: ParticleFilterConfig, sensor: RangeBearingSensor | BeamSensor) -> tuple[bool, bool]:
    """How a run uses ``cfg.workers`` > 1 threads: (draw the wheel normals ahead, split the blocks).

    The results are the same either way. Blocks whose numpy calls are long (float64 trigonometry,
    beams, maximum-likelihood association) run on the threads together, and the next step's wheel
    draws are made during the serial correction. The float32 landmark likelihood is many short
    calls, which two threads spend handing the GIL to each other (measured: slower than one
    thread), so its blocks stay on the calling thread and the other draws the next step's normals
    meanwhile (~20 % of a step).
    """
    if cfg.workers == 1:
        return False, False
    ahead = cfg.motion.model == "wheels"
    short_calls = cfg.dtype == "float32" and isinstance(sensor, RangeBearingSensor) and cfg.association == "known"
    return ahead, not (ahead and short_calls)


def _draw_ahead(gens: Sequence[np.random.Generator], n: int, workers: int) -> Callable[[], list[Array]]:
    """Start drawing the wheel model's normals of every block for the next step on a pool thread.

    Returns ``finish()`` (:func:`~pose_uncertainty.localization.sensors.run_ahead`), which gives the
    draws. Each block's generator serves its motion only and gives the same numbers in the same
    order whichever thread draws them, so the run does not depend on it; the draws (~20 % of a
    step on one thread) then overlap the correction and the resampling of the current step.
    """
    blocks = chunks(n)
    return run_ahead(lambda: [wheel_draws(g, b - a) for g, (a, b) in zip(gens, blocks, strict=True)], workers)


def _particle_region_flags(particles: Array, w: Array, world: World, truth: Array, h: float) -> NDArray[np.bool_]:
    """Truth in the highest-density regions of the particles' weighted (x, y) histogram (cells of ``h``).

    Only cells with mass can be in a region (and the truth's cell is outside without mass): the
    flags of the occupied cells alone are those of the whole grid. They are counted on the box of
    cells the particles span, numbered row by row as the grid is (so the occupied cells come in
    the grid's order, each summed over its particles in their order: the same numbers).
    """
    x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
    nx, ny = max(1, math.ceil((x1 - x0) / h)), max(1, math.ceil((y1 - y0) / h))
    ti, tj = math.floor((truth[0] - x0) / h), math.floor((truth[1] - y0) / h)
    if not (0 <= ti < nx and 0 <= tj < ny):
        return np.zeros(3, dtype=bool)
    i = np.floor((particles[:, 0] - x0) / h)  # cell of each particle, as floats
    j = np.floor((particles[:, 1] - y0) / h)
    box = i.min(), i.max(), j.min(), j.max()
    if not (box[0] >= 0 and box[1] < nx and box[2] >= 0 and box[3] < ny):  # some off the grid (or NaN)
        on_grid = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        if not on_grid.any():
            return np.zeros(3, dtype=bool)
        i, j, w = i[on_grid], j[on_grid], w[on_grid]
        box = i.min(), i.max(), j.min(), j.max()
    i0, j0 = int(box[0]), int(box[2])
    span = int(box[3]) - j0 + 1
    hist = np.asarray(np.bincount(((i - i0) * span + (j - j0)).astype(np.intp), w), dtype=np.float64)
    key = (ti - i0) * span + (tj - j0)
    inside = 0 <= tj - j0 < span and 0 <= key < hist.size
    return region_flags_of_mass(float(hist[key]) if inside else 0.0, hist[hist > 0])


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
    distance_threshold: float | None = None,
) -> FilterResult:
    """Monte Carlo localization along a simulated run, with the landmark sensor or the beam model.

    ``distance_threshold``: with the beam model, the distance filter of Skalka 2011 §5.1
    (:func:`~pose_uncertainty.localization.dynamic.distance_filter`) — each scan's beams whose probability of
    being a short reading under the predicted particles reaches the threshold are left out of the correction
    (None: every beam is used). Diagnostics per step: ``ess`` (after the correction), ``resampled`` (0/1),
    ``injected``, ``log_evidence``, ``n_measurements`` (the beams kept), ``wrong_associations``.
    Snapshots / ``on_step`` state: ``particles`` (n, 3) and ``weights`` (n,).
    """
    cfg = config or ParticleFilterConfig()
    st = start or Start(pose=tuple(run.true_poses[0]))  # type: ignore[arg-type]
    rec = StepRecorder("particle", run, check_keep(keep, run.n_steps), on_step)
    n = cfg.n_particles
    P = initial_particles(st, world, n, rng)
    w = np.full(n, 1.0 / n)
    uniform = -math.log(n)
    lw = np.full(n, uniform)  # log w, kept beside w: a correction adds, no logarithm per step
    slow_fast = [-math.inf, -math.inf]
    gens = rng.spawn(len(chunks(n)))  # the motion's generator of each block of particles
    ahead, split = _thread_plan(cfg, sensor)
    kcfg = cfg if split else replace(cfg, workers=1)  # the blocks' and the resampling's threads
    draws = None  # this step's wheel draws when drawn ahead
    for k in range(run.n_steps + 1):
        rec.tic()
        finish = None
        if ahead and not split and k < run.n_steps:  # the next step's draws during all of this one
            finish = _draw_ahead(gens, n, cfg.workers)
        model = _measurement_model(run, world, sensor, k, cfg)
        ll: Array | None
        if distance_threshold is not None and model is not None and isinstance(sensor, BeamSensor):
            P, _, _ = _predict_and_weigh(P, None, run, k, kcfg, gens, draws)  # the filter needs the prediction
            ll, kept = _filtered_beams(P, w, run.beam_z[k], world, sensor, distance_threshold)  # type: ignore[index]
            wrong_each, model = None, ((model[0], kept) if kept else None)
        else:
            P, ll, wrong_each = _predict_and_weigh(P, model, run, k, kcfg, gens, draws)
        if ahead and split and k < run.n_steps:  # during the correction and the resampling
            finish = _draw_ahead(gens, n, cfg.workers)
        ess, res, inj, logev, m, wrong = _ess(w), False, 0, 0.0, 0, 0.0
        if model is not None and ll is not None:
            m = model[1]
            wrong = float(w @ wrong_each) if wrong_each is not None else 0.0
            lw += ll
            w, logev = normalize_log_weights(lw)  # w ∝ w_prev·p(z|x); logev = log Σ w_prev·p(z|x)
            lw -= logev
            ess = _ess(w)
            inj = _n_inject(cfg, logev / max(m, 1), slow_fast, rng)
            P, w, res = pf_resample(P, w, rng, cfg.resampling, cfg.ess_threshold, inj, world, kcfg.workers)
            if res:
                lw.fill(uniform)
        if finish is not None:
            draws = finish()  # within the step's clock
        rec.toc(k)
        mean, cov = weighted_mean_cov(P, w)
        flags = _particle_region_flags(P, w, world, run.true_poses[k], cfg.hdr_resolution)
        P[:, 2] = wrap_angle(P[:, 2])
        rec.record(k, mean, cov, flags, {"particles": P, "weights": w}, ess=ess, resampled=float(res),
                   injected=inj, log_evidence=logev, n_measurements=m, wrong_associations=wrong)  # fmt: skip
    return rec.result()
