"""Localization runs: configuration, execution, log → replay → verify, tables and figures from the log."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from scipy import stats as sstats

from pose_uncertainty.analysis import measures
from pose_uncertainty.cli import main
from pose_uncertainty.core import stats
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.core.schema import load_schema
from pose_uncertainty.core.table_io import read_table
from pose_uncertainty.core.validation import parse_numbers
from pose_uncertainty.experiments import sweep
from pose_uncertainty.experiments.localization import (
    LocalizationConfig,
    execute_localization,
    expand_localization,
)
from pose_uncertainty.localization import ekf as E
from pose_uncertainty.localization import histogram as HF
from pose_uncertainty.localization import particle as PF
from pose_uncertainty.localization import resampling as R
from pose_uncertainty.localization import sensors as S
from pose_uncertainty.localization import simulate as SIM
from pose_uncertainty.localization.evaluation import mass_region_flags, nees, pose_errors
from pose_uncertainty.localization.motion import Motion, sample_motion, wheel_draws
from pose_uncertainty.localization.world import World, sample_free_poses
from pose_uncertainty.methods import maps as M
from pose_uncertainty.pipeline.tables import collect_table
from pose_uncertainty.present import localization as LF
from pose_uncertainty.records import localization as LL
from pose_uncertainty.records.reproducibility import MISMATCH
from pose_uncertainty.records.run import PartialLogWarning, RunLogError, open_run, verify_run

REPO = Path(__file__).resolve().parents[1]
BOX = [[0.0, 0.0, 6.0, 0.0], [6.0, 0.0, 6.0, 5.0], [6.0, 5.0, 0.0, 5.0], [0.0, 5.0, 0.0, 0.0]]
CONFIG = {
    "kind": "localization",
    "name": "tiny",
    "seed": 3,
    "repeat": 2,
    "world": {"name": "box", "walls": {"segments": BOX, "resolution": 0.25},
              "landmarks": [{"id": 0, "x": 0.5, "y": 0.5}, {"id": 1, "x": 5.5, "y": 0.7},
                            {"id": 2, "x": 3.0, "y": 4.5}, {"id": 7, "x": 0.6, "y": 4.2}]},
    "trajectory": {"name": "tour", "segments": [["line", 2.0], ["arc", 1.0, 1.5707963267948966]],
                   "speed": 0.5, "dt": 0.2, "start": [1.0, 1.0, 0.0]},
    "truth": {"k_r": "1e-3", "k_l": 1e-3},  # as YAML 1.1 reads 1e-3: a string
    "sensors": {"landmarks": {"range_std": 0.1, "bearing_std": 0.05, "max_range": 6.0, "period": 0.4}},
    "filters": {"ekf": {}, "histogram": {"resolution": 0.25, "ntheta": 18}, "particle": {"n_particles": 300}},
    "log": {"particles_every": 2, "max_particles_logged": 50, "grid_every": 3},
}  # fmt: skip


@pytest.fixture(scope="module")
def result() -> LL.LocalizationResult:
    return execute_localization(LocalizationConfig.from_dict(CONFIG))


@pytest.fixture(scope="module")
def logged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("loc")
    cfg = d / "config.yaml"
    cfg.write_text(yaml.safe_dump(CONFIG), encoding="utf-8")
    out = d / "run.mcap"
    assert main(["run", str(cfg), "-o", str(out)]) == 0
    return out


# --- configuration -------------------------------------------------------------------------------


def _mutated(path: str, value: object) -> dict:
    cfg = json.loads(json.dumps(CONFIG))
    *head, last = path.split(".")
    node = cfg
    for key in head:
        node = node.setdefault(key, {})
    node[last] = value
    return cfg


@pytest.mark.parametrize(
    ("path", "value", "pattern"),
    [
        ("filters.particle.n_particles", 0, r"'filters\.particle\.n_particles' must be an integer in \[1, 1000000000\], got 0"),
        ("sensors.landmarks.range_std", -0.1, r"'sensors\.landmarks\.range_std' must be > 0 \(allowed: \(0, inf\)\), got -0\.1"),
        ("truth.regime", "sometimes", r"'truth\.regime' must be one of 'per_step', 'per_run', got 'sometimes'"),
        ("filters.particle.n_partcles", 10, r"unknown config key\(s\) 'filters\.particle\.n_partcles' \(allowed: .*n_particles"),
        ("success.head_tol", 4.0, r"'success\.head_tol' must be in \(0, 3\.14159\], got 4\.0"),
        ("repeat", 0, r"'repeat' must be an integer in \[1, 10000\], got 0"),
        ("filters.ekf.sensor", "beams", r"'filters\.ekf\.sensor' must be one of 'landmarks', got 'beams'"),
        ("filters.histogram.motion", {"model": "wheels"},
         r"'filters\.histogram\.motion\.model' must be one of 'velocity', 'odometry', got 'wheels'"),
        ("world.walls.resolution", 0, r"world key 'walls\.resolution' has bad value 0; allowed: > 0 and <= 10"),
        ("world.file", "no/such/world.yaml", r"'world\.file': no/such/world\.yaml: no such file"),
        ("scenario.kind", "kidnapped", r"'scenario\.kidnap_pose' is missing"),
        ("scenario.kidnap_step", 3, r"'scenario\.kidnap_step' must be null unless scenario\.kind is 'kidnapped', got 3"),
        ("sensors.landmarks.period", "soon", r"'sensors\.landmarks\.period' must be a real number written like 0\.0005, 5\.0e-4 or 5e-4, got 'soon'"),
        ("world.random_landmarks", {"count": -1}, r"'world\.random_landmarks\.count' must be an integer in \[0, 100000\], got -1"),
        ("filters.particle.resampling", "roulette", r"'filters\.particle\.resampling' must be one of .*'systematic'"),
    ],
)  # fmt: skip
def test_bad_config_is_one_line_naming_key_value_and_range(path: str, value: object, pattern: str) -> None:
    with pytest.raises(ValueError, match=pattern) as err:
        LocalizationConfig.from_dict(_mutated(path, value))
    assert "\n" not in str(err.value)


def test_config_needs_a_filter_and_a_sensor() -> None:
    with pytest.raises(ValueError, match=r"'filters' must configure at least one filter"):
        LocalizationConfig.from_dict(_mutated("filters", {}))
    with pytest.raises(ValueError, match=r"'sensors' must configure landmarks or beams"):
        LocalizationConfig.from_dict(_mutated("sensors", {"landmarks": None}))


def test_numbers_as_yaml_strings_and_defaults_round_trip() -> None:
    cfg = LocalizationConfig.from_dict(CONFIG)
    assert cfg.truth["k_r"] == 1e-3
    assert parse_numbers({"a": ["1e-3", "x", "2"], "b": "-.5E+2"}) == {"a": [1e-3, "x", 2.0], "b": -50.0}
    # every parameter is in to_dict and the logged form rebuilds the same configuration
    full = cfg.to_dict()
    assert LocalizationConfig.from_dict(full) == cfg
    # each filter's motion defaults to the truth's own model
    assert full["filters"]["ekf"]["motion"] == {"model": "wheels", "k_r": 1e-3, "k_l": 1e-3, "noise": "normal",
                                                "scaling": "squared", "alphas": None}  # fmt: skip
    hm = full["filters"]["histogram"]["motion"]
    assert hm["model"] == "velocity"
    assert hm["scaling"] == "abs"
    assert hm["alphas"][0] == pytest.approx(1e-3 / (2 * 0.2))  # α1 = k̄/(2Δt)


def test_world_file_is_read_in_and_logged_inline(tmp_path: Path) -> None:
    world = {"name": "w", "walls": {"segments": BOX, "resolution": 0.25}, "landmarks": [{"id": 3, "x": 1, "y": 2}]}
    f = tmp_path / "w.yaml"
    f.write_text(yaml.safe_dump(world), encoding="utf-8")
    cfg = LocalizationConfig.from_dict({**CONFIG, "world": {"file": str(f), "random_landmarks": {"count": 5, "seed": 2}}})
    assert cfg.world["source"] == str(f)
    assert cfg.world["landmarks"] == [{"id": 3, "x": 1, "y": 2}]
    assert "file" not in cfg.world
    w = cfg.build_world()
    assert w.n_landmarks == 6
    assert w.landmark_ids.tolist() == [3, 4, 5, 6, 7, 8]
    assert not w.grid.is_occupied(w.landmarks).any()  # random landmarks avoid the walls
    f.write_text("landmarks: []\nbounds: [0, 1, 0, 1]\n", encoding="utf-8")  # the file changes: the log does not
    assert LocalizationConfig.from_dict(cfg.to_dict()) == cfg


def test_shipped_localization_sets_expand() -> None:
    schema = load_schema(REPO / "workflow/schemas/config.schema.yaml")
    for name in ("config.yaml", "quick.yaml"):
        cfg = yaml.safe_load((REPO / "config" / name).read_text(encoding="utf-8"))
        sets = expand_localization(sweep.validate_config(cfg, schema))
        assert {"LOC_room", "LOC_global", "LOC_kidnapped"} <= set(sets), name
        for runs in sets.values():
            assert len({r.id for r in runs}) == len(runs)
            for r in runs:
                assert LocalizationConfig.from_dict(r.config).to_dict() == r.config
    bad = {"seed": 1, "localization": {"sets": {"S": {"base": {**CONFIG, "repeat": 0}}}}}
    with pytest.raises(sweep.ConfigError, match=r"localization\.sets\.S, run 'run': config key 'repeat'"):
        expand_localization(bad)


# --- execution: the measures against independent routes -----------------------------------------


def test_measures_equal_an_independent_recomputation(result: LL.LocalizationResult) -> None:
    """The EKF's logged measures against the same filter run separately on the same seeded runs."""
    cfg = result.config
    traj, world = cfg.build_trajectory(), cfg.build_world()
    sen = cfg.landmark_sensor()
    runs = [SIM.simulate(traj, world, np.random.default_rng([cfg.seed, 0, r]), k_r=1e-3, k_l=1e-3,
                         landmark_sensor=sen, truth="commanded") for r in range(cfg.repeat)]  # fmt: skip
    start = cfg.start(traj)
    ekfs = [E.run_ekf(run, world, sen, E.EKFConfig(cfg.motion("ekf")), start) for run in runs]
    np.testing.assert_array_equal(result.filters["ekf"].mean, ekfs[0].mean)
    np.testing.assert_array_equal(result.true_poses, runs[0].true_poses)
    pe = np.concatenate([pose_errors(e.mean, run.true_poses)[0] for e, run in zip(ekfs, runs, strict=True)])
    m = result.metrics
    assert m["loc_ekf_rms_position_error"] == pytest.approx(math.sqrt(np.mean(pe**2)), rel=1e-12)
    ne = np.stack([nees(e.mean, e.cov, run.true_poses) for e, run in zip(ekfs, runs, strict=True)])
    np.testing.assert_allclose(result.filters["ekf"].series["nees_avg"], ne.mean(axis=0), rtol=1e-12)
    lo, hi = sstats.chi2.ppf([0.025, 0.975], 3 * cfg.repeat) / cfg.repeat
    assert (m["loc_nees_band_low"], m["loc_nees_band_high"]) == pytest.approx((lo, hi), rel=1e-12)
    inside = np.concatenate([e.in_region for e in ekfs]).mean(axis=0)
    assert [m[f"loc_ekf_coverage_{k}"] for k in ("1s", "2s", "3s")] == pytest.approx(inside.tolist(), rel=1e-12)
    dr = np.concatenate([pose_errors(run.odometry, run.true_poses)[0] for run in runs])
    assert m["loc_dead_reckoning_rms_position_error"] == pytest.approx(math.sqrt(np.mean(dr**2)), rel=1e-12)
    # every logged number has a unit and a definition
    for key in m:
        unit, definition = measures.describe(key)
        assert unit
        assert definition
        assert result.metric_units[key] == unit


def test_filters_localize_better_than_dead_reckoning(result: LL.LocalizationResult) -> None:
    m = result.metrics
    for f in ("ekf", "histogram", "particle"):
        assert m[f"loc_{f}_rms_position_error"] < 0.5 * m["loc_dead_reckoning_rms_position_error"], f
        assert m[f"loc_{f}_success_rate"] == 1.0, f


def test_wilson_interval_known_values() -> None:
    # 8 of 10 at 95 %: (0.4902, 0.9433) (Wilson 1927; e.g. Newcombe 1998, Table I); 0 of n starts at 0
    assert stats.wilson_interval(8, 10) == pytest.approx((0.49016, 0.94332), abs=1e-5)
    lo, hi = stats.wilson_interval(0, 4)
    assert lo == 0.0
    assert hi == pytest.approx(1.96**2 / (4 + 1.96**2), rel=1e-3)
    with pytest.raises(ValueError, match="successes must be in"):
        stats.wilson_interval(5, 4)


# --- the log ---------------------------------------------------------------------------------------


def test_log_is_lossless_and_byte_identical(result: LL.LocalizationResult, logged: Path, tmp_path: Path) -> None:
    log = open_run(logged)
    assert isinstance(log, LL.LocalizationLog)
    assert [d for d in LL.compare_localization(log, result) if not d.startswith("note: ")] == []
    assert log.metric_definitions == result.metric_definitions
    # the same configuration and seed give the same bytes (no timings inside)
    again = LL.write_localization(tmp_path / "again.mcap", execute_localization(LocalizationConfig.from_dict(CONFIG)))
    assert again.read_bytes() == logged.read_bytes()
    other = execute_localization(LocalizationConfig.from_dict({**CONFIG, "seed": 4}))
    assert LL.localization_log_bytes(other) != logged.read_bytes()


def test_foxglove_topics(result: LL.LocalizationResult, logged: Path) -> None:
    K = result.n_steps + 1
    counts: dict[str, int] = {}
    schemas: dict[str, str] = {}
    with open(logged, "rb") as fh:
        for schema, channel, _msg in make_reader(fh).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas[channel.topic] = schema.name
    per_step = ["/tf", "/truth/pose", "/measurements/landmarks"] + [
        f"/filters/{f}/{t}" for f in ("ekf", "histogram", "particle") for t in ("pose", "state", "ellipse")]
    for topic in per_step:
        assert counts[topic] == K, topic
    particle_steps = sorted({*range(0, K, 2), K - 1})
    grid_steps = sorted({*range(0, K, 3), K - 1})
    assert counts["/filters/particle/particles"] == len(particle_steps)
    assert counts["/filters/histogram/grid"] == len(grid_steps)
    assert sorted(result.filters["particle"].particles) == particle_steps
    assert result.filters["particle"].particles[0].shape == (50, 4)
    assert schemas["/world"] == "foxglove.SceneUpdate"
    assert schemas["/world/occupancy"] == "foxglove.Grid"
    assert schemas["/filters/particle/particles"] == "foxglove.PointCloud"
    assert schemas["/filters/ekf/state"] == "pose_uncertainty.PoseCovariance2D"
    assert schemas["/localization/data"] == schemas["/filters/ekf/series"] == "pose_uncertainty.NamedArrays"
    for topic in ("/world", "/truth/path", "/odometry/path", "/localization/data", "/metrics"):
        assert counts[topic] == 1, topic


@pytest.mark.slow
def test_replay_verify_ok_and_tampered(logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(logged), "--verify", "--at", "3.0"]) == 0
    out = capsys.readouterr().out
    assert "verify: identical" in out
    assert "localization log" in out
    assert "state at step 15" in out
    assert "particle: mean" in out
    res = execute_localization(LocalizationConfig.from_dict(CONFIG))
    tr_ = res.filters["ekf"]
    mean = tr_.mean.copy()
    mean[5, 0] += 1e-9
    bad = LL.write_localization(tmp_path / "tampered.mcap",
                                dataclasses.replace(res, filters={**res.filters, "ekf": dataclasses.replace(tr_, mean=mean)}))  # fmt: skip
    assert main(["replay", str(bad), "--verify"]) == 1
    out = capsys.readouterr().out
    assert "MISMATCH /filters/ekf/" in out
    assert "[5]" in out
    assert "verify: MISMATCH" in out
    # the same data with another drawing of the ellipses: only the bytes tell
    original = LL._ELLIPSE_POINTS
    LL._ELLIPSE_POINTS = original + 2
    try:
        drawn = LL.write_localization(tmp_path / "display.mcap", res)
    finally:
        LL._ELLIPSE_POINTS = original
    drawn_cmp = verify_run(open_run(drawn))
    assert drawn_cmp.status == MISMATCH
    assert drawn_cmp.mismatches, drawn_cmp.mismatches
    assert all("/ellipse" in line for line in drawn_cmp.mismatches), drawn_cmp.mismatches


def test_truncated_log_is_refused_and_recovered(logged: Path, tmp_path: Path) -> None:
    data = logged.read_bytes()
    with open(logged, "rb") as fh:
        last = make_reader(fh).get_summary().chunk_indexes[-1]
    part = tmp_path / "part.mcap"  # cut inside the last chunk: the earlier ones are whole
    part.write_bytes(data[: last.chunk_start_offset + last.chunk_length // 2])
    with pytest.raises(RunLogError, match="truncated"):
        open_run(part)
    with pytest.warns(PartialLogWarning, match="partial log"):
        log = open_run(part, recover=True)
    assert log.partial
    assert 0 < log.filters["ekf"].mean.shape[0] < log.times.size
    np.testing.assert_array_equal(log.filters["ekf"].mean, open_run(logged).filters["ekf"].mean[: log.filters["ekf"].mean.shape[0]])
    assert verify_run(log).mismatches == ["the log is partial; a partial log cannot be verified"]


def test_table_columns_equal_the_logged_metrics(logged: Path, tmp_path: Path) -> None:
    timings = tmp_path / "run.timings.json"
    timings.write_text(json.dumps({"ekf_step_s": 0.00125, "particle_step_s": 0.5}), encoding="utf-8")
    rows = read_table(collect_table("LOC", [logged], [timings], tmp_path / "t.csv"))
    log = open_run(logged)
    (row,) = rows
    for key, value in log.metrics.items():
        assert row[key] == value or (math.isnan(value) and row[key] is None), key
    assert row["param.filters.particle.n_particles"] == 300
    assert row["param.truth.k_r"] == 1e-3
    assert row["param.scenario.kind"] == "tracking"
    assert row["time_ekf_step"] == 0.00125
    assert row["run"] == "tiny"
    assert row["n_steps"] == log.n_steps


@pytest.mark.slow
def test_figures_drawn_from_the_log_are_identical(result: LL.LocalizationResult, logged: Path, tmp_path: Path) -> None:
    kinds = list(LF.RUN_FIGURES)
    a = LF.render_localization_run_figures(logged, kinds, [tmp_path / f"a_{k}.png" for k in kinds])
    b = LF.render_localization_run_figures(logged, kinds, [tmp_path / f"b_{k}.png" for k in kinds])
    c = LF.render_localization_figures(result, tmp_path / "c", ["png"])  # from the result itself
    for pa, pb in zip(a, b, strict=True):
        assert pa.read_bytes() == pb.read_bytes()
    for k, pa in zip(kinds, a, strict=True):
        assert pa.read_bytes() == (tmp_path / "c" / f"{k}.png").read_bytes()
    assert len(c) == 3
    timings = tmp_path / "t.json"
    timings.write_text(json.dumps({"ekf_step_s": 1e-3, "histogram_step_s": 5e-3, "particle_step_s": 2e-3}))
    for kind in LF.SET_FIGURES:
        p1 = LF.render_localization_set_figure(kind, [logged], [timings], tmp_path / f"s1_{kind}.png")
        p2 = LF.render_localization_set_figure(kind, [logged], [timings], tmp_path / f"s2_{kind}.png")
        assert p1.read_bytes() == p2.read_bytes()


def test_run_figures_keep_long_titles_inside() -> None:
    """A single-filter run (the errors figure is 4.2 in wide) with a long name, as LOC_resampling's
    "linear_time_always": every title and the errors suptitle are wrapped onto lines inside the figure,
    above the axes (the suptitle above the column titles)."""
    name = "multinomial_with_the_longest_name_always"
    res = execute_localization(LocalizationConfig.from_dict({**CONFIG, "name": name, "filters": {"ekf": {}}}))
    for kind, fig in LF.localization_figure_set(res).items():
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        if kind == "errors":
            assert fig._suptitle is not None
            text, below = fig._suptitle, [ax.title.get_window_extent(renderer) for ax in fig.axes if ax.get_title()]
        else:
            text, below = fig.axes[0].title, [fig.axes[0].get_window_extent(renderer)]
        assert text.get_text().replace("\n", " ").startswith(name), kind  # the information is kept
        box = text.get_window_extent(renderer)
        assert fig.bbox.contains(box.x0, box.y0), kind
        assert fig.bbox.contains(box.x1, box.y1), kind
        assert box.y0 >= max(b.y1 for b in below), kind


# --- the pieces it is made of --------------------------------------------------------------------


def test_tour_is_its_segments() -> None:
    a = tr.tour([["line", 2.0], ["arc", 1.0, 1.5], ["turn", -0.5]], laps=2, speed=0.5, dt=0.1)
    segs = [tr.Line(2.0), tr.Arc(1.0, 1.5), tr.Turn(-0.5)] * 2
    b = tr.from_segments(segs, speed=0.5, dt=0.1)
    np.testing.assert_array_equal(a.ds_r, b.ds_r)
    np.testing.assert_array_equal(a.ds_l, b.ds_l)
    with pytest.raises(ValueError, match=r"segments\[1\] must be \[kind, numbers...\]"):
        tr.tour([["line", 1.0], ["spiral", 2.0]])
    with pytest.raises(ValueError, match=r"segments\[0\] \(arc\) must have 2 number"):
        tr.tour([["arc", 1.0]])


def test_commanded_truth_and_noisy_encoders() -> None:
    # the truth is the commanded path; the encoders' errors are N(0, k|Δs|) per step and wheel:
    # standardised, their mean is within 5/√N of 0 and their variance within 5√(2/N) of 1
    traj = tr.tour([["line", 5.0], ["arc", 1.0, 3.0]], speed=0.5, dt=0.05)
    world = World(np.array([[1.0, 1.0]]), np.arange(1))
    run = SIM.simulate(traj, world, np.random.default_rng(5), k_r=2e-3, k_l=5e-4, truth="commanded")
    np.testing.assert_array_equal(run.true_poses, traj.poses)
    e = np.concatenate([(run.ds_r - traj.ds_r) / np.sqrt(2e-3 * np.abs(traj.ds_r)),
                        (run.ds_l - traj.ds_l) / np.sqrt(5e-4 * np.abs(traj.ds_l))])  # fmt: skip
    assert abs(e.mean()) <= 5 / math.sqrt(e.size)
    assert abs(e.var() - 1) <= 5 * math.sqrt(2 / e.size)
    assert not np.allclose(run.odometry, run.true_poses)
    # per run: one scale error per wheel, the same on every step
    per_run = SIM.simulate(traj, world, np.random.default_rng(5), k_r=2e-3, k_l=5e-4, truth="commanded", regime="per_run")
    ratio = per_run.ds_r / traj.ds_r
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-12)
    with pytest.raises(ValueError, match="truth must be one of 'drifts', 'commanded'"):
        SIM.simulate(traj, world, np.random.default_rng(5), truth="sideways")


# --- the faster kernels: the same numbers by a second route ----------------------------------------


def test_grid_landmark_likelihood_equals_the_scalar_formula(rng: np.random.Generator) -> None:
    world = World(np.array([[0.3, 0.9], [-0.8, 0.2]]), np.arange(2), bounds=(-0.5, 0.5, -0.4, 0.4))
    grid = HF.pose_grid_for(world, 0.1, 12)
    sen = S.RangeBearingSensor(range_std=0.2, bearing_std=0.1)
    z = S.landmark_h(np.array([0.05, -0.1, 2.5]), world.landmarks) + rng.normal(0, 0.05, (2, 2))
    got = HF.landmark_log_likelihood_grid(grid, z, world.landmarks, sen)
    ref = np.zeros(grid.shape)
    for i, x in enumerate(grid.x):
        for j, y in enumerate(grid.y):
            for k, th in enumerate(grid.theta):
                for (r, phi), (mx, my) in zip(z, world.landmarks, strict=True):
                    e = (phi - math.atan2(my - y, mx - x) + th + math.pi) % (2 * math.pi) - math.pi
                    ref[i, j, k] += (-0.5 * ((r - math.hypot(mx - x, my - y)) / 0.2) ** 2 - 0.5 * (e / 0.1) ** 2
                                     - math.log(2 * math.pi * 0.2 * 0.1))  # fmt: skip
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-10)


def test_landmark_likelihood_in_blocks_and_threads_is_the_whole(rng: np.random.Generator) -> None:
    lm = rng.uniform(-5, 5, (6, 2))
    z = S.landmark_h(np.array([0.2, -0.4, 1.0]), lm) + rng.normal(0, 0.05, (6, 2))
    P = np.column_stack([rng.normal(0, 1, 5000), rng.normal(0, 1, 5000), rng.uniform(-7, 7, 5000)])
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05)
    # the same blocks on one or two threads: the same bits; another cut into blocks: the same
    # numbers up to the rounding of the arithmetic (the matrix products' kernels treat a block's
    # last rows apart), ~1e-15 relative in float64 and ~1e-7 in float32
    for dtype, rtol in (("float64", 1e-13), ("float32", 1e-6)):
        whole = S.landmark_log_likelihood(P, z, lm, sen, dtype=dtype, chunk=5000)
        lik = S.LandmarkLikelihood(z, lm, sen, dtype)
        np.testing.assert_array_equal(lik(P), whole)
        np.testing.assert_allclose(np.concatenate([lik(P[:1234]), lik(P[1234:])]), whole, rtol=rtol)
        np.testing.assert_array_equal(S.landmark_log_likelihood(P, z, lm, sen, dtype=dtype, chunk=700, workers=2),
                                      S.landmark_log_likelihood(P, z, lm, sen, dtype=dtype, chunk=700))  # fmt: skip
    assert [b - a for a, b in S.chunks(20_000)] == [6667, 6667, 6666]


@pytest.mark.parametrize(
    ("dtype", "motion"),
    [("float32", Motion(k_r=1e-3, k_l=1e-3)),  # second thread: the next step's wheel draws, blocks on one
     ("float64", Motion(k_r=1e-3, k_l=1e-3)),  # blocks on both threads, wheel draws during the correction
     ("float64", Motion(model="velocity"))],  # blocks on both threads
)
def test_particle_filter_does_not_depend_on_its_threads(dtype: str, motion: Motion) -> None:
    # 9000 particles: two blocks, each with its own generator; one thread or two, the same run
    world = World(np.array([[2.0, 1.0], [0.0, 3.0], [4.0, -1.0]]), np.arange(3))
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, period=0.3)
    run = SIM.simulate(tr.straight(1.0, speed=0.5, dt=0.1), world, np.random.default_rng(1), landmark_sensor=sen)
    out = []
    for workers in (1, 2):
        cfg = PF.ParticleFilterConfig(n_particles=9000, motion=motion, dtype=dtype, workers=workers)
        out.append(PF.run_particle(run, world, sen, np.random.default_rng(2), cfg, keep=[run.n_steps]))
    np.testing.assert_array_equal(out[0].mean, out[1].mean)
    np.testing.assert_array_equal(out[0].snapshots[run.n_steps]["particles"], out[1].snapshots[run.n_steps]["particles"])


def test_resampling_by_copies_in_blocks_is_the_selection(rng: np.random.Generator) -> None:
    # pf_resample (copies per particle from the pointers' strata, written block by block, on one or
    # two threads; the systematic pointers never built) against the seed's selection on the same
    # draws: particles[select(q, pointers)], then the injected ones. 20 001 particles: three blocks.
    world = World(np.zeros((0, 2)), np.zeros(0, dtype=int), bounds=(0.0, 4.0, 0.0, 3.0))
    n = 20_001
    P = rng.normal(0.0, 1.0, (n, 3))
    w = rng.gamma(0.5, size=n)
    w[rng.random(n) < 0.2] = 0.0
    w /= w.sum()
    for scheme in R.SCHEMES:
        for n_inject in (0, 37):
            g = np.random.default_rng(5)
            T = R.pointers(n - n_inject, g, scheme)
            injected = sample_free_poses(world, n_inject, g) if n_inject else np.zeros((0, 3))
            want = np.vstack([P[R.select(R.cumulative_weights(w), T)], injected])
            for workers in (1, 2):
                got, w_new, res = PF.pf_resample(P, w, np.random.default_rng(5), scheme, 0.5, n_inject, world, workers)
                np.testing.assert_array_equal(got, want)
                assert res
                assert np.all(w_new == 1.0 / n)


def test_motion_and_likelihood_write_into_given_arrays(rng: np.random.Generator) -> None:
    # the out= forms the particle filter uses are the allocating ones, bit for bit
    world = World(np.array([[2.0, 1.0], [0.0, 3.0], [4.0, -1.0]]), np.arange(3))
    sen = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05)
    run = SIM.simulate(tr.straight(1.0, speed=0.5, dt=0.1), world, np.random.default_rng(1), landmark_sensor=sen)
    P = rng.normal(0.0, 0.1, (500, 3))
    models = (Motion(k_r=1e-3, k_l=2e-3), Motion(model="velocity"), Motion(model="odometry"))
    for motion in models:
        for dtype in ("float64", "float32"):
            out = np.full_like(P, np.nan)
            got = sample_motion(P, motion, run, 3, np.random.default_rng(4), dtype, out=out)
            assert got is out
            np.testing.assert_array_equal(out, sample_motion(P, motion, run, 3, np.random.default_rng(4), dtype))
    # the wheel draws taken beforehand (as a second thread draws them ahead) move the particles alike
    for dtype in ("float64", "float32"):
        draws = wheel_draws(np.random.default_rng(4), 500)
        np.testing.assert_array_equal(sample_motion(P, models[0], run, 3, np.random.default_rng(99), dtype, draws=draws),
                                      sample_motion(P, models[0], run, 3, np.random.default_rng(4), dtype))  # fmt: skip
    with pytest.raises(ValueError, match=r"draws must have shape \(2, 500\)"):
        sample_motion(P, models[0], run, 3, np.random.default_rng(4), draws=np.zeros((2, 7)))
    with pytest.raises(ValueError, match="draws are the wheel model's"):
        sample_motion(P, models[1], run, 3, np.random.default_rng(4), draws=np.zeros((2, 500)))
    z, lm = run.landmark_z[4][run.landmark_valid[4]], world.landmarks[run.landmark_valid[4]]
    assert z.shape[0] == 3
    for dtype in ("float64", "float32"):
        lik = S.LandmarkLikelihood(z, lm, sen, dtype)
        out = np.full(500, np.nan)
        lik(P, out)
        np.testing.assert_array_equal(out, lik(P))
        np.testing.assert_array_equal(S.LandmarkLikelihood.trusted(z, lm, sen, dtype)(P), lik(P))
        np.testing.assert_array_equal(lik(P), S.landmark_log_likelihood(P, z, lm, sen, dtype=dtype))


def test_work_run_ahead_runs_once_on_whichever_thread() -> None:
    # run_ahead: the result of one call, whether a pool thread or the caller ran it; run_blocks: every
    # block once, however the caller and the pool thread share them
    calls: list[int] = []
    for _ in range(50):
        finish = S.run_ahead(lambda: calls.append(1) or len(calls), 2)
        assert finish() == len(calls)
    assert len(calls) == 50
    assert S.run_ahead(lambda: 7, 1)() == 7
    seen: list[int] = []
    S.run_blocks(seen.append, 9, 2)
    assert sorted(seen) == list(range(9))


def test_particle_region_flags_from_occupied_cells_equal_the_whole_grid(rng: np.random.Generator) -> None:
    world = World(np.zeros((0, 2)), np.zeros(0, dtype=int), bounds=(0.0, 4.0, 0.0, 3.0))
    h = 0.1
    for trial in range(40):
        spread = 0.3 if trial % 2 else 1.5  # a tight cloud (a box of cells), or one partly off the grid
        P = np.column_stack([rng.normal(2, spread, 400), rng.normal(1.5, spread * 2 / 3, 400), np.zeros(400)])
        w = rng.random(400)
        w /= w.sum()
        truth = np.array([rng.normal(2, 0.4), rng.normal(1.5, 0.3), 0.0])
        nx, ny = 40, 30
        i, j = np.floor((P[:, 0]) / h).astype(int), np.floor(P[:, 1] / h).astype(int)
        ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        hist = np.bincount(i[ok] * ny + j[ok], w[ok], minlength=nx * ny).reshape(nx, ny)
        whole = mass_region_flags(hist, (math.floor(truth[0] / h), math.floor(truth[1] / h)))
        np.testing.assert_array_equal(PF._particle_region_flags(P, w, world, truth, h), whole)


def test_beam_terms_once_give_the_same_probabilities(rng: np.random.Generator) -> None:
    sen = S.BeamSensor(n_beams=4, max_range=5.0, sigma_hit=0.1)
    zs = rng.uniform(0, 5, (30, 4))
    z = np.clip(zs + rng.normal(0, 0.2, zs.shape), 0, 5.0)
    np.testing.assert_array_equal(S.beam_probability(z, zs, sen, S.beam_terms(zs, sen)), S.beam_probability(z, zs, sen))


def test_a_reused_transition_predicts_as_a_fresh_one() -> None:
    g = Grid.square(0.0, 0.0, 24, 20, 0.05, 18)
    b = np.zeros(g.shape)
    b[10:13, 8:11, 3:6] = 1.0
    b /= b.sum()
    args = ("velocity", g, (0.3, 0.2), 0.1, (0.02, 0.0, 0.05, 0.0, 0.0, 0.0))
    t = M.grid_transition(*args)
    first, _ = M.predict_on_grid(b, t)
    assert sorted(t.source_windows) == [3, 4, 5]  # the headings with mass
    second, _ = M.predict_on_grid(first, t)  # windows from the cache, and new ones for new headings
    fresh, _ = M.predict_on_grid(first, M.grid_transition(*args))
    np.testing.assert_array_equal(second, fresh)
    assert len(t.source_windows) > 3
