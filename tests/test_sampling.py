"""Monte Carlo truth against Method A, the two error regimes, determinism."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from pose_uncertainty.core import stats
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import sampling as sp

N_MC = 200_000


def _cov_tolerance(S, n, z=5.0):
    """z standard errors of each sample-covariance entry for a Gaussian: √((ΣiiΣjj + Σij²)/n)."""
    d = np.diag(S)
    return z * np.sqrt((np.outer(d, d) + S**2) / n)


@pytest.mark.parametrize(
    "traj",
    [
        tr.straight(0.5, dt=0.01),
        tr.arc(radius=0.5, angle=math.pi / 2, dt=0.01),
        tr.rotation(math.pi / 2, dt=0.01),
        tr.s_curve(radius=0.25, dt=0.01),
    ],
    ids=["straight", "arc", "rotation", "s_curve"],
)
@pytest.mark.slow
def test_covariance_matches_monte_carlo_on_short_paths(traj, rng):
    # small k keeps the heading spread ~0.01 rad, so the first-order (linearisation) error is
    # ~σθ² ≈ 1e-4 relative: far below the Monte Carlo standard error at n = 2e5 (~0.3 %)
    k_r, k_l = 1e-6, 2e-6
    res = cv.propagate(traj, k_r, k_l)
    end = sp.sample_end_poses(traj, k_r, k_l, N_MC, rng)
    mean, C = stats.mean_cov(end)
    S = res.covs[-1]
    assert np.all(np.abs(C - S) <= _cov_tolerance(S, N_MC))
    assert np.all(np.abs(mean - res.poses[-1]) <= 5 * np.sqrt(np.diag(S) / N_MC) + 1e-12)


def test_coverage_of_the_ellipse(rng):
    t = tr.arc(radius=0.5, angle=1.0, dt=0.01)
    res = cv.propagate(t, 1e-6, 1e-6)
    xy = sp.sample_end_poses(t, 1e-6, 1e-6, N_MC, rng)[:, :2]
    for pr in (0.5, 0.9, cv.PR_3SIGMA):
        frac = stats.fraction_inside_ellipse(xy, res.poses[-1, :2], res.covs[-1, :2, :2], pr)
        # binomial standard error √(p(1−p)/n), 5 of them
        assert abs(frac - pr) <= 5 * math.sqrt(pr * (1 - pr) / N_MC)


@pytest.mark.parametrize("regime", ["per_step", "per_run"])
def test_heading_variance_both_regimes(regime, rng):
    # on a straight line θ_end = (Σe_r − Σe_l)/b exactly, in both regimes the variance of each
    # wheel's total travel is k·L at the end of the run: σθ² = (k_r + k_l) L / b²
    t = tr.straight(2.0, dt=0.02, track=0.2)
    end = sp.sample_end_poses(t, 5e-4, 3e-4, N_MC, rng, regime=regime)
    expected = (5e-4 + 3e-4) * 2.0 / 0.2**2
    var = end[:, 2].var(ddof=1)
    assert abs(var - expected) <= 5 * expected * math.sqrt(2 / (N_MC - 1))


@pytest.mark.slow
def test_per_run_cloud_is_narrower_across_and_bent(rng):
    # systematic errors: heading error is constant-rate, so across-track spread grows slower
    t = tr.straight(1.0, dt=0.01)
    step = stats.mean_cov(sp.sample_end_poses(t, 5e-4, 5e-4, N_MC, rng))[1]
    run = stats.mean_cov(sp.sample_end_poses(t, 5e-4, 5e-4, N_MC, rng, regime="per_run"))[1]
    # per-step σy² ≈ K L³/(3b²); per-run θ(s) = θ_end s/L gives σy² ≈ σθ² L²/4 = K L³/(4b²)
    assert_allclose(run[1, 1] / step[1, 1], 0.75, rtol=0.05)


def test_same_seed_bit_identical_and_thread_count_free():
    t = tr.arc(radius=1.0, angle=1.0, dt=0.01)
    a = sp.sample_end_poses(t, 5e-4, 5e-4, 5000, np.random.default_rng(7), workers=1)
    b = sp.sample_end_poses(t, 5e-4, 5e-4, 5000, np.random.default_rng(7), workers=2)
    c = sp.sample_end_poses(t, 5e-4, 5e-4, 5000, np.random.default_rng(8), workers=2)
    assert_array_equal(a, b)
    assert not np.array_equal(a, c)


@pytest.mark.parametrize("method", ["exact", "euler", "euler_end", "midpoint"])
def test_fast_end_path_equals_general_integration(method):
    # two routes: in-place end-only kernel vs integrate_end with a checkpoint at N
    t = tr.s_curve(dt=0.02)
    a = sp.sample_end_poses(t, 5e-4, 5e-4, 3000, np.random.default_rng(3), method=method)
    b = sp.sample_end_poses(
        t, 5e-4, 5e-4, 3000, np.random.default_rng(3), method=method, checkpoints=[0, t.n_steps]
    )
    assert_allclose(a, b[:, 1], rtol=0, atol=1e-12)
    assert_allclose(b[:, 0], np.zeros((3000, 3)))


def test_zero_noise_gives_the_nominal_pose(rng):
    t = tr.direct()
    end = sp.sample_end_poses(t, 0.0, 0.0, 10, rng, method="exact")
    assert_allclose(end, np.broadcast_to(t.poses[-1], (10, 3)), atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n": 0}, r"n must be an integer >= 1.*got 0"),
        ({"k_r": -1.0}, r"k_r must be >= 0"),
        ({"regime": "random"}, r"regime must be one of 'per_step', 'per_run', got 'random'"),
        ({"method": "rk4"}, r"method must be one of"),
        ({"checkpoints": [1000]}, r"checkpoints must be step indices in \[0, 100\]"),
    ],
)
def test_bad_sampling_input(kwargs, match, rng):
    args = {"k_r": 1e-4, "k_l": 1e-4, "n": 10}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        sp.sample_end_poses(tr.straight(1.0), rng=rng, **args)


def test_stats_helpers(rng):
    x = rng.multivariate_normal([1, 2], [[2.0, 0.3], [0.3, 0.5]], size=100_000)
    m, C = stats.mean_cov(x)
    assert_allclose(m, x.mean(axis=0))
    assert_allclose(C, np.cov(x.T))
    with pytest.raises(ValueError, match="n >= 2"):
        stats.mean_cov(x[:1])


def test_initial_covariance_matches_propagation(rng):
    # start poses drawn from N(start, Σ_0): the end cloud equals A Σ_0 Aᵀ + noise (Method A)
    t = tr.arc(radius=0.5, angle=1.0, dt=0.01, start=(0.3, -0.1, 0.4))
    S0 = np.array([[4e-6, 1e-6, 0.0], [1e-6, 2e-6, 5e-7], [0.0, 5e-7, 1e-6]])
    res = cv.propagate(t, 1e-6, 2e-6, cov0=S0)
    end = sp.sample_end_poses(t, 1e-6, 2e-6, N_MC, rng, cov0=S0)
    _, C = stats.mean_cov(end)
    assert np.all(np.abs(C - res.covs[-1]) <= _cov_tolerance(res.covs[-1], N_MC))


def test_initial_covariance_fast_path_equals_general():
    t = tr.s_curve(dt=0.02)
    S0 = np.diag([1e-4, 2e-4, 3e-4])
    a = sp.sample_end_poses(t, 5e-4, 5e-4, 2000, np.random.default_rng(4), cov0=S0)
    b = sp.sample_end_poses(
        t, 5e-4, 5e-4, 2000, np.random.default_rng(4), cov0=S0, checkpoints=[t.n_steps]
    )
    assert_allclose(a, b[:, 0], rtol=0, atol=1e-12)


def test_bad_initial_covariance(rng):
    with pytest.raises(ValueError, match="cov0 must be positive semi-definite"):
        sp.sample_end_poses(tr.straight(1.0), 1e-4, 1e-4, 10, rng, cov0=np.diag([1.0, -1.0, 1.0]))
    with pytest.raises(ValueError, match="cov0 must be a symmetric 3x3"):
        sp.sample_end_poses(tr.straight(1.0), 1e-4, 1e-4, 10, rng, cov0=np.eye(2))


@pytest.mark.parametrize("kernel", ["numpy", "compiled"])
def test_kept_normals_give_the_same_cloud_for_other_error_constants(kernel):
    """A DrawCache keeps each chunk's standard normals (they depend on the seed, particles and steps
    only): a second call with other k_r, k_l or cov0 takes them, and its cloud is the one drawn
    afresh, bit for bit, for both kernels (numpy's per-chunk draws, which the cache keeps and
    ``draws="auto"`` takes with a cache) and with the start offsets drawn after them."""
    t = tr.straight(0.5, speed=0.5, dt=0.01, track=0.2)
    cache = sp.DrawCache()
    c0 = np.diag([1e-4, 2e-4, 1e-3])
    for k_r, cov0, regime in [(7e-4, None, "per_step"), (2e-3, None, "per_step"), (2e-3, c0, "per_step"),
                              (5e-4, c0, "per_step"), (5e-4, None, "per_run"), (9e-4, None, "per_run")]:  # fmt: skip
        kept = sp.sample_end_poses(t, k_r, 5e-4, 700, np.random.default_rng(4), regime=regime, cov0=cov0,
                                   kernel=kernel, cache=cache)  # fmt: skip
        fresh = sp.sample_end_poses(t, k_r, 5e-4, 700, np.random.default_rng(4), regime=regime, cov0=cov0,
                                    kernel=kernel, draws="per-chunk")  # fmt: skip
        assert_array_equal(kept, fresh)
    assert cache._kept  # and it did keep them


def test_a_draw_cache_asks_for_per_chunk_draws():
    # the compiled kernel draws the per-block normals itself: nothing a cache could keep
    t = tr.straight(0.5, speed=0.5, dt=0.01, track=0.2)
    per_block = sp.sample_end_poses(t, 7e-4, 5e-4, 300, np.random.default_rng(4), kernel="compiled")
    kept = sp.sample_end_poses(t, 7e-4, 5e-4, 300, np.random.default_rng(4), kernel="compiled", cache=sp.DrawCache())
    per_chunk = sp.sample_end_poses(t, 7e-4, 5e-4, 300, np.random.default_rng(4), kernel="compiled", draws="per-chunk")
    assert_array_equal(kept, per_chunk)
    assert not np.array_equal(kept, per_block)
    with pytest.raises(ValueError, match=r"^a DrawCache keeps numpy's per-chunk draws \(allowed with cache: draws "
                                         r"'auto', 'per-chunk'\), got draws 'per-block'$"):  # fmt: skip
        sp.sample_end_poses(t, 7e-4, 5e-4, 300, np.random.default_rng(4), draws="per-block", cache=sp.DrawCache())


def test_draw_cache_returns_the_draw_and_leaves_the_stream_where_it_would_be():
    cache = sp.DrawCache(max_bytes=1000)  # one block of 2 × 50 normals (800 bytes)
    for _ in range(2):  # drawn, then kept
        g, h = np.random.default_rng(8), np.random.default_rng(8)
        assert_array_equal(cache.normals(g, (2, 50)), h.standard_normal((2, 50)))
        assert_array_equal(g.standard_normal(5), h.standard_normal(5))  # the next draws are unchanged
    assert len(cache._kept) == 1
    cache.normals(np.random.default_rng(9), (2, 50))  # a second block: the first goes (least recently used)
    assert len(cache._kept) == 1
    assert cache._bytes == 800
    cache.normals(np.random.default_rng(10), (10, 50))  # larger than the cache: drawn, not kept
    assert cache._bytes == 800
