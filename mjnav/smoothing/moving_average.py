"""Simple (SMA) and weighted (WMA) centred moving averages of a path.

End points: both filters use a centred window that shrinks symmetrically near the ends. Point i averages
the points i - m_i .. i + m_i with m_i = min(m, i, N - 1 - i), so the first and last points are kept
exactly (m_i = 0), the window never runs off the path, and no point is pulled towards one side (a
one-sided or zero-padded window would shift the ends of a curved path). For the WMA the matching central
part of the weight vector is used and renormalised.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike, NDArray

from mjnav.smoothing.path import check_path


def _half_windows(n: int, m: int) -> NDArray[np.int64]:
    i = np.arange(n)
    return np.minimum(np.minimum(i, n - 1 - i), m)


def moving_average(path: ArrayLike, window: int) -> NDArray[np.float64]:
    """Simple moving average with a centred window of ``window = 2m + 1`` points.

    Interior point i becomes the mean of points i - m .. i + m. Near the ends the window shrinks
    symmetrically (see the module docstring), so the end points are unchanged.

    Args:
        path: (N, 2) positions, metres, N >= 2.
        window: odd window length 2m + 1 >= 1 (1 returns a copy).

    Returns:
        (N, 2) smoothed positions, metres.

    Raises:
        PathError: invalid path.
        ValueError: ``window`` not a positive odd integer.
    """
    p = check_path(path)
    if int(window) != window or window < 1 or window % 2 == 0:
        raise ValueError(f"window must be a positive odd integer (2m + 1), got {window}")
    m = (int(window) - 1) // 2
    n = p.shape[0]
    mi = _half_windows(n, m)
    csum = np.zeros((n + 1, 2))
    np.cumsum(p, axis=0, out=csum[1:])
    i = np.arange(n)
    total = csum[i + mi + 1] - csum[i - mi]
    out = total / (2 * mi + 1)[:, None]
    out[0], out[-1] = p[0], p[-1]  # exact, free of cumulative-sum round-off
    return out


def triangular_weights(window: int) -> NDArray[np.float64]:
    """Linearly decaying weights 1, 2, .., m + 1, .., 2, 1 for a centred WMA of ``window = 2m + 1`` points.

    Args:
        window: odd window length 2m + 1 >= 1.

    Returns:
        (window,) weights summing to 1.
    """
    if int(window) != window or window < 1 or window % 2 == 0:
        raise ValueError(f"window must be a positive odd integer (2m + 1), got {window}")
    m = (int(window) - 1) // 2
    w = (m + 1 - np.abs(np.arange(-m, m + 1))).astype(np.float64)
    return w / w.sum()


def weighted_moving_average(path: ArrayLike, weights: ArrayLike) -> NDArray[np.float64]:
    """Weighted moving average with a centred window of ``len(weights) = 2m + 1`` points.

    Interior point i becomes sum_j w_j p_{i+j} / sum_j w_j for j = -m .. m (``weights[0]`` multiplies
    p_{i-m}). Near the ends only the central weights w_{-m_i} .. w_{m_i} are used and renormalised (see the
    module docstring), so the end points are unchanged. Asymmetric weights are allowed but shift the path.

    Args:
        path: (N, 2) positions, metres, N >= 2.
        weights: (2m + 1,) non-negative finite weights with a positive centre weight; they need not sum
            to 1.

    Returns:
        (N, 2) smoothed positions, metres.

    Raises:
        PathError: invalid path.
        ValueError: weights of even length, negative, non-finite, or with a zero centre weight.
    """
    p = check_path(path)
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.shape[0] % 2 == 0:
        raise ValueError(f"weights must be a 1-D array of odd length 2m + 1, got shape {w.shape}")
    if not np.isfinite(w).all() or (w < 0.0).any():
        raise ValueError("weights must be finite and non-negative")
    m = (w.shape[0] - 1) // 2
    if w[m] <= 0.0:
        raise ValueError("the centre weight must be positive (it is the only weight used at the end points)")
    n = p.shape[0]
    mi = _half_windows(n, m)
    # (N, 2m+1) weight rows, zeroed outside each point's symmetric half-window, then normalised
    offsets = np.abs(np.arange(-m, m + 1))
    wmat = np.where(offsets[None, :] <= mi[:, None], w[None, :], 0.0)
    wmat /= wmat.sum(axis=1, keepdims=True)
    padded = np.zeros((n + 2 * m, 2))
    padded[m : m + n] = p
    windows = sliding_window_view(padded, 2 * m + 1, axis=0)  # (N, 2, 2m+1)
    out = np.einsum("ncw,nw->nc", windows, wmat)
    out[0], out[-1] = p[0], p[-1]
    return out
