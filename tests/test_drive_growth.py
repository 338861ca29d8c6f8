"""Growth of the spreads along and across a straight, per drive, against closed forms."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.analysis import drive_growth as ad
from pose_uncertainty.core import drives as dr
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.methods import drive_noise as dn

STRAIGHT = tr.straight(5.0, dt=0.01)
MODEL = dn.DriveErrorModel(k=5e-4, steer_var=math.radians(1.0) ** 2)


def test_differential_spreads_grow_as_the_half_and_three_halves_powers():
    g = ad.drive_growth(dr.follow(dr.Differential(0.2), STRAIGHT), MODEL)
    s = np.array(g["distance"])
    # closed forms of the straight (test_covariance): σ_along² = K s/4, σ_across² ≈ K s³/(3b²)
    K = 2 * 5e-4
    assert_allclose(g["method_a"]["sigma_along"], np.sqrt(K * s / 4), rtol=1e-9)
    assert_allclose(g["method_a"]["sigma_across"], np.sqrt(K * s**3 / (3 * 0.2**2)), rtol=1e-3)
    fits = g["method_a"]["fits"]
    assert fits["sigma_along"]["power_exponent"] == pytest.approx(0.5, abs=1e-9)
    assert fits["sigma_across"]["power_exponent"] == pytest.approx(1.5, abs=1e-3)


@pytest.mark.parametrize("regime", ["per_step", "per_run"])
def test_synchro_drive_spreads_without_turning(regime):
    # no heading error: along from the travel k, across from the steering angle,
    # per step σ_across² = Σ ΔS² steer_var (√s), per run σ_across = s·σ_ψ (s¹)
    g = ad.drive_growth(dr.follow(dr.SynchroDrive(), STRAIGHT), MODEL, regime=regime)
    s = np.array(g["distance"])
    var = math.radians(1.0) ** 2
    expected = np.sqrt(s * 0.01 * var) if regime == "per_step" else s * math.sqrt(var)
    assert_allclose(g["method_a"]["sigma_across"], expected, rtol=1e-6)
    assert_allclose(g["method_a"]["sigma_theta"], 0.0, atol=0)
    assert "sigma_theta" not in g["method_a"]["fits"]


def test_monte_carlo_growth_matches_method_a_at_small_errors():
    g = ad.drive_growth(
        dr.follow(dr.Omni3(0.15), tr.straight(1.0, dt=0.02)),
        dn.DriveErrorModel(k=1e-6),
        n_points=5,
        n_particles=20_000,
        seed=3,
    )
    # a standard deviation's relative standard error is ≈ 1/√(2n) = 0.5 %; five of them
    for k in ad.MEASURES:
        assert_allclose(g["monte_carlo"][k], g["method_a"][k], rtol=0.025)
