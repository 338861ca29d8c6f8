"""The interactive explorer: its numbers are the library's, its config is the run's, it binds loopback.

The settings → numbers function (:func:`pose_uncertainty.present.explore.compute`) is checked
against routes that do not go through the run: the sampler, Method A's and Method C's
propagation and the coverage function called directly. The saved configuration is run with
``pose-uncertainty run`` and its log read back; a bad value gives the run's one-line error
(in the page too, keeping the last picture); the server, started as the command, listens on
127.0.0.1 only (the socket's address read from /proc).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hostile import interrupt, interruptible

from pose_uncertainty.analysis.accuracy import coverage_ellipse, pr_label
from pose_uncertainty.cli import main
from pose_uncertainty.core import trajectories
from pose_uncertainty.core.stats import mahalanobis_sq, pr_to_k, wilson_interval
from pose_uncertainty.experiments.config import RunConfig
from pose_uncertainty.methods import covariance, sampling, unscented
from pose_uncertainty.methods.particles import DrawCache
from pose_uncertainty.present import explore
from pose_uncertainty.records.formats import open_run

SRC = Path(__file__).resolve().parents[1] / "src"
SMALL = {
    "path": "arc",
    "size": "1.0",
    "dt": "0.02",
    "n_particles": "400",
    "k_r": "2e-3",
    "seed": "5",
}


@pytest.fixture(scope="module")
def view() -> explore.View:
    return explore.compute(explore.run_config(SMALL))


def test_compute_equals_the_library_called_directly(view: explore.View) -> None:
    """Cloud, Method A, Method C and their coverages recomputed without the run's executor."""
    cfg = RunConfig.from_dict(explore.run_config(SMALL))
    assert cfg.k_r == 2e-3
    assert cfg.trajectory["radius"] == 1.0
    assert cfg.monte_carlo.n_particles == 400
    traj = trajectories.from_config(cfg.trajectory)
    a = covariance.propagate(traj, cfg.k_r, cfg.k_l)
    c = unscented.propagate(traj, cfg.k_r, cfg.k_l)
    cloud = sampling.sample_end_poses(traj, cfg.k_r, cfg.k_l, 400, np.random.default_rng(cfg.seed),
                                      regime=cfg.monte_carlo.regime, method=cfg.monte_carlo.method)  # fmt: skip
    # the explorer's loops are the compiled ones: the same draws, equal to numpy's up to rounding
    compiled = sampling.sample_end_poses(traj, cfg.k_r, cfg.k_l, 400, np.random.default_rng(cfg.seed),
                                         regime=cfg.monte_carlo.regime, method=cfg.monte_carlo.method,
                                         kernel="compiled", draws="per-chunk")  # fmt: skip
    np.testing.assert_array_equal(view.result.end_poses, compiled)
    np.testing.assert_allclose(view.result.end_poses, cloud, rtol=0, atol=1e-12)
    np.testing.assert_allclose(view.result.unscented_covs, c.covs, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(view.result.covs[-1], a.covs[-1], rtol=1e-12, atol=0)
    pr = cfg.pr
    label = pr_label(pr)
    want_a = coverage_ellipse(cloud[:, :2], a.poses[-1, :2], a.covs[-1, :2, :2], (pr,))[label]
    want_c = coverage_ellipse(cloud[:, :2], c.poses[-1, :2], c.covs[-1, :2, :2], (pr,))[label]
    assert view.coverage["a"]["fraction"] == pytest.approx(want_a, abs=0.5 / 400)
    assert view.coverage["c"]["fraction"] == pytest.approx(want_c, abs=0.5 / 400)
    lo, hi = wilson_interval(round(want_a * 400), 400)
    assert (view.coverage["a"]["low"], view.coverage["a"]["high"]) == pytest.approx((lo, hi))
    assert view.coverage["a"]["low"] < view.coverage["a"]["fraction"] < view.coverage["a"]["high"]
    # the drawn regions: A's and C's boundaries lie on their own Pr-ellipses
    for key, res in (("a", a), ("c", c)):
        ring = view.regions[key][0]
        d2 = mahalanobis_sq(ring, res.poses[-1, :2], res.covs[-1, :2, :2])
        np.testing.assert_allclose(d2, float(pr_to_k(pr)), rtol=1e-6)
    assert "e" in view.regions
    assert view.regions["e"][0].shape[1] == 2
    # σ along/across: the final values are Methods A's and C's logged measures, and C's curve is
    # the unscented propagation's own covariances (called directly above) in the nominal frame
    for key, prefix in (("a", "A"), ("c", "C")):
        for w in ("along", "across"):
            assert view.spreads[key][f"sigma_{w}"][-1] == pytest.approx(
                view.result.metrics[f"{prefix}_sigma_{w}"], rel=1e-9
            ), (key, w)
    theta = view.result.poses[:, 2]
    along_c = np.sqrt(np.einsum("ni,nij,nj->n", np.stack([np.cos(theta), np.sin(theta)], -1),
                                c.covs[:, :2, :2], np.stack([np.cos(theta), np.sin(theta)], -1)))  # fmt: skip
    np.testing.assert_allclose(view.spreads["c"]["sigma_along"], along_c, rtol=1e-9, atol=1e-15)
    # the growth exponents are fits of those curves (a straight line of σ²: along ∝ s^(1/2) …)
    assert set(view.growth) == {"a", "c"}
    assert 0.3 < view.growth["a"]["sigma_along"]["power_exponent"] < 2.0
    assert view.distance[-1] == pytest.approx(view.result.metrics["path_length"], rel=1e-9)


def test_same_settings_same_picture(view: explore.View) -> None:
    again = explore.compute(explore.run_config(SMALL))
    np.testing.assert_array_equal(again.result.end_poses, view.result.end_poses)
    np.testing.assert_array_equal(again.regions["e"][0], view.regions["e"][0])
    assert again.coverage == view.coverage


def test_saved_config_runs_and_its_log_holds_the_numbers(
    view: explore.View, tmp_path: Path
) -> None:
    cfg = tmp_path / "explored.yaml"
    explore.save_run_config(cfg, explore.run_config(SMALL))
    out = tmp_path / "run.mcap"
    assert main(["run", str(cfg), "-o", str(out)]) == 0
    log = open_run(out)
    shown = view.result.metrics
    for key in ("accuracy_cartesian_coverage_xy_98_89", "accuracy_unscented_coverage_xy_98_89",
                "accuracy_expcoords_coverage_xy_98_89", "A_sigma_along", "MC_coverage_pr"):  # fmt: skip
        assert log.metrics[key] == shown[key], key
    # "Open a log": the explorer's settings come back from the log
    settings, base = explore.load_log_settings(out)
    assert {k: settings[k] for k in ("path", "n_particles", "seed", "regime")} == {
        "path": "arc", "n_particles": "400", "seed": "5", "regime": "per_step"}  # fmt: skip
    assert float(settings["k_r"]) == 2e-3
    assert float(settings["size"]) == 1.0
    reopened = explore.compute(explore.run_config(settings, base))
    assert reopened.coverage == view.coverage


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("k_r", "-1", "'k_r'"),
        ("k_l", "abc", "'k_l'"),
        ("track", "0", "track"),
        ("n_particles", "2.5", "n_particles"),
    ],
)
def test_bad_value_gives_the_run_config_one_line_error(field: str, value: str, words: str) -> None:
    data = explore.run_config({**SMALL, field: value})
    with pytest.raises(ValueError, match=field) as exc:
        explore.compute(data)
    msg = str(exc.value)
    assert "\n" not in msg
    assert words in msg
    assert repr(value).strip("'") in msg
    with pytest.raises(
        ValueError, match=field
    ) as same:  # the same line as the run's own validation
        RunConfig.from_dict(data)
    assert str(same.value) == msg


def test_map_alphas_are_the_run_configs() -> None:
    """The map's motion-model error constants: a field of the page, validated by the run config."""
    settings = {**TINY_MAP, "map_alphas": "0.1, 0.02, 0.03, 0.04"}
    cfg = RunConfig.from_dict(explore.run_config(settings))
    assert cfg.maps[0].params["alphas"] == [0.1, 0.02, 0.03, 0.04]
    default = RunConfig.from_dict(explore.run_config(TINY_MAP))  # empty: the model's own
    assert default.maps[0].params["alphas"] == [0.05] * 4
    with pytest.raises(ValueError, match="alphas") as exc:  # six for the odometry model's four
        RunConfig.from_dict(explore.run_config({**settings, "map_alphas": "0.1, 0.1, 0.1, 0.1, 0.1, 0.1"}))
    assert "\n" not in str(exc.value)
    with pytest.raises(ValueError, match="alphas"):  # not numbers
        RunConfig.from_dict(explore.run_config({**settings, "map_alphas": "a, b, c, d"}))
    with pytest.raises(ValueError, match=r"map alphas '\[1' is not a list"):  # not a list at all
        explore.run_config({**settings, "map_alphas": "[1"})


def test_cost_guard_refuses_in_the_explorer() -> None:
    data = explore.run_config(
        {**SMALL, "n_particles": "100000000", "size": "50", "path": "straight"}
    )
    RunConfig.from_dict(data)  # valid, but too costly
    with pytest.raises(ValueError, match="limit"):
        explore.compute(data)


def test_page_shows_the_error_and_keeps_the_last_picture() -> None:
    pytest.importorskip("bokeh")
    from bokeh.document import Document

    doc = Document()
    explore.make_document(doc, SMALL)
    k_r, err, cov = (doc.select_one({"name": n}) for n in ("field-k_r", "error", "coverage"))
    good = cov.text
    assert err.text == ""
    assert re.search(r'id="coverage-a">[0-9.]+<', good)
    k_r.value = "-3"
    assert "k_r" in err.text
    assert "-3" in err.text
    assert "\n" not in err.text
    assert cov.text == good  # the last good picture stays
    k_r.value = "8e-3"  # a larger k_r: the numbers change
    assert err.text == ""
    assert cov.text != good


def _listening(pid: int) -> list[tuple[str, int]]:
    """(address, port) of the TCP sockets the process listens on, from /proc."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            inodes.add(link[8:-1])
    out = []
    for table, width in (("tcp", 8), ("tcp6", 32)):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            f = line.split()
            if f[3] == "0A" and f[9] in inodes:  # LISTEN
                addr, port = f[1].split(":")
                raw = bytes.fromhex(addr)
                if width == 8:
                    ip = ".".join(str(b) for b in raw[::-1])
                else:
                    words = [raw[i : i + 4][::-1] for i in range(0, 16, 4)]
                    ip = ":".join(b"".join(words).hex()[i : i + 4] for i in range(0, 32, 4))
                out.append((ip, int(port, 16)))
    return out


@pytest.mark.slow  # the server in a new interpreter (imports bokeh)
def test_server_binds_loopback_by_default() -> None:
    pytest.importorskip("bokeh")
    env = {**os.environ, "PYTHONPATH": f"{SRC}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen(interruptible([sys.executable, "-m", "pose_uncertainty.cli", "explore"]), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)  # fmt: skip
    try:
        line = proc.stdout.readline() if proc.stdout else ""
        m = re.search(r"http://127\.0\.0\.1:(\d+)/", line)
        assert m, line
        port = int(m.group(1))
        assert _listening(proc.pid) == [("127.0.0.1", port)]
    finally:
        interrupt(proc)
    assert proc.returncode == 130  # interrupted: the CLI's status for SIGINT


def test_light_run_keeps_every_number_of_the_full_run(view: explore.View) -> None:
    """``execute(distances=False, coverage_only=True)`` (each move of a control) leaves out the
    accuracy comparison's entries the page does not show: every measure it keeps equals the full
    run's to the bit (the generator is drawn from alike), every region's planar coverage among them."""
    from pose_uncertainty.experiments.run import execute

    # the explorer's loops: the compiled ones on numpy's per-chunk draws, which a DrawCache keeps
    full = execute(view.config, kernel="compiled", cache=DrawCache()).metrics
    light = view.result.metrics
    left_out = set(full) - set(light)
    assert set(light) <= set(full)
    assert left_out
    assert all(k.startswith("accuracy_") and "_coverage_xy_" not in k for k in left_out)
    assert {k for k in full if "_coverage_xy_" in k} <= set(light)
    assert {k: light[k] for k in light} == {k: full[k] for k in light}
    # without coverage_only every entry but the density distances is kept, as before
    no_distances = execute(view.config, distances=False, kernel="compiled", cache=DrawCache()).metrics
    assert all(k.endswith(("hellinger", "kl", "model_mass_on_grid", "_floor")) for k in set(full) - set(no_distances))
    # against the numpy loops a run logs: every coverage (a count) the same, the rest up to rounding
    logged = execute(view.config).metrics
    assert {k: light[k] for k in light if "coverage" in k} == {k: logged[k] for k in light if "coverage" in k}
    for k in light:
        assert light[k] == pytest.approx(logged[k], rel=1e-9, abs=1e-12, nan_ok=True), k
    # the banana's level is the one its coverage used: the share of the cloud at or above it
    from pose_uncertainty.methods import expcoords

    cfg = view.config
    traj = trajectories.from_config(cfg.trajectory)
    E = expcoords.propagate(traj, cfg.k_r, cfg.k_l)
    dens = expcoords.pdf_xy(view.result.end_poses[:, :2], E.poses[-1], E.covs[-1])
    label = pr_label(cfg.pr).replace(".", "_")
    level = view.result.expcoords_levels[label]
    assert float(np.mean(dens >= level)) == light[f"accuracy_expcoords_coverage_xy_{label}"]
    assert not any("level" in k for k in full)  # the levels are not logged measures


TINY_MAP = {**SMALL, "path": "straight", "size": "0.3", "dt": "0.05", "map": "odometry", "map_resolution": "0.02"}


def test_page_draws_the_map_region_and_its_coverage_of_each_new_cloud() -> None:
    """The map is the run's (its region the Pr region of the run's map), its coverage the library's
    for the cloud shown; a k_r move redraws the coverage without recomputing the map."""
    pytest.importorskip("bokeh")
    from bokeh.document import Document

    from pose_uncertainty.analysis.accuracy import coverage_gridded

    doc = Document()
    explore.make_document(doc, TINY_MAP, background=False)
    status, source, err = (doc.select_one({"name": n}) for n in ("map-status", "source-map", "error"))
    assert err.text == ""
    view = explore.compute(explore.run_config(TINY_MAP))
    mp = view.result.maps[0]
    label = pr_label(view.config.pr)
    want = coverage_gridded(mp, view.result.end_poses[:, :2], [view.config.pr])[label]
    assert re.search(r'id="coverage-map">([0-9.]+)<', status.text).group(1) == f"{100 * want:.2f}"
    assert len(source.data["xs"]) >= 1
    # the drawn boundary encloses the map's Pr region: its cells of mass ≥ the level
    level, _ = mp.region_xy(view.config.pr)
    ring = np.column_stack([source.data["xs"][0], source.data["ys"][0]])
    from matplotlib.path import Path as Polygon

    marg = mp.marginal_xy()
    i, j = np.unravel_index(int(np.argmax(marg)), marg.shape)
    assert marg[i, j] >= level
    assert Polygon(ring).contains_point((mp.x[i], mp.y[j]))
    # a k_r move: a new cloud, the same map (not recomputed), the coverage of the new cloud
    doc.select_one({"name": "field-k_r"}).value = "6e-3"
    moved = explore.compute(explore.run_config({**TINY_MAP, "k_r": "6e-3"}))
    np.testing.assert_array_equal(moved.result.maps[0].values, mp.values)  # the map ignores k_r
    again = coverage_gridded(mp, moved.result.end_poses[:, :2], [view.config.pr])[label]
    assert re.search(r'id="coverage-map">([0-9.]+)<', status.text).group(1) == f"{100 * again:.2f}"
    assert again != want


TOUR = {**SMALL, "path": "tour", "segments": "[[line, 0.5], [turn, 1.5708], [arc, 0.4, 1.0]]", "profile": "ramp"}
SOURCES = {**SMALL, "error_sources": "pulses_per_rev: 200, surface_rel_std: 0.02"}


def test_segments_profile_and_error_sources_are_the_run_configs(tmp_path: Path) -> None:
    """The path as a list of segments, the speed profile and the wheel-noise model's error sources:
    page fields that become the run configuration's keys, change the picture, and round-trip
    through a saved config, ``pose-uncertainty run`` and "Open a log"."""
    base = explore.compute(explore.run_config(SMALL))
    cfg = RunConfig.from_dict(explore.run_config(TOUR))
    assert cfg.trajectory["segments"] == [["line", 0.5], ["turn", 1.5708], ["arc", 0.4, 1.0]]
    assert cfg.trajectory["profile"] == "ramp"
    want = trajectories.tour([["line", 0.5], ["turn", 1.5708], ["arc", 0.4, 1.0]], profile="ramp",
                             speed=0.5, dt=0.02, track=0.2)  # fmt: skip
    src = RunConfig.from_dict(explore.run_config(SOURCES))
    assert src.drive is not None
    assert src.drive.type == "differential"
    assert src.drive.errors.encoder["pulses_per_rev"] == 200
    assert src.drive.errors.encoder["surface_rel_std"] == 0.02
    for settings in (TOUR, SOURCES):
        view = explore.compute(explore.run_config(settings))
        assert view.coverage["a"] != base.coverage["a"] or view.regions["a"][0].shape != base.regions["a"][0].shape
        assert not np.array_equal(view.result.covs[-1], base.result.covs[-1])
        if settings is TOUR:
            assert view.result.n_steps == want.n_steps
            a = covariance.propagate(want, 2e-3, 5e-4)  # Method A on the tour built directly
            np.testing.assert_array_equal(view.result.poses, a.poses)
            np.testing.assert_allclose(view.result.covs, a.covs, rtol=1e-12, atol=0)
        path = explore.save_run_config(tmp_path / "explored.yaml", explore.run_config(settings))
        out = tmp_path / "explored.mcap"
        assert main(["run", str(path), "-o", str(out)]) == 0
        logged = open_run(out).metrics
        for key, name in (("a", "cartesian"), ("c", "unscented"), ("e", "expcoords")):
            if key in view.coverage:
                assert view.coverage[key]["fraction"] == logged[f"accuracy_{name}_coverage_xy_98_89"], key
        assert ("c" in view.coverage) == (settings is TOUR)  # Method C is the two-wheel k model's
        opened, cfg_map = explore.load_log_settings(out)
        for k in ("path", "profile", "segments", "error_sources"):
            assert RunConfig.from_dict(explore.run_config(opened, cfg_map)).to_dict() == RunConfig.from_dict(
                explore.run_config(settings)).to_dict(), k  # fmt: skip
        out.unlink()


def test_a_bad_segment_list_shows_its_one_line_error_and_keeps_the_picture() -> None:
    pytest.importorskip("bokeh")
    from bokeh.document import Document

    doc = Document()
    explore.make_document(doc, TOUR, background=False)
    segs, err, cov, src = (doc.select_one({"name": n}) for n in ("field-segments", "error", "coverage", "source-a"))
    good, ring = cov.text, list(src.data["xs"][0])
    assert err.text == ""
    for bad, words in (("[[line]]", "segments[0]"), ("[[jump, 1.0]]", "jump"), ("[[line, 1", "not a list")):
        segs.value = bad
        assert words in err.text
        assert "\n" not in err.text
        assert cov.text == good
        assert list(src.data["xs"][0]) == ring
    segs.value = "[[line, 0.8]]"  # a good list again: a new picture
    assert err.text == ""
    assert cov.text != good


def test_a_change_of_the_map_fields_or_back_to_the_picture_computes_no_move(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only what a control invalidates is computed: the map's own fields start its background
    computation only, and a bad value typed back to the shown one clears the error, no move."""
    pytest.importorskip("bokeh")
    from bokeh.document import Document

    doc = Document()
    explore.make_document(doc, SMALL, background=False)
    calls: list[str] = []
    real = explore.compute

    def counted(data: object, progress: object = None) -> explore.View:
        calls.append("map" if data["maps"] else "move")  # type: ignore[index]
        return real(data, progress)  # type: ignore[arg-type]

    monkeypatch.setattr(explore, "compute", counted)
    cov, err = doc.select_one({"name": "coverage"}), doc.select_one({"name": "error"})
    shown = cov.text
    doc.select_one({"name": "field-map_resolution"}).value = "0.05"  # no map: nothing at all
    assert calls == []
    k_l = doc.select_one({"name": "field-k_l"})
    k_l.value = "-1"
    assert "k_l" in err.text
    k_l.value = SMALL.get("k_l", explore.DEFAULTS["k_l"])  # back to the picture shown
    assert err.text == ""
    assert cov.text == shown
    assert calls == ["move"]  # the bad value's validation only
    doc.select_one({"name": "field-k_r"}).value = "3e-3"
    assert calls == ["move", "move"]
    assert cov.text != shown


def test_a_move_of_the_probability_level_reuses_the_clouds_and_gives_the_same_numbers() -> None:
    """``execute(reuse=…)`` of a result that differs in pr only: the same metrics as a fresh run
    (every level's coverage was measured at once), the same cloud object, no Monte Carlo."""
    from pose_uncertainty.analysis.accuracy import PRS
    from pose_uncertainty.experiments.run import execute

    first = RunConfig.from_dict(explore.run_config({**SMALL, "pr": pr_label(PRS[-1])}))
    other = RunConfig.from_dict(explore.run_config({**SMALL, "pr": pr_label(PRS[0])}))
    kw = {"distances": False, "coverage_only": True, "kernel": "compiled", "cache": DrawCache()}
    old = execute(first, **kw)
    fresh = execute(other, **kw)
    reused = execute(other, reuse=old, **kw)
    assert reused.metrics == fresh.metrics
    assert reused.expcoords_levels == fresh.expcoords_levels
    assert reused.end_poses is old.end_poses
    assert "monte_carlo_s" not in reused.timings
    np.testing.assert_array_equal(reused.unscented_covs, fresh.unscented_covs)
    with pytest.raises(ValueError, match="differs in pr only"):
        execute(RunConfig.from_dict(explore.run_config({**SMALL, "k_r": "1e-3"})), reuse=old, **kw)
    # in the explorer: a level change draws the same cloud's coverage at the new level
    view = explore.compute(explore.run_config({**SMALL, "pr": pr_label(PRS[0])}))
    assert view.coverage["a"]["fraction"] == fresh.metrics[f"accuracy_cartesian_coverage_xy_{pr_label(PRS[0])}"]
