"""Sensor models: range–bearing h and its Jacobian, likelihoods, association, ray casting, beam model."""

import itertools
import math

import numpy as np
import pytest
from scipy import integrate
from scipy import stats as sstats

from pose_uncertainty.core.kinematics import wrap_angle
from pose_uncertainty.localization import sensors as S
from pose_uncertainty.localization import world as W

LM = np.array([[2.0, 1.0], [-1.5, 3.0], [0.3, -2.2], [4.0, -0.5]])


def test_h_known_values():
    z = S.landmark_h([1.0, 1.0, math.pi / 2], [[1.0, 3.0], [0.0, 1.0]])
    np.testing.assert_allclose(z, [[2.0, 0.0], [1.0, math.pi / 2]], atol=1e-15)


def test_measurement_jacobian_equals_finite_differences(rng):
    poses = np.column_stack([rng.uniform(-1, 1, 20), rng.uniform(-1, 1, 20), rng.uniform(-4, 4, 20)])
    H = S.landmark_jacobian(poses, LM)
    eps = 1e-6
    for a in range(3):
        d = np.zeros(3)
        d[a] = eps
        zp, zm = S.landmark_h(poses + d, LM), S.landmark_h(poses - d, LM)
        diff = zp - zm
        diff[..., 1] = wrap_angle(diff[..., 1])
        # central differences: truncation O(eps²) ≈ 1e-12 relative, round-off ≈ 1e-16/eps = 1e-10
        np.testing.assert_allclose(H[..., a], diff / (2 * eps), rtol=1e-7, atol=1e-8)


def test_landmark_log_likelihood_equals_the_scalar_formula(rng):
    sen = S.RangeBearingSensor(range_std=0.2, bearing_std=0.05)
    P = np.column_stack([rng.normal(0, 1, 50), rng.normal(0, 1, 50), rng.uniform(-10, 10, 50)])
    z = S.landmark_h(np.array([0.1, -0.2, 0.3]), LM) + rng.normal(0, 0.05, LM.shape)
    ref = np.zeros(50)
    for i, p in enumerate(P):
        for (r, phi), (mx, my) in zip(z, LM, strict=True):
            rh = math.hypot(mx - p[0], my - p[1])
            ph = math.atan2(my - p[1], mx - p[0]) - p[2]
            e = (phi - ph + math.pi) % (2 * math.pi) - math.pi
            ref[i] += (-0.5 * ((r - rh) / 0.2) ** 2 - 0.5 * (e / 0.05) ** 2
                       - math.log(2 * math.pi * 0.2 * 0.05))  # fmt: skip
    got = S.landmark_log_likelihood(P, z, LM, sen, chunk=7)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-9)
    # float32 terms: relative rounding ~1e-7 of each term (|terms| up to ~1e5 here)
    np.testing.assert_array_equal(S.landmark_log_likelihood(P, z, LM, sen, chunk=7, workers=2), got)
    got32 = S.landmark_log_likelihood(P, z, LM, sen, dtype="float32")
    np.testing.assert_allclose(got32, ref, rtol=2e-6, atol=1e-3)


def test_ml_association_per_hypothesis_and_from_a_gaussian(rng):
    sen = S.RangeBearingSensor(range_std=0.05, bearing_std=0.02)
    truth = np.array([0.2, 0.1, 0.4])
    z = S.landmark_h(truth, LM) + rng.normal(0, 0.01, LM.shape)
    order = np.array([2, 0, 3, 1])  # measurements in a shuffled order
    idx, _ll = S.associate(z[order], truth, np.diag([1e-3, 1e-3, 1e-4]), LM, sen)
    np.testing.assert_array_equal(idx, order)
    P = truth + rng.normal(0, 0.01, (30, 3))
    ll_ml, idx_ml = S.landmark_log_likelihood_ml(P, z[order], LM, sen)
    assert np.all(idx_ml == order)
    np.testing.assert_allclose(ll_ml, S.landmark_log_likelihood(P, z[order], LM[order], sen), rtol=1e-12)


def _box_entry(o, a, lo, hi):
    """Distance along the ray (o, angle a) at which it enters the box [lo, hi] (slab method)."""
    d = np.array([math.cos(a), math.sin(a)])
    t0, t1 = 0.0, math.inf
    for k in range(2):
        if abs(d[k]) < 1e-300:
            if not lo[k] <= o[k] <= hi[k]:
                return math.inf
            continue
        ta, tb = (lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
    return t0 if t0 <= t1 else math.inf


def test_ray_casting_equals_the_analytic_distance_to_boxes(rng):
    # occupancy made of axis-aligned blocks of cells: the range is the entry distance into
    # the nearest block (slab method, an independent route), capped at max_range
    h = 0.1
    occ = np.zeros((60, 40), dtype=bool)
    blocks = [(0, 60, 0, 2), (0, 60, 38, 40), (0, 2, 0, 40), (58, 60, 0, 40), (20, 27, 10, 16), (40, 43, 25, 36)]
    for i0, i1, j0, j1 in blocks:
        occ[i0:i1, j0:j1] = True
    g = W.OccupancyGrid(occ, ~occ, h, np.array([-1.0, 0.5]))
    n = 3000
    origins = np.column_stack([rng.uniform(-0.75, 4.75, n), rng.uniform(0.75, 4.25, n)])
    keep = ~g.is_occupied(origins)
    origins = origins[keep]
    angles = rng.uniform(-math.pi, math.pi, origins.shape[0])
    angles[:8] = [0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, 0, math.pi, -math.pi / 2]  # axis rays
    got = S.cast_rays(g, origins, angles, max_range=4.0)
    ref = np.empty_like(got)
    for r, (o, a) in enumerate(zip(origins, angles, strict=True)):
        t = min(_box_entry(o, a, g.origin + h * np.array([i0, j0]), g.origin + h * np.array([i1, j1]))
                for i0, i1, j0, j1 in blocks)  # fmt: skip
        ref[r] = min(t, 4.0)
    np.testing.assert_allclose(got, ref, atol=1e-9)
    assert np.any(ref == 4.0)
    assert np.any(ref < 1.0)
    # a ray starting inside an occupied cell has range 0
    assert S.cast_rays(g, [[-0.95, 0.55]], [0.3], 4.0).tolist() == [0.0]


def test_ray_casting_from_the_grid_equals_the_general_traversal(rng):
    # the traversal of rays that start on the grid (one look-up in the grid padded by a ring of
    # off-grid cells) against the general one (bounds and directions checked at every cell), on the
    # same rays: the same distances to the last bit, axis-aligned rays and ranges past the grid included;
    # and cast_rays, which splits rays starting off the grid to the general one, agrees with it too
    occ = rng.random((37, 23)) < 0.04
    g = W.OccupancyGrid(occ, ~occ, 0.1, np.array([-1.0, 0.5]))
    n = 4000
    origins = np.column_stack([rng.uniform(-1.5, 3.2, n), rng.uniform(0.0, 3.3, n)])  # some off the grid
    angles = rng.uniform(-4.0, 4.0, n)
    angles[:400] = rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2, 2 * math.pi], 400)
    for max_range in (0.25, 2.0, 50.0):
        t_max = max_range / g.resolution
        s = S._dda_init(g, origins[:, 0], origins[:, 1], angles)
        inner = (s["i"] >= 0) & (s["i"] < g.shape[0]) & (s["j"] >= 0) & (s["j"] < g.shape[1])
        assert inner.any()
        assert (~inner).any()
        general, fast = np.full(n, t_max), np.full(n, t_max)
        S._traverse(g, s, t_max, general)
        S._traverse_from_inside(g, {k: a[inner] for k, a in s.items()}, t_max, fast)
        assert fast[inner].tobytes() == general[inner].tobytes()
        assert np.all(fast[~inner] == t_max)  # untouched
        got = S.cast_rays(g, origins, angles, max_range)
        assert got.tobytes() == (np.minimum(general, t_max) * g.resolution).tobytes()
        assert np.any(general[inner] < t_max)
        assert np.any(general[inner] == t_max)


def test_beam_model_is_a_probability_distribution():
    sen = S.BeamSensor(max_range=5.0, sigma_hit=0.2, lambda_short=0.8, z_hit=0.7, z_short=0.1, z_max=0.1, z_rand=0.1)
    for zs in (0.0, 0.3, 2.5, 4.9, 5.0):
        def f(z, zs=zs):
            return float(S.beam_probability(z, zs, sen))
        pts = [p for p in (zs,) if 0 < p < 5.0]
        cont, _ = integrate.quad(f, 0.0, 5.0 - 1e-7, points=pts or None, limit=200)
        # the continuous part integrates to 1 − z_max; the max reading carries the point mass
        # z_max. At z* = 0 (a pose inside a wall) p_short is a spike at 0: its mass z_short is
        # not in the density (documented limit).
        expected = 1.0 - sen.z_max - (sen.z_short if zs == 0.0 else 0.0)
        assert cont == pytest.approx(expected, abs=1e-6), (zs, cont)


def test_beam_sampler_draws_from_the_beam_density():
    # two routes: histogram of 2·10⁵ draws against the density's bin masses (χ² test), and
    # the fraction of max readings against z_max
    sen = S.BeamSensor(max_range=5.0, sigma_hit=0.3, lambda_short=0.8, z_hit=0.6, z_short=0.2, z_max=0.1, z_rand=0.1)
    zs = 2.0
    n = 200_000
    z = S.sample_beam_measurements(np.full(n, zs), sen, np.random.default_rng(4))
    at_max = z == 5.0
    assert abs(at_max.mean() - sen.z_max) <= 5 * math.sqrt(sen.z_max * (1 - sen.z_max) / n)
    edges = np.linspace(0, 5.0, 41)
    counts = np.histogram(z[~at_max], edges)[0]
    mass = np.array([integrate.quad(lambda x: float(S.beam_probability(x, zs, sen)), a, b,
                                    points=[zs] if a < zs < b else None)[0]
                     for a, b in itertools.pairwise(edges)])  # fmt: skip
    expected = n * mass
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    assert sstats.chi2.sf(chi2, len(counts) - 1) > 1e-4, chi2


def test_expected_ranges_rotate_with_the_heading():
    g = W.grid_from_segments(W.rectangle_segments(0, 4, 0, 2), 0.1)
    sen = S.BeamSensor(n_beams=4, max_range=10.0)  # beams at −π, −π/2, 0, π/2
    z = S.expected_ranges(g, np.array([[1.0, 0.5, 0.0], [1.0, 0.5, math.pi / 2]]), sen)
    # inner faces at x = 0.1, 3.9 and y = 0.1, 1.9
    np.testing.assert_allclose(z[0], [0.9, 0.4, 2.9, 1.4], atol=1e-9)
    np.testing.assert_allclose(z[1], [0.4, 2.9, 1.4, 0.9], atol=1e-9)
