"""Jump point search on 8-connected grids with √2 diagonals and no corner cutting (compiled kernel).

Jump point search (D. Harabor and A. Grastien, "Online Graph Pruning for Pathfinding on Grid Maps", AAAI 2011)
is A* over a pruned successor set that skips the many symmetric equal-cost paths of a uniform-cost grid; it
returns exactly optimal paths. This is the no-corner-cutting variant (Harabor and Grastien, "Improving Jump
Point Search", ICAPS 2014), in which a diagonal step needs both orthogonal cells it passes to be free. Pruning
rules, with the arrival direction at a node x:

* diagonal (dr, dc): natural successors (dr, 0), (0, dc), (dr, dc); there are no forced neighbours.
* straight, e.g. east (0, +1): natural successor east. The cell above x is forced when the cell above x's
  predecessor is blocked and it is free; then north and north-east are successors too (likewise below).

A straight jump stops at the goal, at a cell with a forced neighbour (a jump point), or fails at an obstacle.
A diagonal jump tries the two straight jumps from every cell it passes. Following the intermediate pruning of
the ICAPS 2014 paper, jump points found by those straight jumps become successors of the node being expanded
directly (through the diagonal turning cell), and the diagonal scan continues; the turning cells are never
put on the open list. The path between a node and its parent is therefore "diagonal steps, then straight
steps", which :func:`trace_jump_path` expands back into unit steps.

Horizontal jumps use the block-based jumping of the ICAPS 2014 paper: the grid is also packed into bit rows and
one step examines 64 cells with a few word operations (:func:`jump_horizontal`); on open maps this halves the
search time. Vertical jumps scan a column of the byte grid (stride W + 2) cell by cell. Packing a transposed copy
for them as well costs about 0.1 ms per 512×512 query to build; measured, it made the longest open-map queries
about a quarter faster but every short query slower, so it is not done.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros
from numpy.typing import NDArray

from mjnav.planning._kernels import (
    CLOSED,
    FOUND,
    NO_ARRIVAL,
    NOT_FOUND,
    OVERFLOW,
    heap_push,
    heap_sift_down,
)
from mjnav.planning.heuristics import heuristic_value

SQRT2 = math.sqrt(2.0)


@njit(cache=True)
def _jump_straight(
    blocked: NDArray[np.uint8], n: int, d: int, side: int, goal: int
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Straight jump from node ``n`` with flat step ``d``; ``side`` is the flat perpendicular offset.

    Returns:
        (jump point node or −1, number of steps taken).
    """
    k = 0
    while True:
        n += d
        k += 1
        if blocked[n]:
            return -1, k
        if n == goal:
            return n, k
        if (blocked[n - d - side] and not blocked[n - side]) or (blocked[n - d + side] and not blocked[n + side]):
            return n, k


@njit(cache=True, inline="always")
def _window_east(bits: NDArray[np.uint64], base: int, p: int) -> np.uint64:  # pragma: no cover - compiled
    """64 cells of a bit row starting at column ``p`` (bit i = column p + i); ``base`` = the row's first word."""
    k = p >> 6
    sh = np.uint64(p & 63)
    lo = bits[base + k]
    if sh == np.uint64(0):
        return lo
    return (lo >> sh) | (bits[base + k + 1] << (np.uint64(64) - sh))


@njit(cache=True, inline="always")
def _window_west(bits: NDArray[np.uint64], base: int, p: int) -> np.uint64:  # pragma: no cover - compiled
    """64 cells of a bit row ending at column ``p`` (bit 63 = column p, bit i = column p − 63 + i)."""
    k = p >> 6
    sh = np.uint64(p & 63)
    hi = bits[base + k]
    if sh == np.uint64(63):
        return hi
    return (hi << (np.uint64(63) - sh)) | (bits[base + k - 1] >> (sh + np.uint64(1)))


@njit(cache=True)
def jump_horizontal(
    bits: NDArray[np.uint64], words: int, r: int, c: int, dc: int, gr: int, gc: int
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Horizontal straight jump from padded cell (r, c) towards ``dc`` = ±1, 64 cells per step.

    ``bits`` holds the padded grid as rows of ``words`` uint64 words, bit i of word k+1 of a row = column
    64·k + i (word 0 and the last word of each row are all-ones guards). In one step the window of 64 cells
    ahead yields the blocked cells of the row and the forced cells (blocked behind and free beside, in the rows
    above and below) as bit masks; the nearest set bit, or the goal's bit, ends the jump — the block-based
    jumping of Harabor and Grastien (ICAPS 2014).

    Returns:
        (column of the jump point or −1 when an obstacle ends the jump, number of steps taken).
    """
    one = np.uint64(1)
    b0 = r * words + 1
    bu = b0 - words
    bd = b0 + words
    if dc > 0:
        pos = c + 1
        while True:
            blk = _window_east(bits, b0, pos)
            up = _window_east(bits, bu, pos)
            dn = _window_east(bits, bd, pos)
            forced = (_window_east(bits, bu, pos - 1) & ~up) | (_window_east(bits, bd, pos - 1) & ~dn)
            stop = blk | forced
            if r == gr and pos <= gc < pos + 64:
                stop |= one << np.uint64(gc - pos)
            if stop != np.uint64(0):
                i = int(trailing_zeros(stop))  # type: ignore[call-arg]
                cand = pos + i
                if (blk >> np.uint64(i)) & one:
                    return -1, cand - c
                return cand, cand - c
            pos += 64
    else:
        pos = c - 1
        while True:
            blk = _window_west(bits, b0, pos)
            up = _window_west(bits, bu, pos)
            dn = _window_west(bits, bd, pos)
            forced = (_window_west(bits, bu, pos + 1) & ~up) | (_window_west(bits, bd, pos + 1) & ~dn)
            stop = blk | forced
            if r == gr and pos - 64 < gc <= pos:
                stop |= one << np.uint64(63 - (pos - gc))
            if stop != np.uint64(0):
                i = int(leading_zeros(stop))  # type: ignore[call-arg]
                cand = pos - i
                if (blk >> np.uint64(63 - i)) & one:
                    return -1, c - cand
                return cand, c - cand
            pos -= 64


def pack_rows(padded: NDArray[np.uint8], out: NDArray[np.uint64] | None = None) -> tuple[NDArray[np.uint64], int]:
    """Bit rows of a padded (H + 2, W + 2) 0/1 grid for :func:`jump_horizontal`.

    Args:
        padded: the padded grid.
        out: optional buffer of at least (H + 2)·words uint64 to fill (reused between searches).

    Returns:
        (flat bit array, words per row).
    """
    h, w = padded.shape
    words = (w + 63) // 64 + 2
    n = h * words
    bits = np.empty(n, np.uint64) if out is None or out.shape[0] < n else out[:n]
    rows = bits.reshape(h, words)
    rows[...] = np.uint64(0xFFFFFFFFFFFFFFFF)
    packed = np.packbits(padded, axis=1, bitorder="little")
    rows.view(np.uint8)[:, 8 : 8 + packed.shape[1]] = packed
    return bits, words


@njit(cache=True)
def _dir_index(dr: int, dc: int) -> int:  # pragma: no cover - compiled
    """Index of the move (dr, dc) in the tables of :mod:`mjnav.planning._kernels`."""
    if dc == 0:
        return 0 if dr < 0 else 1
    if dr == 0:
        return 2 if dc < 0 else 3
    if dr < 0:
        return 4 if dc < 0 else 5
    return 6 if dc < 0 else 7


@njit(cache=True)
def _relax(
    nodes: NDArray[np.void],
    keys: NDArray[np.float64],
    subs: NDArray[np.float64],
    items: NDArray[np.int64],
    size: int,
    base: int,
    node: int,
    ng: float,
    parent: int,
    arrival: int,
    alpha: float,
    beta: float,
    h: float,
) -> int:  # pragma: no cover - compiled
    """Offer cost ``ng`` to ``node``; returns the new heap size, or −1 when the heap is full."""
    tag = nodes[node].tag
    if tag >= base + CLOSED or (tag >= base and ng >= nodes[node].g):
        return size
    if size == keys.shape[0]:
        return -1
    nodes[node].g = ng
    nodes[node].parent = parent
    nodes[node].tag = base + arrival
    return heap_push(keys, subs, items, size, alpha * ng + beta * h, h, node)


@njit(cache=True)
def jump_point_search(
    blocked: NDArray[np.uint8],
    bits: NDArray[np.uint64],
    words: int,
    width: int,
    start: int,
    goal: int,
    alpha: float,
    beta: float,
    hcode: int,
    nodes: NDArray[np.void],
    base: int,
    keys: NDArray[np.float64],
    subs: NDArray[np.float64],
    items: NDArray[np.int64],
) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """A* over jump points with priority α·g + β·h (ties: smaller h first).

    Args:
        blocked: padded grid, flat, (H + 2)·(W + 2), 1 = occupied.
        bits: the same grid as bit rows (:func:`pack_rows`), for horizontal jumps.
        words: uint64 words per bit row.
        width: padded width W + 2.
        start: start node (flat index into ``blocked``).
        goal: goal node.
        alpha: weight of g.
        beta: weight of h.
        hcode: heuristic code (see :data:`mjnav.planning.heuristics.HEURISTIC_CODES`).
        nodes: node records (:data:`mjnav.planning._kernels.NODE_DTYPE`); the tag's low bits hold the
            arrival direction.
        base: tag base of this search.
        keys: heap storage.
        subs: heap storage.
        items: heap storage.

    Returns:
        (g of the goal, expanded jump points, status: FOUND, NOT_FOUND or OVERFLOW when the heap is full).
    """
    closed = base + CLOSED
    gr = goal // width
    gc = goal - gr * width
    nodes[start].g = 0.0
    nodes[start].parent = -1
    nodes[start].tag = base + NO_ARRIVAL
    size = heap_push(keys, subs, items, 0, 0.0, 0.0, start)
    dirs = np.empty(8, np.int64)
    expanded = 0
    while size > 0:
        cur = items[0]
        size -= 1
        if size > 0:
            heap_sift_down(keys, subs, items, size)
        tag = nodes[cur].tag
        if tag >= closed:
            continue
        nodes[cur].tag = tag + CLOSED
        expanded += 1
        if cur == goal:
            return nodes[goal].g, expanded, FOUND
        gcur = nodes[cur].g
        cr = cur // width
        cc = cur - cr * width
        # Successor directions (indices into the move tables).
        a = tag - base
        nd = 0
        if a == NO_ARRIVAL:
            for k in range(8):
                dirs[k] = k
            nd = 8
        elif a >= 4:
            dirs[0] = 0 if a < 6 else 1
            dirs[1] = 2 if (a == 4 or a == 6) else 3
            dirs[2] = a
            nd = 3
        elif a >= 2:  # horizontal arrival
            dc = -1 if a == 2 else 1
            dirs[0] = a
            nd = 1
            if blocked[cur - dc - width] and not blocked[cur - width]:
                dirs[nd] = 0
                dirs[nd + 1] = _dir_index(-1, dc)
                nd += 2
            if blocked[cur - dc + width] and not blocked[cur + width]:
                dirs[nd] = 1
                dirs[nd + 1] = _dir_index(1, dc)
                nd += 2
        else:  # vertical arrival
            dr = -1 if a == 0 else 1
            dirs[0] = a
            nd = 1
            if blocked[cur - dr * width - 1] and not blocked[cur - 1]:
                dirs[nd] = 2
                dirs[nd + 1] = _dir_index(dr, -1)
                nd += 2
            if blocked[cur - dr * width + 1] and not blocked[cur + 1]:
                dirs[nd] = 3
                dirs[nd + 1] = _dir_index(dr, 1)
                nd += 2
        for i in range(nd):
            dk = dirs[i]
            if dk < 4:
                # Straight jump from cur.
                if dk >= 2:
                    dc = -1 if dk == 2 else 1
                    jc, k = jump_horizontal(bits, words, cr, cc, dc, gr, gc)
                    if jc < 0:
                        continue
                    jr = cr
                    j = cur + k * dc
                else:
                    dr = -1 if dk == 0 else 1
                    j, k = _jump_straight(blocked, cur, dr * width, 1, goal)
                    if j < 0:
                        continue
                    jr = cr + k * dr
                    jc = cc
                h = heuristic_value(hcode, float(abs(jr - gr)), float(abs(jc - gc)))
                size = _relax(nodes, keys, subs, items, size, base, j, gcur + k, cur, dk, alpha, beta, h)
                if size < 0:
                    return np.inf, expanded, OVERFLOW
                continue
            # Diagonal scan with intermediate pruning.
            dr = -1 if dk < 6 else 1
            dc = -1 if (dk == 4 or dk == 6) else 1
            hdir = 2 if dc < 0 else 3
            vdir = 0 if dr < 0 else 1
            step = dr * width + dc
            nn = cur
            nr = cr
            nc = cc
            s = 0
            while True:
                if blocked[nn + dr * width] or blocked[nn + dc]:
                    break
                nn += step
                nr += dr
                nc += dc
                s += 1
                if blocked[nn]:
                    break
                gd = gcur + s * SQRT2
                if nn == goal:
                    size = _relax(nodes, keys, subs, items, size, base, nn, gd, cur, dk, alpha, beta, 0.0)
                    if size < 0:
                        return np.inf, expanded, OVERFLOW
                    break
                jc, k = jump_horizontal(bits, words, nr, nc, dc, gr, gc)
                if jc >= 0:
                    j = nn + k * dc
                    h = heuristic_value(hcode, float(abs(nr - gr)), float(abs(nc + k * dc - gc)))
                    size = _relax(nodes, keys, subs, items, size, base, j, gd + k, cur, hdir, alpha, beta, h)
                    if size < 0:
                        return np.inf, expanded, OVERFLOW
                j, k = _jump_straight(blocked, nn, dr * width, 1, goal)
                if j >= 0:
                    jr = nr + k * dr
                    h = heuristic_value(hcode, float(abs(jr - gr)), float(abs(nc - gc)))
                    size = _relax(nodes, keys, subs, items, size, base, j, gd + k, cur, vdir, alpha, beta, h)
                    if size < 0:
                        return np.inf, expanded, OVERFLOW
    return np.inf, expanded, NOT_FOUND


@njit(cache=True)
def trace_jump_path(nodes: NDArray[np.void], width: int, start: int, goal: int) -> NDArray[np.int64]:
    """(N, 2) (row, col) unpadded cells from ``start`` to ``goal``; each parent link is diagonal then straight."""
    # Count cells first.
    count = 1
    node = goal
    while node != start:
        p = nodes[node].parent
        r = node // width
        pr = p // width
        count += max(abs(r - pr), abs((node - r * width) - (p - pr * width)))
        node = p
    out = np.empty((count, 2), np.int64)
    i = count - 1
    node = goal
    r = node // width
    out[i, 0] = r - 1
    out[i, 1] = node - r * width - 1
    while node != start:
        p = nodes[node].parent
        r = node // width
        c = node - r * width
        pr = p // width
        pc = p - pr * width
        # Walk backwards from node to p: straight part first (it is last on the way forward), then diagonal.
        dr = r - pr
        dc = c - pc
        adr = abs(dr)
        adc = abs(dc)
        sr = 1 if dr > 0 else (-1 if dr < 0 else 0)
        sc = 1 if dc > 0 else (-1 if dc < 0 else 0)
        diag = min(adr, adc)
        straight = max(adr, adc) - diag
        for _ in range(straight):
            if adr > adc:
                r -= sr
            else:
                c -= sc
            i -= 1
            out[i, 0] = r - 1
            out[i, 1] = c - 1
        for _ in range(diag):
            r -= sr
            c -= sc
            i -= 1
            out[i, 0] = r - 1
            out[i, 1] = c - 1
        node = p
    return out
