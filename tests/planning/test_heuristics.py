"""Distance metrics: hand-worked values, broadcasting, and the kernel copy agreeing with the NumPy one."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.planning import METRICS, InvalidInput, chebyshev, euclidean, manhattan, octile
from mjnav.planning.heuristics import HEURISTIC_CODES, heuristic_code, heuristic_value


def test_hand_worked_values() -> None:
    a, b = (0, 0), (3, -5)  # |Δrow| = 3, |Δcol| = 5
    assert manhattan(a, b) == 8.0
    assert euclidean(a, b) == pytest.approx(math.sqrt(34.0))
    assert chebyshev(a, b) == 5.0
    assert octile(a, b) == pytest.approx(5.0 + (math.sqrt(2.0) - 1.0) * 3.0)  # 3 diagonals + 2 straight
    assert octile((2, 2), (2, 2)) == 0.0
    assert isinstance(octile(a, b), float)


def test_broadcasting_over_point_arrays() -> None:
    pts = np.array([[0, 0], [1, 1], [4, 0]])
    d = octile(pts, (0, 0))
    assert isinstance(d, np.ndarray)
    np.testing.assert_allclose(d, [0.0, math.sqrt(2.0), 4.0])
    np.testing.assert_allclose(manhattan(pts, pts[::-1]), [4.0, 0.0, 4.0])


def test_ordering_between_metrics() -> None:
    rng = np.random.default_rng(3)
    a = rng.integers(-50, 50, (200, 2))
    b = rng.integers(-50, 50, (200, 2))
    cheb, euc, octl, man = chebyshev(a, b), euclidean(a, b), octile(a, b), manhattan(a, b)
    assert np.all(cheb <= euc + 1e-12)
    assert np.all(euc <= octl + 1e-12)
    assert np.all(octl <= man + 1e-12)


def test_bad_point_shape_is_typed_error() -> None:
    with pytest.raises(InvalidInput):
        octile((1, 2, 3), (0, 0))
    with pytest.raises(InvalidInput, match="unknown heuristic"):
        heuristic_code("diagonal")


@pytest.mark.parametrize("name", sorted(HEURISTIC_CODES))
def test_kernel_heuristic_matches_numpy_metric(name: str) -> None:
    rng = np.random.default_rng(7)
    for dr, dc in rng.integers(0, 300, (50, 2)):
        expected = METRICS[name]((0, 0), (dr, dc))
        assert heuristic_value(HEURISTIC_CODES[name], float(dr), float(dc)) == pytest.approx(expected, rel=1e-15)
