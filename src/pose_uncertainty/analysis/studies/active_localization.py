"""Active localization (Skalka 2011 §5.2): choosing motions by expected entropy against random and fixed ones.

:func:`active_localization_study` starts ``n_runs`` robots at random places of a world's graph of places
(:func:`pose_uncertainty.localization.topological.place_graph`) with a uniform belief (global
localization) and lets them move for ``n_steps`` steps under three policies:

* ``entropy`` — the action of least expected entropy of the belief
  (:func:`pose_uncertainty.localization.active.run_active`);
* ``random`` — an action drawn uniformly at every step;
* ``fixed`` — a fixed square sweep, ``sweep`` steps east, north, west and south in turn.

A run is localized at the first step whose belief puts at least ``threshold`` on the true place. Measures
per policy: the success rate at the end (with its 95 % Wilson interval), the median and mean time to
localize [steps] of the successful runs, and the share of runs localized within each step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core.stats import wilson_interval
from ...localization import active as ac
from ...localization import topological as tp
from ...localization.world import load_world

__all__ = ["POLICIES", "active_localization_study"]

#: The policies of the study, in the order the report shows them.
POLICIES: tuple[str, ...] = ("entropy", "random", "fixed")


def active_localization_study(
    world: str = "config/worlds/room.yaml",
    spacing: float = 1.0,
    p_move: float = 0.9,
    p_correct: float = 0.9,
    n_runs: int = 400,
    n_steps: int = 30,
    sweep: int = 3,
    threshold: float = 0.9,
    seed: int = 23,
) -> dict[str, Any]:
    """Time to localize and success rate of the three policies on one graph of places (module docs).

    Returns
    -------
    dict: per policy of :data:`POLICIES`: ``success_rate`` [1], ``success_low``, ``success_high`` [1] (95 %
    Wilson interval), ``median_steps``, ``mean_steps`` [steps] (NaN without a success), ``localized_by_step``
    (share of runs localized at or before each step, n_steps + 1 values); ``n_places``, ``n_runs``, ``n_steps``
    """
    graph = tp.place_graph(load_world(world), spacing)
    model = tp.PlaceModel(p_move, p_correct)
    g_start, g_entropy, g_random, g_fixed = np.random.default_rng(seed).spawn(4)
    start = g_start.integers(0, graph.n_nodes, int(n_runs))
    runs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for policy, g in (("entropy", g_entropy), ("random", g_random)):
        r = ac.run_active(graph, model, start, int(n_steps), g, policy=policy)
        runs[policy] = (r.nodes, r.beliefs)
    cycle = np.repeat(np.arange(4), int(sweep))
    actions = np.broadcast_to(np.resize(cycle, int(n_steps)), (start.size, int(n_steps)))
    nodes, obs = tp.sample_topological(graph, model, start, actions, g_fixed)
    runs["fixed"] = (nodes, tp.run_topological(graph, model, actions, obs))
    out: dict[str, Any] = {"n_places": graph.n_nodes, "n_runs": int(start.size), "n_steps": int(n_steps)}
    for policy in POLICIES:
        nodes, beliefs = runs[policy]
        on_truth = np.take_along_axis(beliefs, nodes[..., None], axis=-1)[..., 0] >= threshold  # (R, T+1)
        ever = on_truth.any(axis=1)
        first = np.where(ever, np.argmax(on_truth, axis=1), -1)
        ok = int(on_truth[:, -1].sum())
        lo, hi = wilson_interval(ok, start.size)
        t = first[ever]
        out[policy] = {
            "success_rate": ok / start.size, "success_low": lo, "success_high": hi,
            "median_steps": float(np.median(t)) if t.size else float("nan"),
            "mean_steps": float(np.mean(t)) if t.size else float("nan"),
            "localized_by_step": [float(np.mean((first >= 0) & (first <= k))) for k in range(int(n_steps) + 1)],
        }  # fmt: skip
    return out
