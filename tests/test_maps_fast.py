"""The batched kernels of the histogram filter against their one-at-a-time forms, bit for bit.

The transition kernel of a step is built for all source headings at once
(``maps.prediction._source_windows``) and the step's FFTs run on batches of headings and blocks of
rows; each must give exactly the numbers of the plain loop (one heading, one part, one
``bincount`` at a time), whatever the batch, block and thread count. The belief's moments
are checked against the sums over the whole grid; the likelihoods computed on blocks of
rows against the whole grid at once.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from pose_uncertainty.core.grids import Grid
from pose_uncertainty.core.validation import check_finite, check_nonnegative
from pose_uncertainty.localization import histogram as HF
from pose_uncertainty.localization.sensors import (
    BeamSensor,
    RangeBearingSensor,
    beam_probability,
    beam_terms,
    landmark_h,
)
from pose_uncertainty.localization.world import World
from pose_uncertainty.methods import maps as M
from pose_uncertainty.methods.maps import kernels, prediction
from pose_uncertainty.methods.maps.transition import _rotated_cells

ROOM = Grid.square(0.1, 0.1, 40, 30, 0.2, 36)
FINE = Grid.square(-0.5, -0.5, 60, 50, 0.02, 72)

#: (grid, grid_transition arguments): narrow kernels (every row split into mean and
#: deviations), wide ones (many nodes), the odometry model, triangular noise, a kernel
#: thin across the track only (split and unsplit rows mixed), heading offsets that wrap
#: round a coarse circle (folded)
CASES = {
    "velocity_room": (ROOM, {"model": "velocity", "control": (0.5, 0.3), "dt": 0.1, "alphas": np.full(6, 0.05)}),
    "velocity_fine": (FINE, {"model": "velocity", "control": (1.0, 0.5), "dt": 0.2, "alphas": np.full(6, 0.1)}),
    "odometry_room": (ROOM, {"model": "odometry", "odometry": [[1.0, 2.0, 0.3], [1.06, 2.02, 0.35]],
                             "alphas": np.full(4, 0.05)}),
    "odometry_fine": (FINE, {"model": "odometry", "odometry": [[0.0, 0.0, 0.0], [0.25, 0.05, 0.4]],
                             "alphas": [0.1, 0.01, 0.2, 0.05], "noise": "triangular"}),
    "thin_across": (FINE, {"model": "velocity", "control": (1.0, 0.0), "dt": 0.2,
                           "alphas": [0.2, 0.0, 1e-4, 0.0, 1e-4, 0.0]}),
    "folded": (Grid.square(0.0, 0.0, 20, 20, 0.1, 4), {"model": "velocity", "control": (0.3, 2.0), "dt": 0.5,
                                                      "alphas": [0.05, 0.05, 0.05, 0.5, 0.05, 0.05]}),
}  # fmt: skip


def transition(name):
    grid, kw = CASES[name]
    return M.grid_transition(grid=grid, **kw)


def axis_parts_one_row(f, width, weight):
    """The deposit of one row of nodes on one axis, as lists of (cells, factors), part by part."""
    mean = float(weight @ f)
    std = math.sqrt(max(float(weight @ (f - mean) ** 2), 0.0))
    if std >= 0.5:
        i, first = kernels._splat(f[None], width[None])
        return [(i[0], first[0]), (i[0] + 1, 1.0 - first[0])]
    base = math.floor(mean)
    frac = mean - base
    i, first = kernels._splat((f - mean)[None], width[None])
    out = []
    for idx, w in ((i[0], first[0]), (i[0] + 1, 1.0 - first[0])):
        out.append((idx + base, w * (1.0 - frac)))
        out.append((idx + base + 1, w * frac))
    return out


def source_window_one_at_a_time(t, k):
    """Heading k's kernel window: every (x part, y part, θ part) deposited by its own bincount, in order."""
    kern, (ax, ay, wx, wy), g = t.kernel, t.windows, t.grid
    h, mp = g.resolution, kern.head_mp
    fx, fy = _rotated_cells(kern, g.theta[k : k + 1], h)
    c, s = math.cos(g.theta[k]), math.sin(g.theta[k])
    sa, sb = kern.step_a, kern.step_b
    wdx = (np.abs(c * sa[:, 0] - s * sa[:, 1]) + np.abs(c * sb[:, 0] - s * sb[:, 1])) / h
    wdy = (np.abs(s * sa[:, 0] + c * sa[:, 1]) + np.abs(s * sb[:, 0] + c * sb[:, 1])) / h
    x_parts = axis_parts_one_row(fx[0], np.minimum(wdx, 1.0), kern.weight)
    y_parts = axis_parts_one_row(fy[0], np.minimum(wdy, 1.0), kern.weight)
    win = np.zeros(wx * wy * mp)
    for jx, vx in x_parts:
        for jy, vy in y_parts:
            for jt, vt in zip(*kern.head_parts, strict=True):
                cell = ((jx - ax[k]) * wy + (jy - ay[k])) * mp + jt
                win += np.bincount(cell, kern.weight * vx * vy * vt, minlength=win.size)
    return win.reshape(wx, wy, mp)


@pytest.mark.parametrize("name", sorted(CASES))
def test_source_windows_of_all_headings_equal_the_one_part_at_a_time_deposit(name, monkeypatch):
    t = transition(name)
    g = t.grid
    ks = np.arange(g.ntheta)
    batched = prediction._source_windows(t.kernel, ks, g.theta, g.resolution, t.windows)
    monkeypatch.setattr(prediction, "_WINDOW_BATCH_BYTES", 1)  # one heading per batch
    single = prediction._source_windows(t.kernel, ks[::-1], g.theta, g.resolution, t.windows)[::-1]
    for k in ks:
        ref = source_window_one_at_a_time(t, k)
        assert_array_equal(batched[k], ref)
        assert_array_equal(single[k], ref)
        assert math.isclose(ref.sum(), 1.0, rel_tol=1e-12)  # every node's mass lands in the window


def test_the_cases_cover_split_unsplit_mixed_and_folded_kernels():
    seen = set()
    for name in CASES:
        t = transition(name)
        g = t.grid
        for f in _rotated_cells(t.kernel, g.theta, g.resolution):  # x, then y
            split = kernels._split_rows(f, t.kernel.weight)[1]
            seen.add("mixed" if 0 < split.sum() < split.size else ("split" if split.all() else "unsplit"))
        if t.kernel.head_mp > g.ntheta:
            seen.add("folded")
        if t.kernel.weight.size > 1000:
            seen.add("many nodes")
    assert seen == {"split", "unsplit", "mixed", "folded", "many nodes"}


def random_belief(g, seed, n_slices):
    """A belief on a few heading slices, with slices of negligible mass beside them."""
    rng = np.random.default_rng(seed)
    b = np.zeros(g.shape)
    ks = rng.choice(g.ntheta, n_slices, replace=False)
    b[g.nx // 3 : g.nx // 2, g.ny // 3 : g.ny // 2, ks] = rng.random((g.nx // 2 - g.nx // 3, g.ny // 2 - g.ny // 3,
                                                                      n_slices))  # fmt: skip
    b[:, :, (ks[0] + g.ntheta // 2) % g.ntheta] = 1e-19  # dropped as negligible
    return b / b.sum()


@pytest.mark.parametrize("name", ["velocity_room", "odometry_fine", "folded"])
def test_prediction_does_not_depend_on_batches_blocks_threads_or_overwriting(name, monkeypatch):
    t = transition(name)
    b = random_belief(t.grid, 3, min(7, t.grid.ntheta - 1))
    ref, info = M.predict_on_grid(b, t, workers=1)
    assert info["negligible_slices"] > 0
    kept = b.copy()
    got = {"threads": M.predict_on_grid(b, M.grid_transition(grid=t.grid, **CASES[name][1]), workers=2)}
    monkeypatch.setattr(prediction, "_SPECTRA_BATCH_BYTES", 1)
    monkeypatch.setattr(prediction, "_BLOCK", 1)
    got["small batches and blocks"] = M.predict_on_grid(b, transition(name), workers=1)
    assert_array_equal(b, kept)  # the input is left alone
    own = b.copy()
    got["overwritten"] = M.predict_on_grid(own, transition(name), workers=1, overwrite_belief=True)
    assert got["overwritten"][0] is own
    for key, (new, inf) in got.items():
        assert new.tobytes() == ref.tobytes(), key
        assert inf == info, key
    assert math.isclose(ref.sum() + info["lost_mass"], 1.0, rel_tol=1e-12)


def test_moments_equal_the_sums_over_the_grid():
    g = Grid.square(-1.0, 0.5, 30, 20, 0.1, 24)
    rng = np.random.default_rng(5)
    v = rng.random(g.shape) ** 8
    v[:, :, 3:20] *= 1e-3  # mass near θ = ±π: the deviations wrap round the circular mean
    pm = M.ProbabilityMap(g.x, g.y, g.theta, v, 0.0, "test", g)
    mean, cov = pm.moments()
    w = v / v.sum()
    X, Y, T = np.meshgrid(g.x, g.y, g.theta, indexing="ij")
    th = math.atan2(float(np.sum(w * np.sin(T))), float(np.sum(w * np.cos(T))))
    ref_mean = np.array([np.sum(w * X), np.sum(w * Y), th])
    d = [X - ref_mean[0], Y - ref_mean[1], np.angle(np.exp(1j * (T - th)))]
    ref_cov = np.array([[np.sum(w * a * b) for b in d] for a in d])
    assert abs(th) > 2.5  # the mean heading is near the cut at ±π
    assert_allclose(mean, ref_mean, rtol=1e-13, atol=1e-14)
    assert_allclose(cov, ref_cov, rtol=1e-12, atol=1e-15)
    assert_array_equal(pm.mean(), mean)
    assert_array_equal(pm.cov(), cov)


def test_correction_equals_the_product_formula():
    g = ROOM
    rng = np.random.default_rng(8)
    b = random_belief(g, 9, 5)
    ll = -50.0 * rng.random(g.shape)
    ll[b == 0] = 300.0  # the likelihood of cells without mass does not set the scale
    post, logev = HF.hf_correct(b, ll)
    top = ll[b > 0].max()
    ref = b * np.exp(ll - top)
    assert_allclose(post, ref / ref.sum(), rtol=1e-14, atol=0)
    assert math.isclose(logev, top + math.log(ref.sum()), rel_tol=1e-14)
    with pytest.raises(ValueError, match="zero likelihood on every cell with mass"):
        HF.hf_correct(b, np.where(b > 0, -np.inf, 0.0))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, -1e-300])
def test_large_arrays_are_checked_as_small_ones(bad):
    big = np.full(10_000, 0.5)
    big[1234] = bad
    what = "finite" if not np.isfinite(bad) else ">= 0"
    with pytest.raises(ValueError, match=f"belief must be {what}"):
        check_nonnegative("belief", big)
    huge = np.full(10_000, 1e308)  # finite, though the sum overflows
    assert check_finite("huge", huge) is huge
    assert check_nonnegative("huge", huge) is huge


def test_unknown_correspondences_take_each_cells_best_landmark(monkeypatch):
    world = World(np.array([[0.3, 0.9], [-0.8, 0.2], [0.6, -0.5]]), np.arange(3), bounds=(-1.0, 1.0, -0.8, 0.8))
    grid = HF.pose_grid_for(world, 0.1, 24)
    sen = RangeBearingSensor(range_std=0.2, bearing_std=0.1)
    z = landmark_h(np.array([0.05, -0.1, 2.5]), world.landmarks)[:2] + np.random.default_rng(4).normal(0, 0.05, (2, 2))
    ref = np.zeros(grid.shape)
    for zi in z:  # per measurement, the best landmark of every cell
        ref += np.max([HF.landmark_log_likelihood_grid(grid, zi[None], mj[None], sen) for mj in world.landmarks],
                      axis=0)  # fmt: skip
    assert_array_equal(HF.landmark_log_likelihood_grid_ml(grid, z, world.landmarks, sen), ref)
    monkeypatch.setattr(HF, "_BLOCK", 1000)  # blocks of 2 rows
    assert_array_equal(HF.landmark_log_likelihood_grid_ml(grid, z, world.landmarks, sen), ref)


@pytest.mark.parametrize("theta_major", [True, False])
def test_beam_likelihood_in_blocks_is_the_whole_table(theta_major, monkeypatch):
    sen = BeamSensor(n_beams=4, max_range=5.0, sigma_hit=0.1)
    rng = np.random.default_rng(2)
    nx, ny, nt = 15, 11, 12
    # the table of beam_range_table is stored θ-major (nθ, B, nx, ny); a sum over the beams
    # then runs in that order, and the result keeps it
    table = (np.moveaxis(rng.uniform(0, 5, (nt, 4, nx, ny)), (0, 1), (2, 3)) if theta_major
             else rng.uniform(0, 5, (nx, ny, nt, 4)))  # fmt: skip
    table[2, 3, 4, 1] = 0.0  # a wall at the sensor
    z = np.array([1.0, 5.0, 0.0, 3.3])  # a max reading and a zero one
    with np.errstate(divide="ignore"):
        whole = np.log(beam_probability(z, table, sen, beam_terms(table, sen))).sum(axis=-1)
    monkeypatch.setattr(HF, "_BLOCK", 3 * ny * nt * 4)  # blocks of 3 rows
    got = HF._beam_log_likelihood_grid(z, table, sen, beam_terms(table, sen))
    assert got.tobytes(order="A") == whole.tobytes(order="A")
    assert got.strides == whole.strides
