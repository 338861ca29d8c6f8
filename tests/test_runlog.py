"""Run logs: write → read is lossless, bytes are reproducible, damage is detected cleanly."""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from pose_uncertainty.core import trajectories
from pose_uncertainty.core.grids import Grid
from pose_uncertainty.experiments.run import RunConfig, RunResult, execute
from pose_uncertainty.methods import covariance
from pose_uncertainty.methods.maps import ProbabilityMap
from pose_uncertainty.present import figures
from pose_uncertainty.records import mcap_io
from pose_uncertainty.records import run as runlog
from pose_uncertainty.records.run import PartialLogWarning, RunLogError, open_run, write_run

CONFIG = {
    "name": "s_curve_test",
    "seed": 11,
    "trajectory": {"name": "s_curve", "radius": 0.5, "speed": 0.5, "dt": 0.02, "track": 0.2},
    "k_r": 9e-4,
    "k_l": 1e-4,
    "n_ellipses": 6,
    "monte_carlo": {"n_particles": 3000, "checkpoints": [40]},
}


def synthetic_map(
    name: str, end: np.ndarray, rng: np.random.Generator, log_volume: bool = False
) -> ProbabilityMap:
    """A ProbabilityMap-like record: a normalised Gaussian bump in (x, y, θ) around ``end``."""
    x = end[0] + np.linspace(-0.5, 0.5, 41)
    y = end[1] + np.linspace(-0.5, 0.5, 37)
    theta = np.linspace(-math.pi, math.pi, 16, endpoint=False)
    X, Y, T = np.meshgrid(x - end[0], y - end[1], theta, indexing="ij")
    values = np.exp(-(X**2 / 0.02 + Y**2 / 0.01 + T**2)) * (1.0 + 0.01 * rng.random(X.shape))
    values *= (1.0 - 1e-3) / values.sum()  # probability mass per cell; 1e-3 lost off the grid
    return ProbabilityMap(
        x, y, theta, values, lost_mass=1e-3, model="velocity", name=name,
        params={"alphas": [0.05] * 6, "log_volume": log_volume}, info={"synthetic": True},
    )  # fmt: skip


@pytest.fixture(scope="module")
def result() -> RunResult:
    res = execute(RunConfig.from_dict(CONFIG))
    rng = np.random.default_rng(5)
    # one map logged in full, one as its θ-marginal and the digest of its full array (the default)
    maps = (synthetic_map("vel", res.poses[-1], rng, log_volume=True), synthetic_map("odo", res.poses[-1], rng))
    return dataclasses.replace(res, maps=maps)


@pytest.fixture(scope="module")
def logfile(result: RunResult, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_run(tmp_path_factory.mktemp("log") / "run.mcap", result, include_timings=True)


def exact(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Bit-for-bit equality (also distinguishes -0.0 from 0.0)."""
    if a is None or b is None:
        return a is None and b is None
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


# --- lossless ------------------------------------------------------------------------------


def test_write_read_is_lossless_for_every_topic(result: RunResult, logfile: Path) -> None:
    log = open_run(logfile)
    assert not log.partial
    assert log.config == result.config
    for name in ("times", "poses", "covs", "end_poses"):
        assert exact(getattr(log, name), getattr(result, name)), name
    assert sorted(log.checkpoints) == sorted(result.checkpoints) == [40]
    assert exact(log.checkpoints[40], result.checkpoints[40])
    assert len(log.maps) == len(result.maps) == 2
    vel, odo = log.maps
    full, marg = result.maps
    # with log_volume, the full (x, y, θ) array, bit for bit
    assert (vel.name, vel.model, vel.lost_mass, vel.params, vel.info) == (
        full.name, full.model, full.lost_mass, full.params, full.info)  # fmt: skip
    for attr in ("x", "y", "theta", "values"):
        assert exact(getattr(vel, attr), getattr(full, attr)), attr
    # by default, the exact θ-marginal and the sha256 of the full array (what --verify compares)
    assert exact(odo.marginal_xy(), marg.marginal_xy())
    assert odo.values.shape == (*marg.values.shape[:2], 1)
    assert odo.info[runlog.VOLUME_SHA256] == runlog.volume_sha256(marg.values)
    assert odo.info["theta_cells"] == marg.theta.size
    assert exact(odo.x, marg.x)
    assert exact(odo.y, marg.y)
    assert log.metrics == result.metrics
    assert log.metric_units == result.metric_units
    assert log.metric_definitions == result.metric_definitions
    assert all(log.metric_definitions[k] for k in log.metrics)  # every logged number is defined
    assert log.timings == result.timings  # written because include_timings=True
    assert log.provenance == result.provenance
    assert log.metadata["seed"] == "11"
    assert log.metadata["environment_lock_sha256"] == result.provenance["environment_lock_sha256"]
    assert runlog.compare_results(log, result) == []


def test_topics_and_counts(result: RunResult, logfile: Path) -> None:
    n = result.n_steps + 1
    log = open_run(logfile)
    expected = {
        "/tf": ("foxglove.FrameTransform", n),
        "/robot/pose": ("foxglove.PoseInFrame", n),
        "/robot/path": ("foxglove.SceneUpdate", 1),
        "/covariance": ("pose_uncertainty.PoseCovariance2D", n),
        "/covariance/ellipse": ("foxglove.SceneUpdate", n),
        "/monte_carlo/end_poses": ("foxglove.PointCloud", 1),
        "/monte_carlo/checkpoints": ("foxglove.PointCloud", 1),
        "/maps/vel/grid": ("foxglove.Grid", 1),
        "/maps/vel/volume": ("pose_uncertainty.ProbabilityMap3D", 1),
        "/maps/odo/grid": ("foxglove.Grid", 1),
        "/maps/odo/volume": ("pose_uncertainty.ProbabilityMap3D", 1),
        "/metrics": ("pose_uncertainty.Metrics", 1),
        "/timings": ("pose_uncertainty.Metrics", 1),
    }
    assert log.topics == dict(sorted(expected.items()))


def _decoded(path: Path, topic: str) -> list:
    """Decode one topic with the mcap reader's own CRC validation and the embedded schema."""
    from mcap_protobuf.decoder import DecoderFactory

    with open(path, "rb") as fh:
        reader = make_reader(fh, validate_crcs=True, decoder_factories=[DecoderFactory()])
        return [m for _, _, _, m in reader.iter_decoded_messages(topics=[topic])]


def test_foxglove_topics_agree_with_the_exact_data(result: RunResult, logfile: Path) -> None:
    """Second route: Foxglove messages decoded by mcap-protobuf from the embedded schemas."""
    n = result.n_steps + 1
    poses = _decoded(logfile, "/robot/pose")
    tfs = _decoded(logfile, "/tf")
    assert len(poses) == len(tfs) == n
    xy = np.array([[p.pose.position.x, p.pose.position.y] for p in poses])
    assert exact(xy, result.poses[:, :2])
    # heading from the quaternion about z: θ = 2 atan2(q_z, q_w), equal modulo 2π
    yaw = np.array([2.0 * math.atan2(t.rotation.z, t.rotation.w) for t in tfs])
    np.testing.assert_allclose(np.cos(yaw - result.poses[:, 2]), 1.0, rtol=0, atol=1e-14)
    assert {(t.parent_frame_id, t.child_frame_id) for t in tfs} == {("world", "base_link")}
    stamps = np.array([t.timestamp.seconds + 1e-9 * t.timestamp.nanos for t in tfs])
    np.testing.assert_allclose(stamps, result.times, rtol=0, atol=1e-9)  # ns resolution

    # ellipse vertices lie on the Pr-ellipse: squared Mahalanobis distance k = −2 ln(1 − Pr)
    k = -2.0 * math.log1p(-result.config.pr)
    ellipses = _decoded(logfile, "/covariance/ellipse")
    last = ellipses[-1].entities
    assert {e.id for e in last} == {"ellipse/current", f"ellipse/{n - 1:06d}"}
    pts = np.array([[p.x, p.y] for p in last[0].lines[0].points]) - result.poses[-1, :2]
    S = result.covs[-1, :2, :2]
    d2 = np.einsum("ni,ij,nj->n", pts, np.linalg.inv(S), pts)
    np.testing.assert_allclose(d2, k, rtol=1e-9)
    persistent = sorted(e.id for u in ellipses for e in u.entities if e.id != "ellipse/current")
    assert persistent == [f"ellipse/{i:06d}" for i in result.ellipse_steps()]

    # the grid's mass field is the θ-marginal of the exact volume, cell for cell
    grid = _decoded(logfile, "/maps/vel/grid")[0]
    mp = result.maps[0]
    assert [f.name for f in grid.fields] == ["mass", "red", "green", "blue", "alpha"]
    cells = np.frombuffer(grid.data, dtype=[("d", "<f8"), ("rgba", "u1", 4)]).reshape(
        mp.y.size, mp.x.size
    )
    assert exact(np.ascontiguousarray(cells["d"].T), mp.marginal_xy())
    # in-grid mass + lost mass = 1 (grid route vs the volume's bookkeeping)
    np.testing.assert_allclose(cells["d"].sum() + mp.lost_mass, 1.0, rtol=1e-12)
    # the grid's corner is half a cell before the first cell centre
    assert grid.pose.position.x == mp.x[0] - grid.cell_size.x / 2
    darkest = np.unravel_index(np.argmin(cells["rgba"][..., 0]), cells.shape)
    assert darkest == np.unravel_index(np.argmax(cells["d"]), cells.shape)  # darker = more probable

    cloud = _decoded(logfile, "/monte_carlo/end_poses")[0]
    assert [f.name for f in cloud.fields] == ["x", "y", "theta"]
    assert exact(np.frombuffer(cloud.data, "<f8").reshape(-1, 3), result.end_poses)


def test_every_message_has_a_frame(logfile: Path) -> None:
    from mcap_protobuf.decoder import DecoderFactory

    with open(logfile, "rb") as fh:
        reader = make_reader(fh, validate_crcs=True, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages():
            if channel.topic == "/tf":
                assert msg.parent_frame_id == "world"
            elif channel.topic in ("/robot/path", "/covariance/ellipse"):
                assert all(e.frame_id == "world" for e in msg.entities)
            elif hasattr(msg, "frame_id"):
                assert msg.frame_id == "world", channel.topic


# --- reproducibility and atomic writes -----------------------------------------------------


@pytest.mark.slow
def test_same_config_and_seed_give_identical_bytes(result: RunResult, tmp_path: Path) -> None:
    again = execute(RunConfig.from_dict(CONFIG))
    again = dataclasses.replace(again, maps=result.maps)
    a = write_run(tmp_path / "a.mcap", result).read_bytes()
    b = write_run(tmp_path / "b.mcap", again).read_bytes()
    assert a == b
    assert runlog.log_bytes(result) == a
    other = execute(RunConfig.from_dict({**CONFIG, "seed": 12}))
    assert runlog.log_bytes(dataclasses.replace(other, maps=result.maps)) != a


def test_timings_are_opt_in(result: RunResult) -> None:
    with_t = runlog.log_bytes(result, include_timings=True)
    without = runlog.log_bytes(result)
    assert b"/timings" in with_t
    assert b"/timings" not in without
    changed = dataclasses.replace(result, timings={k: v + 1.0 for k, v in result.timings.items()})
    assert runlog.log_bytes(changed) == without  # timings never leak into a default log


def test_write_is_atomic(
    result: RunResult, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    dest = tmp_path / "run.mcap"
    dest.write_bytes(b"previous content")
    calls = {"n": 0}
    real_put = mcap_io.LogWriter.put

    def failing_put(self: mcap_io.LogWriter, topic: str, msg: object, t_ns: int) -> None:
        calls["n"] += 1
        if calls["n"] > 200:
            raise KeyboardInterrupt("simulated interruption")
        real_put(self, topic, msg, t_ns)

    monkeypatch.setattr(mcap_io.LogWriter, "put", failing_put)
    with pytest.raises(KeyboardInterrupt):
        write_run(dest, result)
    assert dest.read_bytes() == b"previous content"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.mcap"]  # no temporary left behind


KILL_SCRIPT = """
import os, signal, sys
from pose_uncertainty.records import mcap_io, run as runlog
from pose_uncertainty.experiments.run import RunConfig, execute

result = execute(RunConfig.from_dict({config!r}))
real_put, count = mcap_io.LogWriter.put, [0]

def put(self, topic, msg, t_ns):
    count[0] += 1
    if count[0] == 2500:  # well into the per-step messages: die without any clean-up
        self.w._Writer__stream.flush()
        os.kill(os.getpid(), signal.SIGKILL)
    real_put(self, topic, msg, t_ns)

mcap_io.LogWriter.put = put
runlog.write_run(sys.argv[1], result)
"""


KILL_CONFIG = {
    "name": "killed",
    "trajectory": {"name": "straight", "length": 2.0, "speed": 1.0, "dt": 0.002},  # 1000 steps
    "monte_carlo": {"n_particles": 100},
}


@pytest.mark.slow
def test_killed_writer_leaves_only_a_recoverable_part_file(tmp_path: Path) -> None:
    """SIGKILL after 2500 messages (step ≈ 625 of 1000): no log, a .part with whole chunks."""
    import subprocess
    import sys

    result = execute(RunConfig.from_dict(KILL_CONFIG))
    dest = tmp_path / "killed.mcap"
    script = KILL_SCRIPT.format(config=KILL_CONFIG)
    proc = subprocess.run([sys.executable, "-c", script, str(dest)], check=False, timeout=120)
    assert proc.returncode == -9  # SIGKILL
    assert not dest.exists()
    (part,) = tmp_path.glob(".killed.mcap.*.part")
    _one_line_error(part, "truncated")
    with pytest.warns(PartialLogWarning):
        log = open_run(part, recover=True)
    k = log.times.size
    assert 0 < k < result.times.size
    assert exact(log.covs, result.covs[:k])


# --- damaged files -------------------------------------------------------------------------


def _one_line_error(path: Path, match: str) -> str:
    with pytest.raises(RunLogError) as info:
        open_run(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: ")
    assert match in msg, msg
    return msg


@pytest.mark.parametrize("fraction", [0.001, 0.05, 0.3, 0.5, 0.77, 0.999])
def test_truncated_file_gives_clean_error(logfile: Path, tmp_path: Path, fraction: float) -> None:
    data = logfile.read_bytes()
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(data[: max(1, int(len(data) * fraction))])
    _one_line_error(bad, "truncated")


@pytest.mark.slow
def test_every_flipped_byte_is_detected(logfile: Path, tmp_path: Path) -> None:
    """A flip anywhere (header, chunks, indexes, summary, footer) is caught by magic or a CRC."""
    data = logfile.read_bytes()
    rng = np.random.default_rng(3)
    offsets = set(range(64)) | set(range(len(data) - 200, len(data)))
    offsets |= {int(o) for o in rng.integers(0, len(data), 300)}
    bad = tmp_path / "flip.mcap"
    for off in sorted(offsets):
        flipped = bytearray(data)
        flipped[off] ^= 1 << int(rng.integers(0, 8))
        bad.write_bytes(bytes(flipped))
        with pytest.raises(RunLogError) as info:
            open_run(bad)
        msg = str(info.value)
        assert "\n" not in msg, (off, msg)
        assert msg.startswith(f"{bad}: "), (off, msg)
        assert any(word in msg for word in ("corrupted", "not an MCAP", "CRC")), (off, msg)


def test_empty_text_missing_and_foreign_files(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    _one_line_error(empty, "empty file")
    text = tmp_path / "notes.mcap"
    text.write_text("time,x,y\n0,0,0\n", encoding="utf-8")
    _one_line_error(text, "not an MCAP file")
    _one_line_error(tmp_path / "missing.mcap", "no such file")

    from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
    from mcap_protobuf.writer import Writer

    foreign = tmp_path / "foreign.mcap"
    with open(foreign, "wb") as fh, Writer(fh) as w:
        w.write_message("/pose", PoseInFrame(frame_id="map"), log_time=0, publish_time=0)
    _one_line_error(foreign, "not a pose-uncertainty run log")


def test_partial_log_is_recovered_with_a_warning(
    result: RunResult, logfile: Path, tmp_path: Path
) -> None:
    data = logfile.read_bytes()
    part = tmp_path / ".run.mcap.abc.part"
    part.write_bytes(data[: len(data) // 3])
    msg = _one_line_error(part, "truncated")
    assert "recover" in msg
    with pytest.warns(PartialLogWarning, match="partial log"):
        log = open_run(part, recover=True)
    assert log.partial
    assert log.problems
    k = log.times.size
    assert 0 < k < result.times.size
    # what is recovered is exactly the beginning of the run
    assert exact(log.poses, result.poses[:k])
    assert exact(log.covs, result.covs[:k])
    assert log.config == result.config


@pytest.mark.slow
def test_tampered_log_fails_verification(result: RunResult, tmp_path: Path) -> None:
    clean = execute(result.config)
    path = write_run(tmp_path / "fresh.mcap", clean)
    assert runlog.verify_run(open_run(path)).status == "identical"

    covs = clean.covs.copy()
    covs[17, 0, 0] *= 1.0 + 1e-12  # within the contract's tolerance: never "identical"
    tampered = write_run(tmp_path / "tampered.mcap", dataclasses.replace(clean, covs=covs))
    assert runlog.verify_run(open_run(tampered)).status == "equal within tolerance"
    covs[17, 0, 0] *= 1.0 + 1e-8  # beyond it
    tampered = write_run(tmp_path / "tampered.mcap", dataclasses.replace(clean, covs=covs))
    found = runlog.verify_run(open_run(tampered))
    assert found.status == "mismatch"
    assert any(d.startswith("/covariance[17].covariance: 1 of 9 values differ") for d in found.mismatches), found


# --- state at a time -------------------------------------------------------------------------


def test_state_at(result: RunResult, logfile: Path) -> None:
    log = open_run(logfile)
    dt = result.config.trajectory["dt"]
    s = log.state_at(40.5 * dt)
    assert s["step"] == 40
    assert exact(s["pose"], result.poses[40])
    assert exact(s["cloud"], result.checkpoints[40])
    e = covariance.ellipse(result.covs[40, :2, :2], result.config.pr)
    assert (s["alpha"], s["a_major"], s["a_minor"]) == tuple(float(v) for v in e)
    assert log.state_at(0.0)["step"] == 0
    end = log.state_at(float(result.times[-1]))
    assert end["step"] == result.n_steps
    assert exact(end["cloud"], result.end_poses)
    with pytest.raises(ValueError, match="within the run"):
        log.state_at(float(result.times[-1]) + 1.0)


# --- real maps from the config ---------------------------------------------------------------

MAP_CONFIG = {
    "name": "b1_arc",
    "seed": 1,
    # one step of V = 1 m/s, ω = 1 rad/s for Δt = 1 s (Němec 2012 §4.1.1, arc)
    "trajectory": {"name": "arc", "radius": 1.0, "angle": 1.0, "speed": 1.0, "dt": 1.0},
    "monte_carlo": {"n_particles": 500},
    "maps": [
        {"name": "vel", "model": "velocity", "resolution": 0.02, "theta_resolution": 0.2},
        {"name": "odo", "model": "odometry", "resolution": 0.02, "theta_resolution": 0.2},
    ],
}


@pytest.mark.slow
def test_computed_maps_round_trip(tmp_path: Path) -> None:
    from pose_uncertainty.methods import maps

    cfg = RunConfig.from_dict(MAP_CONFIG)
    assert cfg.maps[0].params["alphas"] == [0.05] * 6  # the thesis's constants filled in
    res = execute(cfg)
    assert res.n_steps == 1
    assert [m.name for m in res.maps] == ["vel", "odo"]
    # the map is centred on the closed-form end of the arc (R = 1 m turned by 1 rad)
    center = res.maps[0].center
    np.testing.assert_allclose(
        center, [math.sin(1.0), 1.0 - math.cos(1.0), 1.0], rtol=0, atol=1e-15
    )
    # the map builder called directly with the trajectory's control, (V, ω) = (1, 1) up to
    # rounding, on that grid gives the same array, bit for bit
    traj = trajectories.from_config(cfg.trajectory)
    np.testing.assert_allclose(traj.controls[0], [1.0, 1.0], rtol=0, atol=1e-15)
    grid = Grid.centered(center, resolution=0.02, theta_resolution=0.2)
    direct = maps.single_step_map(
        "velocity", traj.start, traj.controls[0], 1.0, [0.05] * 6, grid=grid
    )
    assert exact(res.maps[0].values, direct.values)
    log = open_run(write_run(tmp_path / "maps.mcap", res))
    assert runlog.compare_results(log, res) == []
    for a, b in zip(log.maps, res.maps, strict=True):
        # the log holds the exact θ-marginal and the digest of the full array (no log_volume)
        assert exact(a.marginal_xy(), b.marginal_xy())
        assert a.info.pop(runlog.VOLUME_SHA256) == runlog.volume_sha256(b.values)
        assert a.info.pop("theta_cells") == b.theta.size
        assert exact(a.center, b.center)
        assert a.info == b.info
        assert a.params == b.params
        assert exact(a.most_probable_xy(), b.most_probable_xy())
    # the odometry map's peak is off the noiseless end point, the velocity map's is on it (claim 10)
    assert log.metrics["map_vel_peak_offset"] < 0.02 < log.metrics["map_odo_peak_offset"]


def test_multi_step_map_round_trip(tmp_path: Path) -> None:
    """A five-step arc: the map is the multi-step (histogram-filter) map along the path."""
    cfg = RunConfig.from_dict(
        {
            "name": "multi",
            "trajectory": {"name": "arc", "radius": 0.5, "angle": 1.0, "speed": 1.0, "dt": 0.1},
            "monte_carlo": {"n_particles": 200},
            "maps": [
                {"name": "odo", "model": "odometry", "resolution": 0.02, "theta_resolution": 0.2}
            ],
        }
    )
    assert cfg.maps[0].params["size"] is None
    assert "max_cells" in cfg.maps[0].params
    res = execute(cfg)
    assert res.n_steps == 5
    mp = res.maps[0]
    np.testing.assert_allclose(mp.values.sum() + mp.lost_mass, 1.0, rtol=0, atol=1e-12)
    log = open_run(write_run(tmp_path / "multi.mcap", res))
    assert runlog.compare_results(log, res) == []
    with pytest.raises(ValueError, match=r"'maps\[0\].corrected'.*multi-step"):
        RunConfig.from_dict({**cfg.to_dict(), "maps": [{"model": "velocity", "corrected": True}]})


def test_bad_map_config_names_the_key() -> None:
    with pytest.raises(ValueError, match=r"'maps\[0\].resolutoin'"):
        RunConfig.from_dict({**MAP_CONFIG, "maps": [{"model": "velocity", "resolutoin": 0.1}]})
    with pytest.raises(ValueError, match=r"'maps\[0\].alphas'"):
        RunConfig.from_dict({**MAP_CONFIG, "maps": [{"model": "odometry", "alphas": [0.1] * 6}]})
    with pytest.raises(ValueError, match=r"'maps\[0\].model' must be one of"):
        RunConfig.from_dict({**MAP_CONFIG, "maps": [{"model": "sensor"}]})


# --- configs ---------------------------------------------------------------------------------


def test_config_round_trip_and_validation() -> None:
    cfg = RunConfig.from_dict(CONFIG)
    assert RunConfig.from_dict(cfg.to_dict()) == cfg
    assert cfg.to_dict()["trajectory"]["profile"] == "constant"  # builder defaults filled in
    with pytest.raises(ValueError, match=r"unknown config key\(s\) 'monte_carlo.particles'"):
        RunConfig.from_dict({**CONFIG, "monte_carlo": {"particles": 3}})
    with pytest.raises(
        ValueError, match=r"'trajectory.radius_m'.*allowed for trajectory 's_curve'"
    ):
        RunConfig.from_dict({**CONFIG, "trajectory": {"name": "s_curve", "radius_m": 1}})
    with pytest.raises(ValueError, match=r"'pr' must be a probability in \(0, 1\), got 1.5"):
        RunConfig.from_dict({**CONFIG, "pr": 1.5})
    with pytest.raises(ValueError, match=r"'k_r' must be >= 0.*got -1"):
        RunConfig.from_dict({**CONFIG, "k_r": -1})
    with pytest.raises(ValueError, match=r"'monte_carlo.regime' must be one of"):
        RunConfig.from_dict({**CONFIG, "monte_carlo": {"regime": "sometimes"}})
    with pytest.raises(ValueError, match=r"'cov0' must be symmetric"):
        RunConfig.from_dict({**CONFIG, "cov0": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]})


def test_metrics_agree_with_independent_routes(result: RunResult) -> None:
    """Logged metrics vs direct computations from the logged arrays.

    (Whether the coverage is close to Pr is a property of Method A, tested with
    the covariance module; with k_r ≠ k_l on this curved path it is not: ≈ 0.94.)
    """
    end, S = result.poses[-1], result.covs[-1, :2, :2]
    d = result.end_poses[:, :2] - end[:2]
    k = -2.0 * math.log1p(-result.config.pr)
    inside = float(np.mean(np.einsum("ni,ij,nj->n", d, np.linalg.inv(S), d) <= k))
    assert result.metrics["MC_coverage_pr"] == inside
    mean = result.end_poses.mean(axis=0)
    assert result.metrics["MC_mean_offset"] == pytest.approx(
        math.dist(mean[:2], end[:2]), rel=1e-12
    )
    e = covariance.ellipse(S, result.config.pr)
    assert result.metrics["A_ellipse_major"] == float(e.a_major)
    # semi-axes² = k · eigenvalues of Σ_xy (second route to the same ellipse)
    lam = np.linalg.eigvalsh(S)
    np.testing.assert_allclose([e.a_minor**2, e.a_major**2], k * lam, rtol=1e-10)


# --- figures ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_figures_from_log_are_identical_to_figures_from_result(
    result: RunResult, logfile: Path, tmp_path: Path
) -> None:
    a = figures.render_figures(result, tmp_path / "a", ("png", "svg"))
    b = figures.render_figures(open_run(logfile), tmp_path / "b", ("png", "svg"))
    assert [p.name for p in a] == [p.name for p in b]
    assert {p.stem for p in a} == {"trajectory", "cloud", "map_vel", "map_odo"}
    for pa, pb in zip(a, b, strict=True):
        assert pa.read_bytes() == pb.read_bytes(), pa.name
    svg = (tmp_path / "a" / "trajectory.svg").read_text(encoding="utf-8")
    assert "<dc:date>" not in svg  # no timestamp in the file


def test_figure_axes_have_units_and_equal_aspect(result: RunResult) -> None:
    for name, fig in figures.figure_set(result).items():
        ax = fig.axes[0]
        assert ax.get_xlabel() == "x [m]", name
        assert ax.get_ylabel() == "y [m]", name
        assert ax.get_aspect() == 1.0, name
    fig = figures.map_figure(result, result.maps[0])
    lo, hi = fig.axes[0].get_xlim()
    assert hi - lo == pytest.approx(1.0)  # the 1 m × 1 m window


def test_fixed_margins_place_the_axes_at_their_inches() -> None:
    """Margins in inches → subplot fractions → axes boxes back in inches: the same geometry (3 × 2 grid)."""
    m = figures.Margins(left=0.85, bottom=0.5, right=0.15, top=0.55, wspace=0.85, hspace=0.35)
    fig = figures.new_figure((7.8, 6.4), margins=m, grid=(3, 2))
    boxes = [fig.add_subplot(3, 2, k).get_position() for k in range(1, 7)]  # fractions of the figure
    ax_w = (7.8 - 0.85 - 0.15 - 0.85) / 2
    ax_h = (6.4 - 0.5 - 0.55 - 2 * 0.35) / 3
    for k, b in enumerate(boxes):
        row, col = divmod(k, 2)
        x0 = 0.85 + col * (ax_w + 0.85)
        y1 = 6.4 - 0.55 - row * (ax_h + 0.35)
        inches = [7.8 * b.x0, 7.8 * b.x1, 6.4 * b.y0, 6.4 * b.y1]
        np.testing.assert_allclose(inches, [x0, x0 + ax_w, y1 - ax_h, y1], atol=1e-9)
    assert fig.get_layout_engine() is None
    with pytest.raises(ValueError, match="margins"):
        figures.new_figure((1.0, 1.0), margins=m)


def test_fixed_margin_figures_keep_their_labels_inside(result: RunResult) -> None:
    """Tick labels, axis labels and legends of every per-run figure lie inside the figure after a draw."""
    for name, fig in figures.figure_set(result).items():
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        texts = [a.get_tightbbox(renderer) for ax in fig.axes for a in (ax.xaxis, ax.yaxis, ax.get_legend())
                 if a is not None]  # fmt: skip
        assert len(texts) >= 3, name  # x and y axis, legend of the main axes
        for box in texts:
            if box is not None:  # an axis without ticks or label (the colour bar's x axis) has no box
                assert fig.bbox.contains(box.x0, box.y0), name
                assert fig.bbox.contains(box.x1, box.y1), name


def test_fixed_margin_figures_keep_long_titles_inside(result: RunResult) -> None:
    """A run whose name makes the longest titles (S001's "straight_b0.1_per_run_euler_end" needs 7.4 in
    on one line, on a 6 in figure): every title is wrapped onto lines that lie inside the figure, and
    the axes are lowered below it (the top margin grows with the lines)."""
    name = "S_chassis_straight_b0.1_per_run_euler_end"
    run = dataclasses.replace(result, config=dataclasses.replace(result.config, name=name))
    for kind, fig in figures.figure_set(run).items():
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        ax = fig.axes[0]
        assert ax.title.get_text().replace("\n", " ").startswith(name), kind  # the information is kept
        box = ax.title.get_window_extent(renderer)
        assert fig.bbox.contains(box.x0, box.y0), kind
        assert fig.bbox.contains(box.x1, box.y1), kind
        assert box.y0 >= ax.get_window_extent(renderer).y1, kind  # above its axes, not over them
        assert ax.title.get_text().count("\n") >= 1, kind  # too long for one line at this name


def test_log_file_mode_is_readable(logfile: Path) -> None:
    assert os.stat(logfile).st_mode & 0o444 == 0o444
