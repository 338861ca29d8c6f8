"""One motion step of the velocity or odometry model, as both map constructions see it.

:class:`_Step` holds one control (or one odometry increment), its noise constants and
settings, and evaluates the step's density at cell centres, averaged over cells, or
integrated exactly over one cell (the cells next to the start, where the corrected
densities have their ``1/r`` singularity). :func:`_make_step` builds it from a control
or from two odometry poses; :func:`_noise_args` checks the noise settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ...core.kinematics import wrap_angle
from ...core.noise import cdf, check_noise, check_scaling, noise_reach, prob, prob_cell
from ...core.validation import (
    check_choice,
)
from ..motion_models import (
    check_alphas,
    odometry_deltas,
    odometry_density,
    odometry_forward,
    odometry_variances,
    velocity_forward,
    velocity_separable,
    velocity_variances,
)
from .kernels import Array, _midpoint_nodes, _ray_box

MODELS: tuple[str, ...] = ("velocity", "odometry")


@dataclass(frozen=True)
class _Step:
    """One motion step of a model, in the start frame (translation invariant)."""

    model: str
    u: Array  # velocity: (V, ω); odometry: (δrot1, δtrans, δrot2)
    dt: float
    alphas: Array
    noise: str
    scaling: str
    corrected: bool
    variance_from: str | None
    odom: tuple[Array, Array] | None  # odometry poses (prev, next)

    def variances(self) -> Array:
        if self.model == "velocity":
            return velocity_variances(self.u, self.alphas, self.scaling)
        v = odometry_variances(self.u[0], self.u[1], self.u[2], self.alphas, self.scaling)
        return np.array([float(x) for x in v])

    def noiseless(self, start: Array) -> Array:
        if self.model == "velocity":
            return velocity_forward(start, self.u[0], self.u[1], 0.0, self.dt)
        return odometry_forward(start, self.u[0], self.u[1], self.u[2])

    def density(
        self, xy: Array, theta_dst: Array, start: Array, cell: tuple[float, float] | None
    ) -> Array:
        """Cell-averaged (or, with ``cell=None``, point) density at positions ``xy`` (..., 2) × headings ``theta_dst`` (M,) → (..., M)."""
        if self.model == "velocity":
            p_xy, phi, v3, wg = velocity_separable(
                xy, self.u, start, self.dt, self.alphas, self.noise, self.scaling,
                self.corrected, cell,
            )  # fmt: skip
            g = wrap_angle(theta_dst - start[2] - phi[..., None]) / self.dt
            if cell is None:
                return np.asarray(p_xy[..., None] * prob(g, v3[..., None], self.noise))
            return np.asarray(
                p_xy[..., None] * prob_cell(g, v3[..., None], wg[..., None], self.noise)
            )
        assert self.odom is not None
        pos = np.broadcast_to(xy[..., None, :], (*xy.shape[:-1], theta_dst.size, 2))
        th = np.broadcast_to(theta_dst, pos.shape[:-1])[..., None]
        hyp = np.concatenate([pos, th], axis=-1)
        return odometry_density(
            hyp, self.odom[0], self.odom[1], start, self.alphas, self.noise, self.scaling,
            self.corrected, self.variance_from, cell,
        )  # fmt: skip

    def exact_cell(
        self,
        s: Array,
        lo: Array,
        hi: Array,
        start_theta: float,
        theta_dst: Array,
        cell: tuple[float, float],
        n_nodes: int = 2001,
    ) -> Array:
        """Exact ``∫_cell p(x, y, θ') dx dy`` of the sampler's density over the cell [lo, hi].

        Returns shape (M,) [1/rad]. 1-D quadrature (midpoint, ``n_nodes``) over
        ``ω̂`` (velocity) or ``δ̂rot1`` (odometry) of the CDF of ``V̂`` (``δ̂trans``)
        between the points where the ray of motion from the start ``s`` (forwards
        and backwards) enters and leaves the cell; the heading-only factor is
        averaged over the heading cell. Used near the start, where the corrected
        density has its ``1/r`` singularity.
        """
        var = self.variances()
        if self.model == "velocity":
            return self._exact_cell_velocity(var, s, lo, hi, start_theta, theta_dst, cell[1], n_nodes)
        return self._exact_cell_odometry(var, s, lo, hi, start_theta, theta_dst, cell[1], n_nodes)

    def _exact_cell_velocity(
        self, var: Array, s: Array, lo: Array, hi: Array, start_theta: float, theta_dst: Array,
        ht: float, n_nodes: int,
    ) -> Array:
        """:meth:`exact_cell`, velocity model: quadrature over ``ω̂`` of the CDF of ``V̂``."""
        sd = np.sqrt(var)
        dt = self.dt
        w, step = _midpoint_nodes(float(self.u[1]), float(sd[1]), -math.pi / dt, math.pi / dt,
                                  noise_reach(self.noise), n_nodes)  # fmt: skip
        phi = w * dt
        sinc = np.sinc(phi / (2 * math.pi))
        beta = start_theta + phi / 2
        f0, f1 = _ray_box(beta, s, lo, hi)
        b0, b1 = _ray_box(beta + math.pi, s, lo, hi)
        scale = dt * sinc
        V = self.u[0]
        pv = (
            cdf(f1 / scale - V, var[0], self.noise)
            - cdf(f0 / scale - V, var[0], self.noise)
            + cdf(-b0 / scale - V, var[0], self.noise)
            - cdf(-b1 / scale - V, var[0], self.noise)
        )
        pw = prob(self.u[1] - w, var[1], self.noise) if sd[1] > 0 else np.ones(1)
        g = wrap_angle(theta_dst[None, :] - start_theta - phi[:, None]) / dt
        pg = prob_cell(g, var[2], ht / dt, self.noise) / dt
        return np.asarray(step * np.sum((pv * pw)[:, None] * pg, axis=0))

    def _exact_cell_odometry(
        self, var: Array, s: Array, lo: Array, hi: Array, start_theta: float, theta_dst: Array,
        ht: float, n_nodes: int,
    ) -> Array:
        """:meth:`exact_cell`, odometry model: quadrature over ``δ̂rot1`` of the CDF of ``δ̂trans``."""
        sd = np.sqrt(var)
        r1u, tru, r2u = (float(v) for v in self.u)
        r1, step = _midpoint_nodes(r1u, float(sd[0]), r1u - math.pi, r1u + math.pi,
                                   noise_reach(self.noise), n_nodes)  # fmt: skip
        r2 = wrap_angle(theta_dst[None, :] - start_theta - r1[:, None])
        if self.variance_from == "hypothesis" or (
            self.variance_from is None and not self.corrected
        ):
            v1, v2, v3 = odometry_variances(r1[:, None], 0.0, r2, self.alphas, self.scaling)
        else:
            v1, v2, v3 = (np.full(r2.shape, var[i]) for i in range(3))
        beta = start_theta + r1
        f0, f1 = (t[:, None] for t in _ray_box(beta, s, lo, hi))
        b0, b1 = (t[:, None] for t in _ray_box(beta + math.pi, s, lo, hi))
        # δ'trans = δtrans − noise ∈ [a, b]  ⇔  noise ∈ [δtrans − b, δtrans − a]
        pt = (
            cdf(tru - f0, v2, self.noise)
            - cdf(tru - f1, v2, self.noise)
            + cdf(tru + b1, v2, self.noise)
            - cdf(tru + b0, v2, self.noise)
        )
        if sd[0] > 0:
            p1 = prob(wrap_angle(r1u - r1)[:, None], v1, self.noise)
        else:
            p1 = np.ones((1, 1))
        p3 = prob_cell(wrap_angle(r2u - r2), v3, ht, self.noise)
        return np.asarray(step * np.sum(p1 * pt * p3, axis=0))


def _make_step(
    model: str,
    control: Array | None,
    dt: float,
    alphas: Array,
    noise: str,
    scaling: str,
    corrected: bool,
    variance_from: str | None,
    odom: tuple[Array, Array] | None,
) -> _Step:
    if model == "velocity":
        assert control is not None
        return _Step(model, control, dt, alphas, noise, scaling, corrected, variance_from, None)
    assert odom is not None
    r1, tr, r2 = odometry_deltas(odom[0], odom[1])
    u = np.array([float(r1), float(tr), float(r2)])
    return _Step(model, u, dt, alphas, noise, scaling, corrected, variance_from, odom)


def _noise_args(model: str, noise: str, scaling: str, alphas: ArrayLike) -> Array:
    check_choice("model", model, MODELS)
    check_noise(noise)
    check_scaling(scaling)
    return check_alphas(alphas, 6 if model == "velocity" else 4)
