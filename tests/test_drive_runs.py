"""Runs with a ``drive`` section: the config, the execution, the log, replay and the table.

Runs without one must log what they logged before the drives existed
(:mod:`default_runs`, reference logs written by the code before the drive section, compared
in ``test_reproducibility.py``).
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from pathlib import Path

import default_runs
import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.cli import main
from pose_uncertainty.core import drives as dr
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.schema import load_schema
from pose_uncertainty.core.table_io import read_table
from pose_uncertainty.experiments import sweep
from pose_uncertainty.experiments.drive_config import GEOMETRY
from pose_uncertainty.experiments.run import RunConfig, RunResult, execute
from pose_uncertainty.pipeline import tables
from pose_uncertainty.present import figures
from pose_uncertainty.present.pipeline_figures import drives_figure
from pose_uncertainty.records.run import open_run, write_run

REPO = Path(__file__).resolve().parents[1]

STRAIGHT = {"name": "straight", "length": 4.0, "dt": 0.1, "speed": 1.0, "track": 0.2}
ARC = {"name": "arc", "radius": 1.0, "angle": math.pi / 2, "dt": 0.1, "speed": 1.0, "track": 0.2}


def _config(drive: dict | None, trajectory: dict = STRAIGHT, **extra) -> dict:
    """A run on ``trajectory`` (Monte Carlo clouds every metre on the 4 m straight line)."""
    mc = {"n_particles": 400, "checkpoints": [10, 20, 30] if trajectory is STRAIGHT else []}
    cfg = {"name": "drive_run", "seed": 5, "trajectory": dict(trajectory), "n_ellipses": 4,
           "monte_carlo": mc, **extra}  # fmt: skip
    if drive is not None:
        cfg["drive"] = drive
    return cfg


TRICYCLE = {"type": "tricycle", "wheelbase": 0.2, "max_steering": math.pi / 2,
            "errors": {"steer_var": 0.01}}  # fmt: skip
SKID = {"type": "skid_steer", "chi": 1.5, "errors": {"slip": {"chi_var": 0.01, "x_icr_var": 4e-4}}}


# --- runs without a drive: the same bytes as before ------------------------------------------


# (their logs against the reference logs: tests/test_reproducibility.py)


def test_runs_without_a_drive_keep_their_config_and_units() -> None:
    cfg = RunConfig.from_dict(default_runs.CONFIGS["straight"])
    assert cfg.drive is None
    assert "drive" not in cfg.to_dict()
    assert "drive" not in cfg.units()
    assert RunConfig.from_dict({**default_runs.CONFIGS["straight"], "drive": None}) == cfg


# --- the config section ----------------------------------------------------------------------


@pytest.mark.parametrize("kind", sorted(GEOMETRY))
def test_every_drive_type_round_trips_with_every_default(kind: str) -> None:
    drive = {"type": kind} if kind != "skid_steer" else {"type": kind, "chi": 1.2}
    cfg = RunConfig.from_dict(_config(drive, ARC))
    d = cfg.to_dict()["drive"]
    assert set(d) == {"type", *GEOMETRY[kind], "errors"}
    assert set(d["errors"]) == {"k", "steer_var", "steer_bias", "encoder", "slip"}
    assert RunConfig.from_dict(cfg.to_dict()) == cfg
    assert RunConfig.from_dict(cfg.to_dict()).to_dict() == cfg.to_dict()
    # units of every key the section writes
    units = cfg.units()["drive"]
    assert set(d) <= set(units)
    assert set(d["errors"]) <= set(units["errors"])
    # the geometry defaults are the drive class's (the track is the trajectory's)
    built = cfg.drive.drive(0.2)  # type: ignore[union-attr]
    assert built == dr.make_drive(kind, **{k: (tuple(map(tuple, v)) if k == "wheels" else v)
                                           for k, v in d.items() if k in GEOMETRY[kind] and v is not None},
                                  **({"track": 0.2} if d.get("track", 0) is None else {}))  # fmt: skip


def test_the_encoder_section_is_filled_with_safranek_2022s_values() -> None:
    cfg = RunConfig.from_dict(_config({"type": "omni3", "errors": {"encoder": {"pulses_per_rev": 1000}}}))
    enc = cfg.to_dict()["drive"]["errors"]["encoder"]
    assert enc == {"pulses_per_rev": 1000, "wheel_diameter": 0.065, "integration_time": 0.01,
                   "surface_rel_std": 0.01, "additive_std": 0.01, "quantisation": True}  # fmt: skip


@pytest.mark.parametrize(
    ("drive", "pattern"),
    [
        ({"type": "tricycle", "wheelbase": 0.0}, r"'drive\.wheelbase' must be > 0 \(allowed: \(0, inf\)\), got 0\.0"),
        ({"type": "tricycle", "max_steering": 2.0},
         r"'drive\.max_steering' must be in \(0, π/2\] rad \(allowed: steering up to ±90°.*got 2\.0"),
        ({"type": "ackermann", "max_steering": -0.1}, r"'drive\.max_steering' must be in \(0, π/2\].*got -0\.1"),
        ({"type": "omni3", "radius": -0.15}, r"'drive\.radius' must be > 0 \(allowed: \(0, inf\)\), got -0\.15"),
        ({"type": "bicycle"}, r"'drive\.type' must be one of 'differential', 'skid_steer'.*got 'bicycle'"),
        ({"type": "differential", "wheelbase": 0.3},
         r"'drive\.wheelbase' does not apply to a differential drive \(allowed for differential: type, track, errors\)"),
        ({"type": "ackermann", "wheelbase": 0.1, "track": 0.5, "max_steering": 1.2},
         r"'drive' \(ackermann\): max_steering=1\.2 rad turns the inner wheel beyond 90°"),
        ({"type": "mdof", "wheels": [[0.1, 0.1]]}, r"'drive\.wheels' must be a list of n >= 2 wheel positions"),
        ({"type": "differential", "errors": {"steer_var": 0.01}},
         r"'drive\.errors\.steer_var' must be 0: the differential drive has no steering angle, got 0\.01"),
        ({"type": "tricycle", "errors": {"slip": {"chi_var": 0.1}}},
         r"'drive\.errors\.slip' must be null: slip applies to a skid_steer drive, not tricycle"),
        ({"type": "omni3", "errors": {"k": [1e-4, 2e-4]}},
         r"'drive\.errors' \(omni3\): k must be one number or one per channel \['s_a', 's_b', 's_c'\]"),
        ({"type": "tricycle", "errors": {"k": -1e-4}}, r"'drive\.errors\.k' must be >= 0"),
        ({"type": "tricycle", "errors": {"wobble": 1}}, r"unknown config key\(s\) 'drive\.errors\.wobble'"),
    ],
)
def test_bad_drive_config_is_one_line_naming_key_value_and_allowed(drive: dict, pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern) as exc:
        RunConfig.from_dict(_config(drive))
    assert "\n" not in str(exc.value)


def test_k_from_k_r_k_l_goes_to_the_right_and_left_channels() -> None:
    cfg = RunConfig.from_dict(_config({"type": "ackermann"}, ARC, k_r=9e-4, k_l=1e-4))
    drive = cfg.drive.drive(0.2)  # type: ignore[union-attr]
    model = cfg.drive.error_model(drive, cfg.k_r, cfg.k_l)  # type: ignore[union-attr]
    assert drive.channels[:2] == ("ds_left", "ds_right")
    assert model.k == (1e-4, 9e-4)
    with pytest.raises(ValueError, match=r"'drive\.errors\.k' is null and k_r = 0\.0009 != k_l = 0\.0001.*omni3"):
        RunConfig.from_dict(_config({"type": "omni3"}, k_r=9e-4, k_l=1e-4))


@pytest.mark.parametrize(
    ("drive", "trajectory", "pattern"),
    [
        ({"type": "tricycle"}, {"name": "rotation", "angle": 1.0},
         (r"'drive' \(tricycle on trajectory 'rotation'\): steering: the tricycle drive cannot make step 0, "
          r"it needs steering angle 90° beyond max_steering=60°")),
        ({"type": "ackermann"}, {"name": "right_angles"}, r"ackermann on trajectory 'right_angles'.*beyond max_steering"),
        ({"type": "skid_steer", "x_icr": 0.05}, {"name": "arc"}, r"skid_steer drive with x_icr=0\.05 m slides sideways"),
    ],
)
def test_a_path_the_drive_cannot_follow_is_rejected_when_read(drive, trajectory, pattern) -> None:
    with pytest.raises(ValueError, match=pattern) as exc:
        RunConfig.from_dict(_config(drive, trajectory, monte_carlo={"n_particles": 0}))
    assert "\n" not in str(exc.value)


def test_the_schema_checks_the_drive_section() -> None:
    schema = load_schema(REPO / "workflow/schemas/config.schema.yaml")
    base = {"experiment_sets": {"S": {"base": {"trajectory": {"name": "arc"}, "monte_carlo": {"n_particles": 0}},
                                      "sweep": [{"drive": [{"type": "tricycle"}, {"type": "omni3", "radius": 0.1}]}]}}}  # fmt: skip
    full = sweep.validate_config(copy.deepcopy(base), schema)
    runs = sweep.expand_all(full)["S"]
    assert [r.config["drive"]["type"] for r in runs] == ["tricycle", "omni3"]
    assert [r.id for r in runs] == ["tricycle", "omni3-r0.1"]  # the drive type reads bare in a run id
    for drive, pattern in (
        ({"type": "tricycle", "max_steering": 2.0}, r"'experiment_sets\.S\.base\.drive\.max_steering' must be in \(0, π/2\] rad .*1\.5707963267948966 rad\), got 2\.0"),
        ({"type": "bicycle"}, r"'experiment_sets\.S\.base\.drive\.type' must be one of 'differential'.*got 'bicycle'"),
        ({"type": "omni3", "radius": 0}, r"'experiment_sets\.S\.base\.drive\.radius' must be > 0.*got 0"),
        ({"type": "tricycle", "steer": 1}, r"unknown config key\(s\) 'experiment_sets\.S\.base\.drive\.steer'"),
    ):
        bad = copy.deepcopy(base)
        bad["experiment_sets"]["S"]["base"]["drive"] = drive
        del bad["experiment_sets"]["S"]["sweep"]
        with pytest.raises(sweep.ConfigError, match=pattern):
            sweep.validate_config(bad, schema)
    # geometry the schema cannot see is caught by the run config, naming the set and run
    bad = copy.deepcopy(base)
    bad["experiment_sets"]["S"]["base"].update(trajectory={"name": "rotation"}, drive={"type": "tricycle"})
    del bad["experiment_sets"]["S"]["sweep"]
    with pytest.raises(sweep.ConfigError, match=r"experiment_sets\.S, run 'run'.*tricycle on trajectory 'rotation'"):
        sweep.validate_config(bad, schema)


# --- execution -------------------------------------------------------------------------------


@pytest.mark.slow
def test_an_explicit_differential_drive_is_the_default_run() -> None:
    """Two routes to one run: the default (covariance, sampling, expcoords) and the generic drive's."""
    cfg = _config(None, {"name": "s_curve", "radius": 0.5, "dt": 0.05, "speed": 0.5, "track": 0.2},
                  k_r=9e-4, k_l=1e-4, monte_carlo={"n_particles": 300, "checkpoints": [20]})  # fmt: skip
    a = execute(RunConfig.from_dict(cfg))
    b = execute(RunConfig.from_dict({**cfg, "drive": {"type": "differential"}}))
    assert_allclose(b.poses, a.poses, rtol=0, atol=1e-12)
    assert_allclose(b.covs, a.covs, rtol=0, atol=1e-15)
    assert_allclose(b.end_poses, a.end_poses, rtol=0, atol=1e-12)
    assert_allclose(b.checkpoints[20], a.checkpoints[20], rtol=0, atol=1e-12)
    for k, v in a.metrics.items():
        # Method C (C_*, MC_mean_offset_C) is the default wheel-noise model's; a drive run has none
        if k.startswith(("A_", "MC_", "path_", "end_")) and k != "MC_mean_offset_C":
            assert b.metrics[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k
    assert not any(k.startswith("C_") for k in b.metrics)


def test_growth_measures_of_a_straight_are_the_closed_forms() -> None:
    """Differential drive on a straight, n midpoint steps of Δs: σ_along² = k s/2 and σ_θ² = 2k s/b²
    (exponent ½ exactly); σ_across² = 2k s³/(3b²)·(1 − 1/(4n²)) (test_pipeline), whose log-log
    least-squares slope over the growth points — 20 poses evenly spaced in s from 5 % of the path,
    rounded up to a step — is computed here from that closed form."""
    k, b, ds, L = 5e-4, 0.2, 0.1, 4.0
    res = execute(RunConfig.from_dict(_config({"type": "differential"}, monte_carlo={"n_particles": 0})))
    m = res.metrics
    assert m["A_growth_sigma_along"] == pytest.approx(0.5, abs=1e-9)
    assert m["A_growth_sigma_theta"] == pytest.approx(0.5, abs=1e-9)
    n = np.unique(np.ceil(np.round(np.linspace(0.05 * L, L, 20) / ds, 9)).astype(int))
    s = n * ds
    across = np.sqrt(2 * k * s**3 / (3 * b**2) * (1 - 1 / (4 * n**2)))
    assert m["A_growth_sigma_across"] == pytest.approx(np.polyfit(np.log(s), np.log(across), 1)[0], abs=1e-9)
    assert "MC_growth_sigma_along" not in m  # no Monte Carlo, no Monte Carlo growth


@pytest.mark.slow
def test_monte_carlo_growth_agrees_with_method_a_at_small_errors() -> None:
    """At k = 1e-7 m the first order is exact; the exponents then differ by sampling noise only.

    A standard deviation from n draws has relative standard error 1/√(2n) (1.1 % at n = 4000);
    five of them at both ends of s ∈ [1, 4] m move a log-log slope by at most
    2·5/√(2n)/ln 4 = 0.081.
    """
    cfg = _config({"type": "omni3", "radius": 0.1, "errors": {"k": 1e-7}},
                  monte_carlo={"n_particles": 4000, "checkpoints": [10, 20, 30]})  # fmt: skip
    m = execute(RunConfig.from_dict(cfg)).metrics
    for q in ("sigma_along", "sigma_across", "sigma_theta"):
        assert m[f"MC_growth_{q}"] == pytest.approx(m[f"A_growth_{q}"], abs=2 * 5 / math.sqrt(8000) / math.log(4))


def test_a_synchro_drive_has_no_heading_growth_and_no_density_comparison() -> None:
    m = execute(RunConfig.from_dict(_config({"type": "synchro", "errors": {"steer_var": 0.01}}))).metrics
    assert m["A_sigma_theta"] == 0.0
    assert "A_growth_sigma_theta" not in m
    assert m["A_growth_sigma_across"] == pytest.approx(0.5, abs=1e-9)  # white steering: a random walk
    assert not any(k.startswith("accuracy_") for k in m)  # the pose covariance is singular in θ


def test_skid_steer_plain_odometry_turns_chi_times_too_far() -> None:
    """Closed form: on an arc of radius r through θ, the skid-steer's track travels read as a differential
    drive turn χθ on radius r/χ; the true end is r(sin θ, 1 − cos θ)."""
    chi, r, th = 1.5, 1.0, math.pi / 2
    m = execute(RunConfig.from_dict(_config(SKID, ARC, monte_carlo={"n_particles": 0}))).metrics
    true = r * np.array([math.sin(th), 1 - math.cos(th)])
    plain = r / chi * np.array([math.sin(chi * th), 1 - math.cos(chi * th)])
    assert m["drive_plain_odometry_heading_error"] == pytest.approx((chi - 1) * th, abs=1e-12)
    assert m["drive_plain_odometry_max_heading_error"] == pytest.approx((chi - 1) * th, abs=1e-12)
    assert m["drive_plain_odometry_position_error"] == pytest.approx(float(np.hypot(*(plain - true))), abs=1e-12)
    assert m["drive_plain_odometry_mahalanobis"] > 3.0
    straight = execute(RunConfig.from_dict(_config(SKID, monte_carlo={"n_particles": 0}))).metrics
    assert straight["drive_plain_odometry_position_error"] == 0.0
    assert straight["drive_plain_odometry_mahalanobis"] == 0.0


def test_maps_do_not_depend_on_the_drive() -> None:
    one_step = {"name": "arc", "radius": 1.0, "angle": 1.0, "dt": 1.0, "speed": 1.0, "track": 0.2}
    maps = [{"name": "velocity", "model": "velocity", "resolution": 0.05, "n_sampler": 500}]
    a = execute(RunConfig.from_dict(_config(None, one_step, maps=maps, monte_carlo={"n_particles": 0})))
    b = execute(RunConfig.from_dict(_config(TRICYCLE, one_step, maps=maps, monte_carlo={"n_particles": 0})))
    assert a.maps[0].values.tobytes() == b.maps[0].values.tobytes()
    assert a.map_samplers["velocity"].tobytes() == b.map_samplers["velocity"].tobytes()


# --- log, replay, verify, table ----------------------------------------------------------------


@pytest.fixture(scope="module")
def drive_logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[RunResult, Path]]:
    d = tmp_path_factory.mktemp("drive_logs")
    out = {}
    for name, cfg in (("tricycle", _config(TRICYCLE)), ("skid_arc", _config(SKID, ARC, monte_carlo={"n_particles": 400}))):
        res = execute(RunConfig.from_dict({**cfg, "name": name}))
        out[name] = (res, write_run(d / f"{name}.mcap", res))
    return out


@pytest.mark.slow
def test_drive_run_log_replays_and_verifies(drive_logs, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    res, path = drive_logs["tricycle"]
    log = open_run(path)
    assert log.config == res.config
    assert json.loads(log.metadata["config"])["drive"]["type"] == "tricycle"
    assert json.loads(log.metadata["config_units"])["drive"]["wheelbase"] == "m"
    assert main(["replay", str(path), "--verify"]) == 0  # runlog.verify_run: recompute, compare bytes
    out = capsys.readouterr().out
    assert "drive     tricycle drive (wheelbase 0.2 m, max_steering 1.5708 rad)" in out
    assert 'drive.type = "tricycle"' in out
    assert "drive.errors.steer_var = 0.01  [rad^2 (per-step variance of each steering angle)]" in out
    assert "A_growth_sigma_across = " in out
    assert "verify: identical" in out
    # tamper with a drive measure, then with the drive itself: both are caught
    m = dict(res.metrics)
    m["A_growth_sigma_across"] += 1e-13  # within the reproducibility tolerance: not identical
    bad = write_run(tmp_path / "metric.mcap", dataclasses.replace(res, metrics=m))
    assert main(["replay", str(bad), "--verify"]) == 0
    assert "verify: equal within tolerance" in capsys.readouterr().out
    m["A_growth_sigma_across"] += 1e-9  # beyond it
    bad = write_run(tmp_path / "metric.mcap", dataclasses.replace(res, metrics=m))
    assert main(["replay", str(bad), "--verify"]) == 1
    assert "MISMATCH /metrics metric A_growth_sigma_across [1]: 1 of 1 values differ" in capsys.readouterr().out
    other = dataclasses.replace(res.config.drive, geometry={**res.config.drive.geometry, "wheelbase": 0.25})
    bad = write_run(tmp_path / "drive.mcap", dataclasses.replace(res, config=dataclasses.replace(res.config, drive=other)))
    assert main(["replay", str(bad), "--verify"]) == 1
    out = capsys.readouterr().out
    assert "MISMATCH /covariance[" in out
    assert "verify: MISMATCH" in out


@pytest.mark.slow
def test_replayed_figures_name_the_drive(drive_logs, tmp_path: Path) -> None:
    res, path = drive_logs["tricycle"]
    log = open_run(path)
    title = figures.trajectory_figure(log).axes[0].get_title()
    assert title.startswith("tricycle: tricycle drive on straight")
    assert "wheelbase 0.2 m" in title
    assert "(tricycle drive)" in figures.cloud_figure(log).axes[0].get_title()  # type: ignore[union-attr]
    assert main(["replay", str(path), "--figures", str(tmp_path / "r"), "--format", "png"]) == 0
    fresh = figures.render_figures(res, tmp_path / "f", ("png",))
    for p in fresh:
        assert (tmp_path / "r" / p.name).read_bytes() == p.read_bytes(), p.name


def test_table_columns_equal_the_logged_metrics_of_drive_runs(drive_logs, tmp_path: Path) -> None:
    paths = [p for _, p in drive_logs.values()]
    rows = read_table(tables.collect_table("D", paths, None, tmp_path / "D.csv"))
    for row, path in zip(rows, paths, strict=True):
        log = open_run(path)
        for k, v in log.metrics.items():
            assert row[k] == v or (math.isnan(v) and row[k] is None), k
        metric_cols = {k for k in row if not k.startswith(("param.", "provenance.")) and row[k] is not None}
        assert metric_cols - set(log.metrics) == {"set", "run", "seed", "n_steps"}
        assert row["param.drive.type"] == log.config.drive.type  # type: ignore[union-attr]
    assert rows[1]["drive_plain_odometry_heading_error"] == pytest.approx(0.25 * math.pi, abs=1e-12)


def test_drives_figure_draws_the_logged_measures(drive_logs) -> None:
    paths = [p for _, p in drive_logs.values()]
    fig = drives_figure(paths)
    assert [ax.get_title() for ax in fig.axes] == ["straight, 4 m", "arc, 1.57 m"]
    keys = ("A_sigma_along", "A_sigma_across", "MC_sigma_along", "MC_sigma_across")
    for ax, path in zip(fig.axes, paths, strict=True):  # one run per panel here
        drawn = [float(line.get_ydata()[0]) for line in ax.lines]
        assert drawn == [open_run(path).metrics[k] for k in keys]


def test_follow_is_what_the_run_drives() -> None:
    """The logged nominal path is Method A's mean of the drive's measurements from follow()."""
    res = execute(RunConfig.from_dict(_config(TRICYCLE, ARC, monte_carlo={"n_particles": 0})))
    path = dr.follow(dr.Tricycle(0.2, math.pi / 2), tr.from_config(res.config.trajectory))
    assert_allclose(res.poses, path.poses_by("midpoint"), rtol=0, atol=1e-12)


@pytest.mark.slow
def test_report_section_formats_the_logged_drive_measures(drive_logs, tmp_path: Path) -> None:
    """The section "Beyond the differential drive" shows the table's numbers, formatted, and nothing else."""
    from pose_uncertainty.pipeline.claims import write_claims
    from pose_uncertainty.pipeline.summary import summarize_pipeline
    from pose_uncertainty.present.pipeline_figures import render_set_figure
    from pose_uncertainty.present.report import _fmt, build_report

    paths = [p for _, p in drive_logs.values()]
    table = tables.collect_table("D", paths, None, tmp_path / "D.csv")
    fig = render_set_figure("drives", paths, tmp_path / "drives.png", "D")
    runs = [{"id": r.config.name, "log": str(p), "swept": {}, "figures": {}}
            for r, p in drive_logs.values()]  # fmt: skip
    manifest = {"sets": [{"name": "D", "title": "D", "source": "", "description": "", "table": str(table),
                          "figures": {"drives": str(fig)}, "runs": runs}], "config": {}}  # fmt: skip
    html = build_report(
        manifest, {"D": table}, write_claims({"D": table}, tmp_path / "claims.json"),
        summarize_pipeline({"D": table}, [], [], tmp_path / "pipeline.json"), tmp_path / "r.html",
    ).read_text(encoding="utf-8")  # fmt: skip
    section = html[html.index('<h2 id="drives">'):html.index('<h2 id="reproducibility">')]
    tri = drive_logs["tricycle"][0].metrics
    skid = drive_logs["skid_arc"][0].metrics
    for value in (tri["A_sigma_across"], tri["MC_sigma_across"], tri["A_growth_sigma_across"],
                  tri["MC_growth_sigma_along"], skid["drive_plain_odometry_position_error"],
                  skid["drive_plain_odometry_mahalanobis"], skid["drive_plain_odometry_max_heading_error"]):  # fmt: skip
        assert _fmt(value, 3) in section, value
    assert "The skid-steer's odometry is not trustworthy in turns." in section
    assert '<a href="#drives">Beyond the differential drive</a>' in html
    # the drives figure is the set's: drawn once in the report (in set D), the section links to it
    assert section.count('<img src="data:image/webp;base64,') == 0
    assert '<a href="#fig-D-set-drives">the figure of set D</a>' in section
    assert html.count('id="fig-D-set-drives"') == 1


def test_a_track_left_to_the_trajectory_is_checked_with_it() -> None:
    """Ackermann's inner wheel stays within 90° iff tan(max_steering) ≤ 2d/b: with b from the trajectory."""
    arc = {**ARC, "track": 0.05}  # 2d/b = 4 ≥ tan(1.2) = 2.57
    drive = {"type": "ackermann", "wheelbase": 0.1, "max_steering": 1.2}
    cfg = RunConfig.from_dict(_config(drive, arc))
    assert cfg.drive.drive(arc["track"]).track == 0.05  # type: ignore[union-attr]
    with pytest.raises(ValueError, match=r"tan\(max_steering\) <= 2·wheelbase/track = 1,"):
        RunConfig.from_dict(_config(drive, {**ARC, "track": 0.2}))
