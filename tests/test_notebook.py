"""The exploration notebook runs top to bottom on logs written by the library."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parents[1] / "notebooks" / "explore_runs.ipynb"
KERNEL = "pose-uncertainty-test"


@pytest.fixture
def kernel_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A kernel spec for *this* interpreter in a private Jupyter path (works from a fresh clone)."""
    spec = tmp_path / "jupyter" / "kernels" / KERNEL
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(
        json.dumps(
            {
                "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
                "display_name": "pose-uncertainty (test)",
                "language": "python",
            }
        ),
        encoding="utf-8",
    )
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("JUPYTER_PLATFORM_DIRS", "1")
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    return tmp_path


def _run(nb_path: Path, cwd: Path) -> dict:
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(nb_path, as_version=4)
    client = NotebookClient(
        nb, kernel_name=KERNEL, timeout=120, resources={"metadata": {"path": str(cwd)}}
    )
    client.execute()
    return nb


def _text(nb: dict) -> str:
    out = []
    for cell in nb["cells"]:
        for o in cell.get("outputs", []):
            out.append(o.get("text", ""))
            out.append(o.get("data", {}).get("text/plain", ""))
    return "\n".join(out)


@pytest.mark.slow
def test_notebook_runs_on_given_logs(kernel_env: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from pose_uncertainty.experiments.run import RunConfig, execute
    from pose_uncertainty.records.run import write_run

    runs = kernel_env / "runs"
    runs.mkdir()
    for name, traj in (
        ("nb_straight", {"name": "straight"}),
        ("nb_arc", {"name": "arc", "radius": 0.5}),
    ):
        cfg = {
            "name": name,
            "seed": 2,
            "trajectory": traj,
            "monte_carlo": {"n_particles": 500, "checkpoints": [20]},
        }
        write_run(runs / f"{name}.mcap", execute(RunConfig.from_dict(cfg)))
    monkeypatch.setenv("POSE_UNCERTAINTY_RUNS", str(runs))
    nb = _run(NOTEBOOK, kernel_env)
    text = _text(nb)
    assert "2 run logs under" in text
    assert "nb_straight" in text
    assert "nb_arc" in text
    assert "step 20 (t = 0.20 s): 500 particles" in text
    images = sum(
        "image/png" in o.get("data", {}) for c in nb["cells"] for o in c.get("outputs", [])
    )
    assert images >= 3  # trajectory, σ(t), cloud


@pytest.mark.slow
def test_notebook_makes_demo_runs_without_logs(
    kernel_env: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("POSE_UNCERTAINTY_RUNS", str(kernel_env / "nothing-here"))
    text = _text(_run(NOTEBOOK, kernel_env))
    assert "demo runs: ['straight.mcap', 'circle.mcap', 'b1_arc.mcap']" in text
    assert "b1_arc/odometry: grid (51, 51, 180)" in text
    assert "maps: 2" in text
