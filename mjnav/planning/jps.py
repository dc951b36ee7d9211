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

Design decisions. Each was measured on the 10 longest queries of three Moving AI maps, kernel time, comparing
variants in the same process: random512-40-5 (a query expands ~32 000 jump points, jumps average 1.7 cells),
maze512-32-9 and Boston_0_256 (long straight jumps, few expansions). Together they halved the kernel time on
random512 and cut it to ~1/5 on the maze and ~1/3 on Boston.

* Straight jumps in both directions are block-based (ICAPS 2014): the grid is packed into bit rows and, for the
  vertical jumps, into bit columns (the transposed grid), and one step of :func:`jump` examines 63 cells with a
  few word operations. :func:`prepare_grid` builds the padded byte grid and both bit grids in one compiled pass
  per query (~30 µs for 512×512, less than the former byte padding plus row packing alone); the padded row
  stride is rounded up to a multiple of 8 so that both packings read eight cells per load. The bit columns made
  the maze kernel ~4× and the Boston kernel ~2× faster and cost random512 1-5 %, where a cell-by-cell scan of
  the short jumps is as fast.
* The node records (:data:`~mjnav.planning._kernels.NODE_DTYPE`, 4.2 MB for 512×512) do not fit the L2 cache:
  on random512 about a third of the time went to waiting for the record of a newly found jump point. Expanding
  a node prefetches the records of the rows around it (:data:`PREFETCH_ROWS`, two cache lines per row), where
  the jump points found from it nearly always are: about −25 % on random512, neutral elsewhere. ±2 rows or ±4-5 rows
  were 3-4 % slower than ±3.
* The open list is a 4-ary heap ordered by f alone and sifted down bottom-up without branches
  (:func:`~mjnav.planning._kernels.heap4_sift_down`): on random512, −25 % against the binary heap ordered by
  (f, h) with signed indices and branching comparisons. Dropping the tie-break on h changed the expansions by
  < 0.5 %: the pruning already removes most equal-f alternatives.
* Successor directions come from a table indexed by arrival direction and 8-neighbourhood (:data:`SUCCESSORS`),
  which also drops the directions whose first step is blocked or cuts a corner, and the diagonal scan starts a
  straight jump only when its first cell is free, so no jump or scan is started only to fail at once: −6 % and
  −5 % on random512.
* Indices into the node records and bit grids are unsigned, so numba emits no negative-index wrap-around:
  −4 % on random512, −12 to −25 % on the other two maps.

Tried and dropped (slower on random512, same-process comparisons): expanding successors whose f equals the
popped f at once from a LIFO stack, as :func:`~mjnav.planning._kernels.best_first` does (+10 to +18 %; the
heap work seems to overlap the prefetches' latency); a radix heap exploiting monotone f (+40 %); prefetching at
push time or around the next heap top instead of around the expanded node (+6 to +30 %); a 1-bit-per-node
"seen" bitmap to skip reading the record of new nodes (+5 %) or separate tag, g and parent arrays (+9 %).
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
    MOVE_DC,
    MOVE_DR,
    NO_ARRIVAL,
    NOT_FOUND,
    OVERFLOW,
    heap4_push,
    heap4_sift_down,
    prefetch,
)
from mjnav.planning.heuristics import heuristic_value

SQRT2 = math.sqrt(2.0)

#: Node records prefetched when a node is expanded: this many rows above and below it, two cache lines each.
PREFETCH_ROWS = 3

_ONES = np.uint64(0xFFFFFFFFFFFFFFFF)
_BYTE_ONES = np.uint64(0x0101010101010101)
# Multiplying eight 0/1 bytes by this gathers byte i into bit 56 + i (the partial products never overlap).
_GATHER = np.uint64(0x0102040810204080)


def grid_layout(h: int, w: int) -> tuple[int, int, int]:
    """Memory layout of the search grids of an (h, w) map for :func:`prepare_grid`.

    Returns:
        (stride, words, twords): the padded row stride (W + 2 rounded up to a multiple of 8; node of padded
        cell (r, c) = r·stride + c), uint64 words per bit row (``stride`` columns) and per bit column
        (H + 2 rows), each including a guard word at both ends.
    """
    stride = (w + 2 + 7) // 8 * 8
    return stride, (stride + 63) // 64 + 2, (h + 2 + 63) // 64 + 2


@njit(cache=True)
def prepare_grid(
    mask: NDArray[np.bool_], grid: NDArray[np.uint8], bits: NDArray[np.uint64], tbits: NDArray[np.uint64]
) -> None:  # pragma: no cover - compiled
    """Fill the search grids of a map in one pass.

    Args:
        mask: (H, W) C-contiguous bool occupancy.
        grid: (H + 2, stride) uint8 output (see :func:`grid_layout`): 1 = blocked, the map at rows 1..H and
            columns 1..W, everything else blocked.
        bits: output, at least (H + 2)·words: ``grid`` as bit rows; row r is the words [r·words, (r + 1)·words),
            bit i of its word k + 1 is column 64·k + i; the first and last word of a row are all ones.
        tbits: output, at least stride·twords: the same for the columns of ``grid`` (its transpose).
    """
    h, w = mask.shape
    hp, stride = grid.shape
    cells = mask.view(np.uint8)
    for c in range(stride):
        grid[0, c] = 1
        grid[hp - 1, c] = 1
    for r in range(h):
        grid[r + 1, 0] = 1
        for c in range(w):
            grid[r + 1, c + 1] = cells[r, c]
        for c in range(w + 1, stride):
            grid[r + 1, c] = 1
    s8 = stride // 8
    words = (stride + 63) // 64 + 2
    twords = (hp + 63) // 64 + 2
    g64 = grid.view(np.uint64).ravel()  # eight cells per word, cell j in byte j
    bits[: hp * words] = _ONES
    tbits[: stride * twords] = _ONES
    row_bytes = bits.view(np.uint8)
    for r in range(hp):
        src = g64[r * s8 : (r + 1) * s8]
        dst = row_bytes[r * words * 8 + 8 : r * words * 8 + 8 + s8]
        for q in range(s8):
            dst[q] = np.uint8((src[q] * _GATHER) >> np.uint64(56))
    # Columns, per block of 64 rows and group of 8 columns: band b of 8 rows gives y[b], whose byte m holds
    # column 8q + m of those rows (bit j = row j of the band); an 8×8 byte transpose of y turns the bands into
    # one column word each.
    y = np.empty(8, np.uint64)
    lo32 = np.uint64(0x00000000FFFFFFFF)
    lo16 = np.uint64(0x0000FFFF0000FFFF)
    lo8 = np.uint64(0x00FF00FF00FF00FF)
    for k in range((hp + 63) // 64):
        for q in range(s8):
            for b in range(8):
                r0 = 64 * k + 8 * b
                v = np.uint64(0)
                if r0 + 8 <= hp:
                    for j in range(8):
                        v |= g64[(r0 + j) * s8 + q] << np.uint64(j)
                else:  # rows past the grid read as blocked
                    for j in range(8):
                        v |= (g64[(r0 + j) * s8 + q] if r0 + j < hp else _BYTE_ONES) << np.uint64(j)
                y[b] = v
            for b in range(4):
                a0 = y[b]
                a1 = y[b + 4]
                y[b] = (a0 & lo32) | (a1 << np.uint64(32))
                y[b + 4] = (a0 >> np.uint64(32)) | (a1 & ~lo32)
            for b in (0, 1, 4, 5):
                a0 = y[b]
                a1 = y[b + 2]
                y[b] = (a0 & lo16) | ((a1 & lo16) << np.uint64(16))
                y[b + 2] = ((a0 >> np.uint64(16)) & lo16) | (a1 & ~lo16)
            for b in (0, 2, 4, 6):
                a0 = y[b]
                a1 = y[b + 1]
                y[b] = (a0 & lo8) | ((a1 & lo8) << np.uint64(8))
                y[b + 1] = ((a0 >> np.uint64(8)) & lo8) | (a1 & ~lo8)
            for m in range(8):
                tbits[(8 * q + m) * twords + 1 + k] = y[m]


@njit(cache=True, inline="always")
def _window_ahead(bits: NDArray[np.uint64], base: int, p: int) -> np.uint64:  # pragma: no cover - compiled
    """64 cells of a bit line starting at position ``p`` (bit i = cell p + i); ``base`` = the line's first word."""
    i = np.uint64(base + (p >> 6))
    sh = np.uint64(p & 63)
    one = np.uint64(1)
    return (bits[i] >> sh) | ((bits[i + one] << one) << (np.uint64(63) - sh))


@njit(cache=True, inline="always")
def _window_behind(bits: NDArray[np.uint64], base: int, p: int) -> np.uint64:  # pragma: no cover - compiled
    """64 cells of a bit line ending at position ``p`` (bit 63 = cell p, bit i = cell p − 63 + i)."""
    i = np.uint64(base + (p >> 6))
    sh = np.uint64(p & 63)
    one = np.uint64(1)
    return (bits[i] << (np.uint64(63) - sh)) | ((bits[i - one] >> one) >> sh)


@njit(cache=True, inline="always")
def jump(
    bits: NDArray[np.uint64], words: int, line: int, pos: int, d: int, gline: int, gpos: int
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Straight jump along one line of a bit grid from cell ``pos`` towards ``d`` = ±1, 63 cells per step.

    With the row bits of :func:`prepare_grid` (``line`` = row, positions = columns) this is a horizontal jump;
    with the column bits (``line`` = column, positions = rows) a vertical one. In one step a 64-cell window
    of the line and of its two neighbour lines yields the blocked cells ahead and the forced cells (blocked
    behind and free beside, in a neighbour line) as bit masks; the nearest set bit, or the goal's bit, ends
    the jump — the block-based jumping of Harabor and Grastien (ICAPS 2014). Windows are extracted without
    branches (a zero shift is split into two shifts).

    Args:
        bits: a bit grid (:func:`prepare_grid`).
        words: uint64 words per line.
        line: the line jumped along.
        pos: start cell (free).
        d: direction, +1 or −1.
        gline: the goal's line.
        gpos: the goal's position.

    Returns:
        (position of the jump point, or −1 when an obstacle ends the jump; number of steps taken).
    """
    one = np.uint64(1)
    b0 = line * words + 1
    bu = b0 - words
    bd = b0 + words
    p = pos
    if d > 0:
        while True:
            blk = _window_ahead(bits, b0, p) >> one  # bit i: cell p + 1 + i, i < 63
            up = _window_ahead(bits, bu, p)
            dn = _window_ahead(bits, bd, p)
            stop = blk | (up & ~(up >> one)) | (dn & ~(dn >> one)) | (one << np.uint64(63))
            if line == gline and p < gpos <= p + 63:
                stop |= one << np.uint64(gpos - p - 1)
            i = int(trailing_zeros(stop))  # type: ignore[call-arg]
            if i < 63:
                cand = p + 1 + i
                if (blk >> np.uint64(i)) & one:
                    return -1, cand - pos
                return cand, cand - pos
            p += 63
    while True:
        blk = _window_behind(bits, b0, p) << one  # bit 63 − i: cell p − 1 − i, i < 63
        up = _window_behind(bits, bu, p)
        dn = _window_behind(bits, bd, p)
        stop = blk | (up & ~(up << one)) | (dn & ~(dn << one)) | one
        if line == gline and p - 63 <= gpos < p:
            stop |= one << np.uint64(64 - p + gpos)
        i = int(leading_zeros(stop))  # type: ignore[call-arg]
        if i < 63:
            cand = p - 1 - i
            if (blk >> np.uint64(63 - i)) & one:
                return -1, pos - cand
            return cand, pos - cand
        p -= 63


def _successor_table() -> NDArray[np.uint8]:
    """Successor directions of a jump point search node, see :data:`SUCCESSORS`."""
    dirs = {(int(MOVE_DR[k]), int(MOVE_DC[k])): k for k in range(8)}
    table = np.zeros(9 * 256, np.uint8)
    for arrival in range(9):
        for nb in range(256):

            def blocked(dr: int, dc: int, nb: int = nb) -> bool:
                return bool((nb >> dirs[(dr, dc)]) & 1)

            if arrival == NO_ARRIVAL:
                cand = set(range(8))
            elif arrival >= 4:
                dr, dc = int(MOVE_DR[arrival]), int(MOVE_DC[arrival])
                cand = {dirs[(dr, 0)], dirs[(0, dc)], arrival}
            else:
                dr, dc = int(MOVE_DR[arrival]), int(MOVE_DC[arrival])
                cand = {arrival}
                for sr, sc in ((dc, dr), (-dc, -dr)):  # the two sides
                    if blocked(sr - dr, sc - dc) and not blocked(sr, sc):
                        cand |= {dirs[(sr, sc)], dirs[(sr + dr, sc + dc)]}
            mask = 0
            for k in cand:
                dr, dc = int(MOVE_DR[k]), int(MOVE_DC[k])
                if not blocked(dr, dc) and (k < 4 or not (blocked(dr, 0) or blocked(0, dc))):
                    mask |= 1 << k
            table[arrival * 256 + nb] = mask
    return table


#: Successor directions: ``SUCCESSORS[a * 256 + nb]`` is the bit mask of the moves (indices of
#: :data:`~mjnav.planning._kernels.MOVE_DR`) to search from a node reached with arrival direction ``a``
#: (:data:`~mjnav.planning._kernels.NO_ARRIVAL` at the start) whose neighbours are blocked where bit k of
#: ``nb`` is set (bit k = the neighbour in move direction k): the natural and forced successors of the
#: pruning rules, minus the moves whose first step is blocked or would cut a corner.
SUCCESSORS = _successor_table()


@njit(cache=True)
def _relax(
    nodes: NDArray[np.void],
    keys: NDArray[np.float64],
    items: NDArray[np.int64],
    size: int,
    base: int,
    node: int,
    ng: float,
    parent: int,
    arrival: int,
    key: float,
) -> int:  # pragma: no cover - compiled
    """Offer cost ``ng`` (priority ``key``) to ``node``; returns the new heap size, or −1 when the heap is full."""
    n = np.uint64(node)
    tag = nodes[n].tag
    if tag >= base + CLOSED or (tag >= base and ng >= nodes[n].g):
        return size
    if size == keys.shape[0]:
        return -1
    nodes[n].g = ng
    nodes[n].parent = parent
    nodes[n].tag = base + arrival
    return heap4_push(keys, items, size, key, node)


@njit(cache=True)
def jump_point_search(
    grid: NDArray[np.uint8],
    bits: NDArray[np.uint64],
    words: int,
    tbits: NDArray[np.uint64],
    twords: int,
    stride: int,
    start: int,
    goal: int,
    alpha: float,
    beta: float,
    hcode: int,
    nodes: NDArray[np.void],
    base: int,
    keys: NDArray[np.float64],
    items: NDArray[np.int64],
) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """A* over jump points with priority α·g + β·h (ties in no particular order).

    Args:
        grid: the padded grid of :func:`prepare_grid`, flat, 1 = blocked.
        bits: its bit rows, for horizontal jumps.
        words: uint64 words per bit row.
        tbits: its bit columns, for vertical jumps.
        twords: uint64 words per bit column.
        stride: padded row stride (node of padded cell (r, c) = r·stride + c).
        start: start node.
        goal: goal node.
        alpha: weight of g.
        beta: weight of h.
        hcode: heuristic code (see :data:`mjnav.planning.heuristics.HEURISTIC_CODES`).
        nodes: node records (:data:`mjnav.planning._kernels.NODE_DTYPE`), at least ``grid.size``; the tag's low
            bits hold the arrival direction.
        base: tag base of this search.
        keys: heap storage (priorities).
        items: heap storage (nodes).

    Returns:
        (g of the goal, expanded jump points, status: FOUND, NOT_FOUND or OVERFLOW when the heap is full).
    """
    closed = base + CLOSED
    last = grid.shape[0] - 1
    gr = goal // stride
    gc = goal - gr * stride
    nodes[start].g = 0.0
    nodes[start].parent = -1
    nodes[start].tag = base + NO_ARRIVAL
    size = heap4_push(keys, items, 0, 0.0, start)
    expanded = 0
    while size > 0:
        cur = items[0]
        size -= 1
        heap4_sift_down(keys, items, size)
        cu = np.uint64(cur)
        tag = nodes[cu].tag
        if tag >= closed:
            continue
        nodes[cu].tag = tag + CLOSED
        expanded += 1
        if cur == goal:
            return nodes[cu].g, expanded, FOUND
        gcur = nodes[cu].g
        cr = cur // stride
        cc = cur - cr * stride
        # The records of columns cc − 2 .. cc + 2 (two cache lines) in the rows around cur: jump points found
        # from cur are nearly always there, and the loads overlap with the work below.
        lo = max(cur - PREFETCH_ROWS * stride - 2, 0)
        hi = min(cur + PREFETCH_ROWS * stride - 2, last - 4)
        for p in range(lo, hi + 1, stride):
            prefetch(nodes, p)
            prefetch(nodes, p + 4)
        nb = (
            int(grid[cur - stride])
            | (int(grid[cur + stride]) << 1)
            | (int(grid[cur - 1]) << 2)
            | (int(grid[cur + 1]) << 3)
            | (int(grid[cur - stride - 1]) << 4)
            | (int(grid[cur - stride + 1]) << 5)
            | (int(grid[cur + stride - 1]) << 6)
            | (int(grid[cur + stride + 1]) << 7)
        )
        todo = np.uint64(SUCCESSORS[(tag - base) * 256 + nb])
        while todo:
            dk = int(trailing_zeros(todo))  # type: ignore[call-arg]
            todo &= todo - np.uint64(1)
            if dk < 4:
                # Straight jump from cur (its first cell is free).
                if dk >= 2:
                    dc = -1 if dk == 2 else 1
                    jc, k = jump(bits, words, cr, cc, dc, gr, gc)
                    if jc < 0:
                        continue
                    jr = cr
                    j = cur + k * dc
                else:
                    dr = -1 if dk == 0 else 1
                    jr, k = jump(tbits, twords, cc, cr, dr, gc, gr)
                    if jr < 0:
                        continue
                    jc = cc
                    j = cur + k * dr * stride
                ng = gcur + k
                h = heuristic_value(hcode, float(abs(jr - gr)), float(abs(jc - gc)))
                size = _relax(nodes, keys, items, size, base, j, ng, cur, dk, alpha * ng + beta * h)
                if size < 0:
                    return np.inf, expanded, OVERFLOW
                continue
            # Diagonal scan with intermediate pruning; its first step is legal (the table checked it).
            dr = -1 if dk < 6 else 1
            dc = -1 if (dk == 4 or dk == 6) else 1
            hdir = 2 if dc < 0 else 3
            vdir = 0 if dr < 0 else 1
            step = dr * stride + dc
            nn = cur
            nr = cr
            nc = cc
            s = 0
            while True:
                nn += step
                nr += dr
                nc += dc
                s += 1
                gd = gcur + s * SQRT2
                if nn == goal:
                    size = _relax(nodes, keys, items, size, base, nn, gd, cur, dk, alpha * gd)
                    if size < 0:
                        return np.inf, expanded, OVERFLOW
                    break
                free_h = grid[np.uint64(nn + dc)] == 0
                free_v = grid[np.uint64(nn + dr * stride)] == 0
                if free_h:
                    jc, k = jump(bits, words, nr, nc, dc, gr, gc)
                    if jc >= 0:
                        ng = gd + k
                        h = heuristic_value(hcode, float(abs(nr - gr)), float(abs(jc - gc)))
                        j = nn + k * dc
                        size = _relax(nodes, keys, items, size, base, j, ng, cur, hdir, alpha * ng + beta * h)
                        if size < 0:
                            return np.inf, expanded, OVERFLOW
                if free_v:
                    jr, k = jump(tbits, twords, nc, nr, dr, gc, gr)
                    if jr >= 0:
                        ng = gd + k
                        h = heuristic_value(hcode, float(abs(jr - gr)), float(abs(nc - gc)))
                        j = nn + k * dr * stride
                        size = _relax(nodes, keys, items, size, base, j, ng, cur, vdir, alpha * ng + beta * h)
                        if size < 0:
                            return np.inf, expanded, OVERFLOW
                if not (free_h and free_v) or grid[np.uint64(nn + step)]:
                    break
    return np.inf, expanded, NOT_FOUND


@njit(cache=True)
def trace_jump_path(nodes: NDArray[np.void], width: int, start: int, goal: int) -> NDArray[np.int64]:
    """(N, 2) (row, col) unpadded cells from ``start`` to ``goal``; each parent link is diagonal then straight.

    ``width`` is the padded row stride the node ids use.
    """
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
