"""The default thread count (core.threads.default_workers) follows OMP_NUM_THREADS, which Snakemake sets per job."""

import os

import numpy as np
import pytest

from pose_uncertainty.core import trajectories as tr
from pose_uncertainty.core.threads import MAX_DEFAULT_WORKERS, default_workers
from pose_uncertainty.methods import sampling

CORES = max(1, min(MAX_DEFAULT_WORKERS, os.cpu_count() or 1))


@pytest.mark.parametrize(
    ("value", "expected"),
    [("1", 1), ("3", 3), ("4,2", 4), (" 2 ", 2), ("100", MAX_DEFAULT_WORKERS), ("0", CORES), ("x", CORES), ("", CORES)],
)
def test_default_workers_reads_omp_num_threads(monkeypatch, value, expected):
    monkeypatch.setenv("OMP_NUM_THREADS", value)
    assert default_workers() == expected


def test_default_workers_without_the_variable_is_the_cores(monkeypatch):
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert default_workers() == CORES


def test_the_sampler_gives_the_same_particles_for_any_default(monkeypatch):
    t = tr.straight(1.0, dt=0.05)
    out = []
    for value in ("1", "3"):
        monkeypatch.setenv("OMP_NUM_THREADS", value)
        out.append(sampling.sample_end_poses(t, 4e-4, 4e-4, 50_000, np.random.default_rng(5)))
    assert np.array_equal(out[0], out[1])
