"""Global sensitivity of a measure to the axes of a factorial sweep: variance-based (Sobol) indices.

A pipeline sweep is a full factorial design: every combination of the levels of its axes is
run once. Give each axis a uniform distribution over its levels; then the model's output ``Y``
is known at every point of the (discrete) input space, and the variance-based indices of Sobol
(Saltelli et al. 2008, ch. 4) are exact averages over the grid, with no sampling error:

* first-order index of axis *i*: ``S_i = Var(E[Y | X_i]) / Var(Y)`` — the share of the variance
  that axis *i* explains alone;
* total index: ``S_Ti = E[Var(Y | X_~i)] / Var(Y) = 1 − Var(E[Y | X_~i]) / Var(Y)`` — its share
  with every interaction it takes part in.

``Σ S_i ≤ 1`` (equal for an additive measure) and ``S_i ≤ S_Ti``; ``S_Ti = 0`` means the measure
does not depend on that axis at all. The conditional means are means over the other axes of the
grid laid out as an array with one dimension per axis (:func:`grid_array`), so the estimator is a
few vectorised reductions. For a measure of continuous inputs sampled on a regular grid the
indices are those of the discretised inputs, which tend to the continuous ones as the grid is
refined (the midpoint rule's error).

Partial dependence (Friedman 2001) is the first-order conditional mean ``E[Y | X_i = level]``
itself, and a response surface over two axes ``E[Y | X_i, X_j]``: :func:`partial_dependence`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["grid_array", "partial_dependence", "sobol_indices", "surface"]

Array = NDArray[np.float64]


def grid_array(y: ArrayLike, codes: ArrayLike, shape: tuple[int, ...]) -> Array:
    """The measure on the full factorial grid: an array with one dimension per axis.

    Parameters
    ----------
    y : (n,) array — the measure of each run
    codes : (n, k) integer array — each run's level index on each of the ``k`` axes
    shape : tuple of k ints — the number of levels of each axis

    Returns
    -------
    array of shape ``shape`` — ``y`` of the run at each combination of levels

    Raises
    ------
    ValueError — a combination missing or given twice (not a full factorial), or a non-finite ``y``
    """
    y_ = np.asarray(y, dtype=np.float64)
    c = np.asarray(codes, dtype=np.int64).reshape(len(y_), len(shape))
    if not np.all(np.isfinite(y_)):
        raise ValueError("every run needs a finite value of the measure for its sensitivity indices")
    n = int(np.prod(shape))
    if len(y_) != n:
        raise ValueError(f"a full factorial of {shape} has {n} runs, got {len(y_)}")
    flat = np.ravel_multi_index(tuple(c.T), shape)
    if np.unique(flat).size != n:
        raise ValueError("a combination of the axes' levels is given twice (and another is missing): not a full factorial")
    out = np.empty(n)
    out[flat] = y_
    return out.reshape(shape)


def sobol_indices(grid: ArrayLike) -> tuple[Array, Array]:
    """First-order and total Sobol indices of each axis of a full factorial grid (see the module).

    Parameters
    ----------
    grid : array, one dimension per axis (:func:`grid_array`), each level equally likely

    Returns
    -------
    (first, total) : two arrays of one index per axis, in [0, 1]; NaN where ``Var(Y) = 0``
    """
    g = np.asarray(grid, dtype=np.float64)
    k = g.ndim
    v = float(g.var())
    if not v > 0.0:
        return np.full(k, np.nan), np.full(k, np.nan)
    first = np.empty(k)
    total = np.empty(k)
    for i in range(k):  # one reduction per axis (k ≤ a handful), none per run
        others = tuple(a for a in range(k) if a != i)
        first[i] = float(g.mean(axis=others).var()) / v if others else 1.0
        total[i] = 1.0 - float(g.mean(axis=i).var()) / v
    return np.clip(first, 0.0, 1.0), np.clip(total, 0.0, 1.0)


def partial_dependence(grid: ArrayLike, axis: int) -> Array:
    """``E[Y | X_axis = level]`` for each level: the mean over every other axis."""
    g = np.asarray(grid, dtype=np.float64)
    return np.asarray(g.mean(axis=tuple(a for a in range(g.ndim) if a != axis)), dtype=np.float64)


def surface(grid: ArrayLike, i: int, j: int) -> Array:
    """``E[Y | X_i, X_j]``: the response surface over two axes (rows: levels of ``i``, columns: of ``j``)."""
    g = np.asarray(grid, dtype=np.float64)
    if i == j:
        raise ValueError(f"a response surface needs two different axes, got {i} twice")
    m = g.mean(axis=tuple(a for a in range(g.ndim) if a not in (i, j)))
    return np.asarray(m if i < j else m.T, dtype=np.float64)
