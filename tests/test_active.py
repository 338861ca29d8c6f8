"""Active localization (Skalka 2011 §5.2): the expected entropy, and entropy-driven motions against
random motions in a corridor designed so that only one direction disambiguates."""

import math

import numpy as np
from numpy.testing import assert_allclose

from pose_uncertainty.core.stats import wilson_interval
from pose_uncertainty.localization.active import (
    choose_action,
    entropy,
    expected_entropy,
    run_active,
)
from pose_uncertainty.localization.topological import ACTIONS, PlaceGraph, PlaceModel

CORRIDOR, DEAD_END, DOOR = 0, 1, 2
A, B = 2, 5  # the two places the robot may be at


def _corridor():
    """Eight places west → east; a door beside place 1 only. From A (2) or B (5): east sees a corridor
    from both, west a door from A and a corridor from B; north and south are walls."""
    n = 8
    nb = -np.ones((n, 4), dtype=np.int64)
    nb[:-1, 0] = np.arange(1, n)  # east
    nb[1:, 2] = np.arange(n - 1)  # west
    features = np.full(n, CORRIDOR)
    features[[0, n - 1]] = DEAD_END
    features[1] = DOOR
    return PlaceGraph(np.stack([np.arange(n), np.zeros(n)], -1).astype(float), nb, features, n_features=3)


def test_entropy_and_expected_entropy_by_two_routes(rng):
    assert entropy(np.full(4, 0.25)) == math.log(4)
    assert entropy(np.array([1.0, 0.0, 0.0])) == 0.0
    g, model = _corridor(), PlaceModel(p_move=0.8, p_correct=0.85)
    T, L = model.transitions(g), model.likelihood(g)
    prior = rng.dirichlet(np.ones(g.n_nodes))
    _, e = choose_action(prior, T, L)
    for a in range(len(ACTIONS)):
        pred = prior @ T[a]
        # explicit sum over the measurements
        ref = 0.0
        for z in range(L.shape[0]):
            joint = L[z] * pred
            ref += joint.sum() * entropy(joint / joint.sum())
        assert_allclose(e[a], ref, rtol=1e-12)
        # Monte Carlo: draw the node and the measurement, average the posterior's entropy
        n = 20_000
        nodes = rng.choice(g.n_nodes, n, p=pred)
        zs = (np.cumsum(L[:, nodes], axis=0) < rng.random(n)).sum(axis=0)
        post = L[zs] * pred
        h = entropy(post / post.sum(axis=1, keepdims=True))
        assert abs(h.mean() - e[a]) < 5 * h.std() / math.sqrt(n) + 1e-12


def test_entropy_choice_moves_west_where_only_west_disambiguates():
    g, model = _corridor(), PlaceModel(p_move=0.9, p_correct=0.9)
    prior = np.zeros(g.n_nodes)
    prior[[A, B]] = 0.5
    action, e = choose_action(prior, model.transitions(g), model.likelihood(g))
    assert ACTIONS[int(action)] == "west"
    assert e[ACTIONS.index("east")] > e[ACTIONS.index("west")]
    # east, north, south and stay teach nothing about A versus B: their expected entropy is the same
    same = [e[ACTIONS.index(x)] for x in ("north", "south", "stay")]
    assert_allclose(same, same[0], rtol=1e-12)


def test_entropy_policy_beats_random_motion():
    # moves that always happen (p_move = 1): the detector's errors are the only noise, so one good
    # look settles A versus B to 0.9/(0.9 + 0.05) = 0.947
    g, model = _corridor(), PlaceModel(p_move=1.0, p_correct=0.9)
    prior = np.zeros(g.n_nodes)
    prior[[A, B]] = 0.5
    n_trials = 400
    rng = np.random.default_rng(2011)
    start = rng.choice([A, B], n_trials)
    rates = {}
    for policy in ("entropy", "random"):
        runs = run_active(g, model, start, 1, np.random.default_rng(5), policy=policy, prior=prior)
        rates[policy] = int(runs.located(0.9).sum())
    # one step: the entropy policy localizes when the detector is right (0.9); random motion only
    # when it happens to go west (1/5 of the time: 0.18)
    lo_entropy, _ = wilson_interval(rates["entropy"], n_trials, confidence=0.999)
    _, hi_random = wilson_interval(rates["random"], n_trials, confidence=0.999)
    assert lo_entropy > hi_random, rates
    assert lo_entropy > 0.7, rates
    assert hi_random < 0.35, rates


def test_several_steps_localize_from_a_uniform_belief():
    g, model = _corridor(), PlaceModel(p_move=0.9, p_correct=0.9)
    rng = np.random.default_rng(3)
    runs = run_active(g, model, rng.integers(0, g.n_nodes, 200), 6, rng)
    assert runs.beliefs.shape == (200, 7, g.n_nodes)
    assert_allclose(runs.beliefs.sum(axis=-1), 1.0)
    h = entropy(runs.beliefs)
    assert h[:, -1].mean() < 0.5 * h[:, 0].mean()
    assert expected_entropy(runs.beliefs[:, :1], model.likelihood(g)).shape == (200, 1)
