"""The drives of Skalka 2011: limits that tie them together, inverses, Jacobians, paths, geometry errors."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from pose_uncertainty.core import drives as dr
from pose_uncertainty.core import kinematics as kin
from pose_uncertainty.core import se2
from pose_uncertainty.core import trajectories as tr

ALL_DRIVES = [
    dr.Differential(0.2),
    dr.SkidSteer(0.2, chi=1.5, x_icr=0.05),
    dr.Tricycle(0.3),
    dr.Ackermann(0.3, 0.2),
    dr.TwoAxleSteering(0.4),
    dr.SynchroDrive(),
    dr.MultiDof(),
    dr.Omni3(0.15),
]
IDS = [d.kind for d in ALL_DRIVES]


def _random_u(drive, rng, shape=(7,)):
    """Measurements with travels ~0.1 m and angles within ±60°."""
    u = rng.normal(scale=0.1, size=(*shape, drive.n_channels))
    angles = np.array([k == "angle" for k in drive.kinds])
    u[..., angles] = rng.uniform(-1.0, 1.0, size=(*shape, int(angles.sum())))
    return u


# --- the twist of each drive against an independent derivation ----------------------------


def test_tricycle_with_zero_steering_drives_straight(rng):
    tri = dr.Tricycle(0.3)
    dS = rng.uniform(0.0, 0.05, 100)
    u = np.stack([dS, np.zeros_like(dS)], axis=-1)
    for method in kin.METHODS:
        poses = tri.integrate(u, (0.0, 0.0, 0.0), method)
        assert_array_equal(poses[:, 1:], 0.0)
        assert_allclose(poses[-1, 0], dS.sum(), rtol=1e-14)


def _icr_of_tricycle(d, omega):
    """ICR as the intersection of the rear-axle line (x = 0) and the steering wheel's axle line."""
    # steering wheel at (d, 0), its axle along (−sin ω, cos ω): (d, 0) + t(−sin ω, cos ω) with x = 0
    t = d / math.sin(omega)
    return np.array([0.0, t * math.cos(omega)])


@pytest.mark.parametrize("omega", [0.3, -0.7, 1.2, math.pi / 2])
def test_tricycle_rear_axle_travel_and_turn(omega):
    # independent route: the steering wheel moves ΔS along a circle about the ICR, the body
    # turns by ΔS / |ICR − wheel| and the rear-axle centre travels |ICR| per radian
    d, dS = 0.3, 0.07
    icr = _icr_of_tricycle(d, omega)
    r_wheel = np.hypot(d - icr[0], icr[1])
    turn = math.copysign(dS / r_wheel, omega)
    xi = dr.Tricycle(d, max_steering=math.pi / 2).twist([dS, omega])
    assert_allclose(xi, [turn * icr[1], 0.0, turn], atol=1e-15)
    assert_allclose(xi, [dS * math.cos(omega), 0.0, dS * math.sin(omega) / d], atol=1e-15)


def test_two_axle_is_tricycle_with_half_wheelbase_and_rear_wheel_rolls(rng):
    L = 0.4
    two, tri = dr.TwoAxleSteering(L), dr.Tricycle(L / 2)
    u = _random_u(two, rng)
    xi = two.twist(u)
    assert_allclose(xi, tri.twist(u), rtol=1e-15)
    # independent check: the rear axle's middle at (−L/2, 0) has velocity v + Ω × r along its
    # wheel angle −ω with the front's speed |ΔS| (both axles run on one track)
    vx, vy = xi[:, 0], xi[:, 1] + xi[:, 2] * (-L / 2)
    assert_allclose(vx * np.sin(-u[:, 1]) - vy * np.cos(-u[:, 1]), 0.0, atol=1e-15)
    assert_allclose(np.hypot(vx, vy), np.abs(u[:, 0]), rtol=1e-14)


def test_ackermann_mid_axle_model_equals_the_bicycle_model(rng):
    ack = dr.Ackermann(0.3, 0.2)
    u = _random_u(ack, rng, (50,))
    assert_allclose(ack.twist(u), dr.Tricycle(0.3).twist(ack.mid_axle(u)), rtol=1e-14, atol=1e-16)
    # and the inverses agree: the mid-axle (ΔS, ω) of the Ackermann inverse is the bicycle's
    xi = dr.Tricycle(0.3).twist(_random_u(dr.Tricycle(0.3), rng, (50,)))
    assert_allclose(
        ack.mid_axle(ack.measurements(xi)), dr.Tricycle(0.3).measurements(xi), atol=1e-15
    )


def test_ackermann_condition_and_rolling_front_wheels(rng):
    d, b = 0.3, 0.2
    ack = dr.Ackermann(d, b)
    omega = rng.uniform(-1.0, 1.0, 40)
    om_l, om_r = ack.wheel_angles(omega)
    # thesis: cot ω_L + b/2d = cot ω = cot ω_R − b/2d (signed: ω > 0 left)
    assert_allclose(1 / np.tan(om_l) + b / (2 * d), 1 / np.tan(omega), rtol=1e-12)
    assert_allclose(1 / np.tan(om_r) - b / (2 * d), 1 / np.tan(omega), rtol=1e-12)
    # the inner wheel turns more than the outer one
    inner = np.where(omega > 0, om_l, om_r)
    outer = np.where(omega > 0, om_r, om_l)
    assert np.all(np.abs(inner) > np.abs(omega))
    assert np.all(np.abs(outer) < np.abs(omega))
    # independent route: rigid-body velocity v + Ω × r of each front wheel is along its angle
    # and as long as its measured travel
    dS = rng.uniform(0.01, 0.1, 40)
    xi = dr.Tricycle(d).twist(np.stack([dS, omega], -1))
    u = ack.measurements(xi)
    for side, ang, travel in ((1, om_l, u[:, 0]), (-1, om_r, u[:, 1])):
        vx, vy = xi[:, 0] - xi[:, 2] * side * b / 2, xi[:, 1] + xi[:, 2] * d
        assert_allclose(vx, travel * np.cos(ang), atol=1e-15)
        assert_allclose(vy, travel * np.sin(ang), atol=1e-15)


def test_omni_forward_and_inverse_are_inverses(rng):
    omni = dr.Omni3(0.15)
    u = rng.normal(size=(100, 3))
    assert_allclose(omni.measurements(omni.twist(u)), u, atol=1e-14)
    xi = rng.normal(size=(100, 3))
    assert_allclose(omni.twist(omni.measurements(xi)), xi, atol=1e-14)
    # the inverse as printed: s_x = (s_b − s_c)/√3, s_y = (s_b + s_c − 2 s_a)/3, ω = −Σs/(3R)
    sa, sb, sc = u.T
    assert_allclose(
        omni.twist(u),
        np.stack(
            [(sb - sc) / math.sqrt(3), (sb + sc - 2 * sa) / 3, -(sa + sb + sc) / (3 * 0.15)], -1
        ),
        rtol=1e-14,
    )
    # independent route: each wheel at angle α drives along the clockwise tangent (sin α, −cos α);
    # its contact point moves with v + Ω × r
    for j, alpha in enumerate(np.radians([0.0, 120.0, 240.0])):
        r = 0.15 * np.array([math.cos(alpha), math.sin(alpha)])
        vx, vy = xi[:, 0] - xi[:, 2] * r[1], xi[:, 1] + xi[:, 2] * r[0]
        assert_allclose(
            omni.measurements(xi)[:, j], vx * math.sin(alpha) - vy * math.cos(alpha), atol=1e-14
        )


def test_synchro_drive_never_changes_heading(rng):
    syn = dr.SynchroDrive()
    u = np.stack([rng.uniform(-1, 1, (20, 300)), rng.uniform(-math.pi, math.pi, (20, 300))], -1)
    for method in kin.METHODS:
        poses = syn.integrate(u, (1.0, 2.0, 0.7), method)
        assert_array_equal(poses[..., 2], 0.7)
    # it moves in the direction ψ relative to the chassis, sideways at ψ = 90°
    assert_allclose(syn.integrate([[1.0, math.pi / 2]])[-1], [0.0, 1.0, 0.0], atol=1e-16)


@pytest.mark.parametrize("drive", [dr.Omni3(0.15), dr.MultiDof(), dr.SynchroDrive()], ids=str)
def test_holonomic_drives_move_sideways(drive):
    xi = np.tile([0.0, 0.01, 0.0], (100, 1))
    path = drive.integrate(drive.measurements(xi), (0.0, 0.0, 0.0))
    assert_allclose(path[-1], [0.0, 1.0, 0.0], atol=1e-14)


@pytest.mark.parametrize(
    "drive", [d for d in ALL_DRIVES if d.kind not in ("omni3", "mdof", "synchro")], ids=str
)
def test_car_like_drives_refuse_sideways_motion(drive):
    with pytest.raises(ValueError, match=r"cannot move sideways|slides sideways") as e:
        drive.measurements([[0.0, 0.01, 0.0]])
    assert "\n" not in str(e.value)


def test_skid_steer_without_slip_is_the_differential_drive(rng):
    u = rng.normal(scale=0.1, size=(30, 2))
    assert_array_equal(dr.SkidSteer(0.2).twist(u), dr.Differential(0.2).twist(u))
    # Martínez et al.: ICRs of the tracks at ±χb/2 and x_ICR: v = Ω × (origin − ICR)
    sk = dr.SkidSteer(0.2, chi=1.4, x_icr=0.03)
    xi = sk.twist(u)
    w = (u[:, 0] - u[:, 1]) / (1.4 * 0.2)
    assert_allclose(xi[:, 2], w, rtol=1e-14)
    assert_allclose(xi[:, 1], -0.03 * w, rtol=1e-14)


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_inverse_kinematics_round_trip(drive, rng):
    u = _random_u(drive, rng, (40,))
    xi = drive.twist(u)
    assert_allclose(drive.twist(drive.measurements(xi)), xi, atol=1e-14)


# --- Jacobians ----------------------------------------------------------------------------


def _numeric_jacobian(f, x, h=1e-6):
    cols = [(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(x.shape[-1])]
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_twist_jacobian_equals_finite_differences(drive, rng):
    u = _random_u(drive, rng, (25,))
    J = drive.twist_jacobian(u)
    assert J.shape == (25, 3, drive.n_channels)
    # central differences: truncation ~h²·|f'''| ≈ 1e-12, rounding ~eps/h ≈ 1e-10
    assert_allclose(J, _numeric_jacobian(drive.twist, u), atol=1e-8)


def test_skid_steer_icr_jacobian_equals_finite_differences(rng):
    sk = dr.SkidSteer(0.2, chi=1.4, x_icr=0.03)
    u = rng.normal(scale=0.1, size=(10, 2))
    G = sk.icr_jacobian(u)
    num = _numeric_jacobian(
        lambda q: sk.twist_icr(u, q[..., 0], q[..., 1]), np.tile([1.4, 0.03], (10, 1))
    )
    assert_allclose(G, num, atol=1e-8)
    # slip does nothing on a straight
    assert_array_equal(sk.icr_jacobian([[0.1, 0.1]]), 0.0)


# --- kinematics of twists -------------------------------------------------------------------


@pytest.mark.parametrize("method", kin.METHODS)
def test_twist_integration_without_lateral_motion_is_todays(method, rng):
    ds, dth = rng.normal(size=(2, 3, 60)) * np.array([0.1, 0.5])[:, None, None]
    a = kin.integrate(ds, dth, (0.3, -0.2, 1.0), method)
    b = kin.integrate_twist(np.stack([ds, np.zeros_like(ds), dth], -1), (0.3, -0.2, 1.0), method)
    assert_array_equal(a, b)
    p = rng.normal(size=(3, 3))
    assert_array_equal(
        kin.step(p, ds[:, 0], dth[:, 0], method),
        kin.step_twist(p, np.stack([ds[:, 0], 0 * ds[:, 0], dth[:, 0]], -1), method),
    )


def test_exact_twist_step_is_the_se2_exponential(rng):
    # independent route: compose with exp(ξ) of the Lie-group machinery
    p = rng.normal(size=(50, 3))
    xi = rng.normal(size=(50, 3))
    xi[:5, 2] = 0.0  # the straight limit
    assert_allclose(kin.step_twist(p, xi, "exact"), se2.compose(p, se2.exp(xi)), atol=1e-14)


# --- paths --------------------------------------------------------------------------------

PATHS = {
    "straight": tr.straight(1.0, dt=0.02),
    "arc": tr.arc(1.0, math.pi / 2, dt=0.02),
    "s_curve": tr.s_curve(1.0, dt=0.02),
    "right_angles": tr.right_angles(dt=0.02),
    "direct": tr.direct(dt=0.02),
}
TURNS_IN_PLACE = {"right_angles", "direct"}
CANNOT_TURN_IN_PLACE = {"tricycle", "ackermann", "two_axle"}


@pytest.mark.parametrize("name", list(PATHS))
@pytest.mark.parametrize("drive", ALL_DRIVES, ids=IDS)
def test_every_drive_follows_every_path_it_can(drive, name):
    t = PATHS[name]
    if drive.kind == "skid_steer":
        drive = dr.SkidSteer(0.2, chi=1.5)  # x_icr ≠ 0 slides sideways in turns (own test)
    if name in TURNS_IN_PLACE and drive.kind in CANNOT_TURN_IN_PLACE:
        with pytest.raises(ValueError, match="needs steering angle 90° beyond max_steering") as e:
            dr.follow(drive, t)
        assert "\n" not in str(e.value)
        return
    p = dr.follow(drive, t)
    assert p.n_steps == t.n_steps
    assert_allclose(p.poses[:, :2], t.poses[:, :2], atol=1e-12)
    if drive.fixed_heading:
        assert_array_equal(p.poses[:, 2], t.start[2])
    else:
        assert_allclose(p.poses[:, 2], t.poses[:, 2], atol=1e-12)


def test_tricycle_with_right_angle_steering_rotates_in_place():
    t = tr.right_angles(dt=0.02)
    p = dr.follow(dr.Tricycle(0.3, max_steering=math.pi / 2), t)
    assert_allclose(p.poses[:, :2], t.poses[:, :2], atol=1e-12)


def test_skid_steer_with_icr_offset_cannot_follow_a_turn():
    with pytest.raises(ValueError, match="slides sideways") as e:
        dr.follow(dr.SkidSteer(0.2, x_icr=0.05), PATHS["arc"])
    assert "\n" not in str(e.value)
    dr.follow(dr.SkidSteer(0.2, x_icr=0.05), PATHS["straight"])  # a straight is fine


def test_drive_path_by_name_and_make_drive():
    p = dr.drive_path(dr.make_drive("omni3", radius=0.2), "s_curve", radius=0.5, dt=0.05)
    assert_allclose(p.poses[-1], [1.0, 1.0, 0.0], atol=1e-12)
    assert dr.make_drive("mdof", wheels=[[0.1, 0.0], [-0.1, 0.0]]).n_wheels == 2
    assert set(dr.DRIVES) == {d.kind for d in ALL_DRIVES}


# --- bad geometry: one-line errors --------------------------------------------------------


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (
            lambda: dr.Tricycle(wheelbase=0.0),
            r"wheelbase must be > 0 \(allowed: \(0, inf\)\), got 0.0",
        ),
        (lambda: dr.Ackermann(wheelbase=0.0), r"wheelbase must be > 0"),
        (lambda: dr.TwoAxleSteering(wheelbase=-1.0), r"wheelbase must be > 0"),
        (
            lambda: dr.Tricycle(max_steering=math.radians(91)),
            r"max_steering must be in \(0, π/2\] rad .*got 1.58",
        ),
        (lambda: dr.Ackermann(max_steering=-0.1), r"max_steering must be in \(0, π/2\]"),
        (
            lambda: dr.Ackermann(0.1, 0.5, max_steering=1.4),
            r"inner wheel beyond 90° \(allowed: tan\(max_steering\)",
        ),
        (lambda: dr.Omni3(radius=-0.1), r"radius must be > 0 \(allowed: \(0, inf\)\), got -0.1"),
        (lambda: dr.Differential(track=0.0), r"track must be > 0"),
        (lambda: dr.SkidSteer(chi=0.0), r"chi must be > 0"),
        (lambda: dr.MultiDof(wheels=((0.1, 0.1), (0.1, 0.1))), r"at least two distinct positions"),
        (lambda: dr.MultiDof(wheels=((0.1, 0.1),)), r"n >= 2 positions"),
        (lambda: dr.make_drive("hovercraft"), r"drive must be one of"),
        (
            lambda: dr.make_drive("omni3", wheelbase=0.3),
            r"drive 'omni3' has no geometry key 'wheelbase' \(allowed: radius\)",
        ),
        (
            lambda: dr.DrivePath(dr.Tricycle(), [[0.1, 0.2], [0.1, -1.2]], 0.01),
            r"cannot make step 1, it needs steering angle -68.75\d*° beyond max_steering=60°",
        ),
    ],
)
def test_bad_geometry_gives_a_one_line_error(make, match):
    with pytest.raises(ValueError, match=match) as e:
        make()
    assert "\n" not in str(e.value)


def test_a_drive_without_steering_limit_takes_any_angle():
    p = dr.DrivePath(dr.MultiDof(((0.1, 0.0), (-0.1, 0.0))), [[0.1, 0.1, 2.0, 2.0]], 0.01)
    assert_allclose(p.twists[0], [0.1 * math.cos(2.0), 0.1 * math.sin(2.0), 0.0], atol=1e-16)
