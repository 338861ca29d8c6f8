"""Resampling of weighted particles: the three schemes of Skalka 2011 (Table 2.1), plus stratified.

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
    law of copies as multinomial. (Skalka 2011 writes the systematic recursion as
    ``T[i] = t[t−1] + 1/n``: read ``T[i−1]``.)

All schemes are unbiased, ``E[copies_i] = n w_i``; the variances obey
``multinomial = linear_time ≥ stratified`` and ``≥ systematic``.

The selection is the seed's merge of two sorted sequences; it is done by binary
search of every pointer in ``q`` (``numpy.searchsorted``, O(n log N) but vectorised —
measured 3× faster here than a linear merge by a stable sort of the concatenation).
The O(n) of the systematic and linear-time schemes is the cost of their pointers,
which need no sort (multinomial's sort is its O(n log n)).

:func:`selection_counts` gives the same selection as copies per particle, ``c_j = C(q_j) −
C(q_{j−1})`` with ``C(x) = #{i : T_i < x}``: for the systematic and stratified schemes, whose
pointer ``T_i`` lies in its stratum ``[i/n, (i+1)/n)``, ``C(q_j)`` is within one of
``n q_j`` (of ``⌈n q_j − u⌉`` for the systematic offset ``u``), and a guess corrected by
comparing ``T`` at it is exact in O(n + N) — measured 2–3× faster than the binary searches
(the particle filter's systematic pointers are not even built: only compared where needed);
the copies then fill the new particle array with one ``numpy.repeat``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

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
    "selection_counts",
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
    """Skalka 2011's selection: pointer ``T_i`` takes the first ``j`` with ``T_i < q_j``.

    Binary search of each pointer in the sorted ``q`` (N,) (``side="right"``: ``T_i = q_j``
    moves past ``j``); ``T`` need not be sorted — the result keeps its order.

    Returns
    -------
    ndarray of int, shape (n,) — in the order of ``T``
    """
    qq = np.asarray(q, dtype=np.float64)
    out = np.searchsorted(qq, np.asarray(T, dtype=np.float64), side="right")
    return np.minimum(out, qq.size - 1).astype(np.int64)  # T < 1 = q_{N−1}; guard rounding


def selection_counts(q: ArrayLike, T: ArrayLike, scheme: str = "systematic") -> IntArray:
    """Copies of each particle under :func:`select` of sorted pointers: ``copies(select(q, T), N)``.

    Parameters
    ----------
    q : array_like, shape (N,) — cumulative weights (:func:`cumulative_weights`)
    T : array_like, shape (n,) — sorted pointers of ``scheme`` (:func:`pointers`)
    scheme : {"multinomial", "stratified", "systematic", "linear_time"} — with
        ``"systematic"`` / ``"stratified"`` the count below each ``q_j`` is found from its
        stratum and corrected (O(n + N)); otherwise by binary search of ``q`` in ``T``

    Returns
    -------
    ndarray of int, shape (N,) — sums to n; ``numpy.repeat(particles, counts, axis=0)`` is
    ``particles[select(q, T)]``
    """
    qq = np.asarray(q, dtype=np.float64)
    TT = np.asarray(T, dtype=np.float64)
    check_choice("scheme", scheme, SCHEMES)
    if scheme not in ("systematic", "stratified") or TT.size == 0:
        return _counts_from_below(np.searchsorted(TT, qq, side="left"), TT.size)
    return _counts_from_below(_strata_below(TT, scheme)(qq), TT.size)


def _strata_below(T: Array, scheme: str) -> Callable[[Array], IntArray]:
    """``C(x) = #{i : T_i < x}`` for sorted pointers ``T`` (n,) with one in each stratum ``[i/n, (i+1)/n)``.

    Returns a function of values ``x`` in [0, 1] (any part of ``q``): the guess ``⌊n x⌋``
    (stratified) or ``⌊n x − u + 1⌋`` (systematic, ``u = n T_0``: ``⌈n x − u⌉`` but at integers),
    corrected by comparing ``T`` around it (:func:`_counts_below`).
    """
    n = T.size
    Tp = np.empty(n + 3)
    Tp[0], Tp[-2:] = -np.inf, np.inf
    Tp[1:-2] = T  # Tp[c + 1] = T_c, with T_{−1} = −∞ and T_n = T_{n+1} = +∞
    shift = 1.0 - T[0] * n if scheme == "systematic" else 0.0

    def below(x: Array) -> IntArray:
        g = x * n
        g += shift
        np.clip(g, 0, n + 1, out=g)  # any sorted T and x: the walk corrects any guess in [0, n + 1]
        return _counts_below(x, lambda c: Tp[c + 1], g.astype(np.intp))  # truncation: the floor of g ≥ 0

    return below


def _systematic_below(n: int, u: float) -> Callable[[Array], IntArray]:
    """:func:`_strata_below` of the systematic pointers ``T_i = (i + u)/n`` of :func:`pointers`, which
    are computed only where compared (the same arithmetic, the same bits: ``T`` is never built).

    ``(c + u)/n`` is below 0 at ``c = −1`` and ≥ 1 at ``c ≥ n``: the sentinels come with the formula.
    """

    def below(x: Array) -> IntArray:
        g = x * n
        g += 1.0 - u  # ⌊n x − u + 1⌋ in [0, n + 1]
        return _counts_below(x, lambda c: (c + u) / n, g.astype(np.intp))

    return below


def _counts_below(q: Array, pointer: Callable[[IntArray], Array], guess: IntArray) -> IntArray:
    """``C(q_j) = #{i : T_i < q_j}`` for sorted pointers ``T_c = pointer(c)``, walking each ``guess_j`` to it.

    ``C`` is the one ``c`` with ``T_{c−1} < q_j ≤ T_c`` (``pointer`` gives ``T_{−1} < 0`` and
    ``T_c ≥ 1`` for ``c ≥ n``; ``guess`` in [0, n + 1]); each pass moves every guess that breaks
    it by one towards it, so a guess off by ``d`` takes ``d + 1`` passes.
    """
    c = guess
    while True:
        up = pointer(c) < q  # T_c < q_j: more pointers below q_j
        down = pointer(c - 1) >= q  # T_{c−1} ≥ q_j: fewer
        if not (up.any() or down.any()):
            return c
        c += up
        c -= down


def _counts_from_below(C: IntArray, n: int) -> IntArray:
    """Copies ``c_j = C(q_j) − C(q_{j−1})`` from the counts below ``C`` (N,), with ``C_{N−1} = n``
    (:func:`select`'s guard: a pointer at 1 goes to the last particle)."""
    counts = np.empty(C.shape, dtype=np.intp)
    counts[0] = C[0]
    np.subtract(C[1:], C[:-1], out=counts[1:])
    counts[-1] = n - (C[-2] if C.size > 1 else 0)
    return counts


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
