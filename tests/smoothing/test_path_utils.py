"""Path utilities: validation, arc length, resampling, headings, curvature, roughness."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.smoothing import (
    PathError,
    check_path,
    cumulative_length,
    curvature,
    headings,
    path_length,
    remove_duplicates,
    resample,
    roughness,
)


def test_check_path_errors() -> None:
    with pytest.raises(PathError, match="at least 2"):
        check_path([[0.0, 0.0]])
    with pytest.raises(PathError, match="shape"):
        check_path(np.zeros((4, 3)))
    with pytest.raises(PathError, match="non-finite value at point 1"):
        check_path([[0.0, 0.0], [math.nan, 1.0], [2.0, 2.0]])
    with pytest.raises(PathError, match="numeric"):
        check_path([["a", "b"], ["c", "d"]])
    assert isinstance(PathError("x"), ValueError)


def test_lengths_hand_worked() -> None:
    p = [[0.0, 0.0], [3.0, 0.0], [3.0, 4.0]]
    np.testing.assert_allclose(cumulative_length(p), [0.0, 3.0, 7.0])
    assert path_length(p) == pytest.approx(7.0)


def test_resample_straight_line() -> None:
    out = resample([[0.0, 0.0], [1.0, 0.0]], 0.3)
    np.testing.assert_allclose(out, [[0, 0], [0.3, 0], [0.6, 0], [0.9, 0], [1.0, 0]], atol=1e-12)


def test_resample_corner_keeps_spacing_along_path() -> None:
    p = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 1.0]])  # includes a repeated point
    out = resample(p, 0.25)
    assert out.shape == (9, 2)
    np.testing.assert_allclose(out[4], [1.0, 0.0])
    np.testing.assert_allclose(out[-1], [1.0, 1.0])
    np.testing.assert_allclose(np.diff(cumulative_length(out)), 0.25)
    with pytest.raises(ValueError, match="spacing_m"):
        resample(p, 0.0)
    with pytest.raises(PathError, match="zero length"):
        resample([[1.0, 1.0], [1.0, 1.0]], 0.1)


def test_curvature_on_circles_both_directions() -> None:
    a = np.linspace(0.0, math.pi, 40)
    ccw = np.c_[2.0 * np.cos(a), 2.0 * np.sin(a)]
    np.testing.assert_allclose(curvature(ccw), 0.5, rtol=1e-12)
    np.testing.assert_allclose(curvature(ccw[::-1] * [1, -1]), 0.5, rtol=1e-12)
    np.testing.assert_allclose(curvature(ccw[::-1]), -0.5, rtol=1e-12)
    assert np.all(curvature([[0, 0], [1, 0], [2, 0]]) == 0.0)
    assert np.all(curvature([[0, 0], [1, 0]]) == 0.0)


def test_headings_hand_worked() -> None:
    h = headings([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    np.testing.assert_allclose(h, [0.0, math.pi / 4, math.pi / 2])


def test_roughness_hand_worked() -> None:
    assert roughness([[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]]) == pytest.approx(1.0)
    assert roughness(np.c_[np.arange(10.0), 2 * np.arange(10.0)]) == pytest.approx(0.0)


def test_remove_duplicates() -> None:
    p = [[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [1.0, 1e-12], [2.0, 0.0], [2.0, 0.0]]
    np.testing.assert_array_equal(remove_duplicates(p), [[0, 0], [1, 0], [2, 0]])
    assert remove_duplicates([[1.0, 1.0], [1.0, 1.0]]).shape == (1, 2)
