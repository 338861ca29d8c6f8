"""Velocity and odometry motion models (Thrun §5.3–5.4; Němec 2012 §2.2): densities and samplers.

Both models are written in the frame of the start pose ``x_{t−1} = (x, y, θ)``: a
hypothesis ``x_t = (x', y', θ')`` has the local displacement

    f = (x'−x) cos θ + (y'−y) sin θ     (forward)      l = −(x'−x) sin θ + (y'−y) cos θ   (left)

so every density is translation invariant and rotates with θ.

Velocity model, ``u = (V, ω)`` for ``Δt``
-----------------------------------------
Inverse (hypothesis → controls ``(V̂, ω̂, γ̂)``). The circle through both points
tangent to the start heading turns by ``Δφ = 2·atan2(l, f)``, wrapped to (−π, π]
(Němec 2012's μ/x*/y*/r* construction gives the same circle; this form has no
singular denominator). We take the *principal branch*: the shorter arc, driven
forwards (``V̂ > 0``) when the hypothesis is ahead (``f ≥ 0``) and backwards
(``V̂ < 0``) when it is behind::

    β = atan2(l, f);  h = β if |β| ≤ π/2 else β ∓ π   (h = Δφ/2 ∈ [−π/2, π/2])
    ω̂ = 2h/Δt,   V̂ = ±√(f²+l²) / (Δt · sinc h),   γ̂ = wrap(θ'−θ−ω̂Δt)/Δt

with ``sinc h = sin h / h`` (1 at h = 0, the straight limit: ``V̂`` = signed
distance / Δt). At zero displacement ``atan2(0, 0) = 0`` gives ``ω̂ = 0, V̂ = 0``.
Other branches (arcs turning by more than π) are not summed: their mass is
``P(|ω̂Δt| > π)``, negligible for the thesis constants (> 6σ away).

Thrun's density is ``prob(V−V̂, σ₁²)·prob(ω−ω̂, σ₂²)·prob(γ̂, σ₃²)`` with
``σ₁² = α1V²+α2ω²`` etc. (or ``α|·|`` with ``scaling="abs"``). It is the
density of the control-space noise evaluated at the preimage, **not** a
density over poses. The pose density of the sampler is obtained by the change
of variables ``(V̂, ω̂, γ̂) → (x', y', θ')`` whose Jacobian determinant is::

    |det J| = |V̂| Δt⁴ sinc²(ω̂Δt/2) / 2

(``corrected=True`` divides by it). The corrected density has an integrable
``1/|V̂|`` (``1/r``) singularity at the start: there every ``ω̂`` reaches the same
point. At exactly zero displacement ``|V̂|`` is floored at :data:`MIN_SPEED`
so the value stays finite; maps integrate the start cell exactly instead.

Odometry model, ``u`` = odometry poses ``x̄ → x̄'``
---------------------------------------------------
``δrot1 = atan2(ȳ'−ȳ, x̄'−x̄) − θ̄``, ``δtrans``, ``δrot2 = θ̄'−θ̄−δrot1`` with these
conventions (documented deviations from the book, which has none):

* rotation in place: if ``δtrans < TRANS_EPS`` (10⁻⁹ m) then ``δrot1 = 0``;
* reverse motion: ``δtrans`` is signed; of the two decompositions
  ``(δrot1, +r)`` and ``(δrot1 ± π, −r)`` the one with ``δrot1`` nearer to 0
  is used for ``u`` (so driving backwards is "no turn, negative translation",
  not "turn round, drive, turn back" with its huge rotational variance);
* a hypothesis uses the decomposition whose ``δ̂rot1`` is nearer to ``u``'s
  ``δrot1`` (the principal branch); at zero hypothesis displacement
  ``δ̂rot1 = δrot1`` of ``u``;
* all rotation differences are wrapped to (−π, π].

Variances: the book's density evaluates them at the hypothesis
(``α1 δ̂rot1² + α2 δ̂trans²`` …, Thrun §5.4) while its sampler uses the odometry
``δ`` — the two disagree. ``variance_from="hypothesis"`` gives the printed
formula, ``"odometry"`` the sampler's. The pose density of the sampler is
``p / |δ̂trans|`` (Jacobian of ``(δrot1, δtrans, δrot2) → (x', y', θ')``), with
variances from the odometry; ``corrected=True`` selects exactly that.

Cell averaging
--------------
With ``cell=(h, h_θ)`` the density is averaged over one grid cell: each noise
factor is replaced by its mean over the interval of control values that one
cell spans along that factor's gradient (:func:`~pose_uncertainty.core.noise.prob_cell`),
width ``w_i = √(Σ_j (∂ĉ_i/∂p_j)² h_j²)``. Velocity: ``|∇V̂| = (1/(Δt s))·√(1+(s′/s)²)``
(``s = sinc(ω̂Δt/2)``), ``|∇ω̂| = 2/(Δt r)``, so ``w_V = h|∇V̂|``, ``w_ω = 2h/(Δt r)``,
``w_γ = √(w_ω² + (h_θ/Δt)²)``; odometry: ``w_rot1 = h/r``, ``w_trans = h``,
``w_rot2 = √(w_rot1² + h_θ²)`` (``r`` = distance from the start).
A term narrower than a cell (zero variance included) is then integrated over
the cell instead of being sampled at its centre, which would alias a thin ridge.
Without ``cell`` the density is the point value (variances ≥ :data:`MIN_VARIANCE`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.kinematics import dsinc, sinc, wrap_angle
from ..core.noise import check_noise, check_scaling, prob, prob_cell, sample, scaled_variance
from ..core.validation import (
    check_choice,
    check_finite,
    check_last_axis,
    check_nonnegative,
    check_positive,
    check_positive_int,
)

__all__ = [
    "MIN_SPEED",
    "TRANS_EPS",
    "VARIANCE_SOURCES",
    "check_alphas",
    "noiseless_velocity_poses",
    "odometry_cell_widths",
    "odometry_deltas",
    "odometry_density",
    "odometry_forward",
    "odometry_variances",
    "sample_controls",
    "sample_odometry",
    "sample_odometry_path",
    "sample_velocity",
    "sample_velocity_path",
    "velocity_cell_widths",
    "velocity_density",
    "velocity_forward",
    "velocity_inverse",
    "velocity_jacobian_det",
    "velocity_separable",
    "velocity_variances",
]

#: Below this translation [m] the odometry rotation δrot1 is undefined and set by convention.
TRANS_EPS: float = 1e-9
#: The speed floor ``|V̂|`` [m/s] in the corrected velocity density at exactly zero displacement.
MIN_SPEED: float = 1e-9
VARIANCE_SOURCES: tuple[str, ...] = ("hypothesis", "odometry")

Array = NDArray[np.float64]


# ----------------------------------------------------------------------------- helpers


def check_alphas(alphas: ArrayLike, n: int) -> Array:
    """Return the ``n`` error constants as float64, each finite and >= 0.

    Raises
    ------
    ValueError
        Naming the bad value (e.g. a negative α) or the wrong count.
    """
    arr = check_nonnegative("alphas", alphas)
    if arr.shape != (n,):
        raise ValueError(
            f"alphas must hold {n} error constants (allowed: shape ({n},), each >= 0), "
            f"got shape {arr.shape}"
        )
    return arr


def _pose(name: str, value: ArrayLike) -> Array:
    return check_finite(name, check_last_axis(name, value, 3))


def _local(x_t: Array, x_prev: Array) -> tuple[Array, Array, Array]:
    """Displacement of ``x_t`` in the frame of ``x_prev``: forward f, left l, heading change."""
    dx = x_t[..., 0] - x_prev[..., 0]
    dy = x_t[..., 1] - x_prev[..., 1]
    c, s = np.cos(x_prev[..., 2]), np.sin(x_prev[..., 2])
    return dx * c + dy * s, -dx * s + dy * c, x_t[..., 2] - x_prev[..., 2]


def _check_cell(cell: tuple[float, float] | None) -> tuple[float, float] | None:
    if cell is None:
        return None
    h = float(check_positive("resolution", cell[0]))
    ht = float(check_positive("theta_resolution", cell[1]))
    return h, ht


# ----------------------------------------------------------------------------- velocity


def _chord_move(xp: Array, head: Array, chord: Array, theta_end: Array) -> Array:
    """Poses (..., 3): ``xp`` moved by ``chord`` [m] along heading ``head``, ending at heading ``theta_end``.

    One step of either model is such a move: turn, translate along the chord, turn.
    """
    return np.stack(
        [xp[..., 0] + chord * np.cos(head), xp[..., 1] + chord * np.sin(head), theta_end], axis=-1
    )


def velocity_variances(control: ArrayLike, alphas: ArrayLike, scaling: str = "squared") -> Array:
    """Variances ``(σ_V², σ_ω², σ_γ²)`` of the velocity model for ``control = (V, ω)``.

    ``σ_V² = α1V²+α2ω²``, ``σ_ω² = α3V²+α4ω²``, ``σ_γ² = α5V²+α6ω²`` (``"squared"``)
    or with ``|V|, |ω|`` (``"abs"``). Returns shape ``(..., 3)``.
    """
    u = check_finite("control", check_last_axis("control", control, 2))
    a = check_alphas(alphas, 6)
    V, w = u[..., 0], u[..., 1]
    return np.stack(
        [scaled_variance(a[2 * i], a[2 * i + 1], V, w, scaling) for i in range(3)], axis=-1
    )


def velocity_inverse(x_t: ArrayLike, x_prev: ArrayLike, dt: float) -> tuple[Array, Array, Array]:
    """Controls ``(V̂, ω̂, γ̂)`` that carry ``x_prev`` to ``x_t`` in ``dt`` (principal branch).

    Parameters
    ----------
    x_t : array_like, shape (..., 3)
        Hypotheses [m, m, rad].
    x_prev : array_like, shape (..., 3)
        Start pose(s), broadcast against ``x_t``.
    dt : float [s], > 0

    Returns
    -------
    V_hat [m/s], omega_hat [rad/s], gamma_hat [rad/s] : ndarray, shape (...)
        ``|ω̂ Δt| ≤ π``; ``V̂ < 0`` for hypotheses behind the start.
    """
    xt, xp = _pose("x_t", x_t), _pose("x_prev", x_prev)
    step = float(check_positive("dt", dt))
    f, l, dth = _local(xt, xp)
    chord = np.hypot(f, l)
    beta = np.arctan2(l, f)
    forward = np.abs(beta) <= np.pi / 2
    h = np.where(forward, beta, beta - np.pi * np.sign(beta))  # Δφ/2 ∈ [−π/2, π/2]
    phi = 2.0 * h
    V_hat = np.where(forward, 1.0, -1.0) * chord / (step * sinc(h))  # sinc h ≥ 2/π here
    gamma_hat = wrap_angle(dth - phi) / step
    return V_hat, phi / step, gamma_hat


def velocity_forward(
    x_prev: ArrayLike, V: ArrayLike, omega: ArrayLike, gamma: ArrayLike, dt: float
) -> Array:
    """Pose after driving ``(V, ω)`` with heading drift ``γ`` for ``dt`` (Thrun §5.3 sampler).

    ``x' = x + VΔt·sinc(ωΔt/2)·cos(θ+ωΔt/2)``, ``y'`` likewise with ``sin``,
    ``θ' = θ + ωΔt + γΔt`` — the arc formula of Thrun §5.3 written without the
    ``V/ω`` division, so ``ω → 0`` is the straight line. Headings are not wrapped.

    Parameters
    ----------
    x_prev : array_like, shape (..., 3)
    V, omega, gamma : array_like, shape (...) [m/s, rad/s, rad/s]
    dt : float [s]

    Returns
    -------
    ndarray, shape (..., 3)
    """
    xp = _pose("x_prev", x_prev)
    V_, w_, g_ = (np.asarray(a, dtype=np.float64) for a in (V, omega, gamma))
    phi = w_ * dt
    # the arc is an odometry step: turn by φ/2, the chord VΔt·sinc(φ/2), turn by φ/2 + γΔt
    return _chord_move(xp, xp[..., 2] + phi / 2.0, V_ * dt * sinc(phi / 2.0), xp[..., 2] + phi + g_ * dt)


def velocity_jacobian_det(V_hat: ArrayLike, omega_hat: ArrayLike, dt: float) -> Array:
    """``|det ∂(x', y', θ')/∂(V̂, ω̂, γ̂)| = |V̂| Δt⁴ sinc²(ω̂Δt/2) / 2``."""
    V_ = np.asarray(V_hat, dtype=np.float64)
    s = sinc(np.asarray(omega_hat, dtype=np.float64) * dt / 2.0)
    return np.abs(V_) * dt**4 * s * s / 2.0


def velocity_cell_widths(
    V_hat: ArrayLike, omega_hat: ArrayLike, r: ArrayLike, dt: float, cell: tuple[float, float]
) -> tuple[Array, Array, Array]:
    """Control-space widths ``(w_V, w_ω, w_γ)`` of one grid cell at the given hypotheses.

    Parameters
    ----------
    V_hat, omega_hat : array_like — preimage controls [m/s, rad/s]
    r : array_like — distance of the hypothesis from the start [m]
    dt : float [s]
    cell : (h, h_θ) [m, rad]
    """
    h, ht = cell
    u = np.asarray(omega_hat, dtype=np.float64) * dt / 2.0
    s, ds = sinc(u), dsinc(u)
    wV = h / (dt * s) * np.sqrt(1.0 + (ds / s) ** 2)
    rr = np.maximum(np.asarray(r, dtype=np.float64), 1e-9 * h)
    ww = 2.0 * h / (dt * rr)
    wg = np.sqrt(ww**2 + (ht / dt) ** 2)
    return wV + 0.0 * np.asarray(V_hat), ww, wg


def velocity_separable(
    xy: ArrayLike,
    control: ArrayLike,
    x_prev: ArrayLike,
    dt: float,
    alphas: ArrayLike,
    noise: str = "normal",
    scaling: str = "squared",
    corrected: bool = False,
    cell: tuple[float, float] | None = None,
) -> tuple[Array, Array, Array, Array]:
    """The velocity density split into its position part and its heading part.

    ``p(x', y', θ') = p_xy(x', y') · prob_cell(wrap(θ'−θ−φ̂)/Δt, σ_γ², w_γ)`` where ``φ̂ = ω̂Δt``
    depends on the position only. Maps use this to evaluate ``(V̂, ω̂)`` once per
    ``(x, y)`` cell instead of once per ``(x, y, θ)`` cell.

    Parameters
    ----------
    xy : array_like, shape (..., 2)
        Hypothesis positions [m].
    control, x_prev, dt, alphas, noise, scaling, corrected, cell
        As :func:`velocity_density` (``x_prev`` shape (3,)).

    Returns
    -------
    p_xy : ndarray, shape (...)
        ``prob(V−V̂)·prob(ω−ω̂)`` [/ Jacobian if corrected].
    phi_hat : ndarray, shape (...)
        ``ω̂Δt`` [rad].
    var_gamma : ndarray, shape (...)
        Variance of ``γ̂``.
    width_gamma : ndarray, shape (...)
        Cell width in ``γ̂`` (0 without ``cell``).
    """
    check_noise(noise)
    check_scaling(scaling)
    u = check_finite("control", control)
    if u.shape != (2,):
        raise ValueError(f"control must have shape (2,) (allowed: (V, omega)), got shape {u.shape}")
    step = float(check_positive("dt", dt))
    cell_ = _check_cell(cell)
    pos = check_finite("xy", check_last_axis("xy", xy, 2))
    xp = _pose("x_prev", x_prev)
    hyp = np.concatenate([pos, np.broadcast_to(xp[..., 2:3], (*pos.shape[:-1], 1))], axis=-1)
    var = velocity_variances(u, alphas, scaling)
    V_hat, w_hat, _ = velocity_inverse(hyp, xp, step)
    if cell_ is None:
        p = prob(u[0] - V_hat, var[0], noise) * prob(u[1] - w_hat, var[1], noise)
        wg = np.zeros(V_hat.shape)
    else:
        r = np.hypot(pos[..., 0] - xp[0], pos[..., 1] - xp[1])
        wV, ww, wg = velocity_cell_widths(V_hat, w_hat, r, step, cell_)
        p = prob_cell(u[0] - V_hat, var[0], wV, noise) * prob_cell(u[1] - w_hat, var[1], ww, noise)
    if corrected:
        p = p / velocity_jacobian_det(np.maximum(np.abs(V_hat), MIN_SPEED), w_hat, step)
    return p, w_hat * step, np.full(V_hat.shape, var[2]), wg


def velocity_density(
    x_t: ArrayLike,
    control: ArrayLike,
    x_prev: ArrayLike,
    dt: float,
    alphas: ArrayLike,
    noise: str = "normal",
    scaling: str = "squared",
    corrected: bool = False,
    cell: tuple[float, float] | None = None,
) -> Array:
    """Velocity-model density ``p(x_t | u, x_{t−1})``, vectorised over hypotheses.

    Parameters
    ----------
    x_t : array_like, shape (..., 3)
        Hypotheses [m, m, rad].
    control : array_like, shape (2,)
        ``(V, ω)`` [m/s, rad/s].
    x_prev : array_like, shape (3,)
        Start pose.
    dt : float [s], > 0
    alphas : array_like, shape (6,), >= 0
    noise : {"normal", "triangular"}
    scaling : {"squared", "abs"}
    corrected : bool
        False: Thrun's value (density of the control noise at the preimage).
        True: pose-space density [1/(m²·rad)], divided by :func:`velocity_jacobian_det`.
    cell : (h, h_θ), optional
        Grid cell size [m, rad]; if given, the density is averaged over one cell
        (see "Cell averaging" in the module docs).

    Returns
    -------
    ndarray, shape (...)
        Finite and >= 0 everywhere.
    """
    xt = _pose("x_t", x_t)
    xp = _pose("x_prev", x_prev)
    if xp.shape != (3,):
        raise ValueError(f"x_prev must have shape (3,), got shape {xp.shape}")
    p_xy, phi, v3, wg = velocity_separable(
        xt[..., :2], control, xp, dt, alphas, noise, scaling, corrected, cell
    )
    g_hat = wrap_angle(xt[..., 2] - xp[2] - phi) / dt
    return p_xy * prob_cell(g_hat, v3, wg, noise)


def _starts(start: ArrayLike, n: int) -> Array:
    s = _pose("start", start)
    if s.shape != (3,) and s.shape != (n, 3):
        raise ValueError(f"start must have shape (3,) or (n, 3) = (…, {n}, 3), got shape {s.shape}")
    return np.broadcast_to(s, (n, 3))


def sample_velocity(
    start: ArrayLike,
    control: ArrayLike,
    dt: float,
    alphas: ArrayLike,
    n: int,
    rng: np.random.Generator,
    noise: str = "normal",
    scaling: str = "squared",
) -> Array:
    """Draw ``n`` end poses of the velocity model (``sample_motion_model_velocity``).

    ``V' = V + sample(σ_V²)``, ``ω' = ω + sample(σ_ω²)``, ``γ' = sample(σ_γ²)``, then
    :func:`velocity_forward`. Headings are not wrapped.

    Parameters
    ----------
    start : array_like, shape (3,) or (n, 3)
    control : array_like, shape (2,) — ``(V, ω)``
    dt : float [s], > 0
    alphas : array_like, shape (6,)
    n : int, >= 1
    rng : numpy.random.Generator
    noise, scaling : see :func:`velocity_density`

    Returns
    -------
    ndarray, shape (n, 3)
    """
    n = check_positive_int("n", n)
    check_noise(noise)
    step = float(check_positive("dt", dt))
    u = check_finite("control", control)
    var = velocity_variances(u, alphas, scaling)
    x0 = _starts(start, n)
    V = u[0] + sample(var[0], rng, noise, n)
    w = u[1] + sample(var[1], rng, noise, n)
    g = sample(var[2], rng, noise, n)
    return velocity_forward(x0, V, w, g, step)


def _per_step_dt(dt: ArrayLike, n_steps: int) -> Array:
    d = check_positive("dt", dt)
    if d.ndim == 0:
        return np.full(n_steps, float(d))
    if d.shape != (n_steps,):
        raise ValueError(f"dt must be a scalar or have shape ({n_steps},), got shape {d.shape}")
    return d


def sample_velocity_path(
    start: ArrayLike,
    controls: ArrayLike,
    dt: ArrayLike,
    alphas: ArrayLike,
    n: int,
    rng: np.random.Generator,
    noise: str = "normal",
    scaling: str = "squared",
) -> Array:
    """Monte Carlo of the velocity model along a whole trajectory: ``n`` end poses.

    Parameters
    ----------
    start : array_like, shape (3,)
    controls : array_like, shape (N, 2) — ``(V, ω)`` per step
    dt : float or array_like, shape (N,) [s]
    alphas, n, rng, noise, scaling : as :func:`sample_velocity`

    Returns
    -------
    ndarray, shape (n, 3)
    """
    u = check_finite("controls", check_last_axis("controls", controls, 2))
    steps = _per_step_dt(dt, u.shape[0])
    x = np.array(_starts(start, check_positive_int("n", n)))
    for k in range(u.shape[0]):
        x = sample_velocity(x, u[k], float(steps[k]), alphas, n, rng, noise, scaling)
    return x


def noiseless_velocity_poses(start: ArrayLike, controls: ArrayLike, dt: ArrayLike) -> Array:
    """Noiseless poses of the velocity model along ``controls``: shape (N+1, 3).

    Němec 2012 (§4.2) takes these as the odometry ``u`` of the odometry-model experiments.
    """
    u = check_finite("controls", check_last_axis("controls", controls, 2))
    steps = _per_step_dt(dt, u.shape[0])
    out = np.empty((u.shape[0] + 1, 3))
    out[0] = _pose("start", start)
    for k in range(u.shape[0]):
        out[k + 1] = velocity_forward(out[k], u[k, 0], u[k, 1], 0.0, float(steps[k]))
    return out


# ----------------------------------------------------------------------------- odometry


def odometry_deltas(
    pose_prev: ArrayLike, pose_next: ArrayLike, ref_rot1: ArrayLike = 0.0
) -> tuple[Array, Array, Array]:
    """Decompose ``pose_prev → pose_next`` into ``(δrot1, δtrans, δrot2)`` (conventions above).

    Parameters
    ----------
    pose_prev, pose_next : array_like, shape (..., 3)
    ref_rot1 : array_like, shape (...)
        Of the forward ``(a, +r)`` and reverse ``(a ± π, −r)`` decompositions the
        one with ``δrot1`` nearer to ``ref_rot1`` is returned; when ``r < TRANS_EPS``,
        ``δrot1 = ref_rot1``. Use 0 for the odometry ``u`` itself.

    Returns
    -------
    rot1 [rad], trans [m] (signed), rot2 [rad] : ndarray, shape (...)
        Rotations wrapped to (−π, π].
    """
    xp, xn = _pose("pose_prev", pose_prev), _pose("pose_next", pose_next)
    ref = np.asarray(ref_rot1, dtype=np.float64)
    f, l, dth = _local(xn, xp)
    r = np.hypot(f, l)
    a = np.arctan2(l, f)
    flipped = wrap_angle(a - np.pi)
    use_flip = np.abs(wrap_angle(flipped - ref)) < np.abs(wrap_angle(a - ref))
    tiny = r < TRANS_EPS
    rot1 = np.where(tiny, wrap_angle(ref), np.where(use_flip, flipped, a))
    trans = np.where(use_flip & ~tiny, -r, r)
    rot2 = wrap_angle(dth - rot1)
    return rot1, trans, rot2


def odometry_forward(x_prev: ArrayLike, rot1: ArrayLike, trans: ArrayLike, rot2: ArrayLike) -> Array:
    """Compose ``(δrot1, δtrans, δrot2)`` onto ``x_prev``: shape (..., 3), heading unwrapped."""
    xp = _pose("x_prev", x_prev)
    r1, tr, r2 = (np.asarray(a, dtype=np.float64) for a in (rot1, trans, rot2))
    head = xp[..., 2] + r1
    return _chord_move(xp, head, tr, head + r2)


def odometry_variances(
    rot1: ArrayLike, trans: ArrayLike, rot2: ArrayLike, alphas: ArrayLike, scaling: str = "squared"
) -> tuple[Array, Array, Array]:
    """Variances of the three odometry noise terms.

    ``σ₁² = α1 δrot1² + α2 δtrans²``, ``σ₂² = α3 δtrans² + α4 (δrot1² + δrot2²)``,
    ``σ₃² = α1 δrot2² + α2 δtrans²`` (``"squared"``), or with absolute values (``"abs"``).
    """
    a = check_alphas(alphas, 4)
    v1 = scaled_variance(a[0], a[1], rot1, trans, scaling)
    v2 = scaled_variance(a[2], a[3], trans, rot1, scaling) + scaled_variance(
        0.0, a[3], 0.0, rot2, scaling
    )
    v3 = scaled_variance(a[0], a[1], rot2, trans, scaling)
    return v1, v2, v3


def odometry_cell_widths(trans_hat: ArrayLike, cell: tuple[float, float]) -> tuple[Array, Array, Array]:
    """Control-space widths ``(w_rot1, w_trans, w_rot2)`` of one grid cell at distance ``|δ̂trans|``."""
    h, ht = cell
    r = np.maximum(np.abs(np.asarray(trans_hat, dtype=np.float64)), 1e-9 * h)
    w1 = h / r
    return w1, np.full_like(w1, h), np.sqrt(w1**2 + ht**2)


def odometry_density(
    x_t: ArrayLike,
    odom_prev: ArrayLike,
    odom_next: ArrayLike,
    x_prev: ArrayLike,
    alphas: ArrayLike,
    noise: str = "normal",
    scaling: str = "squared",
    corrected: bool = False,
    variance_from: str | None = None,
    cell: tuple[float, float] | None = None,
) -> Array:
    """Odometry-model density ``p(x_t | u, x_{t−1})``, vectorised over hypotheses.

    Parameters
    ----------
    x_t : array_like, shape (..., 3)
        Hypotheses.
    odom_prev, odom_next : array_like, shape (3,)
        Odometry poses ``x̄, x̄'`` (the control ``u``).
    x_prev : array_like, shape (3,) or (..., 3)
        Start pose.
    alphas : array_like, shape (4,), >= 0
    noise : {"normal", "triangular"}
    scaling : {"squared", "abs"}
    corrected : bool
        True: pose-space density of :func:`sample_odometry`, ``p/|δ̂trans|``.
    variance_from : {"hypothesis", "odometry"}, optional
        Where the variances are evaluated. Default: "odometry" if ``corrected``
        (the sampler's) else "hypothesis" (the book's printed formula).
    cell : see :func:`velocity_density`

    Returns
    -------
    ndarray, shape (...)
        Finite and >= 0.
    """
    check_noise(noise)
    check_scaling(scaling)
    source = variance_from or ("odometry" if corrected else "hypothesis")
    check_choice("variance_from", source, VARIANCE_SOURCES)
    cell_ = _check_cell(cell)
    op, on = _pose("odom_prev", odom_prev), _pose("odom_next", odom_next)
    r1, tr, r2 = odometry_deltas(op, on)
    h1, ht, h2 = odometry_deltas(x_prev, x_t, ref_rot1=r1)
    if source == "odometry":
        v1, v2, v3 = odometry_variances(r1, tr, r2, alphas, scaling)
    else:
        v1, v2, v3 = odometry_variances(h1, ht, h2, alphas, scaling)
    w1, w2, w3 = (0.0, 0.0, 0.0) if cell_ is None else odometry_cell_widths(ht, cell_)
    p = (
        prob_cell(wrap_angle(r1 - h1), v1, w1, noise)
        * prob_cell(tr - ht, v2, w2, noise)
        * prob_cell(wrap_angle(r2 - h2), v3, w3, noise)
    )
    if corrected:
        p = p / np.maximum(np.abs(ht), MIN_SPEED)
    return p


def sample_odometry(
    start: ArrayLike,
    odom_prev: ArrayLike,
    odom_next: ArrayLike,
    alphas: ArrayLike,
    n: int,
    rng: np.random.Generator,
    noise: str = "normal",
    scaling: str = "squared",
) -> Array:
    """Draw ``n`` end poses of the odometry model (``sample_motion_model_odometry``).

    ``δ'_i = δ_i − sample(σ_i²)`` with the variances of the odometry ``δ``, then
    :func:`odometry_forward`.

    Parameters
    ----------
    start : array_like, shape (3,) or (n, 3)
    odom_prev, odom_next : array_like, shape (3,)
    alphas : array_like, shape (4,)
    n : int; rng : numpy.random.Generator; noise, scaling : as :func:`odometry_density`

    Returns
    -------
    ndarray, shape (n, 3)
    """
    n = check_positive_int("n", n)
    check_noise(noise)
    r1, tr, r2 = odometry_deltas(_pose("odom_prev", odom_prev), _pose("odom_next", odom_next))
    v1, v2, v3 = odometry_variances(r1, tr, r2, alphas, scaling)
    x0 = _starts(start, n)
    s1 = r1 - sample(v1, rng, noise, n)
    st = tr - sample(v2, rng, noise, n)
    s2 = r2 - sample(v3, rng, noise, n)
    return odometry_forward(x0, s1, st, s2)


def sample_odometry_path(
    start: ArrayLike,
    odometry: ArrayLike,
    alphas: ArrayLike,
    n: int,
    rng: np.random.Generator,
    noise: str = "normal",
    scaling: str = "squared",
) -> Array:
    """Monte Carlo of the odometry model along noiseless odometry poses ``(N+1, 3)``."""
    od = _pose("odometry", odometry)
    if od.ndim != 2 or od.shape[0] < 2:
        raise ValueError(f"odometry must have shape (N+1, 3) with N >= 1, got shape {od.shape}")
    x = np.array(_starts(start, check_positive_int("n", n)))
    for k in range(od.shape[0] - 1):
        x = sample_odometry(x, od[k], od[k + 1], alphas, n, rng, noise, scaling)
    return x


# ----------------------------------------------------------------------------- a map's own truth


def sample_controls(
    model: str,
    start: ArrayLike,
    controls: ArrayLike,
    dt: ArrayLike,
    alphas: ArrayLike,
    n: int,
    rng: np.random.Generator,
    noise: str = "normal",
    scaling: str = "squared",
) -> Array:
    """End poses of a motion model's own sampler along velocity controls: what a map predicts.

    One control: :func:`sample_velocity` / :func:`sample_odometry`; several: the
    model's sampler applied step after step (:func:`sample_velocity_path` /
    :func:`sample_odometry_path`), which is what a multi-step map predicts. The
    odometry ``u`` is the noiseless velocity motion (Němec 2012's convention).

    Parameters
    ----------
    model : {"velocity", "odometry"}
    start : array_like, shape (3,); controls : array_like, shape (N, 2) — ``(V, ω)`` per step
    dt : float or array_like, shape (N,) [s]; alphas : the model's error constants
    n : int — number of draws; rng : numpy.random.Generator
    noise, scaling : as the samplers

    Returns
    -------
    ndarray, shape (n, 3)
    """
    check_choice("model", model, ("velocity", "odometry"))
    u = check_finite("controls", check_last_axis("controls", controls, 2)).reshape(-1, 2)
    if model == "velocity":
        if u.shape[0] == 1:
            return sample_velocity(start, u[0], float(_per_step_dt(dt, 1)[0]), alphas, n, rng,
                                   noise=noise, scaling=scaling)  # fmt: skip
        return sample_velocity_path(start, u, dt, alphas, n, rng, noise=noise, scaling=scaling)
    od = noiseless_velocity_poses(start, u, dt)
    if u.shape[0] == 1:
        return sample_odometry(start, od[0], od[1], alphas, n, rng, noise=noise, scaling=scaling)
    return sample_odometry_path(start, od, alphas, n, rng, noise=noise, scaling=scaling)
