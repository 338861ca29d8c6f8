"""The reproducibility contract: a log made on another machine verifies on this one.

Another machine is made here in two ways, both in a subprocess:

* numpy's CPU dispatch turned off (``NPY_DISABLE_CPU_FEATURES`` = every dispatch target this
  CPU has beyond numpy's baseline): the real mechanism, but on a CPU whose dispatched kernels
  agree with the baseline ones for what a run calls (AVX2 machines: the float64 ``sin``,
  ``cos``, ``exp``, ``log`` are scalar libm either way) the log is identical;
* another ``libm`` (:mod:`other_libm`): every transcendental result moved by up to ±2 ulp,
  deterministically. Its logs differ from this machine's in the last bits on every CPU, so
  these tests fail if the tolerance is replaced by byte equality.

The measured worst differences (printed by ``pytest -s``) are ~10⁻¹⁵ to 10⁻¹³ of the
quantities' scales, against a tolerance of 64·2⁻⁵³·(n+64) (7.4·10⁻¹³ at 40 steps).
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import default_runs
import numpy as np
import pytest
from mcap.records import Metadata
from mcap.writer import Writer as McapWriter

from pose_uncertainty.cli import main
from pose_uncertainty.experiments.run import RunConfig, execute
from pose_uncertainty.records import reproducibility as rp
from pose_uncertainty.records.mcap_io import scan
from pose_uncertainty.records.run import log_bytes, open_run, write_run

HERE = Path(__file__).resolve().parent
REFERENCES = HERE / "data" / "default_runs"

STRAIGHT = default_runs.CONFIGS["straight"]

LOCALIZATION = {
    "kind": "localization", "name": "tiny", "seed": 3,
    "world": {"name": "box", "walls": {"segments": [[0, 0, 6, 0], [6, 0, 6, 5], [6, 5, 0, 5], [0, 5, 0, 0]],
                                       "resolution": 0.25},
              "landmarks": [{"id": 0, "x": 0.5, "y": 0.5}, {"id": 1, "x": 5.5, "y": 0.7}, {"id": 2, "x": 3.0, "y": 4.5}]},
    "trajectory": {"name": "tour", "segments": [["line", 2.0], ["arc", 1.0, 1.5707963267948966]],
                   "speed": 0.5, "dt": 0.2, "start": [1.0, 1.0, 0.0]},
    "sensors": {"landmarks": {"range_std": 0.1, "bearing_std": 0.05, "max_range": 6.0, "period": 0.4}},
    "filters": {"ekf": {}, "histogram": {"resolution": 0.25, "ntheta": 18}, "particle": {"n_particles": 300}},
}  # fmt: skip


def _write_config(tmp_path: Path, config: dict, name: str = "config.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(config), encoding="utf-8")
    return path


def _run(args: list[str], env: dict[str, str] | None = None, other_libm: bool = False) -> subprocess.CompletedProcess:
    cmd = [sys.executable, str(HERE / "other_libm.py")] if other_libm else [sys.executable, "-m", "pose_uncertainty.cli"]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, env={**os.environ, **(env or {})},
                          timeout=600, check=False)  # fmt: skip


def _verify(path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["replay", str(path), "--verify"])
    return code, capsys.readouterr().out


# --- the tolerance ---------------------------------------------------------------------------


def test_the_tolerance_is_the_linear_growth_of_two_ulp_per_step() -> None:
    # 64 u (n + 64): 1.1e-12 at 100 steps, 7.1e-11 at 10^4
    assert rp.relative_tolerance(0) == 64 * 64 * 2.0**-53
    assert rp.relative_tolerance(100) == pytest.approx(1.165e-12, rel=1e-3)
    assert rp.relative_tolerance(10_000) == pytest.approx(7.15e-11, rel=1e-3)
    with pytest.raises(ValueError, match="n_steps must be >= 0, got -1"):
        rp.relative_tolerance(-1)


def test_other_libm_moves_results_by_whole_ulps_deterministically() -> None:
    import other_libm

    x = np.random.default_rng(1).uniform(-10, 10, 10_000)
    y = other_libm.nudge(np.sin(x), 2)
    k = (y - np.sin(x)) / np.spacing(np.abs(np.sin(x)))
    assert np.array_equal(k, np.round(k))
    assert set(np.unique(k)) == {-2.0, -1.0, 0.0, 1.0, 2.0}
    assert np.array_equal(y, other_libm.nudge(np.sin(x), 2))  # a function of its argument, as libm is


# --- another machine --------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["straight", "localization",
                                  *(pytest.param(n, marks=pytest.mark.slow)
                                    for n in ("circle_cov0_checkpoints", "per_run_exact", "map_arc"))])
@pytest.mark.slow
def test_a_log_from_another_libm_verifies_within_tolerance(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = LOCALIZATION if name == "localization" else default_runs.CONFIGS[name]
    cfg = _write_config(tmp_path, config)
    theirs, ours = tmp_path / "theirs.mcap", tmp_path / "ours.mcap"
    done = _run(["run", str(cfg), "-o", str(theirs)], other_libm=True)
    assert done.returncode == 0, done.stderr
    assert main(["run", str(cfg), "-o", str(ours)]) == 0
    # the other libm changes the bytes: byte equality would call this log a mismatch
    assert theirs.read_bytes() != ours.read_bytes()
    code, out = _verify(theirs, capsys)
    assert code == 0, out
    assert "verify: equal within tolerance; largest relative difference" in out, out
    assert "MISMATCH" not in out
    worst = float(out.split("largest relative difference ")[1].split()[0])
    tol = float(out.split("; tolerance ")[1].split()[0])
    assert 0 < worst <= tol
    where = out.split("of the quantity's scale, in ")[1].split("; tolerance")[0]
    print(f"\n{name}: worst {worst:.2e} of the scale, tolerance {tol:.2e}, in {where}")  # the closing table
    # and the other way round: this machine's log, recomputed with the other libm
    again = _run(["replay", str(ours), "--verify"], other_libm=True)
    assert again.returncode == 0, again.stdout + again.stderr
    assert "verify: equal within tolerance" in again.stdout


@pytest.mark.slow
def test_a_log_with_simd_dispatch_disabled_verifies(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    found = [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]
    if not found:
        pytest.skip("this CPU has none of numpy's dispatch targets beyond its baseline")
    cfg = _write_config(tmp_path, default_runs.CONFIGS["circle_cov0_checkpoints"])
    theirs, ours = tmp_path / "theirs.mcap", tmp_path / "ours.mcap"
    done = _run(["run", str(cfg), "-o", str(theirs)], env={"NPY_DISABLE_CPU_FEATURES": " ".join(found)})
    assert done.returncode == 0, done.stderr
    assert main(["run", str(cfg), "-o", str(ours)]) == 0
    assert open_run(theirs).provenance["numpy_cpu_dispatch"] == "none"
    assert open_run(ours).provenance["numpy_cpu_dispatch"] == " ".join(found)
    code, out = _verify(theirs, capsys)
    assert code == 0, out
    # the logs differ in their provenance (the dispatch is logged); with it set equal, in the numbers or not
    mine = dataclasses.replace(open_run(ours), provenance=open_run(theirs).provenance)
    same_numbers = log_bytes(mine) == theirs.read_bytes()
    assert ("verify: identical" if same_numbers else "verify: equal within tolerance") in out, out
    assert "note: numpy_cpu_dispatch: log 'none', this machine" in out
    print(f"\ndispatch {found} disabled: the numbers are bit-identical: {same_numbers}")


# --- the default runs' reference logs ---------------------------------------------------------


@pytest.mark.parametrize("name", sorted(default_runs.CONFIGS))
def test_runs_without_a_drive_log_what_they_logged_before(name: str) -> None:
    """The reference logs (written by the code before the drives existed) hold the same records.

    They are of format version 2; the fresh log states that version (same records).
    """
    ref = REFERENCES / f"{name}.mcap"
    logged = open_run(ref)
    version = logged.metadata["format_version"]
    fresh = default_runs.reference_bytes(default_runs.CONFIGS[name], format_version=version)
    cmp = rp.compare_log_bytes(ref.read_bytes(), fresh, n_steps=logged.n_steps)
    assert cmp.status in (rp.IDENTICAL, rp.WITHIN_TOLERANCE), cmp.mismatches
    print(f"\n{name}: format version {version}, {cmp.status}, worst {cmp.worst:.2e} of the scale ({cmp.worst_at})")


def test_a_version_2_log_is_read_summarised_and_verified_by_this_code(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log of the previous format version: read and summarised as is; verified by recomputing
    with the current code, written under the logged version (same records), within tolerance."""
    old = tmp_path / "straight.mcap"
    old.write_bytes((REFERENCES / "straight.mcap").read_bytes())
    log = open_run(old)
    assert log.metadata["format_version"] == "2"
    assert main(["replay", str(old)]) == 0
    assert "format pose-uncertainty-runlog v2" in capsys.readouterr().out
    code, out = _verify(old, capsys)
    assert code == 0, out
    assert "verify: identical" in out or "verify: equal within tolerance" in out, out
    assert "run-log format version 2; recomputed by this code (version 3" in out, out
    # a fresh log states the current version, and the previous one only when asked
    assert open_run(write_run(tmp_path / "new.mcap", execute(RunConfig.from_dict(STRAIGHT)))).metadata[
        "format_version"] == "3"
    with pytest.raises(ValueError, match=r"format_version must be one of 2, 3 .*got '1'"):
        log_bytes(execute(RunConfig.from_dict(STRAIGHT)), format_version="1")


# --- what is a mismatch -----------------------------------------------------------------------


def _rewrite(src: Path, dst: Path, *, metadata: dict[str, str] | None = None, topic: str | None = None,
             edit=None, library: str | None = None) -> Path:  # fmt: skip
    """Copy a log record by record (valid CRCs), changing metadata, one topic's messages or the header."""
    from mcap.records import Channel, Header, Message, Schema
    from mcap_protobuf.decoder import DecoderFactory

    records, problem = scan(src.read_bytes())
    assert problem is None
    schemas = {r.id: r for r in records if isinstance(r, Schema)}
    channels = {r.id: r for r in records if isinstance(r, Channel)}
    with dst.open("wb") as fh:
        w = McapWriter(fh)
        header = next(r for r in records if isinstance(r, Header))
        w.start(profile=header.profile, library=library or header.library)
        ids = {}
        for r in records:
            if isinstance(r, Metadata):
                w.add_metadata(r.name, {**r.metadata, **(metadata or {})})
        for cid, ch in channels.items():
            s = schemas[ch.schema_id]
            sid = w.register_schema(name=s.name, encoding=s.encoding, data=s.data)
            ids[cid] = w.register_channel(topic=ch.topic, message_encoding=ch.message_encoding, schema_id=sid)
        for r in records:
            if isinstance(r, Message):
                data = r.data
                ch = channels[r.channel_id]
                if ch.topic == topic:
                    msg = DecoderFactory().decoder_for(ch.message_encoding, schemas[ch.schema_id])(data)
                    edit(msg)
                    data = msg.SerializeToString(deterministic=True)
                w.add_message(channel_id=ids[r.channel_id], log_time=r.log_time, publish_time=r.publish_time,
                              sequence=r.sequence, data=data)  # fmt: skip
        w.finish()
    return dst


def _moved(src: Path, dst: Path) -> Path:
    """``src`` with the nominal pose of every step moved 1 m along x (valid CRCs)."""

    def move(msg) -> None:
        msg.pose.position.x += 1.0

    return _rewrite(src, dst, topic="/robot/pose", edit=move)


@pytest.fixture
def straight_log(tmp_path: Path) -> Path:
    return write_run(tmp_path / "straight.mcap", execute(RunConfig.from_dict(STRAIGHT)))


def test_a_display_topic_moved_beyond_tolerance_is_a_mismatch(straight_log: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    code, out = _verify(_moved(straight_log, tmp_path / "bad.mcap"), capsys)
    assert code == 1
    assert "MISMATCH /robot/pose[" in out
    assert "pose.position.x" in out
    assert "verify: MISMATCH" in out


@pytest.mark.slow
def test_a_one_ulp_change_is_within_tolerance_but_never_identical(straight_log: Path, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    result = open_run(straight_log)
    covs = result.covs.copy()
    covs[17, 0, 0] = np.nextafter(covs[17, 0, 0], np.inf)
    path = write_run(tmp_path / "ulp.mcap", dataclasses.replace(execute(result.config), covs=covs))
    code, out = _verify(path, capsys)
    assert code == 0, out
    assert "verify: equal within tolerance" in out, out
    assert "[17]" in out, out
    covs[17, 0, 0] *= 1.0 + 1e-9  # far beyond 64 u (n + 64) of the covariances' scale
    path = write_run(tmp_path / "far.mcap", dataclasses.replace(execute(result.config), covs=covs))
    code, out = _verify(path, capsys)
    assert code == 1, out
    assert "MISMATCH /covariance[17].covariance" in out, out


def test_a_changed_unit_or_definition_is_a_mismatch(straight_log: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    def unit(msg):
        msg.metrics[0].unit = "cm^2"

    code, out = _verify(_rewrite(straight_log, tmp_path / "u.mcap", topic="/metrics", edit=unit), capsys)
    assert code == 1, out
    assert ".unit: logged 'cm^2'" in out, out

    def definition(msg):
        msg.metrics[1].definition += " (edited)"

    code, out = _verify(_rewrite(straight_log, tmp_path / "d.mcap", topic="/metrics", edit=definition), capsys)
    assert code == 1, out
    assert ".definition: logged" in out, out


def test_another_library_version_compares_everything_and_says_so(straight_log: Path, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    old = _rewrite(straight_log, tmp_path / "old.mcap", library="pose-uncertainty/0.0.9")
    code, out = _verify(old, capsys)
    assert code == 0
    assert "note: written by pose-uncertainty/0.0.9" in out, out
    assert "verify: identical" not in out, out

    code, out = _verify(_moved(old, tmp_path / "both.mcap"), capsys)
    assert code == 1
    assert "MISMATCH /robot/pose[" in out


def test_a_timings_log_is_compared_apart_from_its_timings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = _write_config(tmp_path, STRAIGHT)
    timed = tmp_path / "timed.mcap"
    assert main(["run", str(cfg), "-o", str(timed), "--timings"]) == 0
    capsys.readouterr()
    code, out = _verify(timed, capsys)
    assert code == 0, out
    assert "timings (/timings) are not reproducible: not compared" in out, out

    code, out = _verify(_moved(timed, tmp_path / "t2.mcap"), capsys)
    assert code == 1


# --- what cannot be compared -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("metadata", "pattern"),
    [
        ({"format_version": "99"}, r"run log format version '99' is not supported \(this reader: 2, 3\)"),
        ({"numpy_version": "1.26.4"}, (r"written with numpy 1\.26\.4, this machine has numpy 2\.\d+\.\d+; a different "
                                      r"major version changes numpy's semantics")),
    ],
)  # fmt: skip
def test_what_cannot_be_recomputed_here_says_so_in_one_line(
    metadata: dict[str, str], pattern: str, straight_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import re

    bad = _rewrite(straight_log, tmp_path / "bad.mcap", metadata=metadata)
    assert main(["replay", str(bad), "--verify"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert re.search(pattern, err), err
    assert "MISMATCH" not in err


def test_every_log_records_the_machine_arithmetic(straight_log: Path) -> None:
    from numpy._core._multiarray_umath import __cpu_baseline__

    prov = open_run(straight_log).provenance
    assert prov["numpy_cpu_baseline"] == " ".join(__cpu_baseline__)
    assert prov["libc"].split()[0] in ("glibc", "musl", "unknown") or prov["libc"]
    assert prov["blas"] != ""
    assert set(rp.environment_notes(prov, prov)) == set()
    assert log_bytes(open_run(straight_log)) == straight_log.read_bytes()  # same machine: the same bytes


@pytest.mark.slow
def test_the_report_flags_logs_made_on_other_arithmetic(tmp_path: Path) -> None:
    from pose_uncertainty.pipeline import tables
    from pose_uncertainty.pipeline.claims import write_claims
    from pose_uncertainty.pipeline.summary import summarize_pipeline
    from pose_uncertainty.present.report import build_report

    result = execute(RunConfig.from_dict(STRAIGHT))
    here, here2 = (write_run(tmp_path / f"{n}.mcap", dataclasses.replace(result, config=dataclasses.replace(result.config, name=n)))
                   for n in ("here", "here2"))  # fmt: skip
    there = write_run(tmp_path / "there.mcap", dataclasses.replace(
        result, config=dataclasses.replace(result.config, name="there"),
        provenance={**result.provenance, "numpy_cpu_dispatch": "X86_V3 X86_V4 AVX512_ICL"}))  # fmt: skip

    def report(paths: list[Path], name: str) -> str:
        table = tables.collect_table("S", paths, None, tmp_path / f"{name}.csv")
        runs = [{"id": open_run(p).config.name, "log": str(p), "swept": {}, "figures": {}} for p in paths]
        manifest = {"sets": [{"name": "S", "title": "S", "source": "", "description": "", "table": str(table),
                              "figures": {}, "runs": runs}], "config": {}}  # fmt: skip
        html = build_report(manifest, {"S": table}, write_claims({"S": table}, tmp_path / f"{name}.claims.json"),
                            summarize_pipeline({"S": table}, [], [], tmp_path / f"{name}.pipeline.json"),
                            tmp_path / f"{name}.html").read_text(encoding="utf-8")  # fmt: skip
        return html[html.index('<h2 id="reproducibility">'):]

    same = report([here], "same")
    assert "Every log records the same CPU dispatch, C library and BLAS kernels" in same
    assert "Logs made on other arithmetic" not in same
    mixed = report([here, here2, there], "mixed")
    assert "Logs made on other arithmetic" in mixed
    assert "numpy_cpu_dispatch" in mixed.split("Logs made on other arithmetic")[1].split("</p>")[0]
    assert "S/there: X86_V3 X86_V4 AVX512_ICL" in mixed
