"""UMBmark: the systematic-error simulator, the small-angle formulas, the direct fit, intervals, CSV, CLI."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty import cli
from pose_uncertainty.analysis import umbmark as um
from pose_uncertainty.methods import systematic as sy

L, B = 4.0, 0.3  # Borenstein's 4 m square; a 0.3 m track
NOMINAL = sy.WheelGeometry(B)
CALIBRATE_DOC = Path(__file__).resolve().parents[1] / "docs" / "howto" / "calibrate.md"


def _truth(E_d, E_b):
    """True geometry, and UMBmark's α (turn deficit) and β (leg curvature) for it [rad]."""
    g = sy.WheelGeometry.from_ratios(B, E_d, E_b)
    return g, (math.pi / 2) * (1 - 1 / E_b), L * (g.scale_r - g.scale_l) / g.track


def _noiseless(true, odometry=NOMINAL):
    return {
        d: sy.return_errors_noiseless(
            L, d, true.scale_r, true.scale_l, true.track,
            odometry.scale_r, odometry.scale_l, odometry.track,
        )
        for d in sy.DIRECTIONS
    }


# --- the simulator ------------------------------------------------------------------------------


@pytest.mark.parametrize(("E_d", "E_b"), [(1.002, 1.01), (0.997, 0.99), (1.0, 1.0)])
def test_step_by_step_simulation_equals_the_segment_kernel(E_d, E_b):
    """Two routes: 10 ms steps through sampling.sample_end_poses (k = 0) vs one exact arc per segment."""
    true, _, _ = _truth(E_d, E_b)
    corrected = sy.WheelGeometry.from_ratios(B, 1.001, 1.004)
    for odometry in (NOMINAL, corrected):
        seg = _noiseless(true, odometry)
        for d in sy.DIRECTIONS:
            runs = sy.return_errors(L, d, true, odometry, 3, np.random.default_rng(0), dt=0.01)
            assert_allclose(runs, np.broadcast_to(seg[d], (3, 2)), rtol=0, atol=1e-11)


def test_sign_convention_first_order():
    """ε = true − odometry in the start frame: ε_ccw ≈ 2L(β−α)(1, −1), ε_cw ≈ −2L(α+β)(1, 1).

    A wider true track (E_b > 1) turns too little (α > 0); a larger right wheel (E_d > 1)
    curves each leg left (β > 0). Second-order terms are below 2L·3(|α|+|β|)² here.
    """
    true, alpha, beta = _truth(1.0002, 1.001)
    c = _noiseless(true)
    tol = 2 * L * 3 * (abs(alpha) + abs(beta)) ** 2
    assert alpha > 0
    assert beta > 0
    assert_allclose(c["ccw"], 2 * L * (beta - alpha) * np.array([1, -1]), atol=tol)
    assert_allclose(c["cw"], -2 * L * (alpha + beta) * np.array([1, 1]), atol=tol)


def test_no_systematic_error_returns_home_and_noise_scatters():
    c = _noiseless(NOMINAL)
    assert_allclose(np.concatenate(list(c.values())), 0.0, atol=1e-14)
    runs = sy.umbmark_runs(L, NOMINAL, NOMINAL, 200, np.random.default_rng(3), k_r=1e-6, k_l=1e-6, dt=0.05)
    assert runs["cw"].shape == (200, 2)
    assert runs["cw"].std(axis=0).min() > 1e-3


# --- the small-angle derivation against the direct fit ----------------------------------------------


@pytest.mark.parametrize("base", [(0.002, 0.01), (-0.002, 0.01), (0.002, -0.01), (0.001, 0.0), (0.0, 0.01)])
def test_zero_random_error_recovers_to_the_small_angle_accuracy(base):
    """UMBmark's error is its derived second-order term up to a third-order remainder.

    α̂ − α = −α² − (3/2)β² − ½(b/L)²β² + R_α,   β̂ − β = −(5/2)αβ − ½(b/L)²αβ + R_β,
    Ê_b − E_b = (π/2)/(π/2 − α)²·(α̂ − α)₂ + R_b,  Ê_d − E_d = (b/L)[(β̂ − β)₂ − (E_b − 1)β] + R_d
    (module docstring of analysis.umbmark; ₂: the second-order terms). Shrinking both
    errors 4-fold must shrink every R 64-fold (third order; a wrong second-order
    coefficient would leave a 16-fold shrink); 25 % is left for the fourth-order terms.
    The direct fit has no approximation: exact to the solver's floor.
    """
    g2 = (B / L) ** 2
    rem = []
    for h in (1.0, 0.25):
        E_d, E_b = 1 + base[0] * h, 1 + base[1] * h
        true, a, b = _truth(E_d, E_b)
        c = _noiseless(true)
        p = um.umbmark_parameters(c["cw"], c["ccw"], L, B)
        err_a = -a * a - 1.5 * b * b - 0.5 * g2 * b * b
        err_b = -2.5 * a * b - 0.5 * g2 * a * b
        rem.append((
            p["alpha"] - a - err_a,
            p["beta"] - b - err_b,
            p["E_b"] - E_b - (math.pi / 2) / (math.pi / 2 - a) ** 2 * err_a,
            p["E_d"] - E_d - (B / L) * (err_b - (E_b - 1) * b),
        ))
        fit_d, fit_b = um.direct_fit(c["cw"], c["ccw"], L, B)
        assert_allclose([fit_d, fit_b], [E_d, E_b], rtol=0, atol=1e-12)
    for j in range(4):
        assert abs(rem[1][j]) <= 1.25 * abs(rem[0][j]) / 64 + 1e-16, j


def test_correction_shrinks_e_max():
    """Re-simulate with the corrected odometry: E_max,syst falls, to what UMBmark predicts.

    UMBmark's correction leaves the small-angle residue (≈ 4 % of E_max here); the
    direct fit's leaves nothing.
    """
    true, _, _ = _truth(1.002, 1.01)
    before = _noiseless(true)
    res = um.umbmark(
        {d: np.repeat(before[d][None], 2, axis=0) for d in sy.DIRECTIONS}, L, B, None, n_boot=0
    )
    after = _noiseless(true, res.corrected())
    e_before, e_after = um.e_max_syst(before["cw"], before["ccw"]), um.e_max_syst(after["cw"], after["ccw"])
    assert e_after < 0.1 * e_before
    assert res.estimates["E_max_before"].value == pytest.approx(float(e_before), rel=1e-14)
    assert res.estimates["E_max_after_predicted"].value == pytest.approx(float(e_after), rel=1e-8)
    fit = sy.WheelGeometry.from_ratios(B, res.estimates["E_d_fit"].value, res.estimates["E_b_fit"].value)
    exact = _noiseless(true, fit)
    assert um.e_max_syst(exact["cw"], exact["ccw"]) < 1e-10
    # zero scatter: both intervals collapse on the estimate
    e = res.estimates["E_d"]
    assert e.std_error == 0.0
    assert e.delta == (e.value, e.value)


# --- intervals from the scatter --------------------------------------------------------------


def _coverage(E_d, E_b, n_runs, repeats, n_boot, names, seed):
    true, _, _ = _truth(E_d, E_b)
    rng = np.random.default_rng(seed)
    runs = {
        d: sy.return_errors(L, d, true, NOMINAL, repeats * n_runs, rng, k_r=1e-6, k_l=1e-6, dt=0.02)
        .reshape(repeats, n_runs, 2)
        for d in sy.DIRECTIONS
    }
    truth = {"E_d": E_d, "E_b": E_b, "E_d_fit": E_d, "E_b_fit": E_b}
    hits = {(name, kind): 0 for name in names for kind in ("delta", "bootstrap")}
    for i in range(repeats):
        res = um.umbmark(
            {d: runs[d][i] for d in sy.DIRECTIONS}, L, B, np.random.default_rng(i), n_boot=n_boot
        )
        for name in names:
            e = res.estimates[name]
            hits[name, "delta"] += e.delta[0] <= truth[name] <= e.delta[1]
            hits[name, "bootstrap"] += e.bootstrap[0] <= truth[name] <= e.bootstrap[1]
    return {k: v / repeats for k, v in hits.items()}


@pytest.mark.slow
def test_delta_intervals_cover_the_truth_at_the_nominal_rate():
    """1000 seeded repeats of 10 cw + 10 ccw runs (k = 10⁻⁶ m, heading noise ≈ 0.02 rad per lap).

    Truth E_d = 1.0005, E_b = 1.005: UMBmark's small-angle bias is ≈ 0.1 standard error
    and the noise-induced bias smaller, so the 95 % intervals should cover 95 %; the
    binomial standard deviation of a coverage from 1000 repeats is √(0.95·0.05/1000) = 0.7 %,
    and 3 of them bound the check.
    """
    cov = _coverage(1.0005, 1.005, 10, 1000, 0, ("E_d", "E_b", "E_d_fit", "E_b_fit"), seed=5)
    tol = 3 * math.sqrt(0.95 * 0.05 / 1000)
    for name in ("E_d", "E_b", "E_d_fit", "E_b_fit"):
        assert abs(cov[name, "delta"] - 0.95) <= tol, (name, cov[name, "delta"])


@pytest.mark.slow
def test_bootstrap_intervals_cover_with_enough_runs():
    """Percentile bootstrap, 40 runs per direction (with 5–10 it undercovers: no t-correction).

    Direct fit (no small-angle bias), 150 repeats × 400 resamples: binomial tolerance
    3·√(0.95·0.05/150) = 5.3 %.
    """
    cov = _coverage(1.002, 1.01, 40, 150, 400, ("E_d_fit", "E_b_fit"), seed=9)
    tol = 3 * math.sqrt(0.95 * 0.05 / 150)
    for name in ("E_d_fit", "E_b_fit"):
        assert abs(cov[name, "bootstrap"] - 0.95) <= tol, (name, cov[name, "bootstrap"])


def test_bootstrap_is_reproducible_and_welch_df_in_range():
    true, _, _ = _truth(1.002, 1.01)
    runs = sy.umbmark_runs(L, true, NOMINAL, 5, np.random.default_rng(1), k_r=1e-6, k_l=1e-6, dt=0.05)
    a = um.umbmark(runs, L, B, np.random.default_rng(4), n_boot=300)
    b = um.umbmark(runs, L, B, np.random.default_rng(4), n_boot=300)
    assert a == b
    alpha = a.estimates["alpha"]
    # α is linear in the centres: its standard error is the two-sample one, exactly
    se = math.sqrt(np.var(runs["cw"][:, 0], ddof=1) / 5 + np.var(runs["ccw"][:, 0], ddof=1) / 5) / (4 * L)
    assert alpha.std_error == pytest.approx(se, rel=1e-6)
    assert 4 <= alpha.df <= 8  # Welch: between n − 1 and 2n − 2
    assert alpha.delta[0] < alpha.value < alpha.delta[1]


# --- CSV and command line ---------------------------------------------------------------------


def _csv(tmp_path, text, name="r.csv"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("direction,x\ncw,1\n", r"missing column\(s\) 'y' in the header"),
        ("direction,x,y\ncw,0.1,abc\n", r"line 2: column 'y': not a number: 'abc'"),
        ("direction,x,y\ncw,nan,0.1\n", r"line 2: column 'x': not finite: 'nan'"),
        ("direction,x,y\ncw,0.1,0.2\nleft,0.1,0.2\n", r"data row 2: column 'direction' must be 'cw' or 'ccw', got 'left'"),
        ("direction,x,y\ncw,0.1,0.2\ncw,0.1,0.2\nccw,0,0\n", r"too few runs: 2 cw and 1 ccw \(need at least 2"),
        ("direction,x,y\ncw,0.1,0.2\n", r"too few runs: 1 cw and 0 ccw"),
        ("", r"empty file"),
    ],
)
def test_bad_csvs_one_line_errors(tmp_path, text, match):
    p = _csv(tmp_path, text)
    with pytest.raises(ValueError, match=match) as info:
        um.read_returns_csv(p)
    assert "\n" not in str(info.value)
    assert str(p) in str(info.value)


def test_bad_settings_one_line_errors():
    runs = {"cw": np.zeros((3, 2)), "ccw": np.zeros((3, 2))}
    with pytest.raises(ValueError, match=r"^side must be > 0"):
        um.umbmark(runs, -1.0, B, None, n_boot=0)
    with pytest.raises(ValueError, match=r"^rng must be a numpy.random.Generator for the bootstrap"):
        um.umbmark(runs, L, B, None)
    with pytest.raises(ValueError, match=r"^returns\['ccw'\] must have shape \(n, 2\) with n >= 2"):
        um.umbmark({"cw": np.zeros((3, 2)), "ccw": np.zeros((1, 2))}, L, B, None, n_boot=0)
    with pytest.raises(ValueError, match=r"^the return errors are too large for UMBmark's formulas"):
        um.umbmark({"cw": np.full((3, 2), 40.0), "ccw": np.full((3, 2), 40.0)}, L, B, None, n_boot=0)


def _readme_csv():
    """The example CSV of the calibration how-to's UMBmark section (the first block after its heading)."""
    text = CALIBRATE_DOC.read_text(encoding="utf-8")
    section = text[text.index("## Systematic errors with UMBmark") :]
    return re.search(r"```text\n(direction,x,y\n.*?)```", section, re.DOTALL).group(1)


def test_readme_example_parses_and_cli_end_to_end(tmp_path, capsys):
    p = _csv(tmp_path, _readme_csv(), "returns.csv")
    runs = um.read_returns_csv(p)
    assert runs["cw"].shape == (5, 2)
    assert runs["ccw"].shape == (5, 2)
    argv = ["calibrate", "--method", "umbmark", str(p), "--side", "4", "--track", "0.3"]
    assert cli.main([*argv, "--n-boot", "200", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    lib = um.umbmark(runs, 4.0, 0.3, np.random.default_rng(0), n_boot=200)
    assert out == json.loads(json.dumps(lib.as_dict()))
    E_d = out["estimates"]["E_d"]
    assert E_d["delta_ci"][0] < E_d["value"] < E_d["delta_ci"][1]
    assert cli.main([*argv, "--diameter", "0.1", "--after", str(p)]) == 0
    text = capsys.readouterr().out
    for needle in ("E_d ", "E_b ", "corrected odometry: D_R = ", "E_max,syst [m]: before", "after (measured)"):
        assert needle in text


def test_cli_umbmark_errors_are_one_line(tmp_path, capsys):
    p = _csv(tmp_path, _readme_csv(), "returns.csv")
    for argv, needle in (
        (["calibrate", "--method", "umbmark", str(p)], "needs --side L"),
        (["calibrate", "--method", "umbmark", str(p), "--side", "4", "--track", "0.3", "--ci", "fisher"],
         "--ci fisher is for --method ml"),
        (["calibrate", "--method", "umbmark", str(tmp_path / "nope.csv"), "--side", "4", "--track", "0.3"],
         "no such file"),
    ):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("error: ")
        assert err.count("\n") == 1
        assert needle in err
