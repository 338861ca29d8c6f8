"""Resampling of weighted particles: the three schemes of seed 002 (Table 2.1), plus stratified.

Every scheme draws ``n`` sorted pointers ``T_0 ≤ … ≤ T_{n−1}`` in [0, 1) and then
runs the seed's common selection: with the cumulative weights
``q_j = Σ_{k≤j} w_k`` (normalised, ``q_{N−1} = 1``), pointer ``T_i`` selects the
first ``j`` with ``T_i < q_j``. Only the pointers differ:

``"multinomial"`` (roulette wheel, O(n log n))
    ``n`` independent uniforms, sorted. Copies of particle ``i`` are
    Binomial(n, w_i): ``Var = n w_i (1 − w_i)``.
``"stratified"``
    one uniform in each stratum: ``T_i = (i + U_i)/n``.
``"systematic"`` (stochastic universal sampling, O(n))
    one uniform for all: ``T_i = (i + U)/n``. Copies of particle ``i`` are
    ``⌊n w_i⌋`` or ``⌈n w_i⌉`` (a particle with ``w ≥ c/n`` survives at least ``c`` times):
    ``Var = f(1 − f)`` with ``f = frac(n w_i)``.
``"linear_time"`` (O(n), the seed's third scheme after Carpenter et al.)
    sorted uniforms without sorting, from exponential spacings: with
    ``E_0 … E_n`` i.i.d. Exp(1) and ``S_k = E_0 + … + E_k``, ``T_i = S_i / S_n``
    (``i < n``) are distributed exactly as ``n`` sorted uniforms — the same
    law of copies as multinomial. (Seed 002 writes the systematic recursion as
    ``T[i] = t[t−1] + 1/n``: read ``T[i−1]``.)

All schemes are unbiased, ``E[copies_i] = n w_i``; the variances obey
``multinomial = linear_time ≥ stratified`` and ``≥ systematic``.

The selection is the seed's merge of two sorted sequences; it is done by binary
search of every pointer in ``q`` (``numpy.searchsorted``, O(n log N) but vectorised —
measured 3× faster here than a linear merge by a stable sort of the concatenation).
The O(n) of the systematic and linear-time schemes is the cost of their pointers,
which need no sort (multinomial's sort is its O(n log n)).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import check_choice, check_finite, check_positive_int, check_probability

__all__ = [
    "SCHEMES",
    "copies",
    "cumulative_weights",
    "effective_sample_size",
    "normalize_log_weights",
    "pointers",
    "resample",
    "select",
]

SCHEMES: tuple[str, ...] = ("multinomial", "stratified", "systematic", "linear_time")

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]


def normalize_log_weights(log_w: ArrayLike) -> tuple[Array, float]:
    """Normalised weights from log-weights, stably: ``w_i = exp(ℓ_i − max ℓ) / Σ exp(ℓ_j − max ℓ)``.

    Returns
    -------
    w : ndarray, shape (N,) — sums to 1
    log_sum : float — ``log Σ exp(ℓ_i)`` (the log evidence when ℓ = log prior weight + log-likelihood)

    Raises
    ------
    ValueError
        If every log-weight is −inf (no particle explains the data) or any is NaN/+inf.
    """
    lw = np.asarray(log_w, dtype=np.float64)
    if lw.ndim != 1 or lw.size == 0:
        raise ValueError(f"log_w must have shape (N,) with N >= 1, got shape {lw.shape}")
    top = float(lw.max())  # NaN if any is NaN, +inf if any is +inf: one pass checks both
    if math.isnan(top) or top == np.inf:
        raise ValueError("log_w must be finite or -inf (allowed: [-inf, inf)), got NaN or +inf")
    if top == -np.inf:
        raise ValueError("log_w must have at least one finite value (allowed: some particle with p > 0), got all -inf")
    e = lw - top
    np.exp(e, out=e)
    s = float(e.sum())
    e /= s
    return e, top + math.log(s)


def effective_sample_size(w: ArrayLike) -> float:
    """``ESS = 1 / Σ w_i²`` of normalised weights: n for equal weights, 1 for a single particle."""
    return _ess(check_finite("w", w))


def _ess(w: Array) -> float:
    """:func:`effective_sample_size` of weights known to be finite (a runner's own)."""
    return float(1.0 / np.dot(w, w))


def cumulative_weights(w: ArrayLike) -> Array:
    """``q_j = Σ_{k≤j} w_k / Σ w``, with ``q_{N−1} = 1`` exactly, shape (N,)."""
    ww = check_finite("w", w)
    if ww.ndim != 1 or ww.size == 0 or np.any(ww < 0) or not ww.sum() > 0:
        raise ValueError("w must be a 1-D array of weights >= 0 with a positive sum (allowed: weights), "
                         f"got shape {ww.shape}, sum {float(ww.sum()) if ww.size else 0.0}")  # fmt: skip
    return _cumulative(ww)


def _cumulative(w: Array) -> Array:
    """:func:`cumulative_weights` of weights known to be valid (a runner's own normalised ones)."""
    q = np.cumsum(w)
    q /= q[-1]
    q[-1] = 1.0
    return q


def pointers(n: int, rng: np.random.Generator, scheme: str = "systematic") -> Array:
    """The ``n`` sorted pointers in [0, 1) of a scheme (see the module docs), shape (n,)."""
    n = check_positive_int("n", n)
    check_choice("scheme", scheme, SCHEMES)
    if scheme == "multinomial":
        return np.sort(rng.random(n))
    if scheme == "stratified":
        return (np.arange(n) + rng.random(n)) / n
    if scheme == "systematic":
        return (np.arange(n) + rng.random()) / n
    S = np.cumsum(rng.standard_exponential(n + 1))  # S_0 … S_n
    return S[:n] / S[n]


def select(q: ArrayLike, T: ArrayLike) -> IntArray:
    """Seed 002's selection: pointer ``T_i`` takes the first ``j`` with ``T_i < q_j``.

    Binary search of each pointer in the sorted ``q`` (N,) (``side="right"``: ``T_i = q_j``
    moves past ``j``); ``T`` need not be sorted — the result keeps its order.

    Returns
    -------
    ndarray of int, shape (n,) — in the order of ``T``
    """
    qq = np.asarray(q, dtype=np.float64)
    out = np.searchsorted(qq, np.asarray(T, dtype=np.float64), side="right")
    return np.minimum(out, qq.size - 1).astype(np.int64)  # T < 1 = q_{N−1}; guard rounding


def resample(w: ArrayLike, rng: np.random.Generator, scheme: str = "systematic", n: int | None = None) -> IntArray:
    """Indices of ``n`` (default ``N``) particles drawn with probabilities ``w`` by ``scheme``.

    Parameters
    ----------
    w : array_like, shape (N,) — weights ≥ 0 (normalised here)
    rng : numpy.random.Generator
    scheme : {"multinomial", "stratified", "systematic", "linear_time"}
    n : int, optional — number of particles after resampling

    Returns
    -------
    ndarray of int, shape (n,), ascending
    """
    q = cumulative_weights(w)
    m = q.size if n is None else check_positive_int("n", n)
    return select(q, pointers(m, rng, scheme))


def copies(indices: ArrayLike, N: int) -> IntArray:
    """How many times each of ``N`` particles was selected, shape (N,)."""
    return np.bincount(np.asarray(indices, dtype=np.int64), minlength=check_positive_int("N", N))


def _check_threshold(threshold: float) -> float:
    """ESS threshold as a fraction of n in (0, 1] (1 = resample at every correction)."""
    t = float(check_finite("ess_threshold", threshold))
    if t == 1.0:
        return t
    return float(check_probability("ess_threshold", t))
