"""How wrong each method is: coverage, density distances and likelihood against Monte Carlo.

Every measure compares a method's predicted distribution of the end pose with a
Monte Carlo cloud of end poses (the ground truth of the wheel-noise model):

coverage
    the fraction of particles inside the method's Pr-region, for
    ``Pr ∈ {0.5, 0.9, 0.9889}`` (:data:`PRS`), nominal against actual. The
    planar region (``coverage_xy``) of a density ``p(x, y)`` is its highest-density
    region ``{p ≥ c}`` holding probability Pr — for a Cartesian Gaussian that
    is the Pr-ellipse (Method A's about the nominal pose, Method C's — the
    unscented transform — about its own mean), for the exponential-coordinates Gaussian a banana, for a
    gridded map a union of cells. The pose region (``coverage_pose``, Gaussian
    methods) is the 3-D ellipsoid ``εᵀΣ⁻¹ε ≤ χ²₃(Pr)`` in each method's own
    coordinates. The binomial standard error of an actual coverage is
    ``√(Pr(1−Pr)/n)``.
density distances
    Hellinger distance ``H = √(1 − Σ √(p_i q_i))`` and ``KL(MC ‖ model) = Σ p_i
    log(p_i/q_i)`` between the histogram of the particles' ``(x, y)`` (cell
    probabilities ``p_i``) and the model's cell probabilities ``q_i`` on one
    grid (:class:`Grid`, described in every result). Model cell probabilities
    are the density at ``s × s`` points per cell times the cell area
    (midpoint rule, ``s = supersample``); ``q_i`` is floored at
    :data:`KL_FLOOR` for the KL. A finite cloud is never at distance 0 from
    its own law; ``*_floor`` gives the distance of the Cartesian Gaussian to a
    histogram of as many draws from itself, the level below which a distance
    means nothing.
likelihood
    the mean log-likelihood of the particles under the method (the measure of
    Long et al., RSS 2012): ``loglik_pose`` w.r.t. ``dx dy dθ`` (Gaussian
    methods), ``loglik_xy`` w.r.t. ``dx dy`` (every method); higher is better.
NEES
    mean normalised estimation error squared ``(p − μ)ᵀΣ⁻¹(p − μ)`` of the
    Gaussian methods; a consistent 3-D Gaussian gives 3 (``nees_pose``), its
    planar block 2 (``nees_xy``).

All functions are plain functions returning dicts of floats. A gridded density
is a :class:`pose_uncertainty.methods.maps.ProbabilityMap` (mass per cell; a
planar density on cell centres becomes one with
:meth:`~pose_uncertainty.methods.maps.ProbabilityMap.from_density_xy`).
The distances use the package's one Hellinger convention
(:func:`pose_uncertainty.core.stats.hellinger`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.grids import Grid
from ..core.stats import PR_3SIGMA, chi2_ppf, hellinger, mahalanobis_sq, pr_to_k
from ..core.trajectories import Trajectory
from ..core.validation import (
    check_finite,
    check_last_axis,
    check_positive_int,
)
from ..methods import covariance as cv
from ..methods import expcoords as ec
from ..methods import unscented as ut
from ..methods.maps import ProbabilityMap
from ..methods.sampling import sample_end_poses

__all__ = [
    "KL_FLOOR",
    "PRS",
    "accuracy_vs_distance",
    "cell_probabilities",
    "compare_methods",
    "coverage_ellipse",
    "coverage_ellipsoid",
    "coverage_gridded",
    "density_at",
    "evaluate_cartesian",
    "evaluate_expcoords",
    "evaluate_gridded",
    "flatten",
    "kl_divergence",
    "pr_label",
]

#: The probabilities of the credible regions compared: 50 %, 90 % and the thesis's 98.89 % (r = 3).
PRS: tuple[float, ...] = (0.5, 0.9, PR_3SIGMA)

#: Floor of a model cell probability in the KL divergence (a zero would make it infinite).
KL_FLOOR: float = 1e-12


def pr_label(pr: float) -> str:
    """Short key for a probability: 0.5 → "50", 0.9 → "90", 0.98889 → "98.89"."""
    return f"{100.0 * pr:.4g}"


# --- grids and histograms -------------------------------------------------------------------


def cell_probabilities(pdf: Any, grid: Grid, supersample: int = 4) -> NDArray[np.float64]:
    """Model probability of each cell by the midpoint rule on ``s × s`` points per cell.

    Parameters
    ----------
    pdf : callable, (m, 2) points [m] → (m,) density [1/m²]
    grid : Grid; supersample : int ≥ 1

    Returns
    -------
    ndarray, shape (nx, ny)
    """
    s = check_positive_int("supersample", supersample)
    off = (np.arange(s) + 0.5) / s
    xs = (grid.x_edges[:-1, None] + off[None, :] * grid.dx).ravel()
    ys = (grid.y_edges[:-1, None] + off[None, :] * grid.dy).ravel()
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    d = np.asarray(pdf(np.stack([X.ravel(), Y.ravel()], axis=-1))).reshape(X.shape)
    nx, ny = grid.nx, grid.ny
    return d.reshape(nx, s, ny, s).mean(axis=(1, 3)) * grid.cell_area


def kl_divergence(p: ArrayLike, q: ArrayLike, floor: float = KL_FLOOR) -> float:
    """``KL(p ‖ q) = Σ_{p_i>0} p_i log(p_i / max(q_i, floor))`` [nats] of cell probabilities."""
    pp = check_finite("p", p)
    qq = check_finite("q", q)
    m = pp > 0
    return float(np.sum(pp[m] * np.log(pp[m] / np.maximum(qq[m], floor))))


# --- coverage ---------------------------------------------------------------------------------


def _fraction_inside(
    points: ArrayLike, center: ArrayLike, cov: ArrayLike, prs: Sequence[float], radius_sq: Callable[[float], Any]
) -> dict[str, float]:
    """``{pr_label(pr): fraction of points with dᵀΣ⁻¹d ≤ radius_sq(pr)}``."""
    d2 = mahalanobis_sq(points, center, cov)
    return {pr_label(pr): float(np.mean(d2 <= radius_sq(pr))) for pr in prs}


def coverage_ellipse(
    xy: ArrayLike, center: ArrayLike, cov_xy: ArrayLike, prs: Sequence[float] = PRS
) -> dict[str, float]:
    """Fraction of planar points inside the Pr-ellipses ``dᵀΣ⁻¹d ≤ −2 ln(1−Pr)``.

    Returns ``{pr_label(pr): fraction}``.
    """
    return _fraction_inside(xy, center, cov_xy, prs, pr_to_k)


def coverage_ellipsoid(
    points: ArrayLike, center: ArrayLike, cov: ArrayLike, prs: Sequence[float] = PRS
) -> dict[str, float]:
    """Fraction of d-dimensional points inside ``dᵀΣ⁻¹d ≤ χ²_d(Pr)``; ``{pr_label: fraction}``."""
    C = check_finite("cov", cov)
    dim = C.shape[-1]
    return _fraction_inside(points, center, C, prs, lambda pr: chi2_ppf(pr, dim))


# --- gridded densities ------------------------------------------------------------------------


def _planar(density: ProbabilityMap) -> tuple[Grid, NDArray]:
    """The map's planar grid (from its cell centres) and its θ-marginal mass per cell."""
    x = check_finite("density.x", density.x)
    y = check_finite("density.y", density.y)
    if x.size < 2 or y.size < 2:
        raise ValueError(f"density grid must have at least 2 cells per axis, got ({x.size}, {y.size})")
    grid = Grid(float(x[0]), float(y[0]), x.size, y.size, float(x[1] - x[0]), float(y[1] - y[0]))
    return grid, density.marginal_xy()


def density_at(density: ProbabilityMap, xy: ArrayLike) -> NDArray[np.float64]:
    """Planar density of a map at points: the mass of the cell holding each point over its area.

    Parameters
    ----------
    density : ProbabilityMap
    xy : array_like, shape (n, 2) [m]

    Returns
    -------
    ndarray, shape (n,) [1/m²] — 0 off the grid
    """
    grid, mass = _planar(density)
    p = check_last_axis("xy", xy, 2).reshape(-1, 2)
    i, j, inside = grid.index_xy(p)
    return np.where(inside, mass[i, j] / grid.cell_area, 0.0)


def coverage_gridded(
    density: ProbabilityMap, xy: ArrayLike, prs: Sequence[float] = PRS
) -> dict[str, float]:
    """Fraction of points inside a map's planar Pr highest-density regions.

    A point is inside when the cell holding it belongs to the region
    (:meth:`ProbabilityMap.region_xy`: Pr of the whole distribution, lost mass
    included; ``nan`` when the grid holds less than Pr).
    """
    grid, mass = _planar(density)
    i, j, inside = grid.index_xy(check_last_axis("xy", xy, 2).reshape(-1, 2))
    at = np.where(inside, mass[i, j], 0.0)
    out = {}
    for pr in prs:
        level, _ = density.region_xy(pr)
        out[pr_label(pr)] = float(np.mean(at >= level)) if math.isfinite(level) else float("nan")
    return out


# --- per-method evaluation --------------------------------------------------------------------


def _safe_mean_log(x: NDArray) -> float:
    with np.errstate(divide="ignore"):
        return float(np.mean(np.log(x)))


def _shape_distances(p: NDArray, q: NDArray) -> tuple[float, float]:
    """(Hellinger, KL) of ``p`` against ``q`` on the compared cells; both NaN when either puts no
    mass on them (a cloud and a model with no cell in common: their shapes on the cells are
    undefined, and the model's mass on the grid, logged beside, says so)."""
    if not (float(np.sum(p)) > 0.0 and float(np.sum(q)) > 0.0):
        return math.nan, math.nan
    return hellinger(p, q), kl_divergence(p, q)


def _distances(p: NDArray, q: NDArray) -> dict[str, float]:
    h, kl = _shape_distances(p, q)
    return {"hellinger": h, "kl": kl, "model_mass_on_grid": float(q.sum())}


def _gauss2_pdf(mean: NDArray, cov: NDArray) -> Any:
    P = np.linalg.inv(cov)
    norm = 1.0 / (2.0 * np.pi * math.sqrt(np.linalg.det(cov)))

    def pdf(pts: NDArray) -> NDArray:
        d = pts - mean
        m2 = P[0, 0] * d[:, 0] ** 2 + 2.0 * P[0, 1] * d[:, 0] * d[:, 1] + P[1, 1] * d[:, 1] ** 2
        return norm * np.exp(-0.5 * m2)

    return pdf


def _check_samples(samples: ArrayLike) -> NDArray:
    s = check_last_axis("samples", samples, 3)
    if s.ndim != 2 or s.shape[0] < 2:
        raise ValueError(f"samples must have shape (n, 3) with n >= 2, got shape {s.shape}")
    return s


def evaluate_cartesian(
    samples: ArrayLike,
    pose: ArrayLike,
    cov: ArrayLike,
    grid: Grid | None = None,
    prs: Sequence[float] = PRS,
    supersample: int = 4,
    distances: bool = True,
) -> dict[str, float]:
    """All accuracy measures of the Cartesian Gaussian ``N(pose, cov)`` (Method A) against a cloud.

    Parameters
    ----------
    samples : array_like, shape (n, 3) — Monte Carlo poses, unwrapped headings
    pose : array_like, shape (3,) — the method's mean pose
    cov : array_like, shape (3, 3) — its covariance, positive definite
    grid : Grid, optional — default :meth:`Grid.covering` of the samples
    prs : probabilities of the credible regions; supersample : see :func:`cell_probabilities`
    distances : bool — False: leave out the density distances on the grid (``hellinger``,
        ``kl``, ``model_mass_on_grid``, the costly part); the other measures are unchanged

    Returns
    -------
    dict: ``coverage_xy_<pr>``, ``coverage_pose_<pr>``, ``hellinger``, ``kl``,
    ``model_mass_on_grid``, ``loglik_pose``, ``loglik_xy``, ``nees_pose``, ``nees_xy``.
    """
    s = _check_samples(samples)
    mu = check_last_axis("pose", pose, 3)
    C = check_finite("cov", cov)
    g = Grid.covering(s[:, :2]) if grid is None else grid
    out: dict[str, float] = {}
    for key, val in coverage_ellipse(s[:, :2], mu[:2], C[:2, :2], prs).items():
        out[f"coverage_xy_{key}"] = val
    for key, val in coverage_ellipsoid(s, mu, C, prs).items():
        out[f"coverage_pose_{key}"] = val
    if distances:
        q = cell_probabilities(_gauss2_pdf(mu[:2], C[:2, :2]), g, supersample)
        out.update(_distances(g.histogram_xy(s[:, :2]), q))
    d3 = mahalanobis_sq(s, mu, C)
    d2 = mahalanobis_sq(s[:, :2], mu[:2], C[:2, :2])
    _, logdet3 = np.linalg.slogdet(C)
    _, logdet2 = np.linalg.slogdet(C[:2, :2])
    out["loglik_pose"] = float(np.mean(-0.5 * d3) - 0.5 * logdet3 - 1.5 * math.log(2 * math.pi))
    out["loglik_xy"] = float(np.mean(-0.5 * d2) - 0.5 * logdet2 - math.log(2 * math.pi))
    out["nees_pose"] = float(np.mean(d3))
    out["nees_xy"] = float(np.mean(d2))
    return out


def evaluate_expcoords(
    samples: ArrayLike,
    pose: ArrayLike,
    cov: ArrayLike,
    rng: np.random.Generator,
    grid: Grid | None = None,
    prs: Sequence[float] = PRS,
    supersample: int = 4,
    n_threshold: int = 200_000,
    distances: bool = True,
    levels: bool = False,
    coverage_only: bool = False,
) -> dict[str, float]:
    """All accuracy measures of the exponential-coordinates Gaussian ``μ exp(N(0, cov))``.

    The planar Pr-region is the banana ``{p(x, y) ≥ c}`` with ``c`` from
    :func:`pose_uncertainty.methods.expcoords.hdr_threshold` (``n_threshold`` draws
    from ``rng``); the pose region and NEES use the exponential coordinates
    ``ε = log(μ⁻¹ g)``.

    Parameters and returned keys as :func:`evaluate_cartesian` (``cov`` is Σ of ε); with
    ``levels`` also ``level_xy_<pr>`` [1/m²]: the density level ``c`` of each planar region
    (what its boundary is drawn at). With ``coverage_only`` only ``coverage_xy_<pr>`` (and the
    levels): the same numbers, each point's density computed only where its brackets do not
    decide it (:func:`pose_uncertainty.methods.expcoords.at_least`).
    """
    s = _check_samples(samples)
    mu = check_last_axis("pose", pose, 3)
    C = check_finite("cov", cov)
    out: dict[str, float] = {}
    if coverage_only:
        return _expcoords_coverage(s, mu, C, rng, prs, n_threshold, levels)
    g = Grid.covering(s[:, :2]) if grid is None else grid
    try:
        dens: NDArray | None = ec.pdf_xy(s[:, :2], mu, C)
    except ec.SingularConditionalError:
        # Σ singular given θ (one step of a two-wheel drive): the planar density, its regions and
        # the distances on the grid are undefined here (NaN); the pose-space measures are not
        dens = None
    thresholds = ec.hdr_threshold(mu, C, np.asarray(prs), rng, n=n_threshold) if dens is not None else None
    for i, pr in enumerate(prs):
        out[f"coverage_xy_{pr_label(pr)}"] = (float(np.mean(dens >= thresholds[i])) if dens is not None
                                              and thresholds is not None else math.nan)  # fmt: skip
        if levels:
            out[f"level_xy_{pr_label(pr)}"] = float(thresholds[i]) if thresholds is not None else math.nan
    eps = ec.coordinates(s, mu)
    for key, val in coverage_ellipsoid(eps, np.zeros(3), C, prs).items():
        out[f"coverage_pose_{key}"] = val
    if dens is not None and distances:
        q = cell_probabilities(lambda pts: ec.pdf_xy(pts, mu, C), g, supersample)
        out.update(_distances(g.histogram_xy(s[:, :2]), q))
    elif distances:
        out.update(hellinger=math.nan, kl=math.nan, model_mass_on_grid=math.nan)
    out["loglik_pose"] = float(np.mean(ec.logpdf_pose(s, mu, C)))
    out["loglik_xy"] = _safe_mean_log(dens) if dens is not None else math.nan
    # NEES in the method's own coordinates: εᵀΣ⁻¹ε (3 if consistent), planar block of ε (2)
    out["nees_pose"] = float(np.mean(mahalanobis_sq(eps, np.zeros(3), C)))
    out["nees_xy"] = float(np.mean(mahalanobis_sq(eps[:, :2], np.zeros(2), C[:2, :2])))
    return out


def _expcoords_coverage(
    s: NDArray, mu: NDArray, C: NDArray, rng: np.random.Generator, prs: Sequence[float], n_threshold: int,
    levels: bool,
) -> dict[str, float]:
    """The planar coverages (and levels) of :func:`evaluate_expcoords`, from the same draws."""
    try:
        ec.pdf_xy(mu[None, :2], mu, C)  # a singular Σ given θ raises here, as the full route does
    except ec.SingularConditionalError:
        thresholds = None
    else:
        thresholds = ec.hdr_threshold(mu, C, np.asarray(prs), rng, n=n_threshold)
    inside = ec.at_least(s[:, :2], mu, C, thresholds) if thresholds is not None else None
    out: dict[str, float] = {}
    for i, pr in enumerate(prs):
        out[f"coverage_xy_{pr_label(pr)}"] = float(np.mean(inside[i])) if inside is not None else math.nan
        if levels:
            out[f"level_xy_{pr_label(pr)}"] = float(thresholds[i]) if thresholds is not None else math.nan
    return out


def evaluate_gridded(
    density: ProbabilityMap,
    samples: ArrayLike,
    grid: Grid | None = None,
    prs: Sequence[float] = PRS,
) -> dict[str, float]:
    """Accuracy measures of a gridded planar density (e.g. a probability map).

    Coverage of its highest-density regions, Hellinger and KL on ``grid`` (the
    map's density looked up at the ``grid``'s cell centres, supersampled
    4 × 4), and ``loglik_xy`` (cell lookup; ``-inf`` if a particle falls
    where the map is 0). No pose-space measures: a map's θ axis is not compared.

    Returns
    -------
    dict: ``coverage_xy_<pr>``, ``hellinger``, ``kl``, ``model_mass_on_grid``,
    ``loglik_xy``, ``fraction_off_map``.
    """
    s = _check_samples(samples)
    map_grid, _ = _planar(density)
    g = Grid.covering(s[:, :2]) if grid is None else grid
    out: dict[str, float] = {}
    for key, val in coverage_gridded(density, s[:, :2], prs).items():
        out[f"coverage_xy_{key}"] = val
    q = cell_probabilities(lambda pts: density_at(density, pts), g, 4)
    out.update(_distances(g.histogram_xy(s[:, :2]), q))
    out["loglik_xy"] = _safe_mean_log(density_at(density, s[:, :2]))
    _, _, inside = map_grid.index_xy(s[:, :2])
    out["fraction_off_map"] = float(1.0 - inside.mean())
    return out


def _floor(
    pose: NDArray, cov_xy: NDArray, n: int, grid: Grid, rng: np.random.Generator, distances: bool = True
) -> dict:
    """Distances of the Cartesian Gaussian to a histogram of ``n`` of its own draws.

    The draws are taken from ``rng`` even without ``distances`` (then nothing is returned):
    what the generator gives next (the banana's thresholds) is the same either way.
    """
    draws = rng.multivariate_normal(pose[:2], cov_xy, size=n, method="eigh")
    if not distances:
        return {}
    q = cell_probabilities(_gauss2_pdf(pose[:2], cov_xy), grid, 4)
    p = grid.histogram_xy(draws)
    h, kl = _shape_distances(p, q)
    return {"hellinger_floor": h, "kl_floor": kl}


def compare_methods(
    samples: ArrayLike,
    cartesian: tuple[ArrayLike, ArrayLike],
    expcoords: tuple[ArrayLike, ArrayLike] | None,
    rng: np.random.Generator,
    densities: Mapping[str, ProbabilityMap] | None = None,
    prs: Sequence[float] = PRS,
    n_bins: int = 60,
    n_threshold: int = 200_000,
    unscented: tuple[ArrayLike, ArrayLike] | None = None,
    distances: bool = True,
    levels: bool = False,
    coverage_only: bool = False,
) -> dict[str, dict[str, float]]:
    """Every method against one Monte Carlo cloud, on one grid.

    Parameters
    ----------
    samples : array_like, shape (n, 3) — Monte Carlo poses
    cartesian : (pose (3,), cov (3, 3)) — Method A
    expcoords : (pose (3,), cov (3, 3)) or None — exponential-coordinates Gaussian
    rng : numpy.random.Generator — for the banana thresholds and the floors
    densities : mapping name → ProbabilityMap, optional
    prs : probabilities; n_bins : bins per axis of the stated grid
    n_threshold : draws for the banana's density thresholds (:func:`evaluate_expcoords`)
    unscented : (pose (3,), cov (3, 3)) or None — Method C (the unscented transform): a
        Cartesian Gaussian about its own mean, measured as :func:`evaluate_cartesian`
        (uses no randomness: the other entries are the same with or without it)
    distances : bool — False: no density distances on the grid (the floors, ``hellinger``,
        ``kl``, ``model_mass_on_grid``), the costly part; every other entry is the same number
        as with True (the generator is drawn from alike)
    levels : bool — True: the banana's entry also holds its regions' density levels
        ``level_xy_<pr>`` (:func:`evaluate_expcoords`)
    coverage_only : bool — True (with ``distances=False``): each method's entry holds its planar
        coverages ``coverage_xy_<pr>`` only (and the banana's levels), the same numbers as
        with False (what the explorer shows on each move)

    Returns
    -------
    dict: ``"grid"`` (the binning, with ``n_samples``), ``"monte_carlo"`` (the
    floors and the binomial standard errors ``coverage_se_<pr>``),
    ``"cartesian"``, ``"expcoords"``, ``"unscented"`` (when given), and one entry per
    gridded density.
    """
    s = _check_samples(samples)
    grid = Grid.covering(s[:, :2], n_bins=n_bins)
    pose_a, cov_a = (np.asarray(v, dtype=float) for v in cartesian)
    res: dict[str, dict[str, float]] = {"grid": {**grid.describe(), "n_samples": float(len(s))}}
    mc = _floor(pose_a, cov_a[:2, :2], len(s), grid, rng, distances)
    for pr in prs:
        mc[f"coverage_se_{pr_label(pr)}"] = math.sqrt(pr * (1 - pr) / len(s))
    res["monte_carlo"] = mc
    if coverage_only and distances:
        raise ValueError("coverage_only needs distances=False (allowed: coverage_only with distances=False)")

    def cartesian_entry(pose: NDArray, cov: NDArray) -> dict[str, float]:
        if coverage_only:
            return {f"coverage_xy_{k}": v for k, v in coverage_ellipse(s[:, :2], pose[:2], cov[:2, :2], prs).items()}
        return evaluate_cartesian(s, pose, cov, grid, prs, distances=distances)

    res["cartesian"] = cartesian_entry(pose_a, cov_a)
    if expcoords is not None:
        pose_e, cov_e = (np.asarray(v, dtype=float) for v in expcoords)
        res["expcoords"] = evaluate_expcoords(s, pose_e, cov_e, rng, grid, prs, n_threshold=n_threshold,
                                              distances=distances, levels=levels, coverage_only=coverage_only)
    if unscented is not None:  # Method C
        res["unscented"] = cartesian_entry(*(np.asarray(v, dtype=float) for v in unscented))
    for name, dens in (densities or {}).items():
        res[name] = evaluate_gridded(dens, s, grid, prs)
    return res


def flatten(result: Mapping[str, Mapping[str, float]], prefix: str = "accuracy") -> dict[str, float]:
    """``{"cartesian": {"kl": 0.1}}`` → ``{"accuracy_cartesian_kl": 0.1}`` (for run-log metrics)."""
    return {
        f"{prefix}_{method}_{key}".replace(".", "_"): float(val)
        for method, d in result.items()
        for key, val in d.items()
    }


def accuracy_vs_distance(
    trajectory: Trajectory,
    k_r: float,
    k_l: float,
    n: int,
    rng: np.random.Generator,
    *,
    n_checkpoints: int = 5,
    regime: str = "per_step",
    prs: Sequence[float] = PRS,
    n_bins: int = 60,
    n_threshold: int = 200_000,
) -> list[dict[str, Any]]:
    """Accuracy of the three Gaussian methods (A, banana, C) at evenly spaced points along a trajectory.

    Draws ``n`` Monte Carlo runs (midpoint integration, ``regime``), keeps the
    clouds at ``n_checkpoints`` steps (the last is the end), and runs
    :func:`compare_methods` at each.

    Returns
    -------
    list of dict, one per checkpoint: ``step``, ``distance`` [m] (path length
    so far) and the entries of :func:`compare_methods`.
    """
    n = check_positive_int("n", n)
    m = check_positive_int("n_checkpoints", n_checkpoints)
    N = trajectory.n_steps
    steps = sorted({max(1, round(N * (i + 1) / m)) for i in range(m)})
    clouds = sample_end_poses(trajectory, k_r, k_l, n, rng, regime=regime, checkpoints=steps)
    A = cv.propagate(trajectory, k_r, k_l)
    E = ec.propagate(trajectory, k_r, k_l)
    C = ut.propagate(trajectory, k_r, k_l)
    dist = np.concatenate([[0.0], np.cumsum(np.abs(trajectory.ds))])
    rows = []
    for c, st in enumerate(steps):
        res = compare_methods(
            clouds[:, c, :],
            (A.poses[st], A.covs[st]),
            (E.poses[st], E.covs[st]),
            rng,
            prs=prs,
            n_bins=n_bins,
            n_threshold=n_threshold,
            unscented=(C.poses[st], C.covs[st]),
        )
        rows.append({"step": st, "distance": float(dist[st]), **res})
    return rows
