"""The dynamic-environment study (Skalka 2011 §5.1) against second routes to its numbers.

* the walking people: their closed-form bouncing paths equal a step-by-step simulation that reflects the
  velocity at each bound;
* the distance filter in both filters: with a threshold of 1 it leaves out no beam (the mixture's random
  component keeps P(short) below 1), so the filtered route through each filter gives the unfiltered route's
  numbers exactly; in the room without people no beam is blocked, and the default threshold drops beams among
  people;
* the histogram filter's correction with cells whose likelihood exceeds that of every cell with mass (which
  the distance filter produces) equals the brute-force Bayes rule;
* the scan-matching study: along a corridor whose ends are out of range the matches' spread is the search
  window's uniform spread (closed form).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pose_uncertainty.analysis.studies.dynamic_environment import (
    BEAM_MODELS,
    DYNAMIC_FILTERS,
    dynamic_environment_study,
    walking_discs,
)
from pose_uncertainty.localization.histogram import hf_correct
from pose_uncertainty.localization.world import load_world

TINY = {"tour": [["line", 1.0]], "densities": [0, 8], "repeat": 1, "n_particles": 60, "n_beams": 8,
        "grid_resolution": 0.5, "grid_ntheta": 8}  # fmt: skip


def test_walking_discs_equal_a_step_by_step_bounce():
    w = load_world("config/worlds/room.yaml")
    times = np.arange(0.0, 40.0, 0.01)
    discs = walking_discs(w, 5, 0.3, 0.7, times, np.random.default_rng(3))
    x0, x1, y0, y1 = w.bounds
    lo, hi = np.array([x0 + 0.3, y0 + 0.3]), np.array([x1 - 0.3, y1 - 0.3])
    p = discs[0, :, :2].copy()
    v = (discs[1, :, :2] - discs[0, :, :2]) / 0.01  # no disc starts at a bound (uniform start)
    np.testing.assert_allclose(np.hypot(*v.T), 0.7, rtol=1e-9)
    for k in range(1, times.size):  # the second route: Euler steps, the velocity mirrored at each bound
        p = p + v * 0.01
        over, under = p > hi, p < lo
        p = np.where(over, 2 * hi - p, np.where(under, 2 * lo - p, p))
        v = np.where(over | under, -v, v)
        np.testing.assert_allclose(discs[k, :, :2], p, atol=1e-9)
    assert np.all(discs[..., 2] == 0.3)
    assert np.all((discs[..., :2] >= lo - 1e-12) & (discs[..., :2] <= hi + 1e-12))


@pytest.mark.slow
def test_distance_filter_at_threshold_one_is_the_mixture_in_both_filters():
    r = dynamic_environment_study(**TINY, threshold=1.0)
    assert [row["n_obstacles"] for row in r["rows"]] == [0, 8]
    assert r["rows"][0]["blocked_share"] == 0.0
    assert r["rows"][1]["blocked_share"] > 0.0  # eight people in the room block some beams
    for row in r["rows"]:
        for f in DYNAMIC_FILTERS:
            assert set(row[f]) == set(BEAM_MODELS)
            assert row[f]["distance_filter"]["beams_used"] == 1.0
            assert row[f]["distance_filter"] == row[f]["mixture"]  # the same numbers by the filtered route
            for v in row[f].values():
                assert 0.0 <= v["success_low"] <= v["success_rate"] <= v["success_high"] <= 1.0


@pytest.mark.slow
def test_the_default_filter_drops_beams_among_people():
    r = dynamic_environment_study(**TINY)
    empty, crowd = r["rows"]
    # (in the empty room it drops some too: readings several σ_hit short of a particle's z* are likelier short)
    for f in DYNAMIC_FILTERS:
        assert crowd[f]["distance_filter"]["beams_used"] < 1.0
        assert crowd[f]["mixture"]["beams_used"] == 1.0
    assert empty["particle"]["mixture"]["success_rate"] == 1.0  # a 1 m line in an empty room: tracked


def test_hf_correct_ignores_likelier_cells_without_mass():
    rng = np.random.default_rng(8)
    belief = rng.random((4, 3, 2))
    belief[0] = 0.0
    belief /= belief.sum()
    loglik = rng.normal(0.0, 1.0, belief.shape) - 800.0
    loglik[0] = 0.0  # far likelier than every cell with mass: exp(800) would overflow
    post, logev = hf_correct(belief, loglik)
    assert np.all(np.isfinite(post))
    want = belief[1:] * np.exp(loglik[1:] + 800.0)  # the brute-force Bayes rule on the cells with mass, shifted
    want = np.concatenate([np.zeros_like(belief[:1]), want])
    np.testing.assert_allclose(post, want / want.sum(), rtol=1e-12)
    assert logev == pytest.approx(math.log(want.sum()) - 800.0, rel=1e-12)


@pytest.mark.slow
def test_scan_matching_study_corridor_spread_is_the_windows():
    from pose_uncertainty.analysis.studies.scan_matching import scan_matching_study

    r = scan_matching_study(tour=[["line", 1.0]], corridor_drive=1.0, repeat=1, n_particles=60, n_beams=12)
    c = r["corridor"]["ekf_matching"]
    # along the corridor every candidate of the window scores alike: a uniform spread over 21 offsets of
    # 0.05 m, σ = 0.05·√((21² − 1)/12 + 1/12) ≈ 0.30 m (the second route: the closed form)
    assert c["match_sigma_x"] == pytest.approx(0.05 * math.sqrt((21**2 - 1) / 12 + 1 / 12), rel=0.05)
    assert c["match_sigma_y"] < 0.1  # across: the walls fix it
    assert r["room"]["ekf_matching"]["match_sigma_x"] < 0.8 * c["match_sigma_x"]  # the room's end walls fix x better
    for place in ("room", "corridor"):
        for m in ("ekf_matching", "particle"):
            v = r[place][m]
            assert 0.0 <= v["failure_low"] <= v["failure_rate"] <= v["failure_high"] <= 1.0
