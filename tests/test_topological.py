"""Topological localization (Skalka 2011 §2.7.1.2): the place graph of the room and the discrete
Bayes filter against brute-force enumeration of node sequences."""

import itertools
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.localization.sensors import cast_rays
from pose_uncertainty.localization.topological import (
    ACTIONS,
    PlaceGraph,
    PlaceModel,
    exits_from_ranges,
    place_graph,
    run_topological,
    sample_topological,
)
from pose_uncertainty.localization.world import load_world

ROOM = load_world("config/worlds/room.yaml")


def test_room_graph_has_corners_walls_and_pillar_junctions():
    g = place_graph(ROOM, spacing=1.0, clearance=0.3)
    # 9 × 7 lattice points inside the walls, less the one enclosed by the pillar
    assert g.n_nodes == 62
    assert np.bincount(g.exits, minlength=5).tolist() == [0, 0, 4, 28, 30]
    # 4 corners; 2·(7 + 5) wall sides + 4 places beside the pillar with 3 exits; the rest open
    opposite = [2, 3, 0, 1]
    for a in range(4):  # every edge is there both ways
        has = g.neighbours[:, a] >= 0
        assert np.all(g.neighbours[g.neighbours[has, a], opposite[a]] == np.flatnonzero(has))
    # the preprocessing of raw laser ranges sees the same exits
    ang = np.arange(4) * math.pi / 2
    r = cast_rays(ROOM.grid, np.repeat(g.positions, 4, axis=0), np.tile(ang, g.n_nodes), 8.0)
    assert np.array_equal(exits_from_ranges(r.reshape(-1, 4), reach=1.0 + 0.3), g.exits)


def _five_nodes():
    # a T junction: 0 — 1 — 2 along x, 3 north of 1, 4 east of 2
    nb = -np.ones((5, 4), dtype=np.int64)
    for i, a, j in ((0, 0, 1), (1, 0, 2), (2, 0, 4), (1, 1, 3)):
        nb[i, a], nb[j, (a + 2) % 4] = j, i
    return PlaceGraph(np.array([[0, 0], [1, 0], [2, 0], [1, 1], [3, 0]], dtype=float), nb,
                      (nb >= 0).sum(axis=1), n_features=5)  # fmt: skip


def test_filter_equals_brute_force_enumeration(rng):
    g = _five_nodes()
    model = PlaceModel(p_move=0.8, p_correct=0.7)
    T, L = model.transitions(g), model.likelihood(g)
    assert_allclose(T.sum(axis=-1), 1.0)
    assert_allclose(L.sum(axis=0), 1.0)
    prior = rng.dirichlet(np.ones(5))
    n_steps = 5
    actions = rng.integers(0, len(ACTIONS), n_steps)
    obs = rng.integers(1, 4, n_steps + 1)
    beliefs = run_topological(g, model, actions, obs, prior)
    # every node sequence l_0 … l_k with its joint probability, marginalised on its last node
    for k in range(n_steps + 1):
        seqs = np.array(list(itertools.product(range(5), repeat=k + 1)))  # (5^(k+1), k+1)
        p = prior[seqs[:, 0]] * L[obs[0], seqs[:, 0]]
        for j in range(1, k + 1):
            p = p * T[actions[j - 1], seqs[:, j - 1], seqs[:, j]] * L[obs[j], seqs[:, j]]
        marginal = np.bincount(seqs[:, -1], weights=p, minlength=5)
        assert_allclose(beliefs[k], marginal / marginal.sum(), rtol=1e-12, atol=1e-15)


def test_a_batch_of_runs_equals_each_run(rng):
    g = place_graph(ROOM)
    model = PlaceModel()
    acts = rng.integers(0, 5, (3, 6))
    _nodes, obs = sample_topological(g, model, rng.integers(0, g.n_nodes, 3), acts, rng)
    batch = run_topological(g, model, acts, obs)
    for r in range(3):
        assert_allclose(batch[r], run_topological(g, model, acts[r], obs[r]), rtol=1e-13)


def test_sampler_follows_the_model(rng):
    g = _five_nodes()
    model = PlaceModel(p_move=0.7, p_correct=0.6)
    n = 40_000
    nodes, obs = sample_topological(g, model, np.ones(n, dtype=np.int64), np.zeros((n, 1), dtype=np.int64), rng)
    T, L = model.transitions(g), model.likelihood(g)
    # frequencies within 5 binomial standard deviations of the model's probabilities
    for counts, p in ((np.bincount(nodes[:, 1], minlength=5), T[0, 1]),
                      (np.bincount(obs[:, 0], minlength=5), L[:, 1])):  # fmt: skip
        assert np.all(np.abs(counts / n - p) <= 5 * np.sqrt(p * (1 - p) / n) + 1e-12)


def test_graph_inputs_are_checked():
    with pytest.raises(ValueError, match="neighbours must"):
        PlaceGraph(np.zeros((2, 2)), np.array([[5, -1, -1, -1], [-1, -1, -1, -1]]), np.zeros(2))
    with pytest.raises(ValueError, match="p_move must be in"):
        PlaceModel(p_move=0.0)
    with pytest.raises(ValueError, match="observations must have shape"):
        run_topological(_five_nodes(), PlaceModel(), [0, 1], [1, 2])
