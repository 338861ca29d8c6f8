"""Measures of a localization: regions and their coverage, NEES, convergence."""

import math

import numpy as np
import pytest

from pose_uncertainty.core.stats import (
    COVERAGE_LEVELS,
    fraction_inside_ellipse,
    hdr_levels,
    hdr_region,
)
from pose_uncertainty.localization import evaluation as MS

PRS = np.array(list(COVERAGE_LEVELS.values()))


def test_hdr_region_known_values():
    m = np.array([[0.05, 0.5], [0.15, 0.3]])
    np.testing.assert_array_equal(hdr_region(m, [0.5, 0.6, 0.9, 0.99])[0], [0.5, 0.3, 0.15, 0.05])
    assert hdr_region(m, 0.8)[0] == 0.3  # 0.5 + 0.3 reaches 0.8 exactly


def test_gaussian_regions_are_the_pr_ellipses(rng):
    # two routes: the flags against core.stats.fraction_inside_ellipse; and for truths drawn
    # from the Gaussian itself the coverage is the nominal Pr within 5 binomial SE
    mean = np.array([1.0, -2.0, 0.3])
    cov = np.array([[0.04, 0.01, 0.002], [0.01, 0.02, -0.001], [0.002, -0.001, 0.01]])
    n = 50_000
    truth = rng.multivariate_normal(mean, cov, n)
    flags = MS.gaussian_region_flags(np.broadcast_to(mean, (n, 3)), np.broadcast_to(cov, (n, 3, 3)), truth)
    for c, pr in enumerate(PRS):
        assert flags[:, c].mean() == fraction_inside_ellipse(truth[:, :2], mean[:2], cov[:2, :2], pr)
        assert abs(flags[:, c].mean() - pr) <= 5 * math.sqrt(pr * (1 - pr) / n)
    nees = MS.nees(np.broadcast_to(mean, (n, 3)), np.broadcast_to(cov, (n, 3, 3)), truth)
    assert abs(nees.mean() - 3) <= 5 * math.sqrt(6 / n)  # χ²(3): variance 6


def test_grid_regions_cover_their_nominal_probability(rng):
    # a Gaussian on 2 cm cells: truths drawn from the gridded distribution itself fall in its
    # highest-density regions with the nominal probability (up to the mass of the boundary
    # cell, < 0.5 % here, and 5 binomial SE)
    h = 0.02
    x = np.arange(-1, 1, h) + h / 2
    X, Y = np.meshgrid(x, x, indexing="ij")
    m = np.exp(-0.5 * ((X / 0.2) ** 2 + (Y / 0.1) ** 2))
    m /= m.sum()
    n = 20_000
    cells = rng.choice(m.size, n, p=m.ravel())
    flags = m.ravel()[cells][:, None] >= hdr_region(m, PRS)[0]
    for c in cells[:50]:  # the per-cell function used by the filters says the same
        np.testing.assert_array_equal(MS.mass_region_flags(m, divmod(int(c), m.shape[1])),
                                      m.ravel()[c] >= hdr_region(m, PRS)[0])  # fmt: skip
    for c, pr in enumerate(PRS):
        assert abs(flags[:, c].mean() - pr) <= 5 * math.sqrt(pr * (1 - pr) / n) + 0.005
    assert not MS.mass_region_flags(m, (-1, 3)).any()


def test_unchecked_region_flags_equal_the_checked_ones(rng):
    # the filters' per-step route (hdr_levels, region_flags_of_mass: no validation) against
    # hdr_region and mass_region_flags, on masses with ties and empty cells, for every cell
    m = np.round(rng.random((7, 9)) ** 3, 2)
    m[rng.random(m.shape) < 0.3] = 0.0
    np.testing.assert_array_equal(hdr_levels(m, PRS), hdr_region(m, PRS)[0])
    for i in range(-1, m.shape[0] + 1):
        for j in range(-1, m.shape[1] + 1):
            inside = 0 <= i < m.shape[0] and 0 <= j < m.shape[1]
            np.testing.assert_array_equal(MS.region_flags_of_mass(float(m[i, j]) if inside else 0.0, m[m > 0]),
                                          MS.mass_region_flags(m, (i, j)))  # fmt: skip


def test_gaussian_region_flags_of_all_steps_equal_those_of_each(rng):
    # the EKF flags its steps after the loop, all at once: the same as one call per step
    n = 200
    mean = rng.normal(size=(n, 3))
    A = rng.normal(size=(n, 3, 3)) * 0.3
    cov = A @ np.swapaxes(A, 1, 2)
    truth = mean + rng.normal(size=(n, 3)) * 0.3
    every = MS.gaussian_region_flags(mean, cov, truth)
    assert 0 < every.sum() < every.size  # both inside and outside
    for k in range(n):
        np.testing.assert_array_equal(every[k], MS.gaussian_region_flags(mean[k], cov[k], truth[k]))


def test_nees_band_and_convergence():
    lo, hi = MS.nees_band(3, 50, 0.95)
    assert lo < 3 < hi
    assert (lo, hi) == pytest.approx((2.36, 3.72), abs=0.01)  # χ²(150) 2.5 % and 97.5 % / 50
    t = np.arange(6) * 0.5
    ok, tc = MS.convergence(t, [3, 0.2, 0.9, 0.1, 0.1, 0.05], np.zeros(6), 0.5, 0.2)
    assert ok
    assert tc == 1.5
    ok, tc = MS.convergence(t, [0.1] * 5 + [0.6], np.zeros(6), 0.5, 0.2)
    assert not ok
    assert tc == math.inf
