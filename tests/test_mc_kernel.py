"""The compiled Monte Carlo kernel against numpy's, on the same draws, within the stated bounds.

Two routes to one cloud: the numpy kernel (the reference, ``kernel="numpy"``) and the compiled
loop (``kernel="compiled"``), both fed by the same seed and the same draw scheme, so the same
normals: numpy's draws of each chunk (``draws="per-chunk"``), or each block's own stream
(``draws="per-block"``: drawn inside the compiled loop, by numpy for the numpy kernel). They
may differ only by rounding: the polynomial ``cos``/``sin`` (within ``SIN_COS_ULPS`` ulp of the
true value, the C library's within 1) and the order of the sums over the steps. The
reproducibility contract's tolerance ``relative_tolerance(N)`` of the cloud's scale is the
bound, on long paths (10⁴ steps), full circles and heading perturbations of many turns.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.drives import follow, make_drive, wheel_path
from pose_uncertainty.methods import drive_sampling, mc_kernel
from pose_uncertainty.methods import sampling as sp
from pose_uncertainty.methods.drive_noise import DriveErrorModel
from pose_uncertainty.methods.wheel_noise import WheelErrorSources
from pose_uncertainty.records.reproducibility import relative_tolerance

METHODS = ("midpoint", "exact", "euler", "euler_end")
DRAWS = mc_kernel.DRAWS  # "per-chunk", "per-block"
B = mc_kernel.DRAW_BLOCK


def _assert_within_contract(a: np.ndarray, b: np.ndarray, n_steps: int) -> None:
    """Positions within rtol(N) of the cloud's extent in x and y together; headings of max(1, |θ|)."""
    rtol = relative_tolerance(n_steps)
    xy_scale = max(1.0, float(np.abs(a[:, :2]).max()))
    th_scale = max(1.0, float(np.abs(a[:, 2]).max()))
    assert np.abs(a[:, :2] - b[:, :2]).max() <= rtol * xy_scale
    assert np.abs(a[:, 2] - b[:, 2]).max() <= rtol * th_scale


def _both(
    traj: tr.Trajectory, k: float, n: int, seed: int, draws: str = "per-block", **kw: object
) -> tuple[np.ndarray, np.ndarray]:
    """The numpy kernel's and the compiled kernel's end poses from one seed and draw scheme."""
    ref = sp.sample_end_poses(traj, k, k, n, np.random.default_rng(seed), kernel="numpy", draws=draws, **kw)  # type: ignore[arg-type]
    fast = sp.sample_end_poses(traj, k, k, n, np.random.default_rng(seed), kernel="compiled", draws=draws, **kw)  # type: ignore[arg-type]
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


@pytest.mark.parametrize("draws", DRAWS)
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("regime", ["per_step", "per_run"])
def test_compiled_equals_numpy_on_the_same_draws(method, regime, draws):
    # 3001 particles: the last block of the per-block draws is not full
    traj = tr.s_curve(dt=0.02)
    ref, fast = _both(traj, 5e-4, 3001, 3, draws, method=method, regime=regime)
    _assert_within_contract(ref, fast, traj.n_steps)
    other = sp.sample_end_poses(traj, 5e-4, 5e-4, 3001, np.random.default_rng(4), kernel="numpy", draws=draws,
                                method=method, regime=regime)  # fmt: skip
    assert not np.array_equal(ref, other)


@pytest.mark.parametrize("draws", DRAWS)
def test_compiled_equals_numpy_with_a_start_covariance(draws):
    traj = tr.arc(radius=0.5, angle=1.0, dt=0.01, start=(0.3, -0.1, 0.4))
    ref, fast = _both(traj, 5e-4, 2000, 5, draws, cov0=np.diag([1e-4, 2e-4, 3e-4]))
    _assert_within_contract(ref, fast, traj.n_steps)


@pytest.mark.parametrize("draws", DRAWS)
@pytest.mark.parametrize("method", ["midpoint", "exact"])
def test_long_path_of_ten_thousand_steps(method, draws):
    # 10⁴ steps (10 laps of a 1 m circle at dt = 0.006 s): the rounding of 10⁴ polynomial
    # cos/sin stays inside rtol(10⁴) = 7·10⁻¹¹ of the cloud's scale
    traj = tr.circle(radius=1.0, laps=10.0, dt=0.006)
    assert traj.n_steps >= 10_000
    ref, fast = _both(traj, 5e-4, 200, 6, draws, method=method)
    _assert_within_contract(ref, fast, traj.n_steps)


@pytest.mark.parametrize("draws", DRAWS)
@pytest.mark.parametrize("laps", [1.0, 3.0])
def test_full_circles_with_heading_noise_of_many_turns(laps, draws):
    # k = 2 m on a 5 cm track: the heading perturbation wanders over several full turns
    # (its spread at the end is √(2kL)/b rad, checked below), so cos/sin see every quadrant
    traj = tr.circle(radius=0.5, laps=laps, dt=0.01, track=0.05)
    ref, fast = _both(traj, 2.0, 2000, 7, draws)
    nominal_end = traj.poses[-1, 2]
    assert np.std(ref[:, 2] - nominal_end) > 4 * math.pi
    _assert_within_contract(ref, fast, traj.n_steps)


@pytest.mark.parametrize("draws", DRAWS)
def test_heading_beyond_the_reduction_falls_back_to_the_c_library(draws):
    # a start heading spread of 10⁷ rad: the polynomial's reduction is not exact there, the
    # kernel recomputes such blocks with the C library's cos/sin
    traj = tr.straight(1.0, dt=0.05)
    cov0 = np.diag([1e-4, 1e-4, 1e14])
    ref, fast = _both(traj, 5e-4, 500, 8, draws, cov0=cov0)
    assert np.abs(ref[:, 2]).max() > mc_kernel.jit_module().REDUCTION_LIMIT
    _assert_within_contract(ref, fast, traj.n_steps)


def test_libm_trigonometry_is_a_third_route():
    traj = tr.s_curve(dt=0.02)
    z = np.random.default_rng(9).standard_normal((2, 400, traj.n_steps))
    nom = drive_sampling._nominal(wheel_path(traj), "midpoint")
    scale = (np.sqrt(5e-4 * np.abs(traj.ds_r)), np.sqrt(5e-4 * np.abs(traj.ds_l)))
    nominal = tuple(np.ascontiguousarray(a) for a in (nom.v1, nom.dtheta, nom.cos, nom.sin))
    args = ((z[0], z[1]), *scale, (1.0, 1.0), nominal, traj.start, traj.track, 0.5, False, None)
    poly = mc_kernel.compiled_end_poses(*args, trig="polynomial")
    libm = mc_kernel.compiled_end_poses(*args, trig="libm")
    _assert_within_contract(libm, poly, traj.n_steps)
    # the drawn blocks write into the caller's rows and draw their own start offsets
    drawn = mc_kernel.BlockDraws(mc_kernel.block_key(np.random.default_rng(9)), (0, 1), False)
    with pytest.raises(ValueError, match=r"^BlockDraws draw their own start offsets into a given out"):
        mc_kernel.compiled_end_poses(drawn, *args[1:])


@pytest.mark.parametrize("kernel", ["numpy", "compiled"])
@pytest.mark.parametrize("draws", DRAWS)
def test_kernels_are_thread_count_free(draws, kernel, monkeypatch):
    # the per-block draws are fixed by the blocks, not by the threads nor the chunks that share
    # them out: 1, 2 and 3 threads, and chunks of one block, give the same bits
    traj = tr.arc(radius=1.0, angle=1.0, dt=0.01)

    def run(workers: int) -> np.ndarray:
        return sp.sample_end_poses(traj, 5e-4, 5e-4, 5000, np.random.default_rng(7), workers=workers,
                                   kernel=kernel, draws=draws, cov0=np.diag([1e-4, 1e-4, 1e-4]))  # fmt: skip

    a = run(1)
    assert_array_equal(a, run(2))
    assert_array_equal(a, run(3))
    monkeypatch.setattr(drive_sampling, "_DRAWN_CHUNK_STEPS", 1)
    monkeypatch.setattr(drive_sampling, "CHUNK_ELEMENTS", 1)
    if draws == "per-block":
        assert_array_equal(a, run(2))
    assert not np.array_equal(a, sp.sample_end_poses(traj, 5e-4, 5e-4, 5000, np.random.default_rng(8),
                                                     kernel=kernel, draws=draws))  # fmt: skip


@pytest.mark.parametrize("cov0", [None, np.diag([1e-4, 1e-4, 1e-4])])
@pytest.mark.parametrize("n", [1, B - 1, B, B + 1, 3 * B + 5])
def test_per_block_draws_of_a_few_particles(n, cov0):
    # fewer particles than a block, exactly one, one more: every particle has its own numbers,
    # which depend on the seed and its index only (the first n of 3B + 5 particles are these n)
    traj = tr.s_curve(dt=0.05)
    ref, fast = _both(traj, 5e-4, n, 12, cov0=cov0)
    _assert_within_contract(ref, fast, traj.n_steps)
    assert np.unique(fast[:, 0]).size == n
    full = sp.sample_end_poses(traj, 5e-4, 5e-4, 3 * B + 5, np.random.default_rng(12), kernel="compiled",
                               draws="per-block", cov0=cov0)  # fmt: skip
    assert_array_equal(fast, full[:n])


def test_auto_uses_the_compiled_kernel_and_its_draws_from_the_threshold(monkeypatch):
    traj = tr.straight(1.0, dt=0.01)
    n = 1000
    ref = sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10), kernel="numpy", draws="per-chunk")
    fast = sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10), kernel="compiled", draws="per-block")
    monkeypatch.setattr(mc_kernel, "MIN_PARTICLE_STEPS", n * traj.n_steps + 1)
    assert_array_equal(sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10)), ref)
    monkeypatch.setattr(mc_kernel, "MIN_PARTICLE_STEPS", n * traj.n_steps)
    assert_array_equal(sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10)), fast)
    # an explicit kernel takes its own draws under "auto": numpy per chunk, compiled per block
    assert_array_equal(sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10), kernel="numpy"), ref)
    assert_array_equal(sp.sample_end_poses(traj, 5e-4, 5e-4, n, np.random.default_rng(10), kernel="compiled"), fast)


def test_bad_kernel_name(rng):
    with pytest.raises(ValueError, match=r"kernel must be one of 'auto', 'numpy', 'compiled', got 'fast'"):
        sp.sample_end_poses(tr.straight(1.0), 1e-4, 1e-4, 10, rng, kernel="fast")


def test_bad_draws_name_and_drives_without_per_block_draws(rng):
    with pytest.raises(ValueError, match=r"draws must be one of 'auto', 'per-chunk', 'per-block', got 'inline'"):
        sp.sample_end_poses(tr.straight(1.0), 1e-4, 1e-4, 10, rng, draws="inline")
    tricycle = follow(make_drive("tricycle"), tr.arc(radius=1.0, angle=0.5, dt=0.05))
    with pytest.raises(ValueError, match=r"draws 'per-block' applies to the differential drive with the travel noise k only.*Tricycle"):
        drive_sampling.sample_poses(tricycle, DriveErrorModel(k=1e-4), 10, rng, draws="per-block")
    encoder = DriveErrorModel(encoder=WheelErrorSources())
    with pytest.raises(ValueError, match=r"got a Differential drive with encoder or slip errors"):
        drive_sampling.sample_poses(wheel_path(tr.straight(1.0)), encoder, 10, rng, draws="per-block")
    # "auto" there: numpy's per-chunk draws, as before
    assert drive_sampling.sample_poses(tricycle, DriveErrorModel(k=1e-4), 10, rng).shape == (10, 3)


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


def test_particle_filter_run_moves_its_particles_by_the_compiled_loop_from_the_threshold(monkeypatch):
    # the whole filter: from MIN_PARTICLE_STEPS particle-steps its motion update is the compiled
    # loop on the filter's own draws (each block of particles from its generator), below it numpy's;
    # the particles and the estimate agree up to the rounding of the polynomial cos/sin
    from pose_uncertainty.localization import particle as PF
    from pose_uncertainty.localization import sensors as S
    from pose_uncertainty.localization import simulate as SIM
    from pose_uncertainty.localization.motion import Motion
    from pose_uncertainty.localization.result import Start
    from pose_uncertainty.localization.world import World

    world = World(np.array([[2.5, 1.5], [-1.0, 3.0], [3.0, -2.0]]), np.arange(3), bounds=(-0.5, 0.5, -0.5, 0.5))
    sensor = S.RangeBearingSensor(range_std=0.1, bearing_std=0.05, max_range=20, period=0.1)
    run = SIM.simulate(tr.arc(radius=1.0, angle=0.4, dt=0.1), world, np.random.default_rng(31), k_r=1e-3, k_l=1e-3,
                       landmark_sensor=sensor)  # fmt: skip
    cfg = PF.ParticleFilterConfig(n_particles=3000, motion=Motion(k_r=1e-3, k_l=2e-3), ess_threshold=1e-9)
    start = Start(pose=(0.0, 0.0, 0.0), std=(0.02, 0.02, 0.02))
    jit, calls = mc_kernel.jit_module(), []

    class Spy:  # counts the compiled motion updates
        def __getattr__(self, name: str) -> object:
            return getattr(jit, name)

        def wheel_step(self, *args: object) -> None:
            calls.append(1)
            jit.wheel_step(*args)

    monkeypatch.setattr(mc_kernel, "jit_module", Spy)

    def filtered(threshold: int) -> tuple[np.ndarray, np.ndarray]:
        monkeypatch.setattr(mc_kernel, "MIN_PARTICLE_STEPS", threshold)
        res = PF.run_particle(run, world, sensor, np.random.default_rng(7), cfg, start, keep=[run.n_steps])
        return res.snapshots[run.n_steps]["particles"], res.mean

    ref, ref_mean = filtered(cfg.n_particles * run.n_steps + 1)
    assert calls == []
    fast, fast_mean = filtered(cfg.n_particles * run.n_steps)
    assert len(calls) >= run.n_steps
    _assert_within_contract(ref, fast, run.n_steps)
    _assert_within_contract(ref_mean, fast_mean, run.n_steps)


# --- the per-block draws: numpy's streams, standard normal, the same clouds -------------------


def _numpy_block_stream(key: np.ndarray, block: int) -> np.random.Generator:
    # written out here rather than through mc_kernel.block_generator: numpy's own objects
    seq = np.random.SeedSequence([int(w) for w in key], spawn_key=(block,))
    return np.random.Generator(np.random.SFC64(seq))


@pytest.mark.parametrize("key_words", [None, (7, 0, 0, 0), (0, 0, 0, 0), (2**32 - 1,) * 4])
def test_block_streams_are_numpys_bit_for_bit(key_words):
    # the compiled stream of a block = numpy's Generator(SFC64(SeedSequence(key, spawn_key=(b,))))
    # .standard_normal, number for number: 10⁶ numbers of block 0 (≈ 1.2·10⁴ through the ziggurat's
    # wedges, ≈ 250 through its tail beyond r = 3.65) and the first numbers of far blocks
    key = mc_kernel.block_key(np.random.default_rng(21)) if key_words is None else np.array(key_words, np.uint64)
    jit = mc_kernel.jit_module()
    got = np.empty(1_000_000)
    jit.block_normals(key, 0, got)
    want = _numpy_block_stream(key, 0).standard_normal(got.size)
    assert_array_equal(got, want)
    assert np.sum(np.abs(want) > 3.6541528853610088) > 100  # the tail was exercised
    for block in (1, 2, 12345, 2**32 - 1):
        got = np.empty((3, 2, B))
        jit.block_normals(key, block, got)
        assert_array_equal(got, _numpy_block_stream(key, block).standard_normal(got.shape))


def test_block_key_comes_from_the_callers_seed_sequence():
    # a child of the caller's seed sequence: the same seed gives the same key, the caller's own
    # stream is not drawn from, and a second call (a second child) gives another key
    a, b = np.random.default_rng(5), np.random.default_rng(5)
    ka = mc_kernel.block_key(a)
    assert_array_equal(ka, mc_kernel.block_key(b))
    assert ka.shape == (4,)
    assert int(ka.max()) < 2**32
    assert not np.array_equal(ka, mc_kernel.block_key(a))
    assert_array_equal(a.standard_normal(4), np.random.default_rng(5).standard_normal(4))
    with pytest.raises(TypeError, match="rng must be seeded from a SeedSequence"):
        mc_kernel.block_key(np.random.Generator(np.random.RandomState(1)._bit_generator))  # legacy seeding


def test_per_block_normals_are_standard_normal():
    # 2.048·10⁶ numbers: 512 blocks of one key, 4000 each. Their mean, variance, skewness and
    # excess kurtosis within 5 standard errors of N(0, 1)'s (√(1/n), √(2/n), √(6/n), √(24/n));
    # the Kolmogorov–Smirnov distance below its 10⁻⁶ quantile √(ln(2/α)/2)/√n; neighbouring blocks
    # and neighbouring numbers uncorrelated (|r| ≤ 5/√pairs)
    from scipy.special import ndtr

    key = mc_kernel.block_key(np.random.default_rng(22))
    z = np.empty((512, 4000))
    for b in range(z.shape[0]):
        mc_kernel.jit_module().block_normals(key, b, z[b])
    x = z.ravel()
    n = x.size
    assert abs(x.mean()) <= 5 * math.sqrt(1 / n)
    assert abs(x.var() - 1.0) <= 5 * math.sqrt(2 / n)
    assert abs(np.mean(x**3)) <= 5 * math.sqrt(6 / n)
    assert abs(np.mean(x**4) - 3.0) <= 5 * math.sqrt(24 / n)
    s = np.sort(x)
    cdf = ndtr(s)
    ks = max(np.max(np.arange(1, n + 1) / n - cdf), np.max(cdf - np.arange(n) / n))
    assert ks <= math.sqrt(math.log(2 / 1e-6) / 2) / math.sqrt(n)
    across = np.mean(z[:-1] * z[1:])  # the same position in neighbouring blocks
    along = np.mean(z[:, :-1] * z[:, 1:])  # neighbouring numbers of one block
    assert abs(across) <= 5 / math.sqrt(z[:-1].size)
    assert abs(along) <= 5 / math.sqrt(z[:, :-1].size)


def _moment_tolerance(a: np.ndarray, z: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """z standard errors of a cloud's mean (3,) and of its covariance entries (3, 3), from its own
    second and fourth moments: Var(mean_j) = Σjj/n, Var(S_jk) ≈ (E[(d_j d_k)²] − Σjk²)/n."""
    n = a.shape[0]
    d = a - a.mean(axis=0)
    S = d.T @ d / n
    m4 = np.einsum("ni,nj->ij", d**2, d**2) / n
    return z * np.sqrt(np.diag(S) / n), z * np.sqrt(np.maximum(m4 - S**2, 0.0) / n)


@pytest.mark.slow
@pytest.mark.parametrize("regime", ["per_step", "per_run"])
def test_per_block_cloud_has_the_moments_of_numpys_draws(regime):
    # two independent samples of one distribution: the compiled kernel's per-block cloud and the
    # numpy kernel's per-chunk cloud (numpy's draws), 10⁵ particles each; their means and
    # covariances differ by less than 5 standard errors of the difference (√2 × one sample's)
    traj = tr.arc(radius=0.5, angle=2.0, dt=0.01)
    n = 100_000
    blocks = sp.sample_end_poses(traj, 5e-4, 3e-4, n, np.random.default_rng(31), kernel="compiled",
                                 draws="per-block", regime=regime)  # fmt: skip
    chunks = sp.sample_end_poses(traj, 5e-4, 3e-4, n, np.random.default_rng(32), kernel="numpy",
                                 draws="per-chunk", regime=regime)  # fmt: skip
    tol_mean, tol_cov = _moment_tolerance(chunks)
    assert np.all(np.abs(blocks.mean(axis=0) - chunks.mean(axis=0)) <= math.sqrt(2) * tol_mean)
    assert np.all(np.abs(np.cov(blocks.T) - np.cov(chunks.T)) <= math.sqrt(2) * tol_cov)


@pytest.mark.slow
def test_per_block_cloud_matches_method_a_and_the_closed_form_heading():
    # Method A's covariance (first order; small k keeps the linearisation error ~σθ² ≈ 10⁻⁴
    # relative, far below the sampling error) and, on a straight line, the exact heading variance
    # (k_r + k_l) L / b² of both regimes, from the compiled kernel with its own draws
    from pose_uncertainty.methods import covariance as cv

    n = 200_000
    traj = tr.arc(radius=0.5, angle=1.5, dt=0.01)
    res = cv.propagate(traj, 1e-6, 2e-6)
    end = sp.sample_end_poses(traj, 1e-6, 2e-6, n, np.random.default_rng(33), kernel="compiled", draws="per-block")
    S = res.covs[-1]
    d = np.diag(S)
    assert np.all(np.abs(np.cov(end.T) - S) <= 5 * np.sqrt((np.outer(d, d) + S**2) / n))
    assert np.all(np.abs(end.mean(axis=0) - res.poses[-1]) <= 5 * np.sqrt(d / n) + 1e-12)
    line = tr.straight(2.0, dt=0.02, track=0.2)
    expected = (5e-4 + 3e-4) * 2.0 / 0.2**2
    for regime in ("per_step", "per_run"):
        th = sp.sample_end_poses(line, 5e-4, 3e-4, n, np.random.default_rng(34), kernel="compiled",
                                 draws="per-block", regime=regime)[:, 2]  # fmt: skip
        assert abs(th.var(ddof=1) - expected) <= 5 * expected * math.sqrt(2 / (n - 1))


def test_per_block_draws_with_checkpoints_and_progress():
    # the numpy kernel takes the per-block numbers with checkpoints too (the compiled one keeps
    # to end poses): its end checkpoint is the end pose of the same draws
    traj = tr.s_curve(dt=0.02)
    seen: list[tuple[int, int]] = []
    cps = sp.sample_end_poses(traj, 5e-4, 5e-4, 500, np.random.default_rng(41), draws="per-block",
                              checkpoints=[0, traj.n_steps], progress=lambda d, n: seen.append((d, n)))  # fmt: skip
    end = sp.sample_end_poses(traj, 5e-4, 5e-4, 500, np.random.default_rng(41), kernel="compiled", draws="per-block")
    assert cps.shape == (500, 2, 3)
    _assert_within_contract(cps[:, 1], end, traj.n_steps)
    assert seen[-1] == (500, 500)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)
