"""Histogram (grid) filter on a fixed ``(x, y, θ)`` grid (Thrun §4.1, §8.2; Kulich 2014).

Prediction: the multi-step map's step (:func:`pose_uncertainty.methods.maps.predict_on_grid`
with the velocity or the odometry model), on a fixed grid: mass that leaves the
grid is counted (``lost_mass``) and not put back. Transition kernels are cached per
distinct control.

Correction: ``Bel(x) ← η p(z | x) Bel(x)`` with the likelihood evaluated at every cell
centre (:func:`landmark_log_likelihood_grid`: the range term depends on ``(x, y)``
only, the bearing term on ``θ`` through ``wrap(φ − atan2(…) + θ)``; or the beam model
through a table of expected ranges, :func:`beam_range_table`), in logarithms and
rescaled by its maximum before the product, then normalised. With
``mask_occupied`` the belief is also multiplied by the map prior
``p(x | m) ∝ [cell not occupied]`` after every prediction (mass inside walls is
removed and the belief renormalised; reported as ``masked_mass``).

The estimate is the grid mean (θ circular) and the grid covariance (θ deviations
wrapped), from cell centres (:class:`pose_uncertainty.methods.maps.ProbabilityMap`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..core.grids import Grid
from ..core.kinematics import wrap_angle
from ..core.validation import check_choice, check_positive, check_positive_int
from ..methods.maps import GridTransition, ProbabilityMap, grid_transition, predict_on_grid
from .dynamic import distance_filter
from .evaluation import region_flags_of_mass
from .motion import Motion
from .result import (
    ASSOCIATIONS,
    FilterResult,
    Start,
    StepCallback,
    StepRecorder,
    check_keep,
    landmark_measurements,
)
from .sensors import BeamSensor, RangeBearingSensor, beam_probability, beam_terms, cast_rays
from .simulate import SimulatedRun
from .world import OccupancyGrid, World

__all__ = [
    "HistogramFilterConfig",
    "beam_range_table",
    "hf_correct",
    "hf_estimate",
    "initial_belief",
    "landmark_log_likelihood_grid",
    "landmark_log_likelihood_grid_ml",
    "pose_grid_for",
    "run_histogram",
]

Array = NDArray[np.float64]
_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class HistogramFilterConfig:
    """Options of the histogram filter.

    Attributes
    ----------
    motion : Motion — ``"velocity"`` or ``"odometry"``
    resolution : float [m], optional — cell side (default: the world grid's, else 0.1)
    ntheta : int — heading cells on the full circle
    mask_occupied : bool — multiply by the free-space prior after every prediction
    association : {"known", "ml"} — true correspondences, or each cell's maximum-likelihood association
    workers : int — FFT threads
    """

    motion: Motion = field(default_factory=lambda: Motion(model="velocity"))
    resolution: float | None = None
    ntheta: int = 72
    mask_occupied: bool = True
    association: str = "known"
    workers: int = -1

    def __post_init__(self) -> None:
        check_choice("histogram.motion.model", self.motion.model, ("velocity", "odometry"))
        if self.resolution is not None:
            check_positive("resolution", self.resolution)
        check_positive_int("ntheta", self.ntheta)
        check_choice("association", self.association, ASSOCIATIONS)


def pose_grid_for(world: World, resolution: float | None, ntheta: int) -> Grid:
    """The filter's grid: the world's occupancy cells, or ``resolution`` cells over ``bounds``."""
    g = world.grid
    if g is not None and (resolution is None or math.isclose(resolution, g.resolution)):
        return g.pose_grid(ntheta)
    h = 0.1 if resolution is None else float(check_positive("resolution", resolution))
    x0, x1, y0, y1 = world.bounds  # type: ignore[misc]
    nx, ny = max(1, math.ceil((x1 - x0) / h)), max(1, math.ceil((y1 - y0) / h))
    return Grid.square(x0 + h / 2, y0 + h / 2, nx, ny, h, check_positive_int("ntheta", ntheta))


def _free_mask(world: World, grid: Grid) -> NDArray[np.bool_]:
    """Cells of ``grid`` whose centre is not in an occupied cell of the world, shape (nx, ny)."""
    if world.grid is None:
        return np.ones((grid.nx, grid.ny), dtype=bool)
    X, Y = np.meshgrid(grid.x, grid.y, indexing="ij")
    return ~world.grid.is_occupied(np.stack([X, Y], axis=-1))


def initial_belief(start: Start, world: World, grid: Grid) -> Array:
    """Initial mass per cell: uniform over free cells × headings, or the start's Gaussian at cell centres.

    A Gaussian narrower than the cells is put on the cell holding its mean.
    """
    if start.is_global:
        b = np.repeat(_free_mask(world, grid).astype(np.float64)[:, :, None], grid.ntheta, axis=2)
        return b / b.sum()
    mu, sd = np.asarray(start.pose), np.maximum(np.asarray(start.std), 1e-12)
    gx = np.exp(-0.5 * ((grid.x - mu[0]) / sd[0]) ** 2)
    gy = np.exp(-0.5 * ((grid.y - mu[1]) / sd[1]) ** 2)
    gt = np.exp(-0.5 * (wrap_angle(grid.theta - mu[2]) / sd[2]) ** 2)
    b = gx[:, None, None] * gy[None, :, None] * gt[None, None, :]
    if not b.sum() > 0 or b.max() < 1e-300:
        b = np.zeros(grid.shape)
        i = int(np.clip(round((mu[0] - grid.x0) / grid.resolution), 0, grid.nx - 1))
        j = int(np.clip(round((mu[1] - grid.y0) / grid.resolution), 0, grid.ny - 1))
        t = round(float(wrap_angle(mu[2] - grid.theta0) % _TWO_PI) / grid.theta_resolution) % grid.ntheta
        b[i, j, t] = 1.0
    return b / b.sum()


def landmark_log_likelihood_grid(grid: Grid, z: Array, landmarks: Array, sensor: RangeBearingSensor) -> Array:
    """``Σ_j log p(z_j | x)`` at every cell centre of ``grid``, shape (nx, ny, nθ).

    Range term on (nx, ny); the bearing error ``wrap(φ_j − atan2(m_y − y, m_x − x) + θ)``
    as ``wrap(a(x, y) + θ)`` with ``a`` computed once per position. The (x, y, θ) arithmetic
    runs on blocks of x rows that stay in cache, in reused buffers.
    """
    range_sq, a = _range_bearing_terms(grid, z, landmarks)
    out = np.empty(grid.shape)
    e, t = np.empty((2, *_block_shape(grid)))
    for b in _row_blocks(grid.nx, grid.ny * grid.ntheta):
        n = b.stop - b.start
        _landmark_sum(a[:, b], range_sq[b], grid.theta, sensor, out[b], e[:n], t[:n])
    out += _log_norm(z.shape[0], sensor)
    return out


#: Elements per block of :func:`landmark_log_likelihood_grid` (≈ 1 MB of float64: cache-resident).
_BLOCK = 1 << 17


def _block_shape(grid: Grid) -> tuple[int, int, int]:
    """Shape of a block of x rows of ``grid`` (:func:`_row_blocks`)."""
    return _rows_per_block(grid.ny * grid.ntheta), grid.ny, grid.ntheta


def _rows_per_block(row_size: int) -> int:
    """Rows of ``row_size`` elements in a block of about :data:`_BLOCK` elements (at least one)."""
    return max(1, _BLOCK // max(1, row_size))


def _row_blocks(n_rows: int, row_size: int) -> list[slice]:
    """The blocks of rows (:func:`_rows_per_block`) of an array of ``n_rows`` rows."""
    rows = _rows_per_block(row_size)
    return [slice(i0, min(n_rows, i0 + rows)) for i0 in range(0, n_rows, rows)]


def _log_norm(n: int, sensor: RangeBearingSensor) -> float:
    """``log`` of the normalising constant of ``n`` range–bearing measurements."""
    return -n * (math.log(_TWO_PI) + math.log(sensor.range_std * sensor.bearing_std))


def _range_bearing_terms(grid: Grid, z: Array, landmarks: Array) -> tuple[Array, Array]:
    """Per position (nx, ny): ``Σ_j (|m_j − x| − r_j)²`` and ``a_j = φ_j − atan2(m_y − y, m_x − x)`` (J, nx, ny)."""
    X, Y = np.meshgrid(grid.x, grid.y, indexing="ij")
    range_sq = np.zeros(X.shape)
    a = np.empty((len(z), *X.shape))
    for j, ((r, phi), (mx, my)) in enumerate(zip(z, landmarks, strict=True)):
        dx, dy = mx - X, my - Y
        er = np.hypot(dx, dy) - r
        range_sq += er * er
        np.subtract(phi, np.arctan2(dy, dx), out=a[j])
    return range_sq, a


def _landmark_sum(a: Array, range_sq: Array, theta: Array, sensor: RangeBearingSensor, acc: Array,
                  eb: Array, tb: Array) -> None:  # fmt: skip
    """``acc ← −½ Σ_j wrap(a_j + θ)²/σ_b² − ½ range_sq/σ_r²`` on a block of rows (in place).

    ``a`` (J, rows, ny), ``range_sq`` (rows, ny), ``theta`` (nθ,); ``acc``, ``eb``, ``tb``
    (rows, ny, nθ), the last two buffers.
    """
    ir, ib = 1.0 / sensor.range_std**2, 1.0 / sensor.bearing_std**2
    acc.fill(0.0)
    for aj in a:
        np.add(aj[:, :, None], theta, out=eb)  # bearing error before wrapping
        np.multiply(eb, 1.0 / _TWO_PI, out=tb)
        np.rint(tb, out=tb)
        tb *= _TWO_PI
        eb -= tb  # wrapped by the nearest multiple of 2π
        eb *= eb
        acc += eb
    acc *= -0.5 * ib
    acc -= (0.5 * ir) * range_sq[:, :, None]


def landmark_log_likelihood_grid_ml(
    grid: Grid, z: Array, landmarks: Array, sensor: RangeBearingSensor
) -> Array:
    """As :func:`landmark_log_likelihood_grid` with unknown correspondences: each cell takes,
    per measurement, the landmark of maximum likelihood (all ``L`` landmarks tried), shape (nx, ny, nθ).

    Per block of rows: for each measurement the maximum over the landmarks of the
    one-measurement log-likelihood (normalising constant included), summed over the measurements.
    """
    terms = [[_range_bearing_terms(grid, zi[None], mj[None]) for mj in landmarks] for zi in z]
    const = _log_norm(1, sensor)
    out = np.zeros(grid.shape)
    ll, best, e, t = np.empty((4, *_block_shape(grid)))
    for b in _row_blocks(grid.nx, grid.ny * grid.ntheta):
        n = b.stop - b.start
        for per_landmark in terms:
            best[:n] = -np.inf
            for range_sq, a in per_landmark:
                _landmark_sum(a[:, b], range_sq[b], grid.theta, sensor, ll[:n], e[:n], t[:n])
                ll[:n] += const
                np.maximum(best[:n], ll[:n], out=best[:n])
            out[b] += best[:n]
    return out


def beam_range_table(occupancy: OccupancyGrid, grid: Grid, sensor: BeamSensor) -> Array:
    """Expected range ``z*`` of every beam from every cell centre and heading, shape (nx, ny, nθ, B).

    Rays are cast once per distinct absolute angle ``θ_k + β_b`` (mod 2π, to 10⁻⁹ rad), so
    beams spaced by whole heading cells cost ``nθ`` casts per cell, not ``nθ·B``. Float32.
    """
    ang = (grid.theta[:, None] + sensor.angles[None, :]) % _TWO_PI  # (nθ, B)
    key = np.round(ang / 1e-9).astype(np.int64)
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    angles = uniq * 1e-9
    X, Y = np.meshgrid(grid.x, grid.y, indexing="ij")
    xy = np.stack([X.ravel(), Y.ravel()], axis=-1)
    table = np.empty((xy.shape[0], angles.size), dtype=np.float32)
    for a_idx, a in enumerate(angles):  # one vectorised cast over all cells per angle
        table[:, a_idx] = cast_rays(occupancy, xy, np.full(xy.shape[0], a), sensor.max_range)
    out = table[:, inv.reshape(ang.shape)].reshape(grid.nx, grid.ny, grid.ntheta, sensor.n_beams)
    return np.asarray(out, dtype=np.float64)


def _beam_log_likelihood_grid(z: Array, table: Array, sensor: BeamSensor, terms: tuple[Array, Array] | None) -> Array:
    """``Σ_b log p(z_b | z*_b(x))`` at every cell of a table of expected ranges (nx, ny, nθ, B).

    On blocks of x rows (cache-sized temporaries); each cell's terms, their sum over the
    beams and the result's memory order are those of the whole table at once.
    """
    mass, eta = beam_terms(table, sensor) if terms is None else terms
    out = np.empty_like(table[..., 0])
    with np.errstate(divide="ignore"):
        for b in _row_blocks(table.shape[0], table[0].size):
            p = beam_probability(z, table[b], sensor, (mass[b], eta[b]))
            out[b] = np.log(p).sum(axis=-1)
    return out


def hf_correct(belief: Array, loglik: Array) -> tuple[Array, float]:
    """``Bel ← η p(z|x) Bel``: the posterior masses and ``log Σ p(z|x) Bel(x)`` (the log evidence).

    On blocks of x rows (cache-sized temporaries); the posterior is laid out in memory as
    the likelihood (its sum runs in that order). Raises ValueError when no cell with mass
    explains the measurement.
    """
    blocks = _row_blocks(belief.shape[0], belief[0].size)
    top = float(np.max([np.max(np.where(belief[b] > 0, loglik[b], -np.inf), initial=-np.inf) for b in blocks]))
    if not math.isfinite(top):
        raise ValueError("measurement has zero likelihood on every cell with mass (allowed: some p(z|x) > 0)")
    post = np.empty_like(loglik, dtype=np.float64)
    for b in blocks:
        # p(z|x) / max p(z|x), the exponential only where it does not underflow to 0 (an
        # underflowing exp takes a slow path, and a sharp likelihood underflows on most cells)
        arg = loglik[b] - top
        ratio = np.zeros_like(arg)
        live = (arg > _EXP_ZERO) & (arg <= 0.0)  # above the top only cells without mass (their product is 0)
        ratio[live] = np.exp(arg[live])
        np.multiply(ratio, belief[b], out=post[b])
    s = float(post.sum())
    post /= s
    return post, top + math.log(s)


#: Below this argument ``exp`` is 0 in double precision (``exp(−745.14)`` is half the smallest subnormal).
_EXP_ZERO = -746.0


def hf_estimate(belief: Array, grid: Grid) -> tuple[Array, Array]:
    """Mean (θ circular) and covariance of the belief's piecewise-uniform density, shapes (3,), (3, 3).

    The histogram filter's density is uniform inside each cell, so its covariance is
    the covariance of the cell centres plus ``diag(h², h², h_θ²)/12`` (Sheppard).
    """
    mean, cov = ProbabilityMap(grid.x, grid.y, grid.theta, belief, 0.0, "histogram", grid).moments()
    h, ht = grid.resolution, grid.theta_resolution
    return mean, cov + np.diag([h * h, h * h, ht * ht]) / 12.0


def _transition(cache: dict[tuple[float, ...], GridTransition], run: SimulatedRun, k: int,
                grid: Grid, m: Motion) -> GridTransition:  # fmt: skip
    """The (cached) grid transition of step ``k → k+1``."""
    if m.model == "velocity":
        u = run.controls[k]
        key = (float(u[0]), float(u[1]), run.dt)
        if key not in cache:
            cache[key] = grid_transition("velocity", grid, u, run.dt, m.alpha_array, noise=m.noise,
                                         scaling=m.scaling)  # fmt: skip
        return cache[key]
    od = run.odometry[k : k + 2]
    rel = od[1] - od[0]
    c, s = math.cos(od[0, 2]), math.sin(od[0, 2])  # the kernel depends on the motion in the odometry frame
    key = (c * rel[0] + s * rel[1], -s * rel[0] + c * rel[1], rel[2])
    if key not in cache:
        cache[key] = grid_transition("odometry", grid, odometry=od, alphas=m.alpha_array, noise=m.noise,
                                     scaling=m.scaling)  # fmt: skip
    return cache[key]


def _loglik_grid(run: SimulatedRun, world: World, sensor: RangeBearingSensor | BeamSensor, k: int,
                 grid: Grid, belief: Array, cfg: HistogramFilterConfig,
                 table: Array | None, terms: tuple[Array, Array] | None = None,
                 distance_threshold: float | None = None) -> tuple[Array | None, int, int]:  # fmt: skip
    """Log-likelihood grid of step ``k``'s measurements (None: no measurement), count, wrong associations."""
    if isinstance(sensor, BeamSensor):
        if not run.beam_valid[k] or run.beam_z is None or table is None:
            return None, 0, 0
        z = run.beam_z[k]
        if distance_threshold is None:
            return _beam_log_likelihood_grid(z, table, sensor, terms), sensor.n_beams, 0
        # the distance filter under the predicted belief: its cells holding more than 10⁻⁹ of the largest mass
        live = belief > 1e-9 * belief.max()
        keep = distance_filter(z, table[live], belief[live] / belief[live].sum(), sensor, distance_threshold)
        if not keep.any():
            return None, 0, 0
        sub = None if terms is None else (terms[0][..., keep], terms[1][..., keep])
        return _beam_log_likelihood_grid(z[keep], table[..., keep], sensor, sub), int(keep.sum()), 0
    if cfg.association == "ml":  # every cell associates for itself
        valid = run.landmark_valid[k]
        if not valid.any():
            return None, 0, 0
        return landmark_log_likelihood_grid_ml(grid, run.landmark_z[k][valid], world.landmarks, sensor), int(valid.sum()), 0
    z, lm, _ = landmark_measurements(run, world, sensor, k, "known", np.zeros(3), np.eye(3))
    if z.shape[0] == 0:
        return None, 0, 0
    return landmark_log_likelihood_grid(grid, z, lm, sensor), z.shape[0], 0


def run_histogram(
    run: SimulatedRun,
    world: World,
    sensor: RangeBearingSensor | BeamSensor,
    config: HistogramFilterConfig | None = None,
    start: Start | None = None,
    *,
    keep: Sequence[int] = (),
    on_step: StepCallback | None = None,
    distance_threshold: float | None = None,
) -> FilterResult:
    """Histogram-filter localization along a simulated run.

    ``distance_threshold``: with the beam model, the distance filter of Skalka 2011 §5.1
    (:func:`~pose_uncertainty.localization.dynamic.distance_filter`) under the predicted belief (None: every
    beam is used). Diagnostics per step: ``lost_mass`` (left the grid in the prediction),
    ``masked_mass`` (fell into occupied cells), ``log_evidence``, ``n_measurements`` (the beams used),
    ``wrong_associations``. Snapshots: ``belief_xy`` (nx, ny); ``on_step`` state:
    ``belief`` (nx, ny, nθ) and ``grid`` (the Grid).
    """
    cfg = config or HistogramFilterConfig()
    st = start or Start(pose=tuple(run.true_poses[0]))  # type: ignore[arg-type]
    rec = StepRecorder("histogram", run, check_keep(keep, run.n_steps), on_step)
    grid = pose_grid_for(world, cfg.resolution, cfg.ntheta)
    free = _free_mask(world, grid)[:, :, None].astype(np.float64) if cfg.mask_occupied else None
    table = beam_range_table(world.grid, grid, sensor) if isinstance(sensor, BeamSensor) and world.grid else None
    terms = beam_terms(table, sensor) if table is not None and isinstance(sensor, BeamSensor) else None
    belief = initial_belief(st, world, grid)
    cache: dict[tuple[float, ...], GridTransition] = {}
    for k in range(run.n_steps + 1):
        rec.tic()
        lost = masked = logev = 0.0
        if k > 0:
            belief, info = predict_on_grid(belief, _transition(cache, run, k - 1, grid, cfg.motion), cfg.workers,
                                           overwrite_belief=True)  # fmt: skip
            lost = info["lost_mass"]
            total = float(belief.sum())
            if free is not None:  # (the prediction is the filter's own array: scaled in place)
                belief *= free
                after = float(belief.sum())
                masked, total = total - after, after
            belief /= total
        ll, m, wrong = _loglik_grid(run, world, sensor, k, grid, belief, cfg, table, terms, distance_threshold)
        if ll is not None:
            belief, logev = hf_correct(belief, ll)
        rec.toc(k)
        mean, cov = hf_estimate(belief, grid)
        xy = belief.sum(axis=2)
        t = run.true_poses[k]
        i, j = round(float(t[0] - grid.x0) / grid.resolution), round(float(t[1] - grid.y0) / grid.resolution)
        flags = region_flags_of_mass(float(xy[i, j]) if 0 <= i < grid.nx and 0 <= j < grid.ny else 0.0, xy)
        rec.record(k, mean, cov, flags, {"belief": belief, "grid": grid, "belief_xy": xy},
                   ("belief_xy",), lost_mass=lost, masked_mass=masked, log_evidence=logev, n_measurements=m,
                   wrong_associations=wrong)  # fmt: skip
    return rec.result()
