"""Active localization: choose the next motion that minimises the expected entropy of the belief (Skalka 2011 §5.2).

Skalka 2011 §5.2 (after Fox, Burgard & Thrun 1998): the uncertainty of a belief is its entropy
``H(Bel) = −Σ_l Bel(l) log Bel(l)``; after action ``a`` and measurement ``z`` the belief is
``Bel(l | a, z) ∝ P(z | l) Bel(l | a)``, and the expected entropy of action ``a`` averages over the
measurements it may bring::

    E_a[H] = Σ_z P(z | a) H(Bel(· | a, z)),      P(z | a) = Σ_l P(z | l) Bel(l | a)
           = Σ_z [ P(z | a) log P(z | a) − Σ_l J log J ],   J = P(z | l) Bel(l | a)

(the second line, used here, needs no division and holds where ``P(z | a) = 0``). Active navigation
takes ``argmin_a E_a[H]``.

:func:`expected_entropy` takes the *predicted* beliefs ``Bel(l | a)`` of the candidate actions and a
discrete measurement model ``P(z | l)``, so it serves any discrete belief: the topological filter
(:func:`choose_action`, :func:`run_active`; predictions by the transition matrices) or a histogram
filter (its grid predicted once per candidate motion, flattened, with the likelihood of a discretised
measurement on the cells).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_choice, check_finite, check_positive_int
from .topological import (
    PlaceGraph,
    PlaceModel,
    sample_features,
    sample_step,
    topological_correct,
    topological_predict,
)

__all__ = ["POLICIES", "ActiveRun", "choose_action", "entropy", "expected_entropy", "run_active"]

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Action choices of :func:`run_active`.
POLICIES: tuple[str, ...] = ("entropy", "random")


def _xlogx(a: Array) -> Array:
    """``a log a`` with ``0 log 0 = 0``."""
    return np.where(a > 0, a * np.log(np.where(a > 0, a, 1.0)), 0.0)


def entropy(belief: ArrayLike) -> Array:
    """``H = −Σ_l Bel(l) log Bel(l)`` [nats] of normalised beliefs (..., n), shape (...)."""
    return np.asarray(-_xlogx(check_finite("belief", belief)).sum(axis=-1))


def expected_entropy(predicted: ArrayLike, likelihood: ArrayLike) -> Array:
    """Expected posterior entropy [nats] of each candidate action (module docs).

    Parameters
    ----------
    predicted : array_like, shape (..., A, n) — ``Bel(l | a)`` of every candidate action
    likelihood : array_like, shape (Z, n) — ``P(z | l)`` of every discrete measurement ``z``

    Returns
    -------
    ndarray, shape (..., A)
    """
    b = check_finite("predicted", predicted)
    L = check_finite("likelihood", likelihood)
    J = b[..., None, :] * L  # (..., A, Z, n)
    pz = J.sum(axis=-1)
    return np.asarray((_xlogx(pz) - _xlogx(J).sum(axis=-1)).sum(axis=-1))


def choose_action(belief: ArrayLike, transitions: ArrayLike, likelihood: ArrayLike) -> tuple[IntArray, Array]:
    """The action of least expected entropy for beliefs (..., n) (ties: the first).

    Parameters
    ----------
    belief : array_like, shape (..., n); transitions : array_like, shape (A, n, n); likelihood : (Z, n)

    Returns
    -------
    action : ndarray of int, shape (...); expected : ndarray, shape (..., A) — ``E_a[H]``
    """
    b = check_finite("belief", belief)
    T = check_finite("transitions", transitions)
    pred = topological_predict(b[..., None, :], T)  # (..., A, n)
    e = expected_entropy(pred, likelihood)
    return np.asarray(np.argmin(e, axis=-1), dtype=np.int64), e


@dataclass(frozen=True, eq=False)
class ActiveRun:
    """Runs of active (or random) localization on a place graph.

    Attributes
    ----------
    nodes, observations : ndarray of int, shape (R, T+1); actions : ndarray of int, shape (R, T)
    beliefs : ndarray, shape (R, T+1, n)
    """

    nodes: IntArray
    observations: IntArray
    actions: IntArray
    beliefs: Array

    def located(self, threshold: float = 0.9) -> NDArray[np.bool_]:
        """Whether each run's final belief puts at least ``threshold`` on its true node, shape (R,)."""
        last = self.beliefs[:, -1]
        return np.asarray(last[np.arange(last.shape[0]), self.nodes[:, -1]] >= threshold)


def run_active(graph: PlaceGraph, model: PlaceModel, start: ArrayLike, n_steps: int, rng: np.random.Generator,
               policy: str = "entropy", prior: ArrayLike | None = None,
               actions: ArrayLike | None = None) -> ActiveRun:  # fmt: skip
    """Simulate runs that localize while choosing their motions, every run at once.

    At each step every run observes its node's feature, updates its belief and picks its next
    action: the least expected entropy (``"entropy"``), or uniformly among ``actions`` (``"random"``).

    Parameters
    ----------
    graph, model : the places and the model
    start : array_like of int, shape (R,) — true start nodes
    n_steps : int ≥ 1; rng : numpy.random.Generator — the truth's and the random policy's draws
    policy : {"entropy", "random"}
    prior : array_like, shape (n,), optional — the initial belief (default uniform)
    actions : sequence of int, optional — the candidate actions (default every action)
    """
    check_choice("policy", policy, POLICIES)
    steps = check_positive_int("n_steps", n_steps)
    T, L = model.transitions(graph), model.likelihood(graph)
    cand = np.arange(T.shape[0]) if actions is None else np.asarray(actions, dtype=np.int64)
    s = np.asarray(start, dtype=np.int64).reshape(-1)
    R, n = s.size, graph.n_nodes
    nodes = np.empty((R, steps + 1), dtype=np.int64)
    obs = np.empty_like(nodes)
    acts = np.empty((R, steps), dtype=np.int64)
    beliefs = np.empty((R, steps + 1, n))
    b0 = np.full(n, 1.0 / n) if prior is None else check_finite("prior", prior) / np.sum(prior)
    nodes[:, 0] = s
    obs[:, 0] = sample_features(L, s, rng)
    b, _ = topological_correct(np.broadcast_to(b0, (R, n)), L[obs[:, 0]])
    beliefs[:, 0] = b
    for k in range(steps):  # over time; every run, action and node at once
        if policy == "entropy":
            acts[:, k] = cand[choose_action(b, T[cand], L)[0]]
        else:
            acts[:, k] = cand[rng.integers(0, cand.size, R)]
        nodes[:, k + 1], obs[:, k + 1] = sample_step(T, L, nodes[:, k], acts[:, k], rng)
        b, _ = topological_correct(topological_predict(b, T[acts[:, k]]), L[obs[:, k + 1]])
        beliefs[:, k + 1] = b
    return ActiveRun(nodes, obs, acts, beliefs)
