"""Compiled search kernels over a padded, flattened occupancy grid (internal).

Conventions shared by every kernel here:

* ``blocked``: (H + 2)·(W + 2) uint8, row-major, 1 = occupied; the map is surrounded by a one-cell blocked
  border so neighbour look-ups need no bounds checks. A cell (row, col) of the map is node
  ``(row + 1)·width + (col + 1)`` with ``width = W + 2``.
* Moves: 4-connected (N, S, W, E) or 8-connected (plus the diagonals, length √2). Without corner cutting a
  diagonal step needs both orthogonal cells it passes to be free; with corner cutting only its target.
* A step costs its length; searches with a cost grid run in :mod:`mjnav.planning._weighted`.
* Per-node search state lives in one record per node (:data:`NODE_DTYPE`: cost-so-far ``g``, ``parent``,
  ``tag``), so a node visit touches one cache line. The records come from a reused
  :class:`~mjnav.planning._workspace.Workspace`; ``tag`` encodes the search they belong to (see
  :data:`CLOSED`), so starting a search costs O(1), not O(H·W).
* Heaps: :func:`heap_push` / :func:`heap_sift_down` are a binary heap of three parallel arrays (``keys``,
  ``subs``, ``items``) ordered by (key, sub); :func:`heap4_push` / :func:`heap4_sift_down` a 4-ary heap of
  (``keys``, ``items``) ordered by key alone, for jump point search (see :mod:`mjnav.planning.jps`). Kernels never
  reallocate an array: a reassigned array variable makes numba emit atomic reference counting in the hot loop.
  A kernel whose heap (or stack) is full returns :data:`OVERFLOW`; the caller grows it and runs again.
* The 4-ary heap indexes with unsigned integers (``np.uint64``): for a signed index numba emits negative-index
  wrap-around code on every access (with signed indices, jump point search on a cluttered map was ~10 % slower,
  measured with a binary heap).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic
from numpy.typing import NDArray

from mjnav.planning.heuristics import heuristic_value

SQRT2 = math.sqrt(2.0)

#: One search node: cost-so-far (cells), parent node, tag. 16 bytes.
NODE_DTYPE = np.dtype([("g", np.float64), ("parent", np.int32), ("tag", np.int32)], align=True)

#: Tag layout: a search owns the tags [base, base + 32) with base a multiple of 32; a node is unvisited when
#: ``tag < base``, open when ``base <= tag < base + CLOSED``, closed when ``tag >= base + CLOSED``. The low four
#: bits hold jump point search's arrival direction (move-table index, :data:`NO_ARRIVAL` at the start).
TAG_SPAN = 32
CLOSED = 16
NO_ARRIVAL = 8

#: Kernel status codes.
FOUND = 1
NOT_FOUND = 0
OVERFLOW = -1

# Move tables: row/col deltas; the first four are the orthogonal moves.
MOVE_DR = np.array([-1, 1, 0, 0, -1, -1, 1, 1], dtype=np.int64)
MOVE_DC = np.array([0, 0, -1, 1, -1, 1, -1, 1], dtype=np.int64)


@intrinsic
def _prefetch(typingctx: Any, arr: Any, index: Any) -> Any:  # pragma: no cover - compiled
    """See :data:`prefetch`."""
    if not isinstance(arr, types.Array) or not isinstance(index, types.Integer):
        return None

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        data = context.make_array(signature.args[0])(context, builder, args[0]).data
        i8p = ir.IntType(8).as_pointer()
        addr = builder.bitcast(builder.gep(data, [args[1]]), i8p)
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]), "llvm.prefetch.p0i8"
        )
        builder.call(fn, [addr, ir.Constant(i32, 0), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(arr, index), codegen


#: ``prefetch(arr, i)`` in a kernel: hint the CPU to load the cache line holding ``arr[i]`` (no bounds check).
#: A pure performance hint (LLVM's ``llvm.prefetch``, read, high locality) that changes no result; ``i`` must lie
#: inside ``arr``, callers clamp it.
prefetch = cast("Callable[[NDArray[Any], int], None]", _prefetch)


@njit(cache=True, inline="always")
def _less(k1: float, s1: float, k2: float, s2: float) -> bool:  # pragma: no cover - compiled
    return k1 < k2 or (k1 == k2 and s1 < s2)


@njit(cache=True)
def heap_push(
    keys: NDArray[np.float64],
    subs: NDArray[np.float64],
    items: NDArray[np.int64],
    size: int,
    key: float,
    sub: float,
    item: int,
) -> int:  # pragma: no cover - compiled
    """Push (key, sub, item) on a binary min-heap ordered by (key, sub); returns the new size.

    The arrays must have room (``size < keys.shape[0]``).
    """
    i = size
    while i > 0:
        p = (i - 1) >> 1
        if _less(key, sub, keys[p], subs[p]):
            keys[i] = keys[p]
            subs[i] = subs[p]
            items[i] = items[p]
            i = p
        else:
            break
    keys[i] = key
    subs[i] = sub
    items[i] = item
    return size + 1


@njit(cache=True)
def heap_sift_down(
    keys: NDArray[np.float64], subs: NDArray[np.float64], items: NDArray[np.int64], size: int
) -> int:  # pragma: no cover - compiled
    """Finish a pop: move the entry at index ``size`` (the old last one) to the root and sift it down.

    Pop is ``top = items[0]; size -= 1; if size > 0: heap_sift_down(keys, subs, items, size)``. The loop has
    no ``break`` on purpose: with one, numba wraps the call in atomic reference counting of the arrays.
    """
    key = keys[size]
    sub = subs[size]
    item = items[size]
    i = 0
    c = 1
    while c < size:
        if c + 1 < size and _less(keys[c + 1], subs[c + 1], keys[c], subs[c]):
            c += 1
        if _less(keys[c], subs[c], key, sub):
            keys[i] = keys[c]
            subs[i] = subs[c]
            items[i] = items[c]
            i = c
            c = 2 * i + 1
        else:
            c = size
    keys[i] = key
    subs[i] = sub
    items[i] = item
    return i


@njit(cache=True, inline="always")
def _heap4_sift_up(
    keys: NDArray[np.float64], items: NDArray[np.int64], i: np.uint64, key: float, item: int
) -> None:  # pragma: no cover - compiled
    """Place (key, item) at the hole ``i`` of a 4-ary heap, moving it up past larger parents."""
    one = np.uint64(1)
    two = np.uint64(2)
    while i > 0:
        p = (i - one) >> two
        if key < keys[p]:
            keys[i] = keys[p]
            items[i] = items[p]
            i = p
        else:
            break
    keys[i] = key
    items[i] = item


@njit(cache=True)
def heap4_push(
    keys: NDArray[np.float64], items: NDArray[np.int64], size: int, key: float, item: int
) -> int:  # pragma: no cover - compiled
    """Push (key, item) on a 4-ary min-heap ordered by key alone; returns the new size.

    Equal keys come out in no particular order. The arrays must have room (``size < keys.shape[0]``).
    """
    _heap4_sift_up(keys, items, np.uint64(size), key, item)
    return size + 1


@njit(cache=True)
def heap4_sift_down(
    keys: NDArray[np.float64], items: NDArray[np.int64], size: int
) -> None:  # pragma: no cover - compiled
    """Finish a pop from a :func:`heap4_push` heap (also when it became empty).

    Pop is ``top = items[0]; size -= 1; heap4_sift_down(keys, items, size)``. Bottom-up (Wegener's variant of
    Floyd's method): the hole left by the root moves down to a leaf along the smallest children, chosen without
    branches (a binary tree of two-way minimums over the four children); then the old last entry (now past
    ``size``) is placed in it and sifted up, which rarely takes a step. The comparisons on the way down are
    data-dependent and unpredictable, so branching on them would cost a misprediction per level.
    """
    one = np.uint64(1)
    two = np.uint64(2)
    three = np.uint64(3)
    n = np.uint64(size)
    key = keys[n]
    item = items[n]
    i = np.uint64(0)
    c = one
    while c + three < n:
        k0 = keys[c]
        k1 = keys[c + one]
        k2 = keys[c + two]
        k3 = keys[c + three]
        a = c + np.uint64(k1 < k0)
        b = c + two + np.uint64(k3 < k2)
        m = b if min(k2, k3) < min(k0, k1) else a
        keys[i] = keys[m]
        items[i] = items[m]
        i = m
        c = (i << two) + one
    if c < n:  # a last, partial group of children
        m = c
        j = c + one
        while j < n:
            if keys[j] < keys[m]:
                m = j
            j += one
        keys[i] = keys[m]
        items[i] = items[m]
        i = m
    _heap4_sift_up(keys, items, i, key, item)


@njit(cache=True)
def step_allowed(
    blocked: NDArray[np.uint8], width: int, node: int, dr: int, dc: int, corner_cutting: bool
) -> bool:  # pragma: no cover - compiled
    """Whether the move (dr, dc) from ``node`` is legal (target free; no corner cut unless allowed)."""
    if blocked[node + dr * width + dc]:
        return False
    return not (dr != 0 and dc != 0 and not corner_cutting and (blocked[node + dr * width] or blocked[node + dc]))


@njit(cache=True)
def best_first(
    blocked: NDArray[np.uint8],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    alpha: float,
    beta: float,
    hcode: int,
    nodes: NDArray[np.void],
    base: int,
    keys: NDArray[np.float64],
    subs: NDArray[np.float64],
    items: NDArray[np.int64],
) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """Best-first search with priority α·g + β·h (ties: smaller h first); A*, Dijkstra and greedy.

    Args:
        blocked: padded grid, see the module docstring.
        width: padded width W + 2.
        start: start node.
        goal: goal node.
        n_moves: 4 or 8.
        corner_cutting: allow diagonal steps past occupied orthogonal cells.
        alpha: weight of g.
        beta: weight of h.
        hcode: heuristic code.
        nodes: :data:`NODE_DTYPE` records (workspace).
        base: tag base of this search.
        keys: heap storage.
        subs: heap storage.
        items: heap storage.

    Returns:
        (g of the goal, number of expanded nodes, status: FOUND, NOT_FOUND or OVERFLOW).
    """
    closed = base + CLOSED
    offs = np.empty(8, np.int64)
    lens = np.empty(8, np.float64)
    for k in range(n_moves):
        offs[k] = MOVE_DR[k] * width + MOVE_DC[k]
        lens[k] = SQRT2 if k >= 4 else 1.0
    gr = goal // width
    gc = goal - gr * width
    size = 0
    nodes[start].g = 0.0
    nodes[start].parent = -1
    nodes[start].tag = base
    size = heap_push(keys, subs, items, size, 0.0, 0.0, start)
    expanded = 0
    # Immediate expansion (A* with α = β only): a successor whose f equals the f just popped is no worse than
    # anything on the heap (f never decreases along a path with a consistent h), so it goes on a small LIFO
    # stack that is served before the heap. The comparison allows a few ulps of rounding in f.
    bypass = alpha == beta
    fast = np.empty(64, np.int64)
    nfast = 0
    fkey = 0.0
    while size > 0 or nfast > 0:
        if nfast > 0:
            nfast -= 1
            cur = fast[nfast]
        else:
            fkey = keys[0]
            cur = items[0]
            size -= 1
            if size > 0:
                heap_sift_down(keys, subs, items, size)
        if nodes[cur].tag >= closed:
            continue
        nodes[cur].tag = closed
        expanded += 1
        if cur == goal:
            return nodes[goal].g, expanded, FOUND
        gcur = nodes[cur].g
        cr = cur // width
        cc = cur - cr * width
        # Free orthogonal neighbours N, S, W, E: the diagonals need two of them unless corners may be cut.
        fn = blocked[cur - width] == 0
        fs = blocked[cur + width] == 0
        fw = blocked[cur - 1] == 0
        fe = blocked[cur + 1] == 0
        for k in range(n_moves):
            nb = cur + offs[k]
            if blocked[nb]:
                continue
            if k >= 4 and not corner_cutting:
                if k == 4:
                    ok = fn and fw
                elif k == 5:
                    ok = fn and fe
                elif k == 6:
                    ok = fs and fw
                else:
                    ok = fs and fe
                if not ok:
                    continue
            tag = nodes[nb].tag
            if tag >= closed:
                continue
            ng = gcur + lens[k]
            if tag < base or ng < nodes[nb].g:
                if size == keys.shape[0]:
                    return np.inf, expanded, OVERFLOW
                nodes[nb].g = ng
                nodes[nb].parent = cur
                nodes[nb].tag = base
                h = heuristic_value(hcode, float(abs(cr + MOVE_DR[k] - gr)), float(abs(cc + MOVE_DC[k] - gc)))
                key = alpha * ng + beta * h
                if bypass and key <= fkey + 1e-14 * (1.0 + fkey) and nfast < 64:
                    fast[nfast] = nb
                    nfast += 1
                else:
                    size = heap_push(keys, subs, items, size, key, h, nb)
    return np.inf, expanded, NOT_FOUND


@njit(cache=True)
def breadth_first(
    blocked: NDArray[np.uint8],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    nodes: NDArray[np.void],
    base: int,
    queue: NDArray[np.int64],
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Breadth-first search (FIFO, fewest steps); records as in :func:`best_first`, ``queue`` one slot per node.

    Returns:
        (number of expanded nodes, status FOUND or NOT_FOUND).
    """
    head = 0
    tail = 1
    queue[0] = start
    nodes[start].tag = base
    nodes[start].parent = -1
    expanded = 0
    while head < tail:
        cur = queue[head]
        head += 1
        expanded += 1
        if cur == goal:
            return expanded, FOUND
        for k in range(n_moves):
            dr = MOVE_DR[k]
            dc = MOVE_DC[k]
            nb = cur + dr * width + dc
            if nodes[nb].tag >= base or not step_allowed(blocked, width, cur, dr, dc, corner_cutting):
                continue
            nodes[nb].tag = base
            nodes[nb].parent = cur
            queue[tail] = nb
            tail += 1
    return expanded, NOT_FOUND


@njit(cache=True)
def depth_first(
    blocked: NDArray[np.uint8],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    nodes: NDArray[np.void],
    base: int,
    stack: NDArray[np.int64],
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Depth-first search (LIFO; a node is visited when popped); records as in :func:`best_first`.

    Neighbours are pushed in the fixed move order (N, S, W, E, NW, NE, SW, SE), so the last one pushed is
    explored first.

    Returns:
        (number of expanded nodes, status: FOUND, NOT_FOUND or OVERFLOW when ``stack`` is full).
    """
    visited = base + CLOSED
    stack[0] = start
    top = 1
    nodes[start].parent = -1
    expanded = 0
    while top > 0:
        top -= 1
        cur = stack[top]
        if nodes[cur].tag >= visited:
            continue
        nodes[cur].tag = visited
        expanded += 1
        if cur == goal:
            return expanded, FOUND
        for k in range(n_moves):
            dr = MOVE_DR[k]
            dc = MOVE_DC[k]
            nb = cur + dr * width + dc
            if nodes[nb].tag >= visited or not step_allowed(blocked, width, cur, dr, dc, corner_cutting):
                continue
            if top == stack.shape[0]:
                return expanded, OVERFLOW
            nodes[nb].parent = cur
            stack[top] = nb
            top += 1
    return expanded, NOT_FOUND


@njit(cache=True)
def trace_path(nodes: NDArray[np.void], width: int, start: int, goal: int) -> NDArray[np.int64]:
    """(N, 2) (row, col) cells of the unpadded map from ``start`` to ``goal`` along unit-step parents."""
    count = 1
    node = goal
    while node != start:
        node = nodes[node].parent
        count += 1
    out = np.empty((count, 2), np.int64)
    node = goal
    for i in range(count - 1, -1, -1):
        r = node // width
        out[i, 0] = r - 1
        out[i, 1] = node - r * width - 1
        if i > 0:
            node = nodes[node].parent
    return out
