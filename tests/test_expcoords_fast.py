"""The pruned planar density of the banana (expcoords.pdf_xy) against the full quadrature sum."""

import numpy as np
import pytest

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import expcoords as ec


def dense_reference(pts, mu, S, n_quad=64):
    """The full sum Σ_q w_q N(p; μ_q, C_q) over every quadrature node, one node at a time."""
    cond = ec._conditional(np.asarray(mu, float), np.asarray(S, float), n_quad)
    out = np.zeros(len(pts))
    for q in range(cond.nodes.size):
        d = pts - cond.means[q]
        P = cond.prec[q]
        m2 = P[0, 0] * d[:, 0] ** 2 + 2.0 * P[0, 1] * d[:, 0] * d[:, 1] + P[1, 1] * d[:, 1] ** 2
        out += cond.weights[q] * np.exp(cond.log_norm[q] - 0.5 * m2)
    return out, cond.nodes.size


def points_around(mu, S, n, seed, spread):
    """Draws from the banana, the same jittered by ``spread``, and a grid over their box."""
    rng = np.random.default_rng(seed)
    draws = ec.sample(mu, S, n, rng)[:, :2]
    jitter = draws + spread * rng.normal(size=draws.shape)
    lo, hi = jitter.min(axis=0), jitter.max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 60), np.linspace(lo[1], hi[1], 60))
    return np.concatenate([draws, jitter, np.stack([gx.ravel(), gy.ravel()], axis=-1)])


def assert_matches_dense(pts, mu, S, n_quad=64, min_nodes=0):
    ref, n_nodes = dense_reference(pts, mu, S, n_quad)
    assert n_nodes >= min_nodes
    new = ec.pdf_xy(pts, mu, S, n_quad=n_quad)
    big = ref > 1e-10 * ref.max()
    assert big.sum() > 0.5 * len(pts)
    rel = np.abs(new - ref)[big] / ref[big]
    assert rel.max() < 1e-9, rel.max()
    assert np.abs(new - ref).max() < 1e-12 * ref.max()  # and nothing sizeable anywhere else
    return new


def banana(traj, k):
    E = ec.propagate(traj, k, k)
    return E.poses[-1], E.covs[-1]


@pytest.mark.slow
def test_thin_straight_banana_matches_the_full_sum():
    mu, S = banana(tr.straight(20.0, dt=0.05, track=0.2), 5e-4)
    pts = points_around(mu, S, 3000, seed=11, spread=0.3)
    assert_matches_dense(pts, mu, S, min_nodes=3000)  # the pruned path, thousands of nodes


@pytest.mark.slow
def test_three_lap_circle_matches_the_full_sum():
    # the heading spread is ±5.8 rad: the curve of conditional means winds round the circle, so
    # nodes far apart in w lie close in the plane; many nodes force the pruned path
    mu, S = banana(tr.circle(radius=1.0, laps=3, dt=0.01, track=0.2), 5e-4)
    pts = points_around(mu, S, 3000, seed=12, spread=0.2)
    cond = ec._conditional(mu, S, 2048)
    assert np.ptp(cond.nodes) > 2 * np.pi
    assert_matches_dense(pts, mu, S, n_quad=2048, min_nodes=2048)


@pytest.mark.parametrize("dense_nodes", [64, 0])
def test_fat_banana_matches_the_full_sum(monkeypatch, dense_nodes):
    # large k, few nodes: the dense sum (default), and the pruned path forced onto it
    monkeypatch.setattr(ec, "_DENSE_NODES", dense_nodes)
    mu, S = banana(tr.straight(0.5, dt=0.05, track=0.2), 0.05)
    pts = points_around(mu, S, 2000, seed=13, spread=0.1)
    assert_matches_dense(pts, mu, S)
    assert_matches_dense(pts, mu, S, n_quad=3)  # a single, partly empty block


@pytest.mark.slow
def test_pruned_density_integrates_to_one():
    mu, S = banana(tr.circle(radius=1.0, laps=3, dt=0.01, track=0.2), 5e-4)
    x = np.linspace(-3.0, 3.0, 301)
    y = np.linspace(-3.0, 3.0, 301)
    Z = ec.marginal_xy_grid(x, y, mu, S, n_quad=2048)
    assert abs(Z.sum() * (x[1] - x[0]) * (y[1] - y[0]) - 1.0) < 2e-3


@pytest.mark.slow
def test_deterministic_and_independent_of_chunking(monkeypatch):
    mu, S = banana(tr.straight(20.0, dt=0.05, track=0.2), 5e-4)
    pts = points_around(mu, S, 3000, seed=14, spread=0.3)
    a = ec.pdf_xy(pts, mu, S)
    assert np.array_equal(a, ec.pdf_xy(pts, mu, S))
    perm = np.random.default_rng(0).permutation(len(pts))
    assert np.array_equal(a[perm], ec.pdf_xy(pts[perm], mu, S))
    halves = [ec.pdf_xy(pts[:777], mu, S), ec.pdf_xy(pts[777:], mu, S)]
    assert np.array_equal(a, np.concatenate(halves))
    monkeypatch.setattr(ec, "_PAIRS_PER_CHUNK", 5000)  # many small chunks
    assert np.array_equal(a, ec.pdf_xy(pts, mu, S))


def test_shapes_and_nan_points():
    mu, S = banana(tr.straight(20.0, dt=0.05, track=0.2), 5e-4)
    pts = ec.sample(mu, S, 12, np.random.default_rng(3))[:, :2].reshape(3, 4, 2)
    out = ec.pdf_xy(pts, mu, S)
    assert out.shape == (3, 4)
    pts[1, 2] = np.nan
    out2 = ec.pdf_xy(pts, mu, S)
    assert np.isnan(out2[1, 2])
    assert np.array_equal(np.isnan(out2), np.isnan(pts).any(-1))
    assert ec.pdf_xy(np.zeros((0, 2)), mu, S).shape == (0,)


# --- quantiles of the density (the banana's region levels) -----------------------------------


@pytest.mark.parametrize(
    ("traj", "k", "n"),
    [
        (tr.straight(2.5, dt=0.01, track=0.2), 7e-4, 20_000),  # the explorer's path: ~430 nodes
        (tr.straight(2.5, dt=0.01, track=0.2), 4e-3, 20_000),  # wider heading spread, more nodes
        (tr.straight(0.5, dt=0.05, track=0.2), 0.05, 5_000),  # a fat banana: the dense sum
        pytest.param(tr.straight(20.0, dt=0.05, track=0.2), 5e-4, 50_000, marks=pytest.mark.slow),
    ],
)
def test_density_quantiles_equal_the_quantiles_of_every_density(traj, k, n):
    """The bracketed route reads few exact densities, and gives np.quantile of all of them, bit for bit."""
    mu, S = banana(traj, k)
    q = np.array([0.0, 1.0 - 0.98889, 0.1, 0.5, 0.9, 1.0])
    for seed in range(3):
        pts = ec.sample(mu, S, n, np.random.default_rng(seed))[:, :2]
        assert np.array_equal(ec.density_quantiles(pts, mu, S, q), np.quantile(ec.pdf_xy(pts, mu, S), q))
    # the same with either route to the brackets (numpy's, or the compiled loop's once loaded)
    from pose_uncertainty.methods import mc_kernel

    mc_kernel.jit_module()
    assert ec._compiled_loaded()
    assert np.array_equal(ec.density_quantiles(pts, mu, S, q), np.quantile(ec.pdf_xy(pts, mu, S), q))
    # scalar q, a handful of points, ties
    assert ec.density_quantiles(pts[:3], mu, S, 0.5) == np.quantile(ec.pdf_xy(pts[:3], mu, S), 0.5)
    twice = np.concatenate([pts[:500], pts[:500]])
    assert np.array_equal(ec.density_quantiles(twice, mu, S, q), np.quantile(ec.pdf_xy(twice, mu, S), q))


@pytest.mark.parametrize(("traj", "k"), [(tr.straight(2.5, dt=0.01, track=0.2), 7e-4),
                                         (tr.straight(2.5, dt=0.01, track=0.2), 4e-3),
                                         (tr.arc(1.0, 2.0, dt=0.01, track=0.2), 2e-3)])
def test_density_brackets_hold_the_density(traj, k):
    """The brackets of density_quantiles: the sum over the blocks kept at truncation 5 (a subset
    of pdf_xy's terms, in single precision, within 2e-5 of the double sum), less its margin, is
    below the density; with the margin and e^-5 of the largest node peak (all it leaves out) added,
    above it: at every point, near the banana and far from it."""
    mu, S = banana(traj, k)
    pts = points_around(mu, S, 4000, seed=21, spread=0.1)
    cond = ec._conditional(mu, S, 64)
    assert cond.nodes.size > ec._DENSE_NODES
    exact = ec.pdf_xy(pts, mu, S)
    for compiled in (False, True):  # numpy's single-precision sum, the compiled loop's
        lo, hi = ec._density_brackets(pts, cond, compiled=compiled)
        assert np.all(lo <= exact), compiled
        assert np.all(exact <= hi), compiled
        assert np.mean(lo < exact) > 0.25  # it does leave terms out
    # the single-precision sum against the double one of the same terms
    double = ec._pdf_xy_pruned(pts, cond, ec._BOUND_TRUNC)
    single = ec._pdf_xy_pruned(pts, cond, ec._BOUND_TRUNC, single=True)
    assert np.all(np.abs(single - double) <= 2e-5 * double)


def test_block_sum_adds_in_numpys_order():
    """A block's terms, node-major, added as numpy adds a contiguous row (eight running sums, then
    a tree): the pruned density is unchanged by its node-major layout."""
    rng = np.random.default_rng(4)
    for m in (1, 7, 300):
        terms = np.exp(rng.uniform(-60.0, 5.0, (ec._BLOCK, m))) * (rng.random((ec._BLOCK, m)) < 0.7)
        r = terms[0:8] + terms[8:16]
        for i in range(16, ec._BLOCK, 8):
            r += terms[i : i + 8]
        mine = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
        assert np.array_equal(mine, np.ascontiguousarray(terms.T).sum(axis=1))


def test_density_quantiles_bad_input():
    mu, S = banana(tr.straight(2.5, dt=0.01, track=0.2), 7e-4)
    with pytest.raises(ValueError, match=r"q must be in \[0, 1\]"):
        ec.density_quantiles([[2.5, 0.0]], mu, S, 1.5)
    with pytest.raises(ValueError, match="xy must have shape"):
        ec.density_quantiles(np.zeros((0, 2)), mu, S, 0.5)
    pts = ec.sample(mu, S, 200, np.random.default_rng(1))[:, :2]
    pts[7] = np.nan  # as np.quantile of the densities: NaN
    assert np.isnan(ec.density_quantiles(pts, mu, S, [0.1, 0.5])).all()


@pytest.mark.parametrize(("traj", "k"), [(tr.straight(2.5, dt=0.01, track=0.2), 7e-4),
                                         (tr.arc(1.0, 2.0, dt=0.01, track=0.2), 2e-3),
                                         (tr.straight(0.5, dt=0.05, track=0.2), 0.05)])  # the dense sum
def test_at_least_equals_the_comparison_of_every_density(traj, k):
    """at_least (brackets, the exact density where they straddle) against pdf_xy at every point."""
    mu, S = banana(traj, k)
    pts = ec.sample(mu, S, 3000, np.random.default_rng(2))[:, :2]
    dens = ec.pdf_xy(pts, mu, S)
    levels = np.quantile(dens, [0.011, 0.1, 0.5])
    levels = np.concatenate([levels, dens[:3]])  # a level equal to a point's density: ">=" holds there
    got = ec.at_least(pts, mu, S, levels)
    assert got.shape == (levels.size, pts.shape[0])
    assert np.array_equal(got, dens[None, :] >= levels[:, None])
    assert got[3:, :3].diagonal().all()


@pytest.mark.parametrize(("traj", "k"), [(tr.straight(2.5, dt=0.01, track=0.2), 7e-4),
                                         (tr.arc(1.0, 2.0, dt=0.01, track=0.2), 2e-3)])
def test_region_contour_is_the_exact_grids_line_for_line(traj, k):
    """region_xy_at reads the exact density only at the corners of cells the brackets leave open:
    its lines are those of the contour of marginal_xy_grid, point for point."""
    import contourpy

    mu, S = banana(traj, k)
    pts = ec.sample(mu, S, 4000, np.random.default_rng(4))[:, :2]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    x, y = (np.linspace(lo[a] - 0.1 * (hi[a] - lo[a]), hi[a] + 0.1 * (hi[a] - lo[a]), 40) for a in (0, 1))
    for pr in (0.5, 0.98889):
        level = float(ec.hdr_threshold(mu, S, pr, np.random.default_rng(5), n=5000))
        want = contourpy.contour_generator(x, y, ec.marginal_xy_grid(x, y, mu, S).T).lines(level)
        got = ec.region_xy_at(x, y, mu, S, level)
        assert len(got) == len(want) >= 1
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
