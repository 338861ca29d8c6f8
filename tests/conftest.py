"""Shared fixtures: seeded generators only (no global RNG); the Chromium of the browser tests."""

import os
from pathlib import Path

import numpy as np
import pytest
from browser import CHROMIUM


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def chromium() -> str:
    """The Chromium binary of the browser tests (``tests/browser.py``); missing, a failure with instructions."""
    if not (os.path.isfile(CHROMIUM) and os.access(CHROMIUM, os.X_OK)):
        pytest.fail(
            f"Chromium not found at {CHROMIUM}: the browser tests need it. "
            "Install Debian's package: apt-get update && apt-get install -y chromium "
            "(or set POSE_UNCERTAINTY_CHROMIUM to a Chromium binary).",
            pytrace=False,
        )
    return CHROMIUM


#: fixtures that run the quick pipeline end to end (a minute or more): their tests are slow
PIPELINE_FIXTURES = {"quick", "quick_report"}
#: the modules whose tests read the quick pipeline's one build (``test_pipeline.quick_pipeline``, in the
#: session's base temporary folder, one per process of ``pytest -n``) and run Snakemake in it: on one
#: process, in turn
PIPELINE_MODULES = {"test_pipeline", "test_one_source", "test_rebuild_scope", "test_report_browser", "test_robot_pipeline",
                    "test_slurm"}
#: modules of a minute or more of work besides the quick pipeline's, handed out first after it (the longest
#: first, so that the two processes of ``pytest -n 2`` end together)
LONG_MODULES = ("test_faults", "test_docs", "test_robot_calibration", "test_lint", "test_notebook")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that needs the quick pipeline ``slow`` (``make test`` runs them all;
    ``pytest -m "not slow"`` is the subset to run while working).

    In a process of ``pytest -n`` the modules of the quick pipeline come first, then
    :data:`LONG_MODULES`: the order :func:`pytest_xdist_make_scheduler` hands them out in."""
    for item in items:
        if PIPELINE_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
    if hasattr(config, "workerinput"):
        def rank(item: pytest.Item) -> int:
            module = item.path.stem
            if module in PIPELINE_MODULES:
                return 0
            return 1 + LONG_MODULES.index(module) if module in LONG_MODULES else 1 + len(LONG_MODULES)

        items.sort(key=rank)


def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """With ``pytest -n N --dist loadscope`` (``make test``): each module's tests on one process, so that a
    module's fixtures are built once, and the modules of the quick pipeline together on one process
    (one build, one Snakemake at a time in its folder). (pytest-xdist's ``xdist_group`` marks do not
    group under pytest 9.2: the node-id suffix they rely on is lost.)"""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ModuleScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return "quick pipeline" if Path(module).stem in PIPELINE_MODULES else module

    return ModuleScheduling(config, log)
