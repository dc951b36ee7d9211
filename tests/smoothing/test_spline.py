"""CasADi piecewise-cubic splines: interpolation, continuity at every knot, arc length."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from mjnav.smoothing import PathError, PiecewiseCubic, fit_spline


def line_then_arc(radius: float = 2.0, step: float = 0.25) -> tuple[np.ndarray, int]:
    """5 m straight along +x, then a left quarter circle; returns (points, index of the junction knot)."""
    s = np.arange(0.0, 5.0, step)
    line = np.c_[s, np.zeros_like(s)]
    ang = np.arange(0.0, math.pi / 2 + 1e-9, step / radius)
    arc = np.c_[5.0 + radius * np.sin(ang), radius - radius * np.cos(ang)]
    return np.r_[line, arc], line.shape[0]


def sine_points() -> np.ndarray:
    t = np.linspace(0.0, 12.0, 25)
    return np.c_[t, 2.0 * np.sin(t / 2.0)]


@pytest.mark.parametrize("continuity", [0, 1, 2])
def test_passes_through_the_points(continuity: int) -> None:
    pts = sine_points()
    sp = fit_spline(pts, continuity)
    np.testing.assert_allclose(sp.evaluate(sp.knots), pts, atol=1e-9)
    assert np.abs(sp.knot_jumps(0)).max() < 1e-9


@pytest.mark.parametrize("continuity", [0, 1, 2])
def test_collinear_points_give_the_line(continuity: int) -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.5], [3.0, 1.5], [4.0, 2.0], [7.0, 3.5]])  # uneven spacing
    sp = fit_spline(pts, continuity)
    t = np.linspace(0.0, sp.parameter_length, 57)
    xy = sp.evaluate(t)
    np.testing.assert_allclose(xy[:, 1], 0.5 * xy[:, 0], atol=1e-9)
    np.testing.assert_allclose(np.abs(sp.evaluate(t, 2)), 0.0, atol=1e-9)


def test_c0_is_the_polyline() -> None:
    pts = sine_points()
    sp = fit_spline(pts, 0)
    mid = 0.5 * (sp.knots[:-1] + sp.knots[1:])
    np.testing.assert_allclose(sp.evaluate(mid), 0.5 * (pts[:-1] + pts[1:]), atol=1e-9)
    assert np.abs(sp.knot_jumps(1)).max() > 0.05  # kinks at the knots


def test_c2_has_no_jumps_in_first_and_second_derivative() -> None:
    sp = fit_spline(sine_points(), 2)
    assert np.abs(sp.knot_jumps(1)).max() < 1e-8
    assert np.abs(sp.knot_jumps(2)).max() < 1e-8
    # the same, numerically: one-sided evaluations just left and right of every interior knot
    eps = 1e-7
    inner = sp.knots[1:-1]
    for order in (1, 2):
        jump = sp.evaluate(inner + eps, order) - sp.evaluate(inner - eps, order)
        assert np.abs(jump).max() < 1e-5


def test_c1_keeps_the_curvature_jump_of_a_line_arc_path() -> None:
    pts, junction = line_then_arc(radius=2.0)
    c1 = fit_spline(pts, 1)
    c2 = fit_spline(pts, 2)
    j1 = np.linalg.norm(c1.knot_jumps(2), axis=1)
    j2 = np.linalg.norm(c2.knot_jumps(2), axis=1)
    assert np.abs(c1.knot_jumps(1)).max() < 1e-8  # still C1
    assert j1[junction - 1] == pytest.approx(0.5, rel=0.1)  # |s''| jumps from 0 to 1/R at the junction
    assert int(np.argmax(j1)) == junction - 1
    assert j2.max() < 1e-8
    # numerically at the junction knot
    tj = c1.knots[junction]
    assert np.linalg.norm(c1.evaluate(tj + 1e-7, 2) - c1.evaluate(tj - 1e-7, 2)) > 0.4


def test_c2_minimises_roughness_among_c2_interpolants() -> None:
    # scipy's natural cubic spline on the same knots is another C2 interpolant: ours must not be rougher
    pts = sine_points()
    sp = fit_spline(pts, 2, w_bend=0.01)
    ref = CubicSpline(sp.knots, pts, bc_type="natural")
    h = np.diff(sp.knots)
    hbar = h.mean()

    def rough(third: np.ndarray, second_left: np.ndarray, second_right: np.ndarray) -> float:
        jerk = np.sum(third**2, axis=1) * h
        bend = np.sum((second_left**2 + second_left * second_right + second_right**2) / 3.0, axis=1) * h
        return float(np.sum(hbar**5 * jerk + 0.01 * hbar**3 * bend))

    inner_left = sp.knots[:-1]
    second_right = sp.evaluate(inner_left, 2) + sp.evaluate(inner_left, 3) * h[:, None]
    ours = rough(sp.evaluate(inner_left, 3), sp.evaluate(inner_left, 2), second_right)
    theirs = rough(ref(inner_left, 3), ref(inner_left, 2), ref(sp.knots[1:], 2))
    assert ours <= theirs + 1e-12
    assert ours < 0.99 * theirs


def test_arc_length_on_a_circle() -> None:
    a = np.linspace(0.0, math.pi, 33)
    sp = fit_spline(np.c_[3.0 * np.cos(a), 3.0 * np.sin(a)], 2)
    assert sp.arc_length == pytest.approx(3.0 * math.pi, rel=1e-4)
    s = np.linspace(0.0, sp.arc_length, 21)
    tangent = sp.at_arc_length(s, 1)
    np.testing.assert_allclose(np.linalg.norm(tangent, axis=1), 1.0, atol=1e-12)
    kappa_vec = sp.at_arc_length(s[3:-3], 2)
    np.testing.assert_allclose(np.linalg.norm(kappa_vec, axis=1), 1.0 / 3.0, rtol=5e-3)
    np.testing.assert_allclose(sp.curvature(sp.parameter_at_arc_length(s[3:-3])), 1.0 / 3.0, rtol=5e-3)
    # points at equal arc-length steps: chords of π·3/20 on a radius-3 circle
    pos = sp.at_arc_length(s)
    chord = 2 * 3.0 * math.sin(3.0 * math.pi / 20 / 6.0)
    np.testing.assert_allclose(np.linalg.norm(np.diff(pos, axis=0), axis=1), chord, rtol=2e-4)
    np.testing.assert_allclose(pos[[0, -1]], [[3.0, 0.0], [-3.0, 0.0]], atol=1e-9)


def test_sample_and_smoothing_mode() -> None:
    pts = sine_points()
    rng = np.random.default_rng(4)
    noisy = pts + rng.normal(0.0, 0.05, pts.shape)
    exact = fit_spline(noisy, 2)
    near = fit_spline(noisy, 2, smoothing=1.0)
    resid = np.linalg.norm(near.evaluate(near.knots) - noisy, axis=1)
    assert 0.0 < resid.max() < 0.3
    t = np.linspace(0.0, exact.parameter_length, 400)
    assert np.sum(near.evaluate(t, 2) ** 2) < 0.5 * np.sum(exact.evaluate(t, 2) ** 2)
    samples = near.sample(0.5)
    assert np.linalg.norm(np.diff(samples[:-1], axis=0), axis=1) == pytest.approx(0.5, rel=0.02)


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="continuity"):
        fit_spline(sine_points(), 3)
    with pytest.raises(PathError, match="coincide"):
        fit_spline([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [2.0, 0.0]], 2)
    with pytest.raises(PathError):
        fit_spline([[0.0, 0.0]], 2)
    sp = fit_spline([[0.0, 0.0], [1.0, 1.0]], 2)
    assert isinstance(sp, PiecewiseCubic)
    np.testing.assert_allclose(sp.evaluate(sp.parameter_length / 2), [0.5, 0.5])
    with pytest.raises(ValueError, match="parameter values"):
        sp.evaluate(5.0)
