"""Shared fixtures: seeded generators only (no global RNG)."""

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


#: fixtures that run the quick pipeline end to end (a minute or more): their tests are slow
PIPELINE_FIXTURES = {"quick", "quick_report"}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test that needs the quick pipeline ``slow`` (``make test`` runs them all;
    ``pytest -m "not slow"`` is the subset to run while working)."""
    for item in items:
        if PIPELINE_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
