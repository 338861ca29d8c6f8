"""The pipeline's job commands (python -m pose_uncertainty.cli.job) write what the library functions write."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from default_runs import CONFIGS
from hostile import run_cli

from pose_uncertainty.cli.job import main
from pose_uncertainty.experiments.study import run_study
from pose_uncertainty.pipeline.jobs import simulate_run


@pytest.mark.slow
def test_simulate_run_writes_the_log_of_the_library_call(tmp_path: Path) -> None:
    config = CONFIGS["right_angles"]
    assert main(["simulate-run", json.dumps(config), str(tmp_path / "a.mcap"), str(tmp_path / "a.json")]) == 0
    simulate_run(config, tmp_path / "b.mcap", tmp_path / "b.json")
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()
    assert set(json.loads((tmp_path / "a.json").read_text(encoding="utf-8"))) >= {"total_s"}


def test_run_study_writes_the_results_of_the_library_call(tmp_path: Path) -> None:
    spec = {"study": "integration_vs_step"}
    assert main(["run-study", "ivs", json.dumps(spec), str(tmp_path / "a.json")]) == 0
    run_study("ivs", spec, tmp_path / "b.json")
    a, b = (json.loads((tmp_path / f"{x}.json").read_text(encoding="utf-8")) for x in "ab")
    a.pop("provenance"), b.pop("provenance")  # (holds the time of the run)
    assert a == b


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["simulate-run", "{not json", "a.mcap", "b.json"], "not valid JSON"),
        (["simulate-run", "[1, 2]", "a.mcap", "b.json"], "must be a JSON object, got list"),
        (["simulate-orbit", "{}", "a", "b"], "invalid choice: 'simulate-orbit'"),
    ],
)
def test_bad_usage_exits_2_and_says_why(tmp_path: Path, argv: list[str], says: str) -> None:
    res = run_cli(argv, tmp_path, module="pose_uncertainty.cli.job")  # as `python -m` ends: argparse's exit
    assert res.code == 2
    assert says in res.stderr.strip().splitlines()[-1]
    assert not list(tmp_path.iterdir())  # nothing written


def test_a_job_checks_the_environment_before_any_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    # as the CLI: a limit that cannot be a number is one line naming the variable, and nothing is written
    monkeypatch.setenv("POSE_UNCERTAINTY_MAX_MEMORY", "1e400")
    spec = {"study": "integration_vs_step"}
    assert main(["run-study", "ivs", json.dumps(spec), str(tmp_path / "a.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "POSE_UNCERTAINTY_MAX_MEMORY" in err[0]
    assert "1e400" in err[0]
    assert not list(tmp_path.iterdir())
