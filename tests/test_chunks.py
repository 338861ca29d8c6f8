"""Batched jobs (config key ``runs_per_job``): a chunk of runs in one process, the same logs.

Two routes to every log: a job per run (``runs_per_job: 1``) and a job per chunk, both made by
Snakemake in this test run from the same config; the logs must be equal byte for byte. A changed
run reruns only its chunk; a run's log can still be asked for by its file.
"""

from __future__ import annotations

import copy
import json
import math
import shutil
from pathlib import Path

import pytest
import yaml
from test_pipeline import REPO, SCHEMA, _config, _planned_jobs, copy_workflow, snakemake

from pose_uncertainty.core.table_io import read_table
from pose_uncertainty.experiments import cost, localization, sweep
from pose_uncertainty.pipeline import chunks

#: A set of six small runs (two chunks of three): two with Monte Carlo, so that a chunk's process
#: reuses its random-number machinery between runs, where state could leak from one run to the next.
TINY = {
    "seed": 11,
    "studies": {"enabled": False},
    "localization": {"enabled": False},
    "experiment_sets": {
        "S": {
            "base": {"trajectory": {"name": "straight", "length": 1.0, "dt": 0.1, "track": 0.2, "speed": 0.5},
                     "monte_carlo": {"n_particles": 0}},
            "sweep": [{"labels": ["a", "b", "c", "d", "e", "f"],
                       "k_r": [5.0e-4, 1.0e-4, 9.0e-4, 5.0e-4, 2.0e-4, 3.0e-4],
                       "monte_carlo.n_particles": [0, 200, 0, 0, 300, 0]}],
        }
    },
}  # fmt: skip


def test_chunk_spec_rebuilds_every_run_configuration_of_the_quick_config() -> None:
    runs = [r for rs in sweep.expand_all(sweep.validate_config(_config("quick.yaml"), SCHEMA)).values() for r in rs]
    for size in (1, 3, 7, len(runs)):
        parts = chunks.chunk_runs(runs, size)
        assert [r for p in parts for r in p] == runs  # every run once, in order
        assert all(1 <= len(p) <= size for p in parts)
        for part in parts:
            spec = json.loads(json.dumps(chunks.chunk_spec([r.config for r in part], [r.path for r in part],
                                                           [f"{r.path}.t" for r in part])))  # fmt: skip
            assert chunks.run_configs(spec) == [r.config for r in part]
            # the JSON keeps each value's type (1 and 1.0 are different logs)
            assert json.dumps(chunks.run_configs(spec)) == json.dumps([r.config for r in part])


def test_config_delta_lists_the_differing_leaves_and_gives_up_on_different_shapes() -> None:
    base = {"k_r": 5e-4, "trajectory": {"name": "straight", "length": 1.0}, "maps": []}
    other = copy.deepcopy(base)
    other["trajectory"]["length"] = 2.0
    assert chunks.config_delta(base, other) == [["trajectory", "length", 2.0]]
    assert chunks.config_delta(base, base) == []
    assert chunks.config_delta(base, {**base, "k_l": 1e-4}) is None
    assert chunks.config_delta(base, {**base, "k_r": 1}) == [["k_r", 1]]  # an int where a float was


def test_a_runs_timings_are_read_from_its_own_file_or_from_its_chunks(tmp_path: Path) -> None:
    own = tmp_path / "a.timings.json"
    own.write_text(json.dumps({"propagate_s": 0.5, "total_s": 1.25}), encoding="utf-8")
    chunk = tmp_path / "chunks" / "0.timings.json"
    chunk.parent.mkdir()
    chunk.write_text(json.dumps({"runs": {"a.mcap": {"propagate_s": 0.5, "total_s": 1.25}, "b.mcap": {"total_s": 2.0}}}), encoding="utf-8")
    assert chunks.read_timings(own, tmp_path / "a.mcap") == {"propagate_s": 0.5, "total_s": 1.25}
    # a run's key in its chunk's file is its log's name, wherever the log is named from
    assert chunks.read_timings(chunk, "data/runs/S/b.mcap") == {"total_s": 2.0}
    assert chunks.read_timings(str(chunk), tmp_path / "a.mcap") == chunks.read_timings(own, "a.mcap")
    assert chunks.read_timings(None, "a.mcap") is None
    assert chunks.read_timings(tmp_path / "missing.json", "a.mcap") is None
    with pytest.raises(KeyError, match=r"holds no run 'c\.mcap'"):
        chunks.read_timings(chunk, "c.mcap")
    # rewritten (a rerun chunk): read again, not the first reading kept
    chunk.write_text(json.dumps({"runs": {"b.mcap": {"total_s": 3.0, "propagate_s": 1.0}}}), encoding="utf-8")
    assert chunks.read_timings(chunk, "b.mcap") == {"propagate_s": 1.0, "total_s": 3.0}


def test_a_chunk_spec_names_the_chunks_timings_file_or_each_runs() -> None:
    configs = [{"k_r": 1.0, "name": "a"}, {"k_r": 2.0, "name": "b"}]
    spec = chunks.chunk_spec(configs, ["a.mcap", "b.mcap"], None, chunk_timings="chunks/0.timings.json")
    assert spec["timings"] == "chunks/0.timings.json"
    assert all("timings" not in r for r in spec["runs"])
    assert chunks.run_configs(spec) == configs
    spec = chunks.chunk_spec(configs, ["a.mcap", "b.mcap"], ["a.json", "b.json"])
    assert "timings" not in spec
    assert [r["timings"] for r in spec["runs"]] == ["a.json", "b.json"]
    with pytest.raises(ValueError, match=r"one log .* per run, got 2 runs, 2 logs and 1 timings files"):
        chunks.chunk_spec(configs, ["a.mcap", "b.mcap"], ["a.json"])


def test_a_chunks_resources_are_its_runs_largest_memory_and_summed_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(REPO)  # the localization runs' world file
    cfg = sweep.validate_config(copy.deepcopy(LOC_TINY), SCHEMA)
    for kind, runs in (("run", sweep.expand_all(cfg)["S"]), ("localization", localization.expand_localization(cfg)["LOC"])):
        configs = [r.config for r in runs]
        costs = [cost.estimate(c) if kind == "run" else cost.estimate_localization(localization.LocalizationConfig.from_dict(c))
                 for c in configs]  # fmt: skip
        want = cost.resources_of(cost.Cost(max(c.mem_bytes for c in costs), math.fsum(c.seconds for c in costs), ()))
        assert cost.chunk_resources(configs, kind) == want, kind
    with pytest.raises(ValueError, match="kind must be 'run' or 'localization', got 'study'"):
        cost.chunk_resources(configs, "study")


@pytest.mark.parametrize("bad", [0, -1, 10_001, 2.0, True, "3"])
def test_runs_per_job_out_of_range_is_refused_naming_the_value(bad: object) -> None:
    with pytest.raises(ValueError, match=r"runs_per_job must be an integer in \[1, 10000\], got"):
        chunks.chunk_runs([1, 2], bad)  # type: ignore[arg-type]


def _workflow(base: Path, name: str, cfg: dict) -> Path:
    work = copy_workflow(base / name)
    (work / "config/tiny.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False), encoding="utf-8")
    return work


def _logs(work: Path, folder: str = "data/runs") -> dict[str, bytes]:
    return {str(p.relative_to(work)): p.read_bytes() for p in sorted((work / folder).rglob("*.mcap"))}


def _built_both_ways(tmp_path: Path, cfg: dict, table: str, runs_per_job: int) -> tuple[Path, Path]:
    """``table`` built in two copies of the workflow: one run per job, and ``runs_per_job`` runs a job."""
    single = _workflow(tmp_path, "single", cfg)
    batched = _workflow(tmp_path, "batched", cfg)
    for work, size in ((single, 1), (batched, runs_per_job)):
        proc = snakemake(work, table, "--configfile", "config/tiny.yaml", "--config", f"runs_per_job={size}")
        assert proc.returncode == 0, proc.stderr[-3000:]
    return single, batched


@pytest.mark.slow
def test_chunked_logs_equal_one_run_per_job_and_a_change_reruns_only_its_chunk(tmp_path: Path) -> None:
    table = "reports/tables/S.csv"
    single, batched = _built_both_ways(tmp_path, TINY, table, 3)
    logs = _logs(single)
    assert len(logs) == 6
    assert _logs(batched) == logs  # the same bytes through either layout
    assert sorted(p.name for p in (batched / "data/benchmarks/simulate_chunk/S").iterdir()) == ["0.tsv", "1.tsv"]
    # the timings: a file per run, or one per chunk holding its runs'; the tables read either
    assert sorted(p.name for p in (single / "data/runs/S").glob("*.timings.json")) == [f"{r}.timings.json" for r in "abcdef"]
    assert not list((batched / "data/runs/S").glob("*.timings.json"))
    held = [json.loads((batched / f"data/runs/S/chunks/{i}.timings.json").read_text(encoding="utf-8"))["runs"] for i in (0, 1)]
    assert [sorted(h) for h in held] == [["a.mcap", "b.mcap", "c.mcap"], ["d.mcap", "e.mcap", "f.mcap"]]
    assert all(h[r].keys() == json.loads((single / f"data/runs/S/{r[0]}.timings.json").read_text(encoding="utf-8")).keys()
               for h in held for r in h)  # fmt: skip
    rows = {name: read_table(work / table) for name, work in (("single", single), ("batched", batched))}
    assert all(row["time_total"] > 0 for rs in rows.values() for row in rs)
    untimed = {name: [{k: v for k, v in row.items() if not k.startswith("time_")} for row in rs] for name, rs in rows.items()}
    assert untimed["batched"] == untimed["single"]  # wall clock apart, one table

    # nothing to do when nothing changed; a log deleted: its chunk again (its output is missing), then the table
    args = ("--dry-run", "--configfile", "config/tiny.yaml", "--config", "runs_per_job=3")  # targets first
    assert _planned_jobs(snakemake(batched, table, *args)) == {}
    kept = shutil.copy2(batched / "data/runs/S/a.mcap", tmp_path / "a.mcap")
    (batched / "data/runs/S/a.mcap").unlink()
    jobs = _planned_jobs(snakemake(batched, table, *args))
    assert jobs == {"simulate_chunk_S_0": 1, "collect_metrics": 1, "total": 2}, jobs
    shutil.copy2(kept, batched / "data/runs/S/a.mcap")
    assert _planned_jobs(snakemake(batched, table, *args)) == {}
    # one run changed: its chunk alone, then its table
    changed = copy.deepcopy(TINY)
    changed["experiment_sets"]["S"]["sweep"][0]["k_r"][4] = 2.5e-4  # run e, in the second chunk
    (batched / "config/tiny.yaml").write_text(yaml.safe_dump(changed, sort_keys=False), encoding="utf-8")
    jobs = _planned_jobs(snakemake(batched, table, *args))
    assert jobs == {"simulate_chunk_S_1": 1, "collect_metrics": 1, "total": 2}, jobs

    # one log asked for by its file: its chunk's job makes it (and one job per run makes one run)
    shutil.rmtree(batched / "data")
    assert _planned_jobs(snakemake(batched, "data/runs/S/b.mcap", *args)) == {"simulate_chunk_S_0": 1, "total": 1}
    single_args = ("--configfile", "config/tiny.yaml", "--dry-run")
    proc = snakemake(single, "data/runs/S/z.mcap", *single_args)
    assert proc.returncode != 0  # not a run of the set
    shutil.rmtree(single / "data")
    jobs = _planned_jobs(snakemake(single, "data/runs/S/b.mcap", *single_args))
    assert jobs == {"simulate_run": 1, "total": 1}, jobs


#: A localization set of three small runs (particle counts swept), its world the room of config/worlds.
LOC_TINY = {
    **{k: v for k, v in TINY.items() if k != "localization"},
    "localization": {
        "enabled": True,
        "defaults": {"world": {"file": "config/worlds/room.yaml"}, "truth": {"k_r": 5.0e-4, "k_l": 5.0e-4},
                     "sensors": {"landmarks": {"range_std": 0.1, "bearing_std": 0.05, "max_range": 6.0, "period": 0.5}}},
        "sets": {
            "LOC": {
                "base": {"repeat": 1,
                         "trajectory": {"name": "tour", "segments": [["line", 1.0]], "speed": 0.5, "dt": 0.1,
                                        "start": [2.0, 1.5, 0.0]},
                         "filters": {"ekf": {}, "particle": {"n_particles": 50}}},
                "sweep": [{"labels": ["p", "q", "r"], "filters.particle.n_particles": [50, 80, 120]}],
            }
        },
    },
}  # fmt: skip


@pytest.mark.slow
def test_chunked_localization_logs_equal_one_run_per_job_and_a_change_reruns_only_its_chunk(tmp_path: Path) -> None:
    table = "reports/tables/localization/LOC.csv"
    single, batched = _built_both_ways(tmp_path, LOC_TINY, table, 2)
    logs = _logs(single, "data/localization")
    assert sorted(Path(p).name for p in logs) == ["p.mcap", "q.mcap", "r.mcap"]
    assert _logs(batched, "data/localization") == logs  # the same bytes through either layout
    names = sorted(p.name for p in (batched / "data/benchmarks/simulate_localization_chunk/LOC").iterdir())
    assert names == ["0.tsv", "1.tsv"]
    held = [json.loads((batched / f"data/localization/LOC/chunks/{i}.timings.json").read_text(encoding="utf-8"))["runs"]
            for i in (0, 1)]  # fmt: skip
    assert [sorted(h) for h in held] == [["p.mcap", "q.mcap"], ["r.mcap"]]
    rows = {name: read_table(work / table) for name, work in (("single", single), ("batched", batched))}
    assert all(row["time_total"] > 0 for rs in rows.values() for row in rs)
    untimed = {name: [{k: v for k, v in row.items() if not k.startswith("time_")} for row in rs] for name, rs in rows.items()}
    assert untimed["batched"] == untimed["single"]

    args = ("--dry-run", "--configfile", "config/tiny.yaml", "--config", "runs_per_job=2")
    assert _planned_jobs(snakemake(batched, table, *args)) == {}
    changed = copy.deepcopy(LOC_TINY)
    changed["localization"]["sets"]["LOC"]["sweep"][0]["filters.particle.n_particles"][2] = 150  # run r, chunk 1
    (batched / "config/tiny.yaml").write_text(yaml.safe_dump(changed, sort_keys=False), encoding="utf-8")
    jobs = _planned_jobs(snakemake(batched, table, *args))
    assert jobs == {"simulate_localization_chunk_LOC_1": 1, "collect_localization_metrics": 1, "total": 2}, jobs
    shutil.rmtree(batched / "data")
    jobs = _planned_jobs(snakemake(batched, "data/localization/LOC/q.mcap", *args))
    assert jobs == {"simulate_localization_chunk_LOC_0": 1, "total": 1}, jobs
