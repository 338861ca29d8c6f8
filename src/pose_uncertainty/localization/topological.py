"""Topological localization: a discrete Bayes filter over a graph of places (Skalka 2011 §2.7.1.2).

Skalka 2011 §2.7.1.2: the belief ``Bel(l)`` is held on the nodes of a graph of places (junctions,
rooms, doors); its edges are the possible moves; the sensor model ``P(z | l)`` is the probability of
detecting the *place feature* ``z`` at node ``l`` — raw sensor data are first preprocessed into such
features. Far fewer nodes than grid cells, so it is cheap and coarse.

The graph (:func:`place_graph`)
-------------------------------
Built from a world's occupancy grid (:mod:`.world`): the nodes are the points of a square lattice of
``spacing`` [m] whose disc of radius ``clearance`` holds no occupied cell; two lattice neighbours are
joined when the segment between them crosses no occupied cell; nodes without any edge are left out.
Each node keeps its neighbour in the
four compass directions (east, north, west, south; −1 where none), and its feature is its number of
exits (a corner of a room has 2, a wall side or a place beside a pillar 3, open floor 4).
:func:`exits_from_ranges` is the preprocessing: four laser ranges along the compass directions → the
number of exits seen (a range beyond ``spacing + clearance``).

The filter
----------
Actions are moves of one place east, north, west or south, or staying (:data:`ACTIONS`): the move
succeeds with probability ``p_move`` and the robot stays otherwise (always, where there is no edge).
The feature detector reports the node's feature with probability ``p_correct`` and each other
feature with ``(1 − p_correct)/(K − 1)``. Prediction ``Bel'(l') = Σ_l T_a[l, l'] Bel(l)``, correction
``Bel(l) ∝ P(z | l) Bel'(l)``: a matrix–vector product and a product over the nodes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_finite, check_last_axis, check_positive
from .world import World

__all__ = [
    "ACTIONS",
    "PlaceGraph",
    "PlaceModel",
    "exits_from_ranges",
    "place_graph",
    "run_topological",
    "sample_features",
    "sample_step",
    "sample_topological",
    "topological_correct",
    "topological_predict",
]

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Actions by index: a move of one place in a compass direction, or staying where it is.
ACTIONS: tuple[str, ...] = ("east", "north", "west", "south", "stay")
_STEPS = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])


@dataclass(frozen=True, eq=False)
class PlaceGraph:
    """A graph of places with compass-labelled edges.

    Attributes
    ----------
    positions : ndarray, shape (n, 2) [m]
    neighbours : ndarray of int, shape (n, 4) — node reached by moving east, north, west, south (−1: none)
    features : ndarray of int, shape (n,) — feature class of each node, in [0, n_features)
    n_features : int — number of feature classes K
    """

    positions: Array
    neighbours: IntArray
    features: IntArray
    n_features: int = 5

    def __post_init__(self) -> None:
        nb = np.asarray(self.neighbours, dtype=np.int64)
        n = nb.shape[0]
        f = np.asarray(self.features, dtype=np.int64)
        if nb.shape != (n, 4) or f.shape != (n,) or n == 0:
            raise ValueError(f"neighbours must have shape (n, 4) and features (n,), got {nb.shape} and {f.shape}")
        if nb.min() < -1 or nb.max() >= n or f.min() < 0 or f.max() >= self.n_features:
            raise ValueError(f"neighbours must be node indices or -1 and features in [0, {self.n_features})")
        object.__setattr__(self, "neighbours", nb)
        object.__setattr__(self, "features", f)
        object.__setattr__(self, "positions", check_finite("positions", self.positions).reshape(n, 2))

    @property
    def n_nodes(self) -> int:
        """Number of nodes n."""
        return int(self.neighbours.shape[0])

    @property
    def exits(self) -> IntArray:
        """Number of edges of every node, shape (n,)."""
        return np.asarray((self.neighbours >= 0).sum(axis=1), dtype=np.int64)


@dataclass(frozen=True)
class PlaceModel:
    """Motion and feature-detector model of the topological filter.

    Attributes
    ----------
    p_move : float in (0, 1] — probability that a move along an existing edge happens
    p_correct : float in (0, 1] — probability that the detector reports the true feature
    """

    p_move: float = 0.9
    p_correct: float = 0.9

    def __post_init__(self) -> None:
        for name in ("p_move", "p_correct"):
            v = float(getattr(self, name))
            if not 0.0 < v <= 1.0:
                raise ValueError(f"{name} must be in (0, 1] (allowed: (0, 1]), got {v}")

    def transitions(self, graph: PlaceGraph) -> Array:
        """``T[a, l, l'] = P(l' | l, a)`` for every action of :data:`ACTIONS`, shape (5, n, n)."""
        n = graph.n_nodes
        T = np.zeros((len(ACTIONS), n, n))
        rows = np.arange(n)
        T[:, rows, rows] = 1.0
        for a in range(4):  # four compass directions, every node at once
            to = graph.neighbours[:, a]
            has = to >= 0
            T[a, rows[has], rows[has]] = 1.0 - self.p_move
            T[a, rows[has], to[has]] += self.p_move
        return T

    def likelihood(self, graph: PlaceGraph) -> Array:
        """``L[z, l] = P(z | l)`` for every feature class ``z``, shape (K, n)."""
        K = graph.n_features
        C = np.full((K, K), (1.0 - self.p_correct) / max(K - 1, 1))
        np.fill_diagonal(C, self.p_correct if K > 1 else 1.0)
        return C[:, graph.features]


def place_graph(world: World, spacing: float = 1.0, clearance: float = 0.3) -> PlaceGraph:
    """The graph of places of a world with an occupancy grid (module docs); features = number of exits.

    Parameters
    ----------
    world : World — with a grid
    spacing : float [m], > 0 — lattice step; lattice points at whole multiples of ``spacing``
    clearance : float [m], > 0 — free radius a place needs
    """
    g = world.grid
    if g is None:
        raise ValueError("world must have an occupancy grid to build a place graph (allowed: walls or image)")
    h = float(check_positive("spacing", spacing))
    c = float(check_positive("clearance", clearance))
    x0, x1, y0, y1 = g.extent()
    ii = np.arange(math.ceil(x0 / h), math.floor(x1 / h) + 1)
    jj = np.arange(math.ceil(y0 / h), math.floor(y1 / h) + 1)
    I, J = np.meshgrid(ii, jj, indexing="ij")
    lattice = np.stack([I.ravel(), J.ravel()], axis=-1)
    pts = lattice * h
    X, Y = np.meshgrid(g.x, g.y, indexing="ij")
    occ = np.stack([X[g.occupied], Y[g.occupied]], axis=-1)  # occupied cell centres (M, 2)
    reach = c + g.resolution * math.sqrt(0.5)  # a cell within reach may hold an obstacle within c
    d = np.min(np.hypot(*(pts[:, None, :] - occ[None, :, :]).transpose(2, 0, 1)), axis=1) if occ.size else np.inf
    keep = np.asarray(d > reach)
    lookup = np.full((ii.size + 2, jj.size + 2), -1, dtype=np.int64)  # lattice index → node (−1 pad)
    li, lj = (lattice[:, 0] - ii[0] + 1)[keep], (lattice[:, 1] - jj[0] + 1)[keep]
    lookup[li, lj] = np.arange(li.size)
    pts = pts[keep]
    nb = np.full((pts.shape[0], 4), -1, dtype=np.int64)
    t = np.linspace(0.0, 1.0, max(2, math.ceil(2 * h / g.resolution) + 1))
    for a, step in enumerate(_STEPS):  # each compass direction for every node at once
        target = lookup[li + step[0], lj + step[1]]
        seg = pts[:, None, :] + t[None, :, None] * (h * step)[None, None, :]
        free = ~g.is_occupied(seg).any(axis=1)
        nb[:, a] = np.where((target >= 0) & free, target, -1)
    return _drop_isolated(pts, nb)


def _drop_isolated(pts: Array, nb: IntArray) -> PlaceGraph:
    """The graph without nodes that have no exits (e.g. a lattice point enclosed by a pillar's walls)."""
    keep = (nb >= 0).any(axis=1)
    new = np.cumsum(keep) - 1
    nb = np.where(nb >= 0, new[np.maximum(nb, 0)], -1)[keep]
    return PlaceGraph(pts[keep], nb, (nb >= 0).sum(axis=1), n_features=5)


def exits_from_ranges(ranges: ArrayLike, reach: float) -> IntArray:
    """Preprocess four compass-direction laser ranges (..., 4) [m] into the number of exits seen.

    A direction is an exit when its range exceeds ``reach`` [m]: for the graph of :func:`place_graph`,
    ``spacing + clearance`` (the next place and its free disc are in view).
    """
    r = check_finite("ranges", check_last_axis("ranges", ranges, 4))
    return np.asarray((r > float(check_positive("reach", reach))).sum(axis=-1), dtype=np.int64)


def topological_predict(belief: ArrayLike, transitions: ArrayLike) -> Array:
    """``Bel'(l') = Σ_l T[l, l'] Bel(l)``: beliefs (..., n) and transitions (..., n, n) → (..., n)."""
    b = check_finite("belief", belief)
    T = check_finite("transitions", transitions)
    return np.asarray((b[..., None, :] @ T)[..., 0, :], dtype=np.float64)


def topological_correct(belief: ArrayLike, likelihood: ArrayLike) -> tuple[Array, Array]:
    """``Bel(l) ∝ P(z | l) Bel'(l)``: the posterior (..., n) and the log evidence ``log Σ P(z|l) Bel'(l)`` (...)."""
    b = check_finite("belief", belief)
    L = check_finite("likelihood", likelihood)
    post = b * L
    s = post.sum(axis=-1, keepdims=True)
    if np.any(s <= 0):
        raise ValueError("observation has zero likelihood on every node with mass (allowed: some P(z|l) > 0)")
    return post / s, np.log(s[..., 0])


def run_topological(graph: PlaceGraph, model: PlaceModel, actions: ArrayLike, observations: ArrayLike,
                    prior: ArrayLike | None = None) -> Array:  # fmt: skip
    """Filter a sequence (or a batch of sequences): correct with ``z_0``, then predict with ``a_{k−1}`` and correct with ``z_k``.

    Parameters
    ----------
    graph, model : the places and the model
    actions : array_like of int, shape (..., T) — indices into :data:`ACTIONS`
    observations : array_like of int, shape (..., T+1) — feature classes
    prior : array_like, shape (n,), optional — default uniform over the nodes

    Returns
    -------
    beliefs : ndarray, shape (..., T+1, n) — the filtered belief after each observation
    """
    a = np.asarray(actions, dtype=np.int64)
    z = np.asarray(observations, dtype=np.int64)
    if a.ndim == 0 or z.shape != (*a.shape[:-1], a.shape[-1] + 1):
        raise ValueError(f"observations must have shape (..., T+1) for actions (..., T), got {z.shape} and {a.shape}")
    n = graph.n_nodes
    T, L = model.transitions(graph), model.likelihood(graph)
    b = np.full(n, 1.0 / n) if prior is None else check_finite("prior", prior)
    b = np.broadcast_to(b / b.sum(), (*z.shape[:-1], n))
    out = np.empty((*z.shape, n))
    b, _ = topological_correct(b, L[z[..., 0]])
    out[..., 0, :] = b
    for k in range(a.shape[-1]):  # over time; every node (and every run) at once
        b, _ = topological_correct(topological_predict(b, T[a[..., k]]), L[z[..., k + 1]])
        out[..., k + 1, :] = b
    return out


def sample_step(transitions: ArrayLike, likelihood: ArrayLike, nodes: ArrayLike, actions: ArrayLike,
                rng: np.random.Generator) -> tuple[IntArray, IntArray]:  # fmt: skip
    """One true step of many runs: the next nodes drawn from ``T[a, l]`` and their feature observations.

    Parameters
    ----------
    transitions : array_like, shape (A, n, n); likelihood : array_like, shape (K, n)
    nodes, actions : array_like of int, shape (R,) — every run's node and action

    Returns
    -------
    nodes : ndarray of int, shape (R,); observations : ndarray of int, shape (R,)
    """
    T, L = np.asarray(transitions), np.asarray(likelihood)
    l, a = np.asarray(nodes, dtype=np.int64), np.asarray(actions, dtype=np.int64)
    nxt = np.minimum((np.cumsum(T[a, l], axis=-1) < rng.random((l.size, 1))).sum(axis=-1), T.shape[-1] - 1)
    return np.asarray(nxt, dtype=np.int64), sample_features(L, nxt, rng)


def sample_features(likelihood: ArrayLike, nodes: ArrayLike, rng: np.random.Generator) -> IntArray:
    """Feature observations at ``nodes`` (int, any shape) by the inverse CDF of each column of ``likelihood`` (K, n)."""
    L, nodes = np.asarray(likelihood, dtype=np.float64), np.asarray(nodes, dtype=np.int64)
    cdf = np.cumsum(L[:, nodes], axis=0)
    return np.asarray(np.minimum((cdf < rng.random(nodes.shape)).sum(axis=0), L.shape[0] - 1), dtype=np.int64)


def sample_topological(graph: PlaceGraph, model: PlaceModel, start: ArrayLike, actions: ArrayLike,
                       rng: np.random.Generator) -> tuple[IntArray, IntArray]:  # fmt: skip
    """Draw true node paths and feature observations for runs from ``start`` (R,) under ``actions`` (R, T).

    Returns
    -------
    nodes : ndarray of int, shape (R, T+1); observations : ndarray of int, shape (R, T+1)
    """
    s = np.asarray(start, dtype=np.int64).reshape(-1)
    a = np.asarray(actions, dtype=np.int64).reshape(s.size, -1)
    T, L = model.transitions(graph), model.likelihood(graph)
    nodes = np.empty((s.size, a.shape[1] + 1), dtype=np.int64)
    obs = np.empty_like(nodes)
    nodes[:, 0], obs[:, 0] = s, sample_features(L, s, rng)
    for k in range(a.shape[1]):  # over time, every run at once
        nodes[:, k + 1], obs[:, k + 1] = sample_step(T, L, nodes[:, k], a[:, k], rng)
    return nodes, obs
