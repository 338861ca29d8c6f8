"""Method C (the unscented transform): exact where the step is linear, A's limit, Monte Carlo, SE(2)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from pose_uncertainty.core import se2
from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.kinematics import wrap_angle
from pose_uncertainty.methods import covariance as cv
from pose_uncertainty.methods import expcoords as ec
from pose_uncertainty.methods import sampling as sp
from pose_uncertainty.methods import unscented as ut

ARC = tr.arc(1.0, np.pi, dt=0.01, track=0.2)  # half circle, 314 steps


def _cov0(sx=0.03, sy=0.02, sth=0.05, rxy=0.3, rxth=0.2, ryth=-0.1):
    sd = np.array([sx, sy, sth])
    R = np.array([[1, rxy, rxth], [rxy, 1, ryth], [rxth, ryth, 1]])
    return R * np.outer(sd, sd)


# --- the sigma-point machinery ------------------------------------------------------------------


def test_default_weights_are_nonnegative_and_small_alpha_makes_w0_huge_negative():
    w = ut.sigma_weights(5)
    assert w.lam == 0.0
    assert np.all(w.Wm >= 0)
    assert np.all(w.Wc >= 0)
    assert_allclose(w.Wm.sum(), 1.0, rtol=1e-15)
    small = ut.sigma_weights(5, alpha=1e-3, beta=2.0)
    # W₀ = 1 − n/(α²(n+κ)) = 1 − 1/α²
    assert_allclose(small.Wm[0], 1.0 - 1e6, rtol=1e-12)
    assert_allclose(small.Wc[0], small.Wm[0] + 1.0 - 1e-6 + 2.0, rtol=1e-12)
    assert_allclose(small.Wm.sum(), 1.0, atol=1e-9)


def test_psd_cholesky_reconstructs_singular_and_regular(rng):
    A = rng.normal(size=(6, 3, 3))
    P = A @ A.swapaxes(-1, -2)
    assert_allclose(ut.psd_cholesky(P), np.linalg.cholesky(P), rtol=1e-12, atol=1e-14)
    B = rng.normal(size=(6, 3, 1))  # rank 1
    Q = B @ B.swapaxes(-1, -2)
    L = ut.psd_cholesky(Q)
    assert_allclose(L @ L.swapaxes(-1, -2), Q, atol=1e-13)
    assert np.all(ut.psd_cholesky(np.zeros((3, 3))) == 0.0)


def test_a_linear_map_is_reproduced_exactly(rng):
    """The UT of an affine map: mean and covariance exact, whatever the weights."""
    m = rng.normal(size=5)
    B = rng.normal(size=(5, 5))
    P = B @ B.T
    T = rng.normal(size=(4, 5))
    for params in ({}, {"alpha": 0.5, "beta": 2.0, "kappa": 1.0}):
        w = ut.sigma_weights(5, **params)
        y = ut.sigma_points(m, ut.psd_cholesky(P), w.lam) @ T.T + 1.0
        mean = w.Wm @ y
        d = y - mean
        assert_allclose(mean, T @ m + 1.0, rtol=1e-12)
        assert_allclose((w.Wc[:, None] * d).T @ d, T @ P @ T.T, rtol=1e-10)


# --- C against A ----------------------------------------------------------------------------


def test_c_equals_a_exactly_for_a_linear_step():
    """Straight steps with a known heading and no wheel noise translate the pose: linear.

    The (x, y) uncertainty rides along unchanged; so does a full covariance (heading
    included) through steps that do not move. C must reproduce A to rounding.
    """
    line = tr.straight(2.0, dt=0.1, track=0.3)
    S_xy = _cov0(sth=0.0, rxth=0.0, ryth=0.0)
    A, C = cv.propagate(line, 0.0, 0.0, cov0=S_xy), ut.propagate(line, 0.0, 0.0, cov0=S_xy)
    assert_allclose(C.poses, A.poses, rtol=2e-15, atol=1e-17)  # a few ulp over 20 steps
    assert_allclose(C.covs, A.covs, rtol=1e-14, atol=1e-20)
    still = tr.Trajectory(ds_r=np.zeros(5), ds_l=np.zeros(5), dt=0.1, track=0.2, start=[1, 2, 0.4])
    S = _cov0(sth=0.3)
    A, C = cv.propagate(still, 1e-3, 1e-3, cov0=S), ut.propagate(still, 1e-3, 1e-3, cov0=S)
    assert_allclose(C.poses, A.poses, rtol=2e-15, atol=1e-17)
    assert_allclose(C.covs, A.covs, rtol=1e-14, atol=1e-20)


def test_c_converges_to_a_as_the_noise_vanishes():
    """Mean difference = c₁k + O(k²) (the second-order shift), covariance difference = c₂k² + O(k³).

    Halving k must halve the first and quarter the second; the ratios approach 2 and 4
    with an O(k) correction (0.5 % at k = 5·10⁻⁵ here, hence the 1 % tolerance).
    """
    diffs = []
    for k in (5e-5, 2.5e-5):
        A, C = cv.propagate(ARC, k, k), ut.propagate(ARC, k, k)
        diffs.append(
            (np.abs(C.poses[-1] - A.poses[-1]).max(), np.abs(C.covs[-1] - A.covs[-1]).max())
        )
    (m1, c1), (m2, c2) = diffs
    assert m1 > 1e-4  # a real difference, not rounding
    assert m1 / m2 == pytest.approx(2.0, rel=0.01)
    assert c1 / c2 == pytest.approx(4.0, rel=0.01)


# --- C against Monte Carlo ---------------------------------------------------------------------


def _moments_and_errors(cloud):
    """Sample mean and covariance with their standard errors.

    SE of a mean √(Σii/n); of a covariance entry √((ΣiiΣjj + Σij²)/n) (Gaussian data).
    """
    n = cloud.shape[0]
    m, S = cloud.mean(axis=0), np.cov(cloud.T)
    d = np.diag(S)
    return m, S, np.sqrt(d / n), np.sqrt((np.outer(d, d) + S**2) / n)


def test_one_step_matches_monte_carlo_to_second_order():
    """One arc step from an uncertain start (σθ = 0.05 rad) with wheel noise.

    C's mean carries the second-order shift E[cos φ] ≈ 1 − σ²/2 that A's misses: A's
    x is off by about 18 standard errors at n = 10⁵, C's within 4. C's own errors are
    fourth order (≈ 0.1 standard error in the mean, ≤ 2.3 in σx² at this n, measured
    over seeds), so 4 standard errors bound each of the 9 comparisons (P ≈ 6·10⁻⁵ each).
    """
    step = tr.Trajectory(ds_r=np.array([1.05]), ds_l=np.array([0.95]), dt=1.0, track=0.2)
    S0, k = _cov0(), 1e-4
    cloud = sp.sample_end_poses(step, k, k, 100_000, np.random.default_rng(7), cov0=S0)
    m, S, se_m, se_S = _moments_and_errors(cloud)
    C, A = ut.propagate(step, k, k, cov0=S0), cv.propagate(step, k, k, cov0=S0)
    assert np.all(np.abs(C.poses[-1] - m) <= 4 * se_m)
    assert np.all(np.abs(C.covs[-1] - S) <= 4 * se_S)
    assert np.abs(A.poses[-1, 0] - m[0]) > 10 * se_m[0]  # the test can tell C from A


@pytest.mark.slow
def test_long_arc_mean_shifts_inward_like_monte_carlo():
    """Half circle: heading noise pulls the mean end point towards the centre (and back).

    A's mean is the noiseless midpoint path whatever k; Monte Carlo's and C's move by
    the same vector to within 4 standard errors of the Monte Carlo mean.
    """
    k = 1e-4
    A, C = cv.propagate(ARC, k, k), ut.propagate(ARC, k, k)
    assert_allclose(A.poses, cv.propagate(ARC, 0.0, 0.0).poses, atol=0)
    cloud = sp.sample_end_poses(ARC, k, k, 100_000, np.random.default_rng(11))
    m, _, se_m, _ = _moments_and_errors(cloud)
    inward = np.array([0.0, -1.0])  # the end (0, 2) looks at the centre (0, 1) along −y
    shift_mc, shift_c = m[:2] - A.poses[-1, :2], C.poses[-1, :2] - A.poses[-1, :2]
    assert shift_mc @ inward > 10 * se_m[1]
    assert shift_c @ inward > 0
    assert np.all(np.abs(shift_c - shift_mc) <= 4 * se_m[:2])


def test_large_heading_uncertainty_stays_positive_semidefinite():
    step = tr.Trajectory(ds_r=np.array([1.0]), ds_l=np.array([1.0]), dt=1.0, track=0.2)
    for sth in (0.5, 1.0, 1.3):
        C = ut.propagate(step, 1e-6, 1e-6, cov0=np.diag([1e-8, 1e-8, sth**2]))
        w = np.linalg.eigvalsh(C.covs[-1])
        assert w.min() >= -1e-15 * w.max()


# --- UT on SE(2) ---------------------------------------------------------------------------


@pytest.mark.parametrize("perturbation", ut.PERTURBATIONS)
def test_se2_equals_expcoords_in_the_small_noise_limit(perturbation):
    """Relative difference O(k) (module docstring): → 0 with k, and proportional to it."""
    rel = []
    for k in (1e-2, 1e-3):
        E = ec.propagate(ARC, k, k, cov0=k * np.eye(3))
        U = ut.propagate_se2(ARC, k, k, cov0=k * np.eye(3), perturbation=perturbation)
        assert_allclose(U.poses, E.poses, atol=1e-12)
        rel.append(np.abs(U.covs - E.covs).max() / np.abs(E.covs).max())
    assert rel[0] < 1e-7
    assert rel[0] / rel[1] == pytest.approx(10.0, rel=0.05)


def _one_step_reference(mu, S, ds_r, ds_l, k, b, perturbation):
    """The SE(2) UT of one step written out on the group (no shortcuts), body-frame result."""
    w = ut.sigma_weights(5)
    Ad = se2.adjoint(mu)
    S_place = Ad @ S @ Ad.T if perturbation == "left" else S
    L = np.zeros((5, 5))
    L[:3, :3] = np.linalg.cholesky(S_place)
    L[3, 3], L[4, 4] = np.sqrt(k * abs(ds_r)), np.sqrt(k * abs(ds_l))
    chi = ut.sigma_points(np.zeros(5), L, w.lam)
    g = se2.compose(se2.exp(chi[:, :3]), mu) if perturbation == "left" else se2.compose(mu, se2.exp(chi[:, :3]))
    r, l_ = ds_r + chi[:, 3], ds_l + chi[:, 4]
    g1 = se2.compose(g, se2.exp(np.stack([(r + l_) / 2, 0 * r, (r - l_) / b], -1)))
    mu1 = se2.compose(mu, se2.exp([(ds_r + ds_l) / 2, 0.0, (ds_r - ds_l) / b]))
    rel = se2.compose(g1, se2.inverse(mu1)) if perturbation == "left" else se2.compose(se2.inverse(mu1), g1)
    rel[:, 2] = wrap_angle(rel[:, 2])
    eps = se2.log(rel)
    Sig = (w.Wc[:, None] * eps).T @ eps
    if perturbation == "left":
        Ad1_inv = se2.adjoint(se2.inverse(mu1))
        Sig = Ad1_inv @ Sig @ Ad1_inv.T
    return Sig


@pytest.mark.parametrize("perturbation", ut.PERTURBATIONS)
def test_se2_step_equals_the_group_computation(perturbation):
    mu = np.array([1.5, -0.7, 2.0])
    S = _cov0(sx=0.1, sy=0.05, sth=0.3)
    step = tr.Trajectory(ds_r=np.array([0.6]), ds_l=np.array([0.3]), dt=1.0, track=0.25, start=mu)
    U = ut.propagate_se2(step, 2e-3, 2e-3, cov0=S, perturbation=perturbation)
    ref = _one_step_reference(mu, S, 0.6, 0.3, 2e-3, 0.25, perturbation)
    assert_allclose(U.covs[-1], ref, rtol=1e-10, atol=1e-15)
    assert_allclose(U.poses[-1], step.poses[-1], atol=1e-14)


# --- batching and input checks -----------------------------------------------------------------


def test_vectorised_equals_per_set_loop(rng):
    t = tr.from_segments([tr.Line(0.5), tr.Arc(0.4, 1.2), tr.Turn(-0.8)], dt=0.05, track=0.2)
    k_r = np.array([1e-4, 5e-4, 2e-3, 0.0])
    k_l = np.array([3e-4, 5e-4, 1e-4, 1e-3])
    track = np.array([0.15, 0.2, 0.3, 0.5])
    cov0 = np.stack([_cov0() * s for s in (0.0, 0.5, 1.0, 2.0)])
    for prop in (ut.propagate, ut.propagate_se2):
        batch = prop(t, k_r, k_l, track=track, cov0=cov0)
        assert batch.covs.shape == (4, t.n_steps + 1, 3, 3)
        for i in range(4):
            one = prop(t, k_r[i], k_l[i], track=track[i], cov0=cov0[i])
            assert_allclose(batch.poses[i], one.poses, rtol=0, atol=1e-12)
            assert_allclose(batch.covs[i], one.covs, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"k_r": -1e-4}, r"^k_r must be >= 0 \(allowed: \[0, inf\)\), got -0.0001$"),
        ({"k_l": float("nan")}, "^k_l must be finite"),
        ({"track": 0.0}, r"^track must be > 0"),
        ({"cov0": np.eye(2)}, r"^cov0 must have shape \(\.\.\., 3, 3\), got shape \(2, 2\)$"),
        ({"cov0": -np.eye(3)}, "^cov0 must be positive semi-definite"),
        ({"alpha": 0.0}, r"^alpha must be > 0"),
        ({"kappa": -5.0}, r"^kappa must make n \+ kappa > 0 \(allowed: kappa > -5\), got -5.0$"),
    ],
)
@pytest.mark.parametrize("prop", [ut.propagate, ut.propagate_se2])
def test_bad_input_one_line_errors(prop, kwargs, match):
    args = {"k_r": 1e-4, "k_l": 1e-4, **kwargs}
    with pytest.raises(ValueError, match=match) as info:
        prop(ARC, args.pop("k_r"), args.pop("k_l"), **args)
    assert "\n" not in str(info.value)


def test_bad_perturbation():
    with pytest.raises(ValueError, match=r"^perturbation must be one of 'right', 'left', got 'up'$"):
        ut.propagate_se2(ARC, 1e-4, 1e-4, perturbation="up")


def test_ut_step_equals_sigma_points_through_the_kinematic_step(rng):
    """ut_step builds its sigma points block by block: the same numbers as the augmented state's
    points (unscented.sigma_points of blockdiag(L_p, √var_r, √var_l)) through kinematics.step."""
    from pose_uncertainty.core.kinematics import step

    w = ut.sigma_weights(5)
    for batch in [(), (4,)]:
        X = rng.normal(size=(*batch, 4, 3)) * [0.1, 0.2, 0.3]
        cov = np.swapaxes(X, -1, -2) @ X
        if not batch:
            cov[0] = cov[:, 0] = 0.0  # a singular Σ, as at the start of a path
        pose = rng.normal(size=(*batch, 3))
        sr, sl = 0.01 + 0.001 * rng.random(batch), 0.008 + 0.001 * rng.random(batch)
        kr, kl, b = 7e-4, 5e-4, np.full(batch, 0.2)
        z = np.concatenate([pose, np.stack([sr, sl], axis=-1)], axis=-1)
        L = np.zeros((*batch, 5, 5))
        L[..., :3, :3] = ut.psd_cholesky(cov)
        L[..., 3, 3], L[..., 4, 4] = np.sqrt(kr * np.abs(sr)), np.sqrt(kl * np.abs(sl))
        chi = ut.sigma_points(z, L, w.lam)
        r, l_ = chi[..., 3], chi[..., 4]
        moved = step(chi[..., :3], (r + l_) / 2.0, (r - l_) / b[..., None], method="midpoint")
        mean = moved[..., :2].swapaxes(-1, -2) @ w.Wm
        got_pose, got_cov = ut.ut_step(pose, cov, sr, sl, kr, kl, b, w)
        assert np.array_equal(got_pose[..., :2], mean)
        d = moved - got_pose[..., None, :]
        d[..., 2] = wrap_angle(d[..., 2])
        ref = np.swapaxes(d * w.Wc[:, None], -1, -2) @ d
        assert np.array_equal(got_cov, 0.5 * (ref + np.swapaxes(ref, -1, -2)))


@pytest.mark.parametrize(
    ("traj", "cov0"),
    [
        (tr.straight(2.5, speed=0.5, dt=0.01, track=0.2), None),
        (tr.circle(0.5, speed=0.5, dt=0.01, track=0.2), np.diag([1e-4, 2e-4, 1e-3])),
        (tr.rotation(6.0, angular_speed=1.0, dt=0.01, track=0.2), None),  # headings round the circle
        (tr.s_curve(0.5, speed=0.5, dt=0.02, track=0.2), np.zeros((3, 3))),
    ],
)
def test_compiled_loop_equals_the_numpy_loop_up_to_rounding(traj, cov0):
    """The compiled Method C (one set) against the batched numpy reference: the same arithmetic
    in another order, equal within a relative 1e-12 of the covariance's scale at every step."""
    ref = ut.propagate(traj, 3e-4, 5e-4, cov0=cov0)
    got = ut.propagate(traj, 3e-4, 5e-4, cov0=cov0, kernel="compiled")
    assert got.covs.shape == ref.covs.shape
    assert got.poses.shape == ref.poses.shape
    scale = np.abs(ref.covs).max(axis=(-1, -2), keepdims=True) + 1e-300
    assert np.max(np.abs(got.covs - ref.covs) / scale) < 1e-12
    assert_allclose(got.poses, ref.poses, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got.covs, np.swapaxes(got.covs, -1, -2))
    with pytest.raises(ValueError, match="one set"):
        ut.propagate(traj, np.array([3e-4, 4e-4]), 5e-4, kernel="compiled")
    with pytest.raises(ValueError, match="kernel"):
        ut.propagate(traj, 3e-4, 5e-4, kernel="fast")
