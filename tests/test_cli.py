"""The command line: run → replay (summary, --at, --figures, --verify) and clean errors."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from pose_uncertainty.cli import main
from pose_uncertainty.experiments.run import RunConfig, execute
from pose_uncertainty.present import figures
from pose_uncertainty.records.run import open_run, write_run

CONFIG = {
    "name": "cli_circle",
    "seed": 4,
    "trajectory": {"name": "circle", "radius": 0.5, "speed": 1.0, "dt": 0.05, "track": 0.2},
    "monte_carlo": {"n_particles": 1500, "regime": "per_run"},
    "n_ellipses": 4,
}


@pytest.fixture(scope="module")
def logged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("cli")
    cfg = d / "config.yaml"
    cfg.write_text(yaml.safe_dump(CONFIG), encoding="utf-8")
    out = d / "run.mcap"
    assert main(["run", str(cfg), "-o", str(out)]) == 0
    return out


def test_run_writes_the_same_bytes_as_the_library(logged: Path, tmp_path: Path) -> None:
    again = write_run(tmp_path / "lib.mcap", execute(RunConfig.from_dict(CONFIG)))
    assert again.read_bytes() == logged.read_bytes()


def test_run_accepts_json(tmp_path: Path, logged: Path) -> None:
    cfg = tmp_path / "config.json"
    cfg.write_text(json.dumps(CONFIG), encoding="utf-8")
    out = tmp_path / "run.mcap"
    assert main(["run", str(cfg), "-o", str(out)]) == 0
    assert out.read_bytes() == logged.read_bytes()


def test_replay_prints_summary(logged: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(logged)]) == 0
    out = capsys.readouterr().out
    n = execute(RunConfig.from_dict(CONFIG)).n_steps + 1
    topic_lines = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines() if ln.startswith("  /")}
    assert topic_lines["/covariance"] == [str(n), "pose_uncertainty.PoseCovariance2D"]
    assert topic_lines["/monte_carlo/end_poses"] == ["1", "foxglove.PointCloud"]
    assert "trajectory.radius = 0.5  [m]" in out
    assert 'monte_carlo.regime = "per_run"' in out
    assert f"final state (step {n - 1}," in out
    assert "MC_coverage_pr = " in out
    assert "environment_lock_sha256: " in out


def test_replay_at_time(logged: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = open_run(logged)
    t = float(log.times[7]) + 0.4 * CONFIG["trajectory"]["dt"]
    assert main(["replay", str(logged), "--at", repr(t)]) == 0
    out = capsys.readouterr().out
    assert f"state at step 7, t = {log.times[7]:.9g} s" in out
    assert main(["replay", str(logged), "--at", "1e6"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --at: time must be within the run")
    assert err.count("\n") == 1


@pytest.mark.slow
def test_replay_figures_identical_to_pipeline(logged: Path, tmp_path: Path) -> None:
    """`replay --figures` (log only) vs the pipeline's call on the freshly computed result."""
    assert main(["replay", str(logged), "--figures", str(tmp_path / "replay")]) == 0
    pipeline = figures.render_figures(execute(RunConfig.from_dict(CONFIG)), tmp_path / "pipeline")
    replayed = sorted((tmp_path / "replay").iterdir())
    assert [p.name for p in replayed] == sorted(p.name for p in pipeline)
    assert {p.name for p in replayed} == {
        "trajectory.png",
        "trajectory.svg",
        "cloud.png",
        "cloud.svg",
    }
    for p in pipeline:
        assert (tmp_path / "replay" / p.name).read_bytes() == p.read_bytes(), p.name


@pytest.mark.slow
def test_run_with_figures_matches_replay(logged: Path, tmp_path: Path) -> None:
    cfg = tmp_path / "config.yaml"
    cfg.write_text(yaml.safe_dump(CONFIG), encoding="utf-8")
    assert (
        main(["run", str(cfg), "-o", str(tmp_path / "r.mcap"), "--figures", str(tmp_path / "a")])
        == 0
    )
    assert main(["replay", str(logged), "--figures", str(tmp_path / "b"), "--format", "png"]) == 0
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["cloud.png", "trajectory.png"]
    for p in (tmp_path / "b").iterdir():
        assert p.read_bytes() == (tmp_path / "a" / p.name).read_bytes()


@pytest.mark.slow
def test_verify_passes_on_fresh_and_fails_on_tampered(
    logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["replay", str(logged), "--verify"]) == 0
    assert "verify: identical" in capsys.readouterr().out

    res = execute(RunConfig.from_dict(CONFIG))
    end = res.end_poses.copy()
    end[3, 1] += 1e-9
    bad = write_run(tmp_path / "tampered.mcap", dataclasses.replace(res, end_poses=end))
    assert main(["replay", str(bad), "--verify"]) == 1
    out = capsys.readouterr().out
    assert "MISMATCH /monte_carlo/end_poses[0].y: 1 of 1500 values differ by up to 1.000e-09" in out
    assert "verify: MISMATCH" in out


@pytest.mark.slow
def test_verify_catches_a_changed_display_topic(logged: Path, tmp_path: Path) -> None:
    """Same data but a different Pr-ellipse drawing: only the byte comparison can see it."""
    res = execute(RunConfig.from_dict(CONFIG))
    from pose_uncertainty.records import run as runlog

    original = runlog._ELLIPSE_POINTS
    runlog._ELLIPSE_POINTS = original + 2
    try:
        bad = write_run(tmp_path / "display.mcap", res)
    finally:
        runlog._ELLIPSE_POINTS = original
    assert main(["replay", str(bad), "--verify"]) == 1


def _expect_clean_error(args: list[str], capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    assert main(args) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.count("\n") == 1, err
    assert err.startswith("error: "), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err
    return err


@pytest.mark.parametrize("cut", [8, 100, 4000, -500, -9])
def test_truncated_logs(
    logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], cut: int
) -> None:
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(logged.read_bytes()[:cut])
    _expect_clean_error(["replay", str(bad)], capsys, str(bad), "truncated")


def test_flipped_empty_text_and_missing(
    logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = bytearray(logged.read_bytes())
    data[len(data) // 2] ^= 0x10
    flipped = tmp_path / "flipped.mcap"
    flipped.write_bytes(bytes(data))
    _expect_clean_error(["replay", str(flipped)], capsys, str(flipped), "corrupted")
    empty = tmp_path / "empty.mcap"
    empty.touch()
    _expect_clean_error(["replay", str(empty)], capsys, str(empty), "empty file")
    text = tmp_path / "README.txt"
    text.write_text("hello, not a log\n", encoding="utf-8")
    _expect_clean_error(["replay", str(text)], capsys, str(text), "not an MCAP file")
    _expect_clean_error(["replay", str(tmp_path / "nope.mcap")], capsys, "no such file")


def test_recover_reads_a_partial_log(
    logged: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    part = tmp_path / "part.mcap"
    part.write_bytes(logged.read_bytes()[: logged.stat().st_size * 2 // 3])
    assert main(["replay", str(part), "--recover"]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith(f"warning: {part}: partial log (truncated")
    assert "PARTIAL" in captured.out
    assert main(["replay", str(part), "--recover", "--verify"]) == 1


def test_bad_config_names_the_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump({**CONFIG, "seeed": 3}), encoding="utf-8")
    _expect_clean_error(
        ["run", str(cfg), "-o", str(tmp_path / "x.mcap")], capsys, "'seeed'", str(cfg)
    )
    cfg.write_text("trajectory: [unclosed\n", encoding="utf-8")
    _expect_clean_error(["run", str(cfg), "-o", str(tmp_path / "x.mcap")], capsys, "not valid YAML")
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.slow
def test_console_entry_point_never_shows_a_traceback(tmp_path: Path) -> None:
    """End to end through a fresh interpreter, as a user would call it."""
    text = tmp_path / "notes.mcap"
    text.write_text("not mcap\n", encoding="utf-8")
    proc = subprocess.run(
        [sys.executable, "-m", "pose_uncertainty.cli", "replay", str(text)],
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert (
        proc.stderr
        == f"error: {text}: not an MCAP file (no MCAP magic; starts with text 'not mcap')\n"
    )
