"""Method C in every run: logged C_* measures, the accuracy comparison, figures, tables, the method guide.

Every logged number is checked against a second route: Method C recomputed from the
logged configuration (``unscented.propagate`` on its trajectory), the Monte Carlo
cloud read back from the log, the table flattened from the log, the guide's counts
redone from the logs themselves.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.analysis import accuracy, measures
from pose_uncertainty.core import trajectories
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.core.stats import PR_3SIGMA, pr_to_k
from pose_uncertainty.core.table_io import read_table
from pose_uncertainty.experiments.run import RunConfig, execute
from pose_uncertainty.methods import covariance, expcoords, unscented
from pose_uncertainty.methods.sampling import sample_end_poses
from pose_uncertainty.pipeline.method_guide import method_guide, unscented_summary
from pose_uncertainty.pipeline.tables import collect_table
from pose_uncertainty.present import figures
from pose_uncertainty.records.run import RunLog, open_run, verify_run, write_run

CIRCLE = {
    "name": "circle2",
    "seed": 3,
    "trajectory": {"name": "circle", "radius": 1.0, "laps": 2.0, "speed": 1.0, "dt": 0.05, "track": 0.2},
    "monte_carlo": {"n_particles": 2000},
}
STRAIGHT = {
    "name": "straight4",
    "seed": 4,
    "trajectory": {"name": "straight", "length": 4.0, "speed": 1.0, "dt": 0.05, "track": 0.2},
    "monte_carlo": {"n_particles": 1000},
}
SHORT = {
    "name": "straight1",
    "seed": 5,
    "trajectory": {"name": "straight", "length": 1.0, "speed": 1.0, "dt": 0.05, "track": 0.2},
    "monte_carlo": {"n_particles": 1000},
}


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Three runs (a circle, two straight lines) written to logs, and a table of them."""
    d = tmp_path_factory.mktemp("method_c")
    out = {cfg["name"]: write_run(d / f"{cfg['name']}.mcap", execute(RunConfig.from_dict(cfg)))
           for cfg in (CIRCLE, STRAIGHT, SHORT)}  # fmt: skip
    out["table"] = collect_table("L_test", [out[n] for n in ("circle2", "straight4", "straight1")], None,
                                 d / "L_test.csv")  # fmt: skip
    return out


@pytest.fixture(scope="module")
def circle(logs: dict[str, Path]) -> RunLog:
    return open_run(logs["circle2"])


def _rotate(v: np.ndarray, theta: float) -> np.ndarray:
    """Planar vector(s) in the frame of heading θ: (along, across)."""
    c, s = math.cos(theta), math.sin(theta)
    return v @ np.array([[c, -s], [s, c]])


@pytest.mark.slow
def test_c_measures_equal_unscented_propagate_on_the_logged_config(circle: RunLog) -> None:
    """Second route: Method C recomputed from the logged configuration, frames and ellipse by hand."""
    cfg = circle.config
    C = unscented.propagate(trajectories.from_config(cfg.trajectory), cfg.k_r, cfg.k_l)
    mean, cov, m = C.poses[-1], C.covs[-1], circle.metrics
    nominal = circle.poses[-1]
    for i, key in enumerate(("C_mean_x", "C_mean_y", "C_mean_theta")):
        assert m[key] == mean[i], key
    for key, (i, j) in {"C_cov_xx": (0, 0), "C_cov_xy": (0, 1), "C_cov_yy": (1, 1)}.items():
        assert m[key] == cov[i, j], key
    # σ along/across: Rᵀ Σ R in the frame of the nominal end heading (not stats.along_across)
    R = _rotate(np.eye(2), nominal[2])
    S_aa = R.T @ cov[:2, :2] @ R
    assert_allclose([m["C_sigma_along"], m["C_sigma_across"]], np.sqrt(np.diag(S_aa)), rtol=1e-12)
    assert m["C_sigma_theta"] == pytest.approx(math.sqrt(cov[2, 2]), rel=1e-15)
    # the Pr-ellipse's semi-axes² = k(Pr) · eigenvalues of Σ_xy
    lam = np.linalg.eigvalsh(cov[:2, :2])
    k = float(pr_to_k(cfg.pr))
    assert_allclose([m["C_ellipse_minor"] ** 2, m["C_ellipse_major"] ** 2], k * lam, rtol=1e-10)
    shift = _rotate(mean[:2] - nominal[:2], nominal[2])
    assert_allclose([m["C_mean_shift_along"], m["C_mean_shift_across"]], shift, rtol=1e-12, atol=1e-15)
    assert m["C_mean_offset"] == pytest.approx(float(np.hypot(*shift)), rel=1e-12)
    # the Monte Carlo mean, from the logged cloud
    mc = circle.end_poses.mean(axis=0)
    assert_allclose([m["MC_mean_shift_along"], m["MC_mean_shift_across"]], _rotate(mc[:2] - nominal[:2], nominal[2]),
                    rtol=1e-12, atol=1e-15)  # fmt: skip
    assert m["MC_mean_offset_C"] == pytest.approx(math.dist(mc[:2], mean[:2]), rel=1e-12)
    # on the circle (left turns) the heading noise pulls both means inwards, i.e. to the left
    assert m["C_mean_shift_across"] > 0
    assert m["MC_mean_shift_across"] > 5 * m["MC_sigma_across"] / math.sqrt(m["MC_n"])


def test_c_accuracy_equals_evaluate_cartesian_on_the_logged_cloud(circle: RunLog) -> None:
    """accuracy_unscented_* = evaluate_cartesian about C's logged mean and covariance; coverage by hand."""
    m, s = circle.metrics, circle.end_poses
    mean = np.array([m["C_mean_x"], m["C_mean_y"], m["C_mean_theta"]])
    cfg = circle.config
    cov = unscented.propagate(trajectories.from_config(cfg.trajectory), cfg.k_r, cfg.k_l).covs[-1]
    grid = Grid.covering(s[:, :2], n_bins=60)
    assert grid.nx == m["accuracy_grid_nx"]
    direct = accuracy.evaluate_cartesian(s, mean, cov, grid)
    for key, val in direct.items():
        assert m[f"accuracy_unscented_{key}".replace(".", "_")] == val, key
    d = s[:, :2] - mean[:2]
    d2 = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov[:2, :2]), d)
    assert m["accuracy_unscented_coverage_xy_98_89"] == float(np.mean(d2 <= float(pr_to_k(PR_3SIGMA))))


def test_adding_method_c_leaves_every_other_comparison_unchanged() -> None:
    t = trajectories.straight(2.0, dt=0.05, track=0.2)
    A, E, C = (f(t, 5e-4, 5e-4) for f in (covariance.propagate, expcoords.propagate, unscented.propagate))
    s = sample_end_poses(t, 5e-4, 5e-4, 500, np.random.default_rng(1))
    args = (s, (A.poses[-1], A.covs[-1]), (E.poses[-1], E.covs[-1]))
    without = accuracy.compare_methods(*args, np.random.default_rng(2), n_threshold=5000)
    with_c = accuracy.compare_methods(*args, np.random.default_rng(2), n_threshold=5000,
                                      unscented=(C.poses[-1], C.covs[-1]))  # fmt: skip
    assert set(with_c) - set(without) == {"unscented"}
    assert {k: with_c[k] for k in without} == without


def test_every_logged_c_measure_has_a_unit_and_definition(circle: RunLog) -> None:
    new = [k for k in circle.metrics if k.startswith(("C_", "MC_mean_shift", "MC_mean_offset_C", "accuracy_unscented"))]
    expected = {f"C_{k}" for k in ("sigma_x", "sigma_y", "sigma_theta", "sigma_along", "sigma_across",
                                    "ellipse_major", "ellipse_minor", "ellipse_angle", "ellipse_area", "bend_ratio",
                                    "mean_x", "mean_y", "mean_theta", "cov_xx", "cov_xy", "cov_yy", "mean_offset",
                                    "mean_shift_along", "mean_shift_across")}
    expected |= {"MC_mean_shift_along", "MC_mean_shift_across", "MC_mean_offset_C"}
    expected |= {f"accuracy_unscented_{k}" for k in ("hellinger", "kl", "model_mass_on_grid", "loglik_pose",
                                                     "loglik_xy", "nees_pose", "nees_xy")}
    expected |= {f"accuracy_unscented_coverage_{w}_{p}" for w in ("xy", "pose") for p in ("50", "90", "98_89")}
    assert set(new) == expected
    for k in new:
        unit, definition = measures.describe(k)
        assert circle.metric_units[k] == unit
        assert circle.metric_definitions[k] == definition
    with pytest.raises(KeyError, match="C_bogus"):
        measures.describe("C_bogus")


def test_replay_verify_passes_with_method_c(circle: RunLog) -> None:
    comparison = verify_run(circle)
    assert comparison.mismatches == []
    assert comparison.status == "identical"


def test_table_columns_equal_the_logged_metrics(logs: dict[str, Path]) -> None:
    rows = {r["run"]: r for r in read_table(logs["table"])}
    for name in ("circle2", "straight4", "straight1"):
        metrics = open_run(logs[name]).metrics
        row = rows[name]
        keys = [k for k in metrics if k.startswith(("C_", "MC_mean_shift", "MC_mean_offset_C", "accuracy_unscented"))]
        assert keys
        for k in keys:
            assert row[k] == metrics[k], (name, k)  # bit for bit (repr round trip)


def test_figures_draw_c_ellipse_from_the_logged_measures(circle: RunLog) -> None:
    m = circle.metrics
    cov = np.array([[m["C_cov_xx"], m["C_cov_xy"]], [m["C_cov_xy"], m["C_cov_yy"]]])
    want = covariance.ellipse_polyline(cov, circle.config.pr, np.array([m["C_mean_x"], m["C_mean_y"]]), 200)
    for fig in (figures.trajectory_figure(circle), figures.cloud_figure(circle)):
        lines = [ln for ln in fig.axes[0].get_lines() if str(ln.get_label()).startswith("Method C (sigma points) ellipse")]
        assert len(lines) == 1
        assert_allclose(lines[0].get_xydata(), want, rtol=0, atol=0)


def _mean_error_from_log(log: RunLog) -> tuple[float, float, float]:
    """|MC mean − A's mean|, |MC mean − C's mean| and √(tr Σ_MC/n), all from the log's arrays and C recomputed."""
    cfg = log.config
    C = unscented.propagate(trajectories.from_config(cfg.trajectory), cfg.k_r, cfg.k_l)
    s = log.end_poses[:, :2]
    mc = s.mean(axis=0)
    se = math.sqrt(np.trace(np.cov(s.T)) / s.shape[0])
    return math.dist(mc, log.poses[-1, :2]), math.dist(mc, C.poses[-1, :2]), se


def _c_coverage_from_log(log: RunLog) -> float:
    cfg = log.config
    C = unscented.propagate(trajectories.from_config(cfg.trajectory), cfg.k_r, cfg.k_l)
    d = log.end_poses[:, :2] - C.poses[-1, :2]
    d2 = np.einsum("ni,ij,nj->n", d, np.linalg.inv(C.covs[-1, :2, :2]), d)
    return float(np.mean(d2 <= float(pr_to_k(PR_3SIGMA))))


def test_method_guide_c_advice_from_the_logs_directly(logs: dict[str, Path]) -> None:
    """The guide's Method C numbers, counted again from the logs' clouds and a recomputed C."""
    rows = {"L_test": read_table(logs["table"])}
    runs = {n: open_run(logs[n]) for n in ("circle2", "straight4", "straight1")}
    errors = {n: _mean_error_from_log(r) for n, r in runs.items()}
    coverage = {n: _c_coverage_from_log(r) for n, r in runs.items()}
    s = unscented_summary(rows)
    assert s is not None
    assert s["n_runs"] == 3
    assert s["mean"]["n_closer"] == sum(c < a for a, c, _ in errors.values())
    assert s["mean"]["n_a_off"] == sum(a > 3 * se for a, _, se in errors.values())
    worst = min(coverage, key=coverage.__getitem__)
    assert s["coverage"]["worst"]["run"] == worst
    assert s["coverage"]["worst"]["coverage"]["c"] == pytest.approx(coverage[worst], abs=0)
    assert [r["run"] for r in s["long_runs"]] == []  # not a long-path set name
    guide = [g for g in method_guide(rows) if g["advice"].startswith("Method C")]
    assert len(guide) == 1
    g = guide[0]
    assert g["numbers"]["n_mean_closer"] == s["mean"]["n_closer"]
    assert g["numbers"]["worst_run"] == worst
    assert f"{100 * coverage[worst]:.2f} %" in g["evidence"]
    # where C beats A: on the circle its mean is nearer the Monte Carlo mean, by more than A's misses by
    a, c, se = errors["circle2"]
    assert a > 3 * se
    assert c < a
    # where it still fails: on the 4 m line the banana holds more than C's ellipse
    r4 = runs["straight4"].metrics
    assert r4["accuracy_expcoords_coverage_xy_98_89"] > r4["accuracy_unscented_coverage_xy_98_89"]


# --- Method C in the studies, and its step dependence ----------------------------------------------


def test_c_along_track_excess_is_proportional_to_the_step() -> None:
    """C's mean and across-track spread hardly depend on Δt; its along-track excess over A's does, ∝ Δt.

    Each step re-forms a Gaussian, which cannot carry the correlation of the along error with θ²:
    every step adds Var(Δs cos θ) ≈ Δs² σ_θ⁴ afresh, and Σ Δs² f(s) = Δs ∫ f ds — proportional to
    Δs = speed·Δt. From Δt = 0.1 to 0.02 s the excess must shrink 5-fold (to the O(Δs) corrections
    of that sum: 1 % here), while the mean and σ_across move by less than 0.2 %.
    """
    out = {}
    for dt in (0.1, 0.02):
        t = trajectories.straight(20.0, dt=dt, track=0.2)
        C, A = unscented.propagate(t, 5e-4, 5e-4), covariance.propagate(t, 5e-4, 5e-4)
        out[dt] = (C.covs[-1, 0, 0] - A.covs[-1, 0, 0], C.covs[-1, 1, 1], C.poses[-1, 0])
    assert_allclose(out[0.1][0] / out[0.02][0], 5.0, rtol=0.01)
    assert_allclose(out[0.1][1:], out[0.02][1:], rtol=2e-3)


def test_growth_laws_and_accuracy_case_carry_method_c() -> None:
    from pose_uncertainty.analysis import studies as st

    t = trajectories.straight(8.0, dt=0.05, track=0.2)
    g = st.growth_laws(t, 5e-4, 5e-4, n_points=8)
    # the heading is linear in the wheel travels: C's σ_θ is A's (closed form √(2ks)/b) exactly
    assert_allclose(g["method_c"]["sigma_theta"], g["method_a"]["sigma_theta"], rtol=1e-12)
    assert_allclose(g["method_c"]["sigma_theta"], np.sqrt(2 * 5e-4 * np.asarray(g["distance"])) / 0.2, rtol=1e-9)
    # the UT's across-track spread stays below A's linearisation as σ_θ grows (E[cos θ] < 1)
    assert np.all(np.asarray(g["method_c"]["sigma_across"][1:]) < np.asarray(g["method_a"]["sigma_across"][1:]))
    assert set(st.growth_laws_study(trajectory={"name": "straight", "length": 4.0, "dt": 0.1, "track": 0.2},
                               n_particles=200)) == {"method_a", "method_c", "monte_carlo"}  # fmt: skip
    row = st.accuracy_case({"name": "straight", "length": 4.0, "dt": 0.05, "track": 0.2}, n=500, n_bins=20,
                           n_threshold=5000, seed=1)  # fmt: skip
    tt = trajectories.straight(4.0, dt=0.05, track=0.2)
    C = unscented.propagate(tt, 5e-4, 5e-4)
    s = sample_end_poses(tt, 5e-4, 5e-4, 500, np.random.default_rng(1))
    assert row["unscented"] == accuracy.evaluate_cartesian(s, C.poses[-1], C.covs[-1], Grid.covering(s[:, :2], 20))
