"""The compiled Monte Carlo kernel against numpy's, on the same draws, within the stated bounds.

Two routes to one cloud: the numpy kernel (the reference, ``kernel="numpy"``) and the compiled
loop (``kernel="compiled"``), both fed by the same seed and so the same normals. They may
differ only by rounding: the polynomial ``cos``/``sin`` (within ``SIN_COS_ULPS`` ulp of the true
value, the C library's within 1) and the order of the sums over the steps. The reproducibility
contract's tolerance ``relative_tolerance(N)`` of the cloud's scale is the bound, on long paths
(10⁴ steps), full circles and heading perturbations of many turns.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.drives import wheel_path
from pose_uncertainty.methods import drive_sampling, mc_kernel
from pose_uncertainty.methods import sampling as sp
from pose_uncertainty.records.reproducibility import relative_tolerance

METHODS = ("midpoint", "exact", "euler", "euler_end")


def _assert_within_contract(a: np.ndarray, b: np.ndarray, n_steps: int) -> None:
    """Positions within rtol(N) of the cloud's extent in x and y together; headings of max(1, |θ|)."""
    rtol = relative_tolerance(n_steps)
    xy_scale = max(1.0, float(np.abs(a[:, :2]).max()))
    th_scale = max(1.0, float(np.abs(a[:, 2]).max()))
    assert np.abs(a[:, :2] - b[:, :2]).max() <= rtol * xy_scale
    assert np.abs(a[:, 2] - b[:, 2]).max() <= rtol * th_scale


def _both(traj: tr.Trajectory, k: float, n: int, seed: int, **kw: object) -> tuple[np.ndarray, np.ndarray]:
    ref = sp.sample_end_poses(traj, k, k, n, np.random.default_rng(seed), kernel="numpy", **kw)  # type: ignore[arg-type]
    fast = sp.sample_end_poses(traj, k, k, n, np.random.default_rng(seed), kernel="compiled", **kw)  # type: ignore[arg-type]
    return ref, fast


def test_polynomial_sin_cos_within_two_ulp_of_numpy():
    # 10⁶ angles: small heading perturbations, a few turns, up to the reduction limit, and
    # neighbours of multiples of π/2 (where the reduction cancels most)
    g = np.random.default_rng(11)
    k = np.arange(-2000, 2000) * (math.pi / 2)
    x = np.concatenate([
        g.normal(0.0, 0.05, 250_000),
        g.uniform(-20.0, 20.0, 250_000),
        g.uniform(-1.0, 1.0, 250_000) * mc_kernel.jit_module().REDUCTION_LIMIT,
        (k[:, None] * (1.0 + g.uniform(-1e-15, 1e-15, (k.size, 62)))).ravel(),
    ])  # fmt: skip
    out = np.empty((2, x.size))
    mc_kernel.jit_module().sin_cos_array(x, out)
    cos, sin = np.cos(x), np.sin(x)
    # the polynomial within SIN_COS_ULPS ulp of the true value, numpy's within 1 ulp of it;
    # the reduction's own error k·|π/2 − (pio2_1 + pio2_2 + pio2_3)| < |x|·2⁻¹⁰² adds to it
    ulps = mc_kernel.SIN_COS_ULPS + 1
    for got, want in ((out[0], cos), (out[1], sin)):
        bound = ulps * np.spacing(np.abs(want)) + np.abs(x) * 2.0**-102
        assert np.all(np.abs(got - want) <= bound)
    assert np.abs(out[0] ** 2 + out[1] ** 2 - 1.0).max() <= 4 * 2.0**-53


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("regime", ["per_step", "per_run"])
def test_compiled_equals_numpy_on_the_same_draws(method, regime):
    traj = tr.s_curve(dt=0.02)
    ref, fast = _both(traj, 5e-4, 3000, 3, method=method, regime=regime)
    _assert_within_contract(ref, fast, traj.n_steps)
    assert not np.array_equal(ref, sp.sample_end_poses(traj, 5e-4, 5e-4, 3000, np.random.default_rng(4)))


def test_compiled_equals_numpy_with_a_start_covariance():
    traj = tr.arc(radius=0.5, angle=1.0, dt=0.01, start=(0.3, -0.1, 0.4))
    ref, fast = _both(traj, 5e-4, 2000, 5, cov0=np.diag([1e-4, 2e-4, 3e-4]))
    _assert_within_contract(ref, fast, traj.n_steps)


@pytest.mark.parametrize("method", ["midpoint", "exact"])
def test_long_path_of_ten_thousand_steps(method):
    # 10⁴ steps (10 laps of a 1 m circle at dt = 0.006 s): the rounding of 10⁴ polynomial
    # cos/sin stays inside rtol(10⁴) = 7·10⁻¹¹ of the cloud's scale
    traj = tr.circle(radius=1.0, laps=10.0, dt=0.006)
    assert traj.n_steps >= 10_000
    ref, fast = _both(traj, 5e-4, 200, 6, method=method)
    _assert_within_contract(ref, fast, traj.n_steps)


@pytest.mark.parametrize("laps", [1.0, 3.0])
def test_full_circles_with_heading_noise_of_many_turns(laps):
    # k = 2 m on a 5 cm track: the heading perturbation wanders over several full turns
    # (its spread at the end is √(2kL)/b rad, checked below), so cos/sin see every quadrant
    traj = tr.circle(radius=0.5, laps=laps, dt=0.01, track=0.05)
    ref, fast = _both(traj, 2.0, 2000, 7)
    nominal_end = traj.poses[-1, 2]
    assert np.std(ref[:, 2] - nominal_end) > 4 * math.pi
    _assert_within_contract(ref, fast, traj.n_steps)


def test_heading_beyond_the_reduction_falls_back_to_the_c_library():
    # a start heading spread of 10⁷ rad: the polynomial's reduction is not exact there, the
    # kernel recomputes such blocks with the C library's cos/sin
    traj = tr.straight(1.0, dt=0.05)
    cov0 = np.diag([1e-4, 1e-4, 1e14])
    ref, fast = _both(traj, 5e-4, 500, 8, cov0=cov0)
    assert np.abs(ref[:, 2]).max() > mc_kernel.jit_module().REDUCTION_LIMIT
    _assert_within_contract(ref, fast, traj.n_steps)


def test_libm_trigonometry_is_a_third_route():
    traj = tr.s_curve(dt=0.02)
    z = np.random.default_rng(9).standard_normal((2, 400, traj.n_steps))
    nom = drive_sampling._nominal(wheel_path(traj), "midpoint")
    scale = (np.sqrt(5e-4 * np.abs(traj.ds_r)), np.sqrt(5e-4 * np.abs(traj.ds_l)))
    nominal = tuple(np.ascontiguousarray(a) for a in (nom.v1, nom.dtheta, nom.cos, nom.sin))
    args = (z[0], z[1], *scale, (1.0, 1.0), nominal, traj.start, traj.track, 0.5, False, None)
    poly = mc_kernel.compiled_end_poses(*args, trig="polynomial")
    libm = mc_kernel.compiled_end_poses(*args, trig="libm")
    _assert_within_contract(libm, poly, traj.n_steps)


def test_compiled_kernel_is_thread_count_free():
    traj = tr.arc(radius=1.0, angle=1.0, dt=0.01)
    a = sp.sample_end_poses(traj, 5e-4, 5e-4, 5000, np.random.default_rng(7), workers=1, kernel="compiled")
    b = sp.sample_end_poses(traj, 5e-4, 5e-4, 5000, np.random.default_rng(7), workers=2, kernel="compiled")
    assert_array_equal(a, b)


def test_auto_uses_the_compiled_kernel_from_the_threshold(monkeypatch):
    traj = tr.straight(1.0, dt=0.01)
    n = 1000
    ref, fast = _both(traj, 5e-4, n, 10)
    assert not np.array_equal(ref, fast)  # the two kernels round differently somewhere
    monkeypatch.setattr(mc_kernel, "MIN_PARTICLE_STEPS", n * traj.n_steps + 1)
    assert_array_equal(sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10)), ref)
    monkeypatch.setattr(mc_kernel, "MIN_PARTICLE_STEPS", n * traj.n_steps)
    assert_array_equal(sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10)), fast)


def test_bad_kernel_name(rng):
    with pytest.raises(ValueError, match=r"kernel must be one of 'auto', 'numpy', 'compiled', got 'fast'"):
        sp.sample_end_poses(tr.straight(1.0), 1e-4, 1e-4, 10, rng, kernel="fast")


@pytest.mark.parametrize("turns", [0.0, 50.0, 3.0e5])
def test_particle_filter_wheel_step_compiled_equals_numpy(turns):
    # the particle filter's motion update: the same draws moved by numpy and by the compiled loop;
    # headings of up to 3·10⁵ turns (2·10⁶ rad, beyond the reduction: the C library's cos/sin)
    from pose_uncertainty.localization import simulate as SIM
    from pose_uncertainty.localization.motion import Motion, sample_motion
    from pose_uncertainty.localization.world import World

    world = World(np.array([[2.0, 1.0]]), np.arange(1))
    run = SIM.simulate(tr.arc(radius=1.0, angle=1.0, dt=0.1), world, np.random.default_rng(1))
    P = np.random.default_rng(2).normal(0.0, 0.1, (3000, 3))
    P[:, 2] += 2 * math.pi * turns
    motion = Motion(k_r=1e-3, k_l=2e-3)
    ref = sample_motion(P, motion, run, 3, np.random.default_rng(4), compiled=False)
    fast = sample_motion(P, motion, run, 3, np.random.default_rng(4), compiled=True)
    # one step: positions within 3 ulp of cos/sin times the step, headings bit for bit
    assert np.abs(fast[:, :2] - ref[:, :2]).max() <= relative_tolerance(1) * max(1.0, np.abs(ref[:, :2]).max())
    assert_array_equal(fast[:, 2], ref[:, 2])
    assert not np.array_equal(ref, sample_motion(P, motion, run, 3, np.random.default_rng(5), compiled=False))


def test_exp_small_is_within_its_bound_on_its_range():
    """The brackets' branch-free exp: within a relative 1.2e-5 of numpy's on [-16, 0]."""
    import numba

    jit = mc_kernel.jit_module()
    f = numba.njit(lambda x: jit.exp_small(x))
    xs = np.concatenate([np.linspace(-16.0, 0.0, 20001), [-1e-300, 0.0, -15.999999]])
    got = np.array([f(x) for x in xs])
    assert np.all(np.abs(got / np.exp(xs) - 1.0) <= 1.2e-5)
