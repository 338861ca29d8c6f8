"""Zero-mean noise densities and samplers of the motion models (Thrun ch. 5; Němec 2012 §2.2.1).

Every function takes a **variance** ``var`` (never a standard deviation)::

    prob_normal(a, b²)     = exp(−a²/(2b²)) / √(2π b²)
    prob_triangular(a, b²) = max(0, 1/(√6 b) − |a|/(6 b²))          (support |a| ≤ √6 b)
    sample_normal(b²)      ~ N(0, b²)                                (library normal)
    sample_triangular(b²)  = (√6/2) (rand(−b, b) + rand(−b, b))

and the variance of each noise term is built from the controls by
:func:`scaled_variance`, either as in the book and Němec 2012 (``"squared"``,
``α_a u_a² + α_b u_b²``, the default) or as in the lecture decks (Kulich 2014 and
the Russian lecture deck on motion models: ``"abs"``, ``α_a |u_a| + α_b |u_b|``).

Zero variance. A variance of exactly zero makes a density a Dirac. The densities
here raise every variance to at least :data:`MIN_VARIANCE` (10⁻¹²) so that they stay
finite (a zero-variance term then acts as a spike of width 10⁻⁶ in its own
units); the samplers return exactly zero noise for zero variance. Maps raise
variances further, to a floor tied to the grid cell (see :mod:`pose_uncertainty.methods.maps`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import as_float_array, check_choice, check_nonnegative

__all__ = [
    "MIN_VARIANCE",
    "NOISES",
    "SCALINGS",
    "cdf",
    "check_noise",
    "check_scaling",
    "noise_reach",
    "prob",
    "prob_cell",
    "prob_normal",
    "prob_triangular",
    "sample",
    "sample_normal",
    "sample_triangular",
    "scaled_variance",
]

NOISES: tuple[str, ...] = ("normal", "triangular")
SCALINGS: tuple[str, ...] = ("squared", "abs")

#: Smallest variance a density is evaluated with (keeps a zero-variance term finite).
MIN_VARIANCE: float = 1e-12

_SQRT6 = math.sqrt(6.0)


def check_noise(noise: str) -> str:
    """Return ``noise`` if it is a known noise name, else raise ValueError listing :data:`NOISES`."""
    return check_choice("noise", noise, NOISES)


def check_scaling(scaling: str) -> str:
    """Return ``scaling`` if known, else raise ValueError listing :data:`SCALINGS`."""
    return check_choice("scaling", scaling, SCALINGS)


def _variance(var: ArrayLike) -> NDArray[np.float64]:
    v = check_nonnegative("var", var)
    return np.maximum(v, MIN_VARIANCE)


def prob_normal(a: ArrayLike, var: ArrayLike) -> NDArray[np.float64]:
    """Zero-mean normal density ``exp(−a²/(2b²)) / √(2π b²)``.

    Parameters
    ----------
    a : array_like
        Points (any shape, broadcast with ``var``).
    var : array_like, >= 0
        Variance ``b²``; values below :data:`MIN_VARIANCE` are raised to it.

    Returns
    -------
    ndarray
        Density, finite and >= 0 everywhere.
    """
    x = as_float_array("a", a)
    v = _variance(var)
    return np.exp(-0.5 * x * x / v) / np.sqrt(2.0 * np.pi * v)


def prob_triangular(a: ArrayLike, var: ArrayLike) -> NDArray[np.float64]:
    """Zero-mean triangular density ``max(0, 1/(√6 b) − |a|/(6 b²))`` of variance ``b²``.

    Parameters
    ----------
    a : array_like
        Points.
    var : array_like, >= 0
        Variance ``b²``; values below :data:`MIN_VARIANCE` are raised to it.

    Returns
    -------
    ndarray
        Density, finite and >= 0, zero outside ``|a| ≤ √6 b``.
    """
    x = as_float_array("a", a)
    v = _variance(var)
    b = np.sqrt(v)
    return np.maximum(0.0, 1.0 / (_SQRT6 * b) - np.abs(x) / (6.0 * v))


def prob(a: ArrayLike, var: ArrayLike, noise: str = "normal") -> NDArray[np.float64]:
    """Density of the named zero-mean noise (``"normal"`` or ``"triangular"``) of variance ``var``."""
    check_noise(noise)
    return prob_normal(a, var) if noise == "normal" else prob_triangular(a, var)


def sample_normal(
    var: ArrayLike, rng: np.random.Generator, size: int | tuple[int, ...] | None = None
) -> NDArray[np.float64]:
    """Draw zero-mean normal noise of variance ``var`` (exactly 0 where ``var == 0``).

    Parameters
    ----------
    var : array_like, >= 0
        Variance, broadcast against ``size``.
    rng : numpy.random.Generator
    size : int or tuple, optional
        Output shape (default: the shape of ``var``).
    """
    v = check_nonnegative("var", var)
    shape = np.shape(v) if size is None else size
    return np.sqrt(v) * rng.standard_normal(shape)


def sample_triangular(
    var: ArrayLike, rng: np.random.Generator, size: int | tuple[int, ...] | None = None
) -> NDArray[np.float64]:
    """Draw zero-mean triangular noise of variance ``var``: ``(√6/2)(rand(−b,b) + rand(−b,b))``.

    Parameters
    ----------
    var : array_like, >= 0
        Variance ``b²``.
    rng : numpy.random.Generator
    size : int or tuple, optional
        Output shape (default: the shape of ``var``).
    """
    v = check_nonnegative("var", var)
    shape = np.shape(v) if size is None else size
    shp = (shape,) if isinstance(shape, int | np.integer) else tuple(shape)
    u = rng.uniform(-1.0, 1.0, size=(2, *shp))
    return np.sqrt(v) * (_SQRT6 / 2.0) * (u[0] + u[1])


def sample(
    var: ArrayLike,
    rng: np.random.Generator,
    noise: str = "normal",
    size: int | tuple[int, ...] | None = None,
) -> NDArray[np.float64]:
    """Draw the named zero-mean noise of variance ``var`` (see :func:`sample_normal`)."""
    check_noise(noise)
    if noise == "normal":
        return sample_normal(var, rng, size)
    return sample_triangular(var, rng, size)


def noise_reach(noise: str) -> float:
    """Half-width of the noise in standard deviations used to bound a kernel.

    ``6`` for the normal (tail mass 2·10⁻⁹), ``√6`` (the exact support) for the triangular.
    """
    check_noise(noise)
    return 6.0 if noise == "normal" else _SQRT6


def scaled_variance(
    alpha_a: ArrayLike,
    alpha_b: ArrayLike,
    u_a: ArrayLike,
    u_b: ArrayLike,
    scaling: str = "squared",
) -> NDArray[np.float64]:
    """Variance of one noise term from two controls.

    ``"squared"`` (book, Němec 2012): ``α_a u_a² + α_b u_b²``;
    ``"abs"`` (Kulich 2014, the Russian lecture deck on motion models): ``α_a |u_a| + α_b |u_b|``.

    Parameters
    ----------
    alpha_a, alpha_b : array_like, >= 0
        Error constants.
    u_a, u_b : array_like
        Control magnitudes (speeds, or odometry rotations/translation).
    scaling : {"squared", "abs"}
    """
    check_scaling(scaling)
    aa = as_float_array("alpha", alpha_a)
    ab = as_float_array("alpha", alpha_b)
    ua = as_float_array("u", u_a)
    ub = as_float_array("u", u_b)
    if scaling == "squared":
        return aa * ua * ua + ab * ub * ub
    return aa * np.abs(ua) + ab * np.abs(ub)


def cdf(a: ArrayLike, var: ArrayLike, noise: str = "normal") -> NDArray[np.float64]:
    """Cumulative distribution of the named zero-mean noise of variance ``var`` at ``a``.

    Used to integrate a density exactly over an interval (the singular map cell).
    Variances below :data:`MIN_VARIANCE` are raised to it, as in :func:`prob`.
    """
    check_noise(noise)
    x = as_float_array("a", a)
    v = _variance(var)
    if noise == "normal":
        from scipy.special import ndtr  # imported where used: scipy.special takes 0.2 s to import

        return np.asarray(ndtr(x / np.sqrt(v)), dtype=np.float64)
    c = _SQRT6 * np.sqrt(v)  # half-width of the support
    t = np.clip(x / c, -1.0, 1.0)
    return np.where(t <= 0.0, 0.5 * (1.0 + t) ** 2, 1.0 - 0.5 * (1.0 - t) ** 2)


def prob_cell(
    a: ArrayLike, var: ArrayLike, width: ArrayLike, noise: str = "normal"
) -> NDArray[np.float64]:
    """Average of the noise density over ``[a − width/2, a + width/2]``.

    ``(F(a + w/2) − F(a − w/2)) / w`` with the CDF ``F`` of :func:`cdf` — the density
    averaged over one grid cell seen in the units of this noise term. Exact cell
    integration in that direction: it stays correct when the noise is narrower
    than a cell, including zero variance (then it is ``1/w`` inside the cell, 0
    outside). Where ``w`` is negligible (< 10⁻³ standard deviations) it is
    :func:`prob`.

    Parameters
    ----------
    a : array_like
    var : array_like, >= 0
    width : array_like, >= 0
    noise : {"normal", "triangular"}
    """
    x = as_float_array("a", a)
    v = _variance(var)
    w = check_nonnegative("width", width)
    wide = w > 1e-3 * np.sqrt(v)
    ws = np.where(wide, w, 1.0)
    box = np.maximum((cdf(x + ws / 2.0, v, noise) - cdf(x - ws / 2.0, v, noise)) / ws, 0.0)
    if np.all(wide):
        return box
    return np.where(wide, box, prob(x, v, noise))
