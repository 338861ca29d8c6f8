"""Sobol indices of a factorial sweep (analysis.sensitivity) against functions with known indices."""

from __future__ import annotations

import numpy as np
import pytest

from pose_uncertainty.analysis.sensitivity import (
    grid_array,
    partial_dependence,
    sobol_indices,
    surface,
)


def _ishigami_exact(a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """The Ishigami function's indices for X_i uniform on [-π, π] (Saltelli et al. 2008, §4.8)."""
    pi = np.pi
    v1 = 0.5 * (1 + b * pi**4 / 5) ** 2
    v2 = a**2 / 8
    v13 = b**2 * pi**8 * (1 / 18 - 1 / 50)
    v = v1 + v2 + v13
    return np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v


def _ishigami_grid(n: int, a: float = 7.0, b: float = 0.1) -> np.ndarray:
    x = -np.pi + (np.arange(n) + 0.5) * 2 * np.pi / n  # cell midpoints: each level equally likely
    x1, x2, x3 = np.meshgrid(x, x, x, indexing="ij")
    return np.sin(x1) + a * np.sin(x2) ** 2 + b * x3**4 * np.sin(x1)


def test_ishigami_indices_converge_to_the_known_ones_at_the_midpoint_rules_rate() -> None:
    exact_first, exact_total = _ishigami_exact(7.0, 0.1)
    errors = []
    for n in (32, 64, 128):
        first, total = sobol_indices(_ishigami_grid(n))
        errors.append(np.max(np.abs(np.concatenate([first - exact_first, total - exact_total]))))
        # on a grid the only error is the midpoint rule's, O(h²) with h = 2π/n: measured 2.4e-3 at n = 32
        # (the x3⁴ and x3⁸ moments); 4e-3·(32/n)² bounds it with a margin of 1.7
        assert errors[-1] < 4e-3 * (32 / n) ** 2, (n, first, total)
        assert first[2] == pytest.approx(0.0, abs=1e-12)  # X3 acts only with X1: no first-order share
    # second order: halving h quarters the error (ratio 4 within 10 %)
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.1)


def test_a_bilinear_function_has_its_exact_indices_on_any_grid() -> None:
    # Y = a X1 + b X2 + c X1 X2 + 0·X3, levels centred: V1 = a² v1, V2 = b² v2, V12 = c² v1 v2 exactly
    l1, l2, l3 = np.array([-2.0, -0.5, 0.5, 2.0]), np.array([-1.0, 0.0, 1.0]), np.array([3.0, 7.0])
    a, b, c = 1.5, -2.0, 0.8
    x1, x2, _ = np.meshgrid(l1, l2, l3, indexing="ij")
    y = a * x1 + b * x2 + c * x1 * x2
    v1, v2 = l1.var(), l2.var()
    v = a**2 * v1 + b**2 * v2 + c**2 * v1 * v2
    first, total = sobol_indices(y)
    np.testing.assert_allclose(first, [a**2 * v1 / v, b**2 * v2 / v, 0.0], atol=1e-12)
    np.testing.assert_allclose(total, [(a**2 + c**2 * v2) * v1 / v, (b**2 + c**2 * v1) * v2 / v, 0.0], atol=1e-12)
    # partial dependence: E[Y | X1] = a X1 (E X2 = 0); the surface over (X1, X2) is Y itself (X3 is inert)
    np.testing.assert_allclose(partial_dependence(y, 0), a * l1, atol=1e-12)
    np.testing.assert_allclose(surface(y, 0, 1), y[:, :, 0], atol=1e-12)
    np.testing.assert_allclose(surface(y, 1, 0), y[:, :, 0].T, atol=1e-12)


def test_grid_array_lays_out_shuffled_runs_and_refuses_a_design_that_is_not_full() -> None:
    rng = np.random.default_rng(3)
    shape = (3, 4, 2)
    grid = rng.normal(size=shape)
    codes = np.array(np.unravel_index(np.arange(grid.size), shape)).T
    order = rng.permutation(grid.size)
    np.testing.assert_array_equal(grid_array(grid.ravel()[order], codes[order], shape), grid)
    with pytest.raises(ValueError, match="full factorial of"):
        grid_array(grid.ravel()[:-1], codes[:-1], shape)
    twice = codes.copy()
    twice[0] = twice[1]
    with pytest.raises(ValueError, match="given twice"):
        grid_array(grid.ravel(), twice, shape)
    with pytest.raises(ValueError, match="finite"):
        grid_array(np.where(np.arange(grid.size) == 0, np.nan, grid.ravel()), codes, shape)


def test_a_constant_measure_has_no_indices() -> None:
    first, total = sobol_indices(np.ones((2, 3)))
    assert np.isnan(first).all()
    assert np.isnan(total).all()
