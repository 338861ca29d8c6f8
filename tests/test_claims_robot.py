"""Every verdict branch of the robot claims (30–34), on small synthetic rows of the robots' table.

The rows hold the columns of :func:`pose_uncertainty.pipeline.robots.robot_row`; each case sets
numbers that must take one branch. The real pipeline's numbers are pinned in
tests/test_one_source.py (golden file).
"""

from __future__ import annotations

import math

import pytest
from scipy.stats import binom

from pose_uncertainty.pipeline.claims import (
    _Q95_SE_SQRT_N,
    NAV2_STRUCTURE,
    _max_misses,
    evaluate_claim,
)

QUANTITIES = ("E_d", "E_b", "wheel_radius_left", "wheel_radius_right", "track", "k_r", "k_l")


def _robot(name: str = "sim", misses: int = 0, **extra) -> dict:
    row: dict = {"robot": name}
    for i, q in enumerate(QUANTITIES):
        miss = i < misses
        row.update({q: 1.1 if miss else 1.0, f"{q}.true": 1.0, f"{q}.std_error": 0.01, f"{q}.ci_lo": 1.09 if miss else 0.98,
                    f"{q}.ci_hi": 1.11 if miss else 1.02, f"{q}.covers": 0 if miss else 1})  # fmt: skip
    row.update(extra)
    return row


def test_the_miss_bound_is_binomials_99_percent_quantile() -> None:
    for n in (7, 14, 70):
        assert _max_misses(n, 0.05) == int(binom.ppf(0.99, n, 0.05))


def test_claim30_branches() -> None:
    c = evaluate_claim({"robots": [_robot()]}, 30)
    assert c.verdict == "confirmed"
    assert c.numbers["n_covered"] == 7
    assert evaluate_claim({"robots": [_robot(misses=2)]}, 30).verdict == "confirmed"  # 2 of 7: P(Bin(7, .05) <= 2) > .99
    worse = evaluate_claim({"robots": [_robot(misses=3)]}, 30)
    assert worse.verdict == "qualified"
    assert worse.numbers["worst_z"] == pytest.approx(10.0)
    assert evaluate_claim({"robots": [_robot(misses=7)]}, 30).verdict == "refuted"
    recorded = {k: v for k, v in _robot().items() if not k.endswith((".true", ".covers"))}
    assert evaluate_claim({"robots": [recorded]}, 30).verdict == "not measured"  # no truth: nothing to recover


def _held(nees: float, cov: float, clo: float, chi: float) -> dict:
    return _robot(**{"held_out.nees_mean": nees, "held_out.nees_band_lo": 1.5, "held_out.nees_band_hi": 5.0,
                     "held_out.ellipse_coverage": cov, "held_out.coverage_lo": clo, "held_out.coverage_hi": chi,
                     "held_out.n_segments": 8})  # fmt: skip


def test_claim31_branches() -> None:
    assert evaluate_claim({"robots": [_held(3.0, 0.9, 0.6, 0.98)]}, 31).verdict == "confirmed"
    assert evaluate_claim({"robots": [_held(7.0, 0.9, 0.6, 0.98)]}, 31).verdict == "qualified"
    assert evaluate_claim({"robots": [_held(7.0, 0.5, 0.2, 0.8)]}, 31).verdict == "refuted"
    assert evaluate_claim({}, 31).verdict == "not measured"


def _nav2(overall: float, translation: float, rotation: float = 0.95, n_draws: int = 20000, per: int = 100,
          inc: int = 50) -> dict:  # fmt: skip
    return _robot(**{"nav2.level": 0.95, "nav2.coverage": overall, "nav2.n_draws": n_draws, "nav2.n_samples": per,
                     "nav2.translation.coverage": translation, "nav2.translation.increments": inc,
                     "nav2.rotation.coverage": rotation, "nav2.rotation.increments": inc})  # fmt: skip


def test_claim32_branches_and_band() -> None:
    band = 4 * math.sqrt(0.95 * 0.05 / 20000) + NAV2_STRUCTURE  # overall: 20000 draws
    assert evaluate_claim({"robots": [_nav2(0.95 + 0.9 * band, 0.95)]}, 32).verdict == "confirmed"
    assert evaluate_claim({"robots": [_nav2(0.95 + 1.1 * band, 0.95)]}, 32).verdict == "qualified"
    assert evaluate_claim({"robots": [_nav2(0.5, 0.5, 0.5)]}, 32).verdict == "refuted"


def _horizon(ratios: list[float], n: int = 1000) -> dict:
    return _robot(**{"horizon.n_mc": n, **{f"horizon.straight.{0.05 * (i + 1):g}.mc_ratio": r for i, r in enumerate(ratios)}})


def test_claim33_branches_and_tolerance() -> None:
    tol = 4 * _Q95_SE_SQRT_N / math.sqrt(1000)
    # the half-normal's 95th percentile at n = 1000: relative s.e. sqrt(.95 .05 / n) / (1.96 · 2φ(1.96)) = 3.0 %
    assert tol == pytest.approx(4 * 0.0301, rel=1e-2)
    assert evaluate_claim({"robots": [_horizon([1.0, 1 + 0.9 * tol])]}, 33).verdict == "confirmed"
    assert evaluate_claim({"robots": [_horizon([1.0, 1 + 1.1 * tol])]}, 33).verdict == "qualified"
    assert evaluate_claim({"robots": [_horizon([0.5, 1.6])]}, 33).verdict == "refuted"
    assert evaluate_claim({"robots": [_horizon([])]}, 33).verdict == "not measured"


def _umbmark(d_lo: float, d_hi: float, b_lo: float = 0.9, b_hi: float = 1.1) -> dict:
    return _robot(**{"umbmark.E_d": 0.5 * (d_lo + d_hi), "umbmark.E_d.ci_lo": d_lo, "umbmark.E_d.ci_hi": d_hi,
                     "umbmark.E_b": 0.5 * (b_lo + b_hi), "umbmark.E_b.ci_lo": b_lo, "umbmark.E_b.ci_hi": b_hi})  # fmt: skip


def test_claim34_branches() -> None:
    assert evaluate_claim({"robots": [_umbmark(0.95, 1.05)]}, 34).verdict == "confirmed"  # wider than 0.98–1.02
    assert evaluate_claim({"robots": [_umbmark(1.05, 1.2)]}, 34).verdict == "qualified"  # E_d misses the truth
    assert evaluate_claim({"robots": [_umbmark(1.001, 1.002, 1.001, 1.002)]}, 34).verdict == "refuted"
    assert evaluate_claim({"robots": [_robot()]}, 34).verdict == "not measured"  # no laps found
