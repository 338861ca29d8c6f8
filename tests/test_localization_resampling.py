"""Resampling schemes: unbiasedness, the variances theory predicts, the seed's selection loop."""

import math

import numpy as np
import pytest
from scipy import stats as sstats

from pose_uncertainty.localization import resampling as R

N = 40
R_DRAWS = 4000


def _weights() -> np.ndarray:
    # uneven weights, some below 1/n and some several times it, one exactly zero
    w = np.random.default_rng(5).gamma(0.7, size=N)
    w[7] = 0.0
    return w / w.sum()


def _copies(scheme: str, seed: int) -> np.ndarray:
    w = _weights()
    rng = np.random.default_rng(seed)
    return np.stack([R.copies(R.resample(w, rng, scheme), N) for _ in range(R_DRAWS)])


def _seed_loop(q: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Skalka 2011, Table 2.1, the common selection loop, literally (scalar Python)."""
    out, i, j = [], 0, 0
    while i < len(T):
        if T[i] < q[j]:
            out.append(j)
            i += 1
        else:
            j += 1
    return np.array(out)


@pytest.mark.parametrize("scheme", R.SCHEMES)
def test_every_scheme_is_unbiased(scheme):
    # E[copies_i] = n w_i. Every scheme's variance is at most the binomial n w (1 − w)
    # (multinomial and linear-time equal it), so the mean over R draws is within
    # 5 √(n w(1−w)/R) of n w_i (per particle, two-sided p ≈ 6e-7; 40 particles).
    w = _weights()
    c = _copies(scheme, 11)
    assert np.all(c.sum(axis=1) == N)
    assert np.all(c[:, 7] == 0)  # a zero weight is never drawn
    sd = np.sqrt(N * w * (1 - w) / R_DRAWS)
    assert np.all(np.abs(c.mean(axis=0) - N * w) <= 5 * sd + 1e-12)


def _chi2_var_band(var_theory: np.ndarray) -> tuple[float, float]:
    # total sample variance Σ_i s_i²; for R draws, Var(s²) ≈ 2σ⁴/(R−1) (normal approximation),
    # summed over particles (treated as independent: conservative enough at 6σ)
    total = float(var_theory.sum())
    sd = math.sqrt(float((2 * var_theory**2 / (R_DRAWS - 1)).sum()))
    return total - 6 * sd, total + 6 * sd


def test_variances_are_ordered_as_theory_says():
    w = _weights()
    var = {s: _copies(s, 12).var(axis=0, ddof=1) for s in R.SCHEMES}
    binom = N * w * (1 - w)
    for s in ("multinomial", "linear_time"):  # Binomial(n, w_i) copies
        lo, hi = _chi2_var_band(binom)
        assert lo <= var[s].sum() <= hi, (s, var[s].sum(), lo, hi)
    f = np.mod(N * w, 1.0)  # systematic: ⌊nw⌋ or ⌈nw⌉ copies, Var = f(1 − f) exactly
    lo, hi = _chi2_var_band(f * (1 - f) + 1e-12)
    assert lo <= var["systematic"].sum() <= hi
    # stratified lies between: strictly below multinomial, its own closed form: Σ_k p_ik(1 − p_ik)
    q = np.concatenate([[0.0], np.cumsum(w)]) * N
    strata = np.arange(N)
    overlap = np.clip(np.minimum(q[1:, None], strata + 1) - np.maximum(q[:-1, None], strata), 0, 1)
    strat = (overlap * (1 - overlap)).sum(axis=1)
    lo, hi = _chi2_var_band(strat + 1e-12)
    assert lo <= var["stratified"].sum() <= hi
    assert strat.sum() < binom.sum()
    assert (f * (1 - f)).sum() < binom.sum()


def test_selection_equals_the_seeds_loop(rng):
    w = _weights()
    q = R.cumulative_weights(w)
    for scheme in R.SCHEMES:
        T = R.pointers(N, rng, scheme)
        assert np.all(np.diff(T) >= 0)
        assert T[0] >= 0
        assert T[-1] < 1
        np.testing.assert_array_equal(R.select(q, T), _seed_loop(q, T))


def test_copies_per_particle_equal_the_selection(rng):
    # selection_counts (a guess from each pointer's stratum, corrected by comparisons) against
    # the binary-search selection it replaces, on uneven weights, zero weights (equal cumulative
    # weights), pointers exactly on cumulative weights (ties: T_i = q_j selects past j), a pointer
    # at 1 (select's guard sends it to the last particle), and more or fewer pointers than particles
    cases = [_weights(), np.full(N, 1.0 / N), np.eye(N)[3], np.r_[np.zeros(N - 1), 1.0]]
    for w in cases:
        q = R.cumulative_weights(w)
        for n in (1, 7, N, 3 * N + 1):
            pointer_sets = [R.pointers(n, rng, scheme) for scheme in R.SCHEMES]
            pointer_sets += [np.arange(n) / n, (np.arange(n) + (1 - 2**-53)) / n, np.sort(rng.choice(q, n))]
            for T in pointer_sets:
                want = R.copies(R.select(q, T), N)
                for scheme in R.SCHEMES:
                    np.testing.assert_array_equal(R.selection_counts(q, T, scheme), want)
            # the particle filter's systematic counts, whose pointers (i + u)/n are never built
            for u in (0.0, 1 - 2**-53, float(rng.random())):
                want = R.copies(R.select(q, (np.arange(n) + u) / n), N)
                np.testing.assert_array_equal(R._counts_from_below(R._systematic_below(n, u)(q), n), want)
    q = R.cumulative_weights([0.5, 0.5, 0.0])
    np.testing.assert_array_equal(R.selection_counts(q, [0.2, 0.7, 1.0]), [1, 1, 1])


def test_linear_time_scheme_is_sorting_based_selection(rng):
    # the same uniforms, shuffled and selected by sorting (roulette wheel, binary search per
    # pointer) give the same multiset as the linear-time merge of the sorted exponential spacings
    w = _weights()
    q = R.cumulative_weights(w)
    T = R.pointers(1000, rng, "linear_time")
    shuffled = rng.permutation(T)
    by_search = np.searchsorted(q, shuffled, side="right")
    np.testing.assert_array_equal(np.sort(by_search), R.select(q, T))
    np.testing.assert_array_equal(np.sort(R.select(q, shuffled)), R.select(q, T))


def test_exponential_spacings_are_sorted_uniforms():
    # T_i = S_i / S_n is the (i+1)-th of n sorted uniforms: T_i ~ Beta(i+1, n−i). Over 2000
    # draws the mean of T_i is within 5 standard errors of (i+1)/(n+1), and the pooled
    # values are uniform (KS test at the 1e-4 level).
    n, reps = 9, 2000
    rng = np.random.default_rng(8)
    T = np.stack([R.pointers(n, rng, "linear_time") for _ in range(reps)])
    i = np.arange(n)
    a, b = i + 1, n - i
    sd = np.sqrt(a * b / ((a + b) ** 2 * (a + b + 1)) / reps)
    assert np.all(np.abs(T.mean(axis=0) - a / (n + 1)) <= 5 * sd)
    assert sstats.kstest(T.ravel(), "uniform").pvalue > 1e-4


def test_log_weights_normalise_stably():
    # exp(−1e4) underflows; the weights must not. The input −1e4 + ln 3 is itself rounded to
    # ulp(1e4) ≈ 1.8e-12, which bounds the attainable relative accuracy of the weights.
    w, log_sum = R.normalize_log_weights([-1e4, -1e4 + math.log(3.0), -np.inf])
    np.testing.assert_allclose(w, [0.25, 0.75, 0.0], rtol=1e-11)
    assert log_sum == pytest.approx(-1e4 + math.log(4.0), rel=1e-15)
    assert R.effective_sample_size(np.full(8, 1 / 8)) == pytest.approx(8.0)
    assert R.effective_sample_size([1.0, 0.0]) == 1.0
    with pytest.raises(ValueError, match="at least one finite"):
        R.normalize_log_weights([-np.inf, -np.inf])


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: R.resample([0.5, 0.5], np.random.default_rng(0), "roulette"), "scheme must be one of"),
        (lambda: R.resample([0.0, 0.0], np.random.default_rng(0)), "positive sum"),
        (lambda: R.resample([-1.0, 2.0], np.random.default_rng(0)), "weights >= 0"),
        (lambda: R.pointers(0, np.random.default_rng(0)), "n must be an integer >= 1"),
    ],
)
def test_bad_resampling_options_get_one_line_errors(call, match):
    with pytest.raises(ValueError, match=match) as err:
        call()
    assert "\n" not in str(err.value)
