"""Shared fixtures: seeded generators only (no global RNG); the Chromium of the browser tests."""

import os

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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that needs the quick pipeline ``slow`` (``make test`` runs them all;
    ``pytest -m "not slow"`` is the subset to run while working)."""
    for item in items:
        if PIPELINE_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
