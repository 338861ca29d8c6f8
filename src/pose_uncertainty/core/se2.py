"""The group SE(2) of planar poses: exponential, logarithm, product, inverse, adjoint, Jacobian.

A pose ``g = (x, y, θ)`` [m, m, rad] is the matrix ``[[R(θ), t], [0, 1]]`` with
``t = (x, y)``; a twist ``ξ = (v₁, v₂, w)`` [m, m, rad] is a body-frame velocity times a
time. Every function takes and returns arrays with leading batch dimensions,
``shape (..., 3)`` for poses and twists and ``shape (..., 3, 3)`` for matrices; a wrong
last axis raises ``ValueError``. Headings are not wrapped: ``compose`` adds them and
``log`` takes them as given, so unwrapped paths (several laps of a circle) stay
one-to-one with their twists.

    exp(ξ) = (V(w) v, w),   V(w) = [[sin w / w, −(1−cos w)/w], [(1−cos w)/w, sin w / w]]

and back by ``log``: ``v = V(w)⁻¹ t`` with ``V(w)⁻¹ = (w/2)[[cot(w/2), 1], [−1, cot(w/2)]]``.
The functions of ``w`` that are ``0/0`` at ``w = 0`` are computed by their series below a
threshold (:func:`cosc`, ``_half_cot``, ``_w_minus_sin_over_w2``).

References: Long, Wolfe, Mashner & Chirikjian, "The Banana Distribution is Gaussian: A
Localization Study with Exponential Coordinates", RSS 2012; Solà, Deray & Atchuthan,
"A micro Lie theory for state estimation in robotics", 2018.

Examples
--------
>>> import numpy as np
>>> from pose_uncertainty.core import se2
>>> g = se2.exp([np.pi / 2, 0.0, np.pi / 2])  # a quarter circle of radius 1
>>> np.round(g, 12).tolist()
[1.0, 1.0, 1.570796326795]
>>> np.allclose(se2.log(g), [np.pi / 2, 0.0, np.pi / 2])
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .kinematics import sinc
from .validation import check_last_axis

__all__ = ["adjoint", "adjoint_inverse", "compose", "cosc", "exp", "inverse", "log", "right_jacobian"]

_SMALL = 1e-4  # below |w| < _SMALL the series of the sinc-like functions are used


def cosc(w: NDArray) -> NDArray:
    """``(1 − cos w)/w``, computed as ``(w/2)·sinc²(w/2)``: 0 at ``w = 0``, no division.

    Parameters
    ----------
    w : ndarray, shape (...) — angle [rad]

    Returns
    -------
    ndarray, shape (...) — dimensionless
    """
    return 0.5 * w * sinc(0.5 * w) ** 2


def _half_cot(w: NDArray) -> NDArray:
    """(w/2)·cot(w/2), 1 at w = 0 (series 1 − w²/12 − w⁴/720 below _SMALL)."""
    small = np.abs(w) < _SMALL
    ws = np.where(small, 1.0, w)
    with np.errstate(divide="ignore", invalid="ignore"):
        full = 0.5 * ws / np.tan(0.5 * ws)
    return np.where(small, 1.0 - w**2 / 12.0 - w**4 / 720.0, full)


def _w_minus_sin_over_w2(w: NDArray) -> NDArray:
    """(w − sin w)/w², 0 at w = 0 (series w/6 − w³/120 below 1e-2)."""
    small = np.abs(w) < 1e-2
    ws = np.where(small, 1.0, w)
    return np.where(small, w / 6.0 - w**3 / 120.0, (ws - np.sin(ws)) / ws**2)


def exp(xi: ArrayLike) -> NDArray[np.float64]:
    """Exponential map of SE(2): twist ``(v₁, v₂, w)`` → pose ``(x, y, θ)``.

    ``(x, y) = V(w)(v₁, v₂)``, ``θ = w`` (not wrapped).

    Parameters
    ----------
    xi : array_like, shape (..., 3) — twist [m, m, rad]

    Returns
    -------
    ndarray, shape (..., 3) — pose [m, m, rad]
    """
    x = check_last_axis("xi", xi, 3)
    v1, v2, w = x[..., 0], x[..., 1], x[..., 2]
    s, c = sinc(w), cosc(w)
    return np.stack([s * v1 - c * v2, c * v1 + s * v2, w], axis=-1)


def log(pose: ArrayLike) -> NDArray[np.float64]:
    """Logarithm of SE(2): pose ``(x, y, θ)`` → twist ``(v₁, v₂, w)`` with ``w = θ``.

    The heading is used as given (unwrapped): the inverse of :func:`exp` for
    any ``θ`` that is not a non-zero multiple of 2π. For the principal
    logarithm wrap θ first.

    Parameters
    ----------
    pose : array_like, shape (..., 3) [m, m, rad]

    Returns
    -------
    ndarray, shape (..., 3) [m, m, rad]
    """
    p = check_last_axis("pose", pose, 3)
    x, y, w = p[..., 0], p[..., 1], p[..., 2]
    # V(w)⁻¹ = (w/2)[[cot(w/2), 1], [−1, cot(w/2)]]
    a = _half_cot(w)
    h = 0.5 * w
    return np.stack([a * x + h * y, -h * x + a * y, w], axis=-1)


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Group product ``a · b`` of poses (``b`` expressed in the frame of ``a``).

    ``t = t_a + R(θ_a) t_b``, ``θ = θ_a + θ_b`` (not wrapped).

    Parameters
    ----------
    a, b : array_like, shape (..., 3), broadcastable [m, m, rad]

    Returns
    -------
    ndarray, shape (broadcast of a and b) [m, m, rad]
    """
    pa = check_last_axis("a", a, 3)
    pb = check_last_axis("b", b, 3)
    c, s = np.cos(pa[..., 2]), np.sin(pa[..., 2])
    return np.stack(
        [
            pa[..., 0] + c * pb[..., 0] - s * pb[..., 1],
            pa[..., 1] + s * pb[..., 0] + c * pb[..., 1],
            pa[..., 2] + pb[..., 2],
        ],
        axis=-1,
    )


def inverse(pose: ArrayLike) -> NDArray[np.float64]:
    """Group inverse ``g⁻¹ = (−Rᵀt, −θ)``: ``compose(g, inverse(g)) = 0``.

    Parameters
    ----------
    pose : array_like, shape (..., 3) [m, m, rad]

    Returns
    -------
    ndarray, shape (..., 3) [m, m, rad]
    """
    p = check_last_axis("pose", pose, 3)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    x, y = p[..., 0], p[..., 1]
    return np.stack([-(c * x + s * y), s * x - c * y, -p[..., 2]], axis=-1)


def adjoint(pose: ArrayLike) -> NDArray[np.float64]:
    """Adjoint matrix ``Ad_g = [[R, (t_y, −t_x)ᵀ], [0, 1]]``: ``g exp(ξ) g⁻¹ = exp(Ad_g ξ)``.

    A homomorphism: ``Ad_{a·b} = Ad_a Ad_b``. Maps a twist ``(v₁, v₂, w)`` [m, m, rad]
    to a twist in the same units (the top-right column carries metres per radian).

    Parameters
    ----------
    pose : array_like, shape (..., 3) [m, m, rad]

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    p = check_last_axis("pose", pose, 3)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    one, zero = np.ones_like(c), np.zeros_like(c)
    return np.stack(
        [
            np.stack([c, -s, p[..., 1]], axis=-1),
            np.stack([s, c, -p[..., 0]], axis=-1),
            np.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )


def adjoint_inverse(pose: ArrayLike) -> NDArray[np.float64]:
    """``Ad_g⁻¹ = Ad_{g⁻¹} = [[Rᵀ, −Rᵀ(t_y, −t_x)ᵀ], [0, 1]]``, without a matrix inverse.

    Parameters
    ----------
    pose : array_like, shape (..., 3) [m, m, rad]

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    return adjoint(inverse(pose))


def right_jacobian(xi: ArrayLike) -> NDArray[np.float64]:
    """Right Jacobian of SE(2): ``exp(ξ + dξ) ≈ exp(ξ) exp(J_r(ξ) dξ)``.

    For ``ξ = (ρ₁, ρ₂, w)``::

        J_r = [[sin w/w,      (1−cos w)/w,  ρ₁(w−sin w)/w² − ρ₂(1−cos w)/w²],
               [−(1−cos w)/w, sin w/w,      ρ₁(1−cos w)/w² + ρ₂(w−sin w)/w²],
               [0,            0,            1                             ]]

    (Solà, Deray & Atchuthan, "A micro Lie theory", 2018, eq. 163), with the
    series at ``w → 0``.

    Parameters
    ----------
    xi : array_like, shape (..., 3) — twist [m, m, rad]

    Returns
    -------
    ndarray, shape (..., 3, 3) — maps a twist increment to a twist increment [m, m, rad]
    """
    x = check_last_axis("xi", xi, 3)
    r1, r2, w = x[..., 0], x[..., 1], x[..., 2]
    s = sinc(w)
    c = cosc(w)
    c2 = 0.5 * sinc(0.5 * w) ** 2  # (1 − cos w)/w²
    d2 = _w_minus_sin_over_w2(w)  # (w − sin w)/w²
    one, zero = np.ones_like(w), np.zeros_like(w)
    return np.stack(
        [
            np.stack([s, c, r1 * d2 - r2 * c2], axis=-1),
            np.stack([-c, s, r1 * c2 + r2 * d2], axis=-1),
            np.stack([zero, zero, one], axis=-1),
        ],
        axis=-2,
    )
