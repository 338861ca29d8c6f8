"""Šafránek 2022's studies and growth laws: known values and two routes to each number."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.analysis import studies as st
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.stats import fit_growth
from pose_uncertainty.methods import wheel_noise as wn


def test_closed_form_arc_equals_trajectory_poses():
    t = st.constant_speed_trajectory(1.0, 0.95, 1.0, 0.01, 0.1)
    assert_allclose(st.exact_constant_arc(1.0, 0.95, 1.0, 0.1, np.float64), t.poses[-1], atol=1e-14)
    # straight limit: no division by zero
    assert_allclose(st.exact_constant_arc(1.0, 1.0, 2.0, 0.1, np.float64), [2.0, 0.0, 0.0])


def test_integration_orders():
    res = st.integration_vs_step()
    assert abs(res["order"]["euler"] - 1.0) < 0.02
    assert abs(res["order"]["euler_end"] - 1.0) < 0.02
    assert abs(res["order"]["midpoint"] - 2.0) < 0.02
    exact = [r["position_error"] for r in res["rows"] if r["method"] == "exact"]
    assert max(exact) < 1e-12
    # Euler's leading error on an arc of turn Θ, length s in N steps is s·Θ/(2N) (chord offset)
    row = next(r for r in res["rows"] if r["method"] == "euler" and r["dt"] == 0.01)
    assert_allclose(row["position_error"], 0.975 * 0.5 / (2 * 100), rtol=0.02)


def test_float64_loop_equals_vectorised_integration():
    rng = np.random.default_rng(1)
    t = st.constant_speed_trajectory(1.0, 0.95, 0.5, 0.01, 0.1)
    r = t.ds_r * (1 + 0.01 * rng.normal(size=(4, t.n_steps)))
    l = t.ds_l * (1 + 0.01 * rng.normal(size=(4, t.n_steps)))
    from pose_uncertainty.methods.sampling import integrate_end

    ref = integrate_end(r, l, 0.1, method="exact")[:, 0, :]
    for nt in ("float64", "longdouble"):
        assert_allclose(st.integrate_in_type(r, l, 0.1, 0.01, nt), ref, atol=1e-12)


def test_number_type_drift():
    rows = {(r["number_type"], r["n_steps"]): r for r in st.number_type_drift((100, 1000))}
    for nt in ("float64", "longdouble"):
        assert rows[(nt, 1000)]["position_error"] < 1e-11
    # float32 has a 6e-8 relative unit roundoff: its drift after 1000 steps is far above float64's
    # and far below a millimetre
    f32 = rows[("float32", 1000)]["position_error"]
    assert 1e-6 < f32 < 1e-3
    assert rows[("float32", 1000)]["position_error"] > rows[("float32", 100)]["position_error"]
    # integer millimetres with C truncation lose up to 1 mm per step: centimetres after 100 steps
    assert rows[("int_mm", 100)]["position_error"] > 0.01


def test_integer_millimetres_collapse_the_cloud():
    t = st.constant_speed_trajectory(1.0, 1.0, 1.0, 0.01, 0.1)
    c = st.number_type_clouds(t, wn.SAFRANEK_2022_CHASSIS, 300, 3)
    # each step's sideways increment (≈10 mm × sin θ, θ ~ 0.03 rad) truncates to 0 mm
    assert c["int_mm"]["distinct_y"] <= 5
    assert c["int_mm"]["std"][1] < 0.05 * c["float64"]["std"][1]
    assert c["float32"]["max_abs_difference_m"] < 1e-5
    assert c["float64"]["max_abs_difference_m"] < 1e-12


def test_error_sources_map_to_k():
    # Monte Carlo of the physical sources against k = σ_v² dt/|v|: the sample variance of the
    # total travel has relative s.e. √(2/n) = 1 % at n = 2e4; 4 s.e.
    r = st.error_sources_vs_monte_carlo(n=20_000)
    assert_allclose(r["k_mc_travel"], r["k_equivalent"], rtol=0.04)
    for name in ("x", "y", "theta"):
        assert_allclose(r[f"var_{name}_mc"], r[f"var_{name}_method_a"], rtol=0.05)


def test_regime_growth_exponents():
    t = tr.straight(2.0, dt=0.02, track=0.2)
    g = st.regime_growth(t, 5e-4, 5e-4, 4000, 3, n_checkpoints=8)
    # per-step: σ_θ ∝ √s; per-run: θ = (ε_r − ε_l) s/b exactly, so σ_θ ∝ s
    assert abs(g["per_step"]["fits"]["sigma_theta"]["power_exponent"] - 0.5) < 0.05
    assert abs(g["per_run"]["fits"]["sigma_theta"]["power_exponent"] - 1.0) < 1e-6
    assert abs(g["per_step"]["fits"]["sigma_across"]["power_exponent"] - 1.5) < 0.1
    assert abs(g["per_run"]["fits"]["sigma_across"]["power_exponent"] - 2.0) < 0.1
    # matched at the end: equal heading spread there (s.e. of a std ≈ 1/√(2n) ≈ 1.1 %)
    assert_allclose(g["per_run"]["sigma_theta"][-1], g["per_step"]["sigma_theta"][-1], rtol=0.05)


def test_fit_growth_recovers_laws():
    s = np.linspace(0.5, 10, 30)
    p = fit_growth(s, 0.3 * s**1.5)
    assert_allclose(p["power_exponent"], 1.5, rtol=1e-10)
    assert p["power_rms_log_residual"] < 1e-10 < p["exp_rms_log_residual"]
    e = fit_growth(s, 0.3 * np.exp(0.4 * s))
    assert_allclose(e["exp_rate"], 0.4, rtol=1e-10)
    assert e["exp_rms_log_residual"] < 1e-10 < e["power_rms_log_residual"]
    with pytest.raises(ValueError, match="at least 3 positive points"):
        fit_growth([1.0, 2.0], [1.0, 2.0])


def test_method_a_growth_on_the_straight_line_is_a_power_law():
    k, b = 5e-4, 0.2
    t = tr.straight(20.0, dt=0.01, track=b)
    g = st.growth_laws(t, k, k, n_points=20)
    fits = g["method_a"]["fits"]
    for name, p in (("sigma_along", 0.5), ("sigma_across", 1.5), ("sigma_theta", 0.5), ("area", 2.0)):
        assert abs(fits[name]["power_exponent"] - p) < 0.01
        assert fits[name]["power_rms_log_residual"] < fits[name]["exp_rms_log_residual"]
    # closed forms: σ_θ² = 2ks/b², σ_along² = ks/2
    s = np.asarray(g["distance"])
    assert_allclose(g["method_a"]["sigma_theta"], np.sqrt(2 * k * s) / b, rtol=1e-9)
    assert_allclose(g["method_a"]["sigma_along"], np.sqrt(k * s / 2), rtol=1e-9)


def test_polar_view_is_more_gaussian():
    from pose_uncertainty.methods.sampling import sample_end_poses

    cloud = sample_end_poses(tr.straight(1.0, dt=0.02, track=0.2), 5e-4, 5e-4, 40_000,
                             np.random.default_rng(5))
    r = st.polar_vs_cartesian(cloud)
    cart, pol = r["cartesian"], r["polar"]
    # the banana skews x (s.e. of a skewness ≈ √(6/n) = 0.012); r is symmetric
    assert cart["x"]["skewness"] < -0.1
    assert abs(pol["r"]["skewness"]) < 0.05
    se = math.sqrt(0.9889 * 0.0111 / 40_000)
    assert abs(pol["coverage_98.89"] - 0.9889) < 4 * se
    assert 0.9889 - cart["coverage_98.89"] > 4 * se


def test_method_cloud_spread_small():
    t = st.constant_speed_trajectory(1.0, 0.95, 1.0, 0.01, 0.1)
    r = st.method_cloud_spread(t, 4.17e-6, 4.17e-6, 2000, 7)
    # same noise, different integrators: Euler's cloud is rotated by ~Δθ/2 per step (O(dt)), a
    # couple of per cent of the covariance; the midpoint rule is O(dt²) from the exact arc
    assert r["midpoint"]["max_rel_cov_difference"] < 1e-3
    assert r["euler"]["max_rel_cov_difference"] < 0.05


def test_accuracy_case_structure():
    row = st.accuracy_case({"name": "straight", "length": 1.0, "dt": 0.2, "track": 0.2}, n=500,
                           n_bins=20, n_threshold=5000, label="straight 1 m")
    assert row["case"] == "straight 1 m"
    assert row["length"] == pytest.approx(1.0)
    assert {"cartesian", "expcoords", "grid", "monte_carlo"} <= set(row)


def test_bad_input():
    with pytest.raises(ValueError, match="number_type must be one of"):
        st.integrate_in_type(np.ones((1, 2)), np.ones((1, 2)), 0.1, 0.01, "int8")
    with pytest.raises(ValueError, match="scheme must be one of"):
        st.integrate_in_type(np.ones((1, 2)), np.ones((1, 2)), 0.1, 0.01, "float32", scheme="x")


@pytest.mark.slow
def test_corrected_map_matches_its_sampler_better_than_the_thesis_map():
    # the sampler's pose-space density (corrected map) against the thesis's Thrun density, both
    # against 2e4 draws of the odometry sampler; coverage s.e. ≤ 0.0035, grid error ~ a cell
    r = st.map_vs_sampler("odometry", (1.0, 1.0), n=20_000, size=3.0, resolution=0.05)
    cm, tm = r["corrected_map"], r["thesis_map"]
    assert abs(cm["coverage_xy_50"] - 0.5) < 0.02
    assert abs(cm["coverage_xy_90"] - 0.9) < 0.015
    assert cm["hellinger"] < tm["hellinger"]
    assert abs(tm["coverage_xy_50"] - 0.5) > 0.05


def test_calibration_demo_interval_width_matches_fisher():
    # one k with Σ = k·G: the MLE is tr(G⁻¹S)/3, so var(k̂) = 2k²/(3n) and the 95 % interval has
    # half-width 1.96·k·√(2/(3n)); profile and Wald intervals agree to O(1/√n) (≈2 % at n = 4000),
    # so 10 % is a safe margin
    n = 4000
    res = st.calibration_demo(n=n, seed=3)
    assert res["true_k"] == 5e-4
    assert res["n"] == n
    rows = {(r["coords"], r["equal"], r["parameter"]): r for r in res["rows"]}
    assert len(rows) == 6
    for coords in ("expcoords", "cartesian"):
        r = rows[(coords, True, "k")]
        half = 0.5 * (r["ci_high"] - r["ci_low"])
        assert_allclose(half, 1.959964 * r["estimate"] * math.sqrt(2 / (3 * n)), rtol=0.1)
        assert r["ci_low"] < r["estimate"] < r["ci_high"]
        assert r["contains_true"] == (r["ci_low"] <= 5e-4 <= r["ci_high"])
        assert_allclose(r["relative_bias"], r["estimate"] / 5e-4 - 1)
    # Method A's model is the more biased one (12 % against 2 % at n = 2e4); the gap, ≈10 % of k, is
    # ≈7 standard errors (√(2/(3n)) ≈ 1.3 %) at n = 4000
    assert rows[("cartesian", True, "k")]["relative_bias"] > rows[("expcoords", True, "k")]["relative_bias"]


@pytest.mark.slow
def test_coverage_vs_distance_rows():
    t = tr.straight(4.0, dt=0.02, track=0.2)
    rows = st.coverage_vs_distance(t, 5e-4, 5e-4, 2000, 1, n_checkpoints=4)
    assert_allclose([r["distance"] for r in rows], [1.0, 2.0, 3.0, 4.0], atol=1e-9)
    # Method A's coverage of its 98.89 % ellipse falls as the banana bends (σ_θ grows with distance):
    # 97.6 % → 61 % here, against binomial standard errors of at most 1.1 % (√(0.39·0.61/2000))
    cov_a = [r["cartesian"]["coverage_xy_98.89"] for r in rows]
    assert cov_a[-1] < cov_a[0]
    assert_allclose(rows[0]["coverage_se_98.89"], math.sqrt(0.98889 * (1 - 0.98889) / 2000), rtol=1e-3)
