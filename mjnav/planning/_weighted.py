"""Best-first search (A*, Dijkstra, greedy) on a grid with a traversal-cost grid (compiled kernels, internal).

This is the search :func:`~mjnav.planning.plan_grid` runs when it is given a ``cost`` grid: the planner service's
default on inflated costmaps. Step model as in :mod:`mjnav.planning.grid`: a step a → b of length d (1 or √2)
costs d·(1 + (cost[a] + cost[b]) / 2), the trapezoid rule over the per-cell factor 1 + cost (scikit-image's
``MCP_Geometric`` with costs 1 + cost gives the same optimal costs).

Memory: one float64 pair per padded node, ``rec[2·i] = g`` (cost so far) and ``rec[2·i + 1] = w`` (half the
step factor, (1 + cost) / 2, so a step costs d·(w[a] + w[b])), from the thread's
:class:`~mjnav.planning._workspace.Workspace`. :func:`prepare_costs` writes every pair once per query (validating
the cost grid in the same pass, ~0.12 ms for 512×512), so the searches need no visit tags: unseen free node
g = +inf; open g ≥ 0; expanded: g stored negated (−0.0 for the start); blocked (map, +inf cost or the one-cell
border) g = −inf, w = +inf. Relaxing a neighbour is one load of its pair and one comparison.

Heuristic: the chosen metric (cells) times ``hscale`` = 1 + min(cost) over the free cells. Every step of length
d costs at least d·hscale, so the scaled metric stays admissible and consistent whenever the metric is
(octile, Euclidean or Chebyshev on 8-connected grids; any of them on 4-connected ones). On maps whose free
cells are all near obstacles (random512-40-5 with the benchmark's cost field: hscale ≈ 4.9) this cuts the
expansions ~3×; elsewhere it is ≈ 1.

Two searches over these arrays:

* :func:`bucket_search`, for the optimal modes with a consistent heuristic (A* with α = β, Dijkstra): the
  open nodes sit in buckets of f of width δ = 0.1·hscale (a circular array of :data:`N_BUCKETS` linked lists),
  each served last-in first-out, i.e. in no particular f order inside a bucket. That makes it label-correcting
  (Δ-stepping with the reduced costs of A*, which are ≥ 0 under a consistent heuristic): a node whose g
  improves after it was expanded is pushed again and expanded again, always into the current bucket or a later
  one, so once a bucket is empty every node whose f lies below its end has its optimal g. An open node whose
  improved f falls in the bucket its entry is in is not pushed again (Boston −10 %). The search stops when
  the current bucket starts at or above the goal's g (nothing left can beat it, the heuristic being
  admissible), skipping meanwhile every node whose f is not below the goal's g (:data:`GOAL_TOLERANCE`). Pushing
  and popping are O(1); the price is the re-expansions: +0.75 % on maze512-32-9, +24 % on Boston_0_256 with
  the benchmark's cost field (a smaller δ has fewer but runs no faster: the wider buckets' depth-first order
  keeps the memory accesses local). On a planner-like 400×400 costmap (rectangles, a 10-cell cost ramp around
  them, zero cost elsewhere; 30 queries) it expands 1.9× the heap search's nodes and takes 12 ms against the
  heap search's 13 ms and the former kernel's 36 ms; δ = 0.02 would take 8.5 ms there but costs the benchmark
  ~10 %. Last-in first-out also crosses zero-cost plateaus of equal f depth first
  (an empty 100×100 zero-cost grid corner to corner: 99 expansions). Keys may run at most
  :data:`N_BUCKETS`·δ ahead of the current bucket; cost grids whose steps reach further (1 + the largest cost
  above ~260 × (1 + the smallest)) use the heap search.
* :func:`weighted_search`, for the others (weighted A*, greedy, Manhattan on 8-connected moves), whose
  expansion order defines them: an indexed 4-ary heap ordered by f alone, with decrease-key, bottom-up
  sift-down with a branch-free choice of the smallest child (as :func:`~mjnav.planning._kernels.heap4_sift_down`)
  and a small LIFO stack, served before the heap, for successors whose f equals the popped f (the tie-break
  towards larger g). Expanded nodes are never re-opened, so a path's cost is the g it reports.

Measured (kernel only, the 10 longest queries of maze512-32-9 with the benchmark's cost field, ~246 000
expansions each, i.e. the whole free map: A* cannot prune a maze with an octile heuristic; variants compared in
one process, best of 3 to 7, thread CPU time where the machine was loaded): the former generic kernel
(16-byte visit-tagged records + a separate padded cost array, binary heap ordered by (f, h), duplicate entries)
~200 ns per expansion; a 4-ary f-keyed heap ~95 ns; (g, w) pairs without tags ~85-90 ns; decrease-key instead
of duplicates (1.63 → 1.0 heap entries per expansion) ~80 ns on the maze and −30 % on Boston_0_256; the bucket
search ~55 ns (maze −33 %, Boston −22 %, random512-40-5 −30 %, same costs to 1e-9); prefetching, while a
node is expanded, the three neighbour rows of the next node in its bucket −6 to −8 % on the maze (neutral on
Boston; two nodes ahead: no better); no parent links (the path is read back from g, :func:`trace_back`) −4 %;
~50 ns in the end. Per query, the grid pass (:func:`prepare_costs`) went from 0.51 to 0.12 ms by vectorising
it (it was most of a random512 query). A profile of the heap search: ~60 % in the neighbour loop, ~25 % in
the sift-down. Tried and dropped: fully unrolled neighbour
relaxation through an inlined helper (2-3× slower as compiled by numba); a float multiply instead of the integer
division recovering (row, col) (no change); an exactly ordered two-level bucket queue (a small heap for the
current bucket) replaying the heap search's own push/pop trace (no faster than the 4-ary heap); prefetching the
three neighbour rows of a node when it is popped (+5-10 % on the maze); branch-free relaxation collecting the
improved neighbours first (no change); int32 heap positions (no change); a "hot" buffer for successors that
beat the heap top (on the maze only 2 of 252 000 pushes did).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mjnav.planning._kernels import FOUND, MOVE_DC, MOVE_DR, NOT_FOUND, OVERFLOW, prefetch
from mjnav.planning.heuristics import heuristic_value

SQRT2 = math.sqrt(2.0)

#: :func:`bucket_search` status: a key beyond the bucket window (the caller uses :func:`weighted_search`).
OUT_OF_WINDOW = -2

#: Bucket array length of :func:`bucket_search` (a power of two) and bucket width in units of the cheapest step
#: (1 + min cost): keys may run 4096 × 0.1 cheapest steps ahead of the current bucket.
N_BUCKETS = 4096
BUCKET_WIDTH = 0.1
#: :func:`bucket_search` does not expand a node whose f is within this fraction below the goal's g: it could
#: improve the goal by no more than that, and on plateaus of equal f (zero-cost regions) it would expand them all.
GOAL_TOLERANCE = 1e-12
#: :func:`bucket_search` expands a node again only if its g improves by more than this fraction: sums of the
#: same steps in another order differ in the last bits, and on zero-cost plateaus such "improvements" would
#: cascade into re-expansions (on a planner-like costmap 2/3 of all expansions). A path loses at most this
#: fraction of its cost per step, far below the 1e-9 the costs are checked to.
REOPEN_TOLERANCE = 1e-13

#: :func:`prepare_costs` verdicts on the cost grid.
COSTS_OK = 0
COSTS_NAN = 1
COSTS_NEGATIVE = 2


@njit(cache=True)
def prepare_costs(
    occupied: NDArray[np.bool_], cost: NDArray[np.float64], rec: NDArray[np.float64]
) -> tuple[int, float, float]:  # pragma: no cover - compiled
    """Write the (g, w) pair of every padded node for a new search and validate ``cost`` in the same pass.

    Args:
        occupied: (H, W) C-contiguous bool, True = blocked.
        cost: (H, W) C-contiguous float64 extra cost per unit length, ≥ 0 or +inf (impassable).
        rec: float64 storage of at least 2·(H + 2)·(W + 2) values; see the module docstring.

    Returns:
        (verdict: :data:`COSTS_OK`, :data:`COSTS_NAN` or :data:`COSTS_NEGATIVE` (NaN wins), the smallest and the
        largest cost of a free cell: +inf and 0 when there is none).

    The loop is written so that LLVM vectorises it (0.51 → 0.12 ms for 512×512): each pair is one complex128
    store, and the checks and the smallest/largest cost are integer reductions over the costs' bit patterns
    (for floats ≥ 0 the bit pattern orders like the value; NaN and negative patterns are told apart first).
    """
    h, w = occupied.shape
    width = w + 2
    inf = np.inf
    inf_bits = np.int64(0x7FF0000000000000)
    no_sign = np.int64(0x7FFFFFFFFFFFFFFF)
    minus_zero = np.int64(-0x8000000000000000)
    occ = occupied.ravel().view(np.uint8)
    values = cost.ravel()
    bits = values.view(np.int64)
    pairs = rec.view(np.complex128)
    border = complex(-inf, inf)  # g = −inf, w = +inf: blocked
    for c in range(width):
        pairs[c] = border
        pairs[(h + 1) * width + c] = border
    lo = inf_bits
    hi = np.int64(0)
    nan = np.int64(0)
    negative = np.int64(0)
    for r in range(h):
        row = (r + 1) * width
        pairs[row] = border
        pairs[row + width - 1] = border
        src = r * w
        for c in range(w):
            e = values[src + c]
            x = bits[src + c]
            nan |= np.int64((x & no_sign) > inf_bits)
            negative |= np.int64((x < 0) & (x != minus_zero))
            blocked = (occ[src + c] != 0) | (x == inf_bits)
            pairs[row + 1 + c] = border if blocked else complex(inf, 0.5 + 0.5 * e)
            lo = min(lo, inf_bits if blocked else x)
            hi = max(hi, np.int64(0) if blocked else x)
    extremes = np.empty(2, np.int64)
    extremes[0] = lo
    extremes[1] = hi
    lo_hi = extremes.view(np.float64)
    if nan:
        return COSTS_NAN, lo_hi[0], lo_hi[1]
    return (COSTS_NEGATIVE if negative else COSTS_OK), lo_hi[0], lo_hi[1]


@njit(cache=True, inline="always")
def _sift_up(
    keys: NDArray[np.float64], items: NDArray[np.int64], pos: NDArray[np.int64], i: np.uint64, key: float, item: int
) -> None:  # pragma: no cover - compiled
    """Place (key, item) at the hole ``i`` of the indexed 4-ary heap, moving larger parents down."""
    one = np.uint64(1)
    two = np.uint64(2)
    while i > 0:
        p = (i - one) >> two
        kp = keys[p]
        if key < kp:
            keys[i] = kp
            moved = items[p]
            items[i] = moved
            pos[np.uint64(moved)] = i
            i = p
        else:
            break
    keys[i] = key
    items[i] = item
    pos[np.uint64(item)] = i


@njit(cache=True)
def _sift_down(
    keys: NDArray[np.float64], items: NDArray[np.int64], pos: NDArray[np.int64], size: int
) -> None:  # pragma: no cover - compiled
    """Finish a pop from the indexed 4-ary heap (``size`` ≥ 1 entries left, the old last one at index ``size``).

    As :func:`~mjnav.planning._kernels.heap4_sift_down` (bottom-up, branch-free choice of the smallest child),
    keeping ``pos`` (heap index of each node) up to date.
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
        moved = items[m]
        items[i] = moved
        pos[np.uint64(moved)] = i
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
        moved = items[m]
        items[i] = moved
        pos[np.uint64(moved)] = i
        i = m
    _sift_up(keys, items, pos, i, key, item)


@njit(cache=True)
def weighted_search(
    rec: NDArray[np.float64],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    alpha: float,
    beta: float,
    hcode: int,
    hscale: float,
    pos: NDArray[np.int64],
    keys: NDArray[np.float64],
    items: NDArray[np.int64],
) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """Best-first search with priority α·g + β·hscale·h over the pairs written by :func:`prepare_costs`.

    Args:
        rec: (g, w) pairs of the padded nodes (node of map cell (r, c) = (r + 1)·width + c + 1).
        width: padded width W + 2.
        start: start node (free).
        goal: goal node (free, ≠ start).
        n_moves: 4 or 8.
        corner_cutting: allow diagonal steps past blocked orthogonal cells.
        alpha: weight of g.
        beta: weight of h.
        hcode: heuristic code (:data:`mjnav.planning.heuristics.HEURISTIC_CODES`).
        hscale: factor on the heuristic, 1 + the smallest free-cell cost.
        pos: int64 per node, its index in the heap while it is open (−1 when it waits on the LIFO stack); read
            only for open nodes, so it needs no initialisation.
        keys: heap storage (priorities).
        items: heap storage (nodes).

    Returns:
        (g of the goal, number of expanded nodes, status: FOUND, NOT_FOUND or OVERFLOW when the heap is full).
    """
    inf = np.inf
    one = np.uint64(1)
    offs = np.empty(8, np.int64)
    lens = np.empty(8, np.float64)
    for k in range(8):
        offs[k] = MOVE_DR[k] * width + MOVE_DC[k]
        lens[k] = SQRT2 if k >= 4 else 1.0
    gr = goal // width
    gc = goal - gr * width
    rec[2 * start] = 0.0
    _sift_up(keys, items, pos, np.uint64(0), 0.0, start)
    size = 1
    expanded = 0
    bypass = alpha == beta
    fast = np.empty(64, np.int64)
    nfast = 0
    fkey = 0.0
    up = np.uint64(2 * width)
    fn = fs = fw = fe = True
    while size > 0 or nfast > 0:
        if nfast > 0:
            nfast -= 1
            cur = fast[nfast]
        else:
            fkey = keys[0]
            cur = items[0]
            size -= 1
            if size > 0:
                _sift_down(keys, items, pos, size)
        cu = np.uint64(2 * cur)
        g0 = rec[cu]
        if g0 < 0.0:
            continue  # closed: a stale entry
        rec[cu] = -g0
        expanded += 1
        if cur == goal:
            return g0, expanded, FOUND
        w0 = rec[cu + one]
        cr = cur // width
        cc = cur - cr * width
        if not corner_cutting:
            # Free orthogonal neighbours N, S, W, E (w finite): the diagonals need two of them.
            fn = rec[cu - up + one] != inf
            fs = rec[cu + up + one] != inf
            fw = rec[cu - one] != inf
            fe = rec[cu + np.uint64(3)] != inf
        for k in range(n_moves):
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
            nb = cur + offs[k]
            j = np.uint64(2 * nb)
            ng = g0 + lens[k] * (w0 + rec[j + one])
            old = rec[j]
            if ng < old:  # false for closed (g < 0) and blocked (g = −inf, w = +inf) nodes
                if size == keys.shape[0]:
                    return inf, expanded, OVERFLOW
                rec[j] = ng
                h = heuristic_value(hcode, float(abs(cr + MOVE_DR[k] - gr)), float(abs(cc + MOVE_DC[k] - gc)))
                key = alpha * ng + beta * (hscale * h)
                if old != inf and pos[nb] >= 0:  # open, on the heap: decrease its key
                    _sift_up(keys, items, pos, np.uint64(pos[nb]), key, nb)
                elif bypass and key <= fkey + 1e-14 * (1.0 + fkey) and nfast < 64:
                    fast[nfast] = nb
                    nfast += 1
                    pos[nb] = -1
                else:
                    _sift_up(keys, items, pos, np.uint64(size), key, nb)
                    size += 1
    return inf, expanded, NOT_FOUND


@njit(cache=True)
def bucket_search(
    rec: NDArray[np.float64],
    width: int,
    start: int,
    goal: int,
    n_moves: int,
    corner_cutting: bool,
    hweight: float,
    hcode: int,
    delta: float,
    entries: NDArray[np.int64],
    links: NDArray[np.int64],
    heads: NDArray[np.int64],
) -> tuple[float, int, int]:  # pragma: no cover - compiled
    """Optimal search with priority f = g + hweight·h in buckets of width ``delta`` (see the module docstring).

    The heuristic must be consistent (f never decreases along an edge), ``hweight·h`` a lower bound of the
    remaining cost, and every key pushed less than ``heads.shape[0]·delta`` above the current bucket's start.

    Args:
        rec: (g, w) pairs from :func:`prepare_costs`.
        width: padded width W + 2.
        start: start node (free).
        goal: goal node (free, ≠ start).
        n_moves: 4 or 8.
        corner_cutting: allow diagonal steps past blocked orthogonal cells.
        hweight: factor on the heuristic (0 for Dijkstra).
        hcode: heuristic code (:data:`mjnav.planning.heuristics.HEURISTIC_CODES`).
        delta: bucket width, cost units.
        entries: bucket entries (nodes), the entry pool.
        links: next entry in the same bucket (or in the free list), one per pool slot.
        heads: first entry of each bucket of the circular bucket array (its length, a power of two); any content.

    Returns:
        (g of the goal, number of expansions (a node whose g improved after its expansion counts again),
        status: FOUND, NOT_FOUND, OVERFLOW when the pool is full, or :data:`OUT_OF_WINDOW`).
    """
    inf = np.inf
    one = np.uint64(1)
    mask = heads.shape[0] - 1
    heads[:] = -1
    offs = np.empty(8, np.int64)
    lens = np.empty(8, np.float64)
    for k in range(8):
        offs[k] = MOVE_DR[k] * width + MOVE_DC[k]
        lens[k] = SQRT2 if k >= 4 else 1.0
    inv = 1.0 / delta
    octile = hcode == 3
    gr = goal // width
    gc = goal - gr * width
    sr = start // width
    sc = start - sr * width
    rec[2 * start] = 0.0
    cur_b = int(hweight * heuristic_value(hcode, float(abs(sr - gr)), float(abs(sc - gc))) * inv)
    entries[0] = start
    links[0] = -1
    heads[cur_b & mask] = 0
    used = 1  # pool slots handed out so far; freed slots are chained from free
    free = -1
    count = 1  # entries in the buckets
    expanded = 0
    g_goal = inf
    g_cut = inf
    all_moves = 255
    up = np.uint64(2 * width)
    stop_b = np.iinfo(np.int64).max  # the bucket after the goal's, once the goal is reached
    while count > 0 and cur_b < stop_b:
        b = cur_b & mask
        e = heads[b]
        if e < 0:
            cur_b += 1
            continue
        nxt = links[e]
        heads[b] = nxt
        links[e] = free
        free = e
        count -= 1
        cur = entries[e]
        if nxt >= 0:  # the next node of this bucket: load its neighbourhood while this one is expanded
            p0 = 2 * (entries[nxt] - width - 1)
            prefetch(rec, p0)
            prefetch(rec, p0 + 5)
            prefetch(rec, p0 + 2 * width)
            prefetch(rec, p0 + 2 * width + 5)
            prefetch(rec, p0 + 4 * width)
            prefetch(rec, p0 + 4 * width + 5)
        cu = np.uint64(2 * cur)
        g0 = rec[cu]
        if g0 < 0.0 or (g0 == 0.0 and expanded > 0):
            continue  # expanded with its current g already (−0.0: the start): a stale entry
        cr = cur // width
        cc = cur - cr * width
        if g_cut < inf and g0 + hweight * heuristic_value(hcode, float(abs(cr - gr)), float(abs(cc - gc))) >= g_cut:
            rec[cu] = -g0  # cannot lead to a cheaper goal path (within GOAL_TOLERANCE): not expanded, but an
            continue  # improvement must push it again (its entry is gone), as for an expanded node
        rec[cu] = -g0
        expanded += 1
        w0 = rec[cu + one]
        allowed = all_moves
        if not corner_cutting:
            fn = int(rec[cu - up + one] != inf)
            fs = int(rec[cu + up + one] != inf)
            fw = int(rec[cu - one] != inf)
            fe = int(rec[cu + np.uint64(3)] != inf)
            allowed = 15 | ((fn & fw) << 4) | ((fn & fe) << 5) | ((fs & fw) << 6) | ((fs & fe) << 7)
        for k in range(n_moves):
            if not (allowed >> k) & 1:
                continue
            nb = cur + offs[k]
            j = np.uint64(2 * nb)
            ng = g0 + lens[k] * (w0 + rec[j + one])
            old = rec[j]
            # An improvement (false for blocked nodes: w = +inf, so ng = +inf); an expanded node (g < 0) must
            # improve by more than REOPEN_TOLERANCE to be expanded again.
            if ng < abs(old) and (old > 0.0 or ng < old * (REOPEN_TOLERANCE - 1.0)):
                rec[j] = ng
                if nb == goal:
                    g_goal = ng
                    g_cut = ng * (1.0 - GOAL_TOLERANCE)
                    stop_b = int(ng * inv) + 1
                    continue
                hr = float(abs(cr + MOVE_DR[k] - gr))
                hc = float(abs(cc + MOVE_DC[k] - gc))
                h = max(hr, hc) + (SQRT2 - 1.0) * min(hr, hc) if octile else heuristic_value(hcode, hr, hc)
                nb_b = max(int((ng + hweight * h) * inv), cur_b)  # (a key a few ulps below the bucket: this one)
                if old < inf and old > 0.0 and max(int((old + hweight * h) * inv), cur_b) == nb_b:
                    continue  # open (g > 0: it has an entry), and that entry is in the same bucket
                if nb_b - cur_b > mask:
                    return inf, expanded, OUT_OF_WINDOW
                if free >= 0:
                    slot = free
                    free = links[slot]
                elif used < entries.shape[0]:
                    slot = used
                    used += 1
                else:
                    return inf, expanded, OVERFLOW
                entries[slot] = nb
                links[slot] = heads[nb_b & mask]
                heads[nb_b & mask] = slot
                count += 1
    if g_goal < inf:
        return g_goal, expanded, FOUND
    return inf, expanded, NOT_FOUND


@njit(cache=True)
def trace_back(
    rec: NDArray[np.float64], width: int, start: int, goal: int, n_moves: int, corner_cutting: bool
) -> NDArray[np.int64]:  # pragma: no cover - compiled
    """(N, 2) (row, col) cells of the unpadded map from ``start`` to ``goal``, read back from the g values.

    The searches keep no parent links: a node's g was set as g(u) + d·(w(u) + w(v)) by the neighbour u that
    reached it, which was expanded at the time and kept that g (or, in the bucket search, improved it and then
    improved the node too). So from the goal each step back goes to a neighbour u, reached by a legal move, with
    exactly that sum; should rounding leave none (improvements smaller than an ulp), to the neighbour with the
    smallest such sum below the node's g. g decreases strictly along the way, so it ends at the start.
    """
    inf = np.inf
    up = 2 * width
    cells = np.empty((64, 2), np.int64)
    count = 0
    node = goal
    while True:
        if count == cells.shape[0]:
            grown = np.empty((2 * count, 2), np.int64)
            grown[:count] = cells
            cells = grown
        r = node // width
        cells[count, 0] = r - 1
        cells[count, 1] = node - r * width - 1
        count += 1
        if node == start:
            break
        j = 2 * node
        g = abs(rec[j])
        w = rec[j + 1]
        fn = rec[j - up + 1] != inf
        fs = rec[j + up + 1] != inf
        fw = rec[j - 1] != inf
        fe = rec[j + 3] != inf
        best = -1
        best_g = g
        for k in range(n_moves):
            if k >= 4 and not corner_cutting:
                # The move u → node passes the cells beside node opposite to its direction.
                ok = (fn if MOVE_DR[k] > 0 else fs) and (fw if MOVE_DC[k] > 0 else fe)
                if not ok:
                    continue
            u = node - (MOVE_DR[k] * width + MOVE_DC[k])
            ju = 2 * u
            via = abs(rec[ju]) + (SQRT2 if k >= 4 else 1.0) * (rec[ju + 1] + w)
            if via == g:
                best = u
                break
            if via < best_g:
                best = u
                best_g = via
        if best < 0:
            raise RuntimeError("trace_back: a reached node without a predecessor")
        node = best
    out = np.empty((count, 2), np.int64)
    for i in range(count):
        out[i] = cells[count - 1 - i]
    return out
