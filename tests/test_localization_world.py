"""Worlds: files, occupancy grids from segments and images, free-space sampling, one-line errors."""

import json
import math
import re

import matplotlib.image as mpimg
import numpy as np
import pytest
import yaml

from pose_uncertainty.localization import ekf, histogram, particle, sensors
from pose_uncertainty.localization import world as W
from pose_uncertainty.localization.motion import Motion
from pose_uncertainty.localization.result import Start

ROOM = {
    "name": "room",
    "landmarks": [{"id": 3, "x": 1.0, "y": 1.0}, {"id": 7, "x": 4.0, "y": 2.5}],
    "walls": {"segments": [[0, 0, 5, 0], [5, 0, 5, 3], [5, 3, 0, 3], [0, 3, 0, 0]], "resolution": 0.1},
}


def test_world_file_yaml_and_json_give_the_same_world(tmp_path):
    (tmp_path / "w.yaml").write_text(yaml.safe_dump(ROOM))
    (tmp_path / "w.json").write_text(json.dumps(ROOM))
    a, b = W.load_world(tmp_path / "w.yaml"), W.load_world(tmp_path / "w.json")
    assert a.name == "room"
    assert a.landmark_ids.tolist() == [3, 7]
    np.testing.assert_array_equal(a.landmarks, [[1, 1], [4, 2.5]])
    np.testing.assert_array_equal(a.grid.occupied, b.grid.occupied)
    assert a.bounds == a.grid.extent()


def test_walls_rasterise_to_the_expected_cells():
    g = W.grid_from_segments(W.rectangle_segments(0, 5, 0, 3), 0.1, thickness=0.02, margin=0.09)
    # cells whose centre lies within 0.01 + h√2/2 ≈ 0.081 of a wall: the centres at ±0.05 of
    # each wall line (the corner cells too, 0.0707 from the corner); those at ±0.15 are free
    assert g.origin.tolist() == pytest.approx([-0.1, -0.1])
    assert g.shape == (52, 32)
    x, y = g.x, g.y
    X, Y = np.meshgrid(x, y, indexing="ij")
    near = np.minimum.reduce([np.abs(X), np.abs(X - 5), np.abs(Y), np.abs(Y - 3)]) <= 0.081
    inside = (X > -0.1) & (X < 5.1) & (Y > -0.1) & (Y < 3.1)
    np.testing.assert_array_equal(g.occupied, near & inside)
    assert not g.free[g.occupied].any()


def _write_pgm(path, pix, binary=True):
    h, w = pix.shape
    if binary:
        path.write_bytes(f"P5\n# a comment\n{w} {h}\n255\n".encode() + pix.astype(np.uint8).tobytes())
    else:
        path.write_text(f"P2\n{w} {h}\n255\n" + " ".join(map(str, pix.ravel().tolist())) + "\n")


@pytest.mark.parametrize("kind", ["P5", "P2", "png"])
def test_image_rows_start_at_the_top_and_origin_is_the_lower_left_corner(tmp_path, kind):
    pix = np.full((4, 6), 254, dtype=np.uint8)  # white = free
    pix[0, 5] = 0  # top-right pixel black = occupied
    pix[3, 0] = 205  # bottom-left grey = unknown (occupancy 0.196..0.65)
    name = "map.png" if kind == "png" else "map.pgm"
    if kind == "png":
        mpimg.imsave(tmp_path / name, pix, cmap="gray", vmin=0, vmax=255)
    else:
        _write_pgm(tmp_path / name, pix, binary=kind == "P5")
    data = {"image": {"path": name, "resolution": 0.5, "origin": [-1.0, 2.0]}}
    g = W.world_from_dict(data, tmp_path).grid
    assert g.shape == (6, 4)
    assert g.occupied[5, 3]
    assert g.occupied.sum() == 1
    assert not g.free[0, 0]
    assert not g.occupied[0, 0]
    assert g.extent() == (-1.0, 2.0, 2.0, 4.0)
    assert g.is_occupied([[-1 + 5.5 * 0.5, 2 + 3.5 * 0.5]]).tolist() == [True]


def test_free_space_samples_are_uniform_over_free_cells():
    world = W.world_from_dict(ROOM)
    n = 40_000
    P = W.sample_free_poses(world, n, np.random.default_rng(2))
    g = world.grid
    i, j, inside = g.cell_of(P[:, :2])
    assert inside.all()
    assert g.free[i, j].all()
    # the free region is the rectangle [0.1, 4.9] × [0.1, 2.9]: mean (2.5, 1.5), sd 4.8/√12;
    # the sample mean is within 5 standard errors; headings uniform on [−π, π)
    assert abs(P[:, 0].mean() - 2.5) <= 5 * 4.8 / math.sqrt(12 * n)
    assert abs(P[:, 1].mean() - 1.5) <= 5 * 2.8 / math.sqrt(12 * n)
    assert P[:, 2].min() >= -math.pi
    assert P[:, 2].max() < math.pi


def _bad(**changes):
    d = json.loads(json.dumps(ROOM))
    for key, value in changes.items():
        node = d
        parts = key.split(".")
        for p in parts[:-1]:
            node = node[int(p)] if p.isdigit() else node[p]
        last = parts[-1]
        if value is KeyError:
            del node[int(last) if last.isdigit() else last]
        else:
            node[int(last) if last.isdigit() else last] = value
    return d


@pytest.mark.parametrize(
    ("data", "needles"),
    [
        (_bad(**{"walls.resolution": -0.1}), ["walls.resolution", "-0.1", "> 0"]),
        (_bad(**{"landmarks.1.x": "far"}), ["landmarks[1].x", '"far"', "type number"]),
        (_bad(**{"landmarks.0.id": KeyError}), ["landmarks[0].id", "missing"]),
        (_bad(**{"landmarks.1.id": 3}), ["landmarks.id", "3", "unique"]),
        (_bad(colour="red"), ["colour", "red", "only the keys"]),
        (_bad(**{"walls.segments.0": [0, 0, 5]}), ["walls.segments[0]", "4"]),
        (_bad(bounds=[0, -1, 0, 1]), ["bounds", "x_max > x_min"]),
        (_bad(image={"path": "m.pgm", "resolution": 0.1, "origin": [0, 0]}), ["walls", "image", "exclusive"]),
    ],
)
def test_bad_world_files_get_one_line_errors(data, needles):
    with pytest.raises(ValueError, match=re.escape(needles[0])) as err:
        W.world_from_dict(data)
    msg = str(err.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_unreadable_world_file_is_one_line(tmp_path):
    (tmp_path / "w.yaml").write_text("landmarks: [\n")
    with pytest.raises(ValueError, match=r"w\.yaml: not valid YAML \(.*line 2") as err:
        W.load_world(tmp_path / "w.yaml")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("make", "needles"),
    [
        (lambda: sensors.RangeBearingSensor(range_std=0.0), ["range_std", "0.0", "(0, inf)"]),
        (lambda: sensors.RangeBearingSensor(fov=7.0), ["fov", "7.0", "<= 2π"]),
        (lambda: sensors.RangeBearingSensor(period=-1), ["period", "-1", "> 0"]),
        (lambda: sensors.BeamSensor(z_hit=0.5), ["z_hit + z_short + z_max + z_rand", "0.7", "1"]),
        (lambda: sensors.BeamSensor(n_beams=0), ["n_beams", "0", ">= 1"]),
        (lambda: sensors.BeamSensor(lambda_short=-2), ["lambda_short", "-2", "> 0"]),
        (lambda: particle.ParticleFilterConfig(ess_threshold=1.5), ["ess_threshold", "1.5", "(0, 1)"]),
        (lambda: particle.ParticleFilterConfig(resampling="roulette"), ["resampling", "roulette", "multinomial"]),
        (lambda: particle.ParticleFilterConfig(injection_fraction=1.0), ["injection_fraction", "1.0", "[0, 1)"]),
        (lambda: particle.ParticleFilterConfig(alpha_slow=0.5, alpha_fast=0.1), ["alpha_slow", "0.5", "alpha_fast"]),
        (lambda: particle.ParticleFilterConfig(n_particles=0), ["n_particles", "0", ">= 1"]),
        (lambda: Motion(model="ackermann"), ["motion.model", "ackermann", "wheels"]),
        (lambda: Motion(model="velocity", alphas=(0.1,) * 4), ["alphas", "6", "(4,)"]),
        (lambda: Motion(k_r=-1e-3), ["k_r", "-0.001", ">= 0"]),
        (lambda: ekf.EKFConfig(motion=Motion(model="odometry")), ["ekf.motion.model", "odometry", "velocity"]),
        (lambda: histogram.HistogramFilterConfig(motion=Motion()), ["histogram.motion.model", "wheels"]),
        (lambda: histogram.HistogramFilterConfig(ntheta=0), ["ntheta", "0", ">= 1"]),
        (lambda: Start(scenario="lost"), ["scenario", "lost", "global"]),
    ],
)
def test_bad_sensor_parameters_and_filter_options_get_one_line_errors(make, needles):
    with pytest.raises(ValueError, match=re.escape(needles[0])) as err:
        make()
    msg = str(err.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, (needle, msg)
