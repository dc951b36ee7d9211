"""Line rasterisation: hand-worked cases, structural properties and an exact brute-force supercover check."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from mjnav.mapping import InvalidParameterError, bresenham, diagonal_addition, supercover


def cells(a: np.ndarray) -> list[tuple[int, int]]:
    assert a.dtype == np.int64
    assert a.ndim == 2
    assert a.shape[1] == 2
    return [(int(r), int(c)) for r, c in a]


# ---------------------------------------------------------------------------------------------------------
# bresenham
# ---------------------------------------------------------------------------------------------------------


def test_bresenham_hand_worked_shallow_line_with_a_tie() -> None:
    # (0,0)→(1,2): column-major, offset at col 1 is 1·1/2 = ½, an exact tie → toward the start's row (0).
    assert cells(bresenham(0, 0, 1, 2)) == [(0, 0), (0, 1), (1, 2)]


def test_bresenham_reversal_gives_the_same_cells_reversed() -> None:
    assert cells(bresenham(1, 2, 0, 0)) == [(1, 2), (0, 1), (0, 0)]


def test_bresenham_hand_worked_negative_direction() -> None:
    # (0,0)→(3,−7): 7 column steps, rows round(i·3/7) counted from the canonical start (3, −7).
    assert cells(bresenham(0, 0, 3, -7)) == [
        (0, 0),
        (0, -1),
        (1, -2),
        (1, -3),
        (2, -4),
        (2, -5),
        (3, -6),
        (3, -7),
    ]


def test_bresenham_steep_line_is_row_major() -> None:
    # (0,0)→(5,2): columns round(i·2/5) for rows 0..5 = 0, 0.4, 0.8, 1.2, 1.6, 2 → 0, 0, 1, 1, 2, 2.
    assert cells(bresenham(0, 0, 5, 2)) == [(0, 0), (1, 0), (2, 1), (3, 1), (4, 2), (5, 2)]


def test_bresenham_degenerate_and_axis_aligned() -> None:
    assert cells(bresenham(4, -2, 4, -2)) == [(4, -2)]
    assert cells(bresenham(2, 5, 2, 1)) == [(2, 5), (2, 4), (2, 3), (2, 2), (2, 1)]
    assert cells(bresenham(0, 3, 3, 3)) == [(0, 3), (1, 3), (2, 3), (3, 3)]
    assert cells(bresenham(0, 0, -3, 3)) == [(0, 0), (-1, 1), (-2, 2), (-3, 3)]


def test_bresenham_properties_on_random_lines() -> None:
    rng = np.random.default_rng(1)
    for r0, c0, r1, c1 in rng.integers(-30, 30, size=(300, 4)).tolist():
        line = bresenham(r0, c0, r1, c1)
        assert len(line) == max(abs(r1 - r0), abs(c1 - c0)) + 1
        assert tuple(line[0]) == (r0, c0)
        assert tuple(line[-1]) == (r1, c1)
        steps = np.abs(np.diff(line, axis=0))
        assert np.all(steps.max(axis=1) == 1)  # 8-connected, always advancing
        np.testing.assert_array_equal(bresenham(r1, c1, r0, c0), line[::-1])
        # Every cell is the nearest to the ideal line along the minor axis (within ½ cell).
        dr, dc = r1 - r0, c1 - c0
        if abs(dc) >= abs(dr) and dc != 0:
            ideal = r0 + (line[:, 1] - c0) * dr / dc
            assert np.all(np.abs(line[:, 0] - ideal) <= 0.5 + 1e-12)
        elif dr != 0:
            ideal = c0 + (line[:, 0] - r0) * dc / dr
            assert np.all(np.abs(line[:, 1] - ideal) <= 0.5 + 1e-12)


def test_bresenham_accepts_numpy_integers_and_refuses_floats() -> None:
    assert cells(bresenham(np.int32(0), np.int64(0), np.int16(1), 2)) == [(0, 0), (0, 1), (1, 2)]
    with pytest.raises(InvalidParameterError):
        bresenham(0, 0, 1.5, 2)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        bresenham(0, 0, 1, "2")  # type: ignore[arg-type]
    with pytest.raises(InvalidParameterError):
        bresenham(0, 0, 10**30, 0)


# ---------------------------------------------------------------------------------------------------------
# diagonal addition
# ---------------------------------------------------------------------------------------------------------


def test_diagonal_addition_45_degrees_takes_the_major_axis_neighbour_at_corners() -> None:
    # The centre line passes exactly through every corner; columns are the major axis at 45°.
    assert cells(diagonal_addition(0, 0, 2, 2)) == [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2)]


def test_diagonal_addition_hand_worked_without_ties() -> None:
    # (0,0)→(2,5): Bresenham rows 0,0,1,1,2,2. Step col 1→2: the line row = 2·col/5 reaches row ½ at col 1.25,
    # before the column boundary 1.5 → it enters (1, 1). Step col 3→4: row 1½ at col 3.75, after the boundary
    # 3.5 → it enters (1, 4).
    assert cells(diagonal_addition(0, 0, 2, 5)) == [
        (0, 0),
        (0, 1),
        (1, 1),
        (1, 2),
        (1, 3),
        (1, 4),
        (2, 4),
        (2, 5),
    ]


def test_diagonal_addition_tie_inside_a_shallow_line() -> None:
    # (0,0)→(1,3): the line reaches row ½ exactly at col 1.5, a corner → major-axis neighbour (0, 2).
    assert cells(diagonal_addition(0, 0, 1, 3)) == [(0, 0), (0, 1), (0, 2), (1, 2), (1, 3)]


def test_diagonal_addition_properties_on_random_lines() -> None:
    rng = np.random.default_rng(2)
    for r0, c0, r1, c1 in rng.integers(-20, 20, size=(300, 4)).tolist():
        line = diagonal_addition(r0, c0, r1, c1)
        assert len(line) == abs(r1 - r0) + abs(c1 - c0) + 1
        assert tuple(line[0]) == (r0, c0)
        assert tuple(line[-1]) == (r1, c1)
        assert np.all(np.abs(np.diff(line, axis=0)).sum(axis=1) == 1)  # 4-connected
        got = set(cells(line))
        assert len(got) == len(line)
        assert set(cells(bresenham(r0, c0, r1, c1))) <= got
        assert got <= set(cells(supercover(r0 + 0.5, c0 + 0.5, r1 + 0.5, c1 + 0.5)))


# ---------------------------------------------------------------------------------------------------------
# supercover
# ---------------------------------------------------------------------------------------------------------


def test_supercover_diagonal_through_corners_includes_all_touching_cells() -> None:
    # Centre of (0,0) to centre of (2,2): passes the corners (1,1) and (2,2) → both side cells each time.
    assert sorted(cells(supercover(0.5, 0.5, 2.5, 2.5))) == [
        (0, 0),
        (0, 1),
        (1, 0),
        (1, 1),
        (1, 2),
        (2, 1),
        (2, 2),
    ]


def test_supercover_general_segment_hand_worked() -> None:
    # (row, col) (0.2, 0.3) → (2.7, 1.1): at col = 1 the row is 0.2 + 0.7·2.5/0.8 = 2.3875, so column 0 spans
    # rows 0..2 and column 1 only row 2.
    assert cells(supercover(0.2, 0.3, 2.7, 1.1)) == [(0, 0), (1, 0), (2, 0), (2, 1)]


def test_supercover_shallow_segment_through_one_corner() -> None:
    # (0.5, 0.5) → (1.5, 3.5): row = 0.5 + (col − 0.5)/3 is exactly 1 at col 2 → (0,1),(0,2),(1,1),(1,2) all
    # touch.
    assert cells(supercover(0.5, 0.5, 1.5, 3.5)) == [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (1, 3)]


def test_supercover_along_a_grid_line_touches_both_sides() -> None:
    assert sorted(cells(supercover(1.0, 0.5, 1.0, 2.5))) == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)]


def test_supercover_points() -> None:
    assert cells(supercover(0.5, 0.5, 0.5, 0.5)) == [(0, 0)]
    assert sorted(cells(supercover(1.0, 1.0, 1.0, 1.0))) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert cells(supercover(-0.5, -1.5, -0.5, -1.5)) == [(-1, -2)]


def test_supercover_order_follows_the_segment() -> None:
    fwd = cells(supercover(0.2, 0.3, 2.7, 1.1))
    back = cells(supercover(2.7, 1.1, 0.2, 0.3))
    assert back == fwd[::-1]


def _touches(r: int, c: int, p0: tuple[Fraction, Fraction], p1: tuple[Fraction, Fraction]) -> bool:
    """Exact test: does the closed square [r, r+1]×[c, c+1] meet the segment p0–p1 (points as (row, col))?"""
    (y0, x0), (y1, x1) = p0, p1
    if max(x0, x1) < c or min(x0, x1) > c + 1 or max(y0, y1) < r or min(y0, y1) > r + 1:
        return False
    sides = [(x1 - x0) * (yy - y0) - (y1 - y0) * (xx - x0) for yy in (r, r + 1) for xx in (c, c + 1)]
    return not (all(s > 0 for s in sides) or all(s < 0 for s in sides))


def test_supercover_matches_exact_brute_force_on_quarter_cell_endpoints() -> None:
    # Endpoints on a ¼-cell lattice make corner crossings and grid-line runs frequent and keep float64 exact.
    rng = np.random.default_rng(3)
    for q in rng.integers(-8, 28, size=(250, 4)).tolist():
        r0, c0, r1, c1 = (v / 4 for v in q)
        got = cells(supercover(r0, c0, r1, c1))
        assert len(set(got)) == len(got)
        p0 = (Fraction(q[0], 4), Fraction(q[1], 4))
        p1 = (Fraction(q[2], 4), Fraction(q[3], 4))
        expected = {
            (r, c)
            for r in range(int(np.floor(min(r0, r1))) - 1, int(np.floor(max(r0, r1))) + 2)
            for c in range(int(np.floor(min(c0, c1))) - 1, int(np.floor(max(c0, c1))) + 2)
            if _touches(r, c, p0, p1)
        }
        assert set(got) == expected, (r0, c0, r1, c1)


def test_supercover_rejects_non_finite_endpoints() -> None:
    with pytest.raises(InvalidParameterError):
        supercover(0.0, 0.0, float("nan"), 1.0)
    with pytest.raises(InvalidParameterError):
        supercover(0.0, float("inf"), 1.0, 1.0)
    with pytest.raises(InvalidParameterError):
        supercover(0.0, 0.0, 1e300, 0.0)
    with pytest.raises(InvalidParameterError):
        supercover("a", 0.0, 1.0, 1.0)  # type: ignore[arg-type]
