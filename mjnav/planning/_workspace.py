"""Per-thread search memory reused across queries (internal).

A search over a padded grid of n nodes needs per-node state (cost-so-far, parent, open/closed). Allocating and
initialising it for every query costs O(n) and, for large maps, mostly page faults on fresh memory — more
than a whole long search on a 256×256 map. Instead each thread keeps one :class:`Workspace` that grows to the
largest grid seen (up to :data:`MAX_CACHED_NODES`; larger grids get a throw-away workspace). Node records carry
a *tag* naming the search that wrote them (see :mod:`mjnav.planning._kernels`), so records of earlier searches
read as unvisited and starting a search is O(1): ``base += TAG_SPAN``.

Memory per node: 16 (record) + 8 (BFS queue) + 1 (map copy) bytes, plus the heap (24 bytes per entry,
initially n / 4 entries, doubled on overflow), once jump point search has run its two bit grids (about
1/4 byte per node) and once a search with a cost grid has run its (g, w) pairs and heap positions
(24 bytes per node, see :mod:`mjnav.planning._weighted`).
"""

from __future__ import annotations

import threading

import numpy as np
from numpy.typing import NDArray

from mjnav.planning._kernels import NODE_DTYPE, TAG_SPAN
from mjnav.planning._weighted import N_BUCKETS

#: Grids up to this many (padded) nodes keep their workspace between calls (≈ 31 bytes per node).
MAX_CACHED_NODES = 1 << 24

_TAG_LIMIT = int(np.iinfo(np.int32).max) - 2 * TAG_SPAN


class Workspace:
    """Reusable per-node arrays for one thread; see the module docstring.

    Attributes:
        capacity: number of nodes the arrays hold.
        nodes: node records (:data:`~mjnav.planning._kernels.NODE_DTYPE`).
        queue: int64 FIFO storage (BFS), one slot per node.
        blocked: uint8 padded grid buffer.
        bits, tbits: uint64 buffers for the bit rows and bit columns of jump point search, grown on demand by
            :meth:`bit_grids`.
        rec, pos: float64 (g, w) pairs and int64 heap positions of the cost-grid searches, grown on demand by
            :meth:`cost_grids`.
        heads: bucket heads of the cost-grid bucket search.
        keys, subs, items: binary-heap storage (``items`` doubles as the DFS stack and, with ``links``, as the
            entry pool of the cost-grid bucket search); a kernel that fills it reports an overflow and the caller
            retries after :meth:`grow_heap`.
        links: int64, as long as ``items``: next-entry links of the bucket search.
        base: the tag base of the current search.
    """

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.nodes: NDArray[np.void] = np.zeros(capacity, NODE_DTYPE)
        self.queue: NDArray[np.int64] = np.empty(capacity, np.int64)
        self.blocked: NDArray[np.uint8] = np.empty(capacity, np.uint8)
        self.bits: NDArray[np.uint64] = np.empty(0, np.uint64)
        self.tbits: NDArray[np.uint64] = np.empty(0, np.uint64)
        self.rec: NDArray[np.float64] = np.empty(0, np.float64)
        self.pos: NDArray[np.int64] = np.empty(0, np.int64)
        self.heads: NDArray[np.int64] = np.empty(N_BUCKETS, np.int64)
        heap = max(1024, capacity // 4)
        self.keys: NDArray[np.float64] = np.empty(heap, np.float64)
        self.subs: NDArray[np.float64] = np.empty(heap, np.float64)
        self.items: NDArray[np.int64] = np.empty(heap, np.int64)
        self.links: NDArray[np.int64] = np.empty(heap, np.int64)
        self.base = 0

    def begin(self) -> int:
        """Start a new search: returns its tag base (tags of older searches are all smaller)."""
        self.base += TAG_SPAN
        if self.base >= _TAG_LIMIT:
            self.nodes["tag"] = 0
            self.base = TAG_SPAN
        return self.base

    def bit_grids(self, n_bits: int, n_tbits: int) -> tuple[NDArray[np.uint64], NDArray[np.uint64]]:
        """The bit-row and bit-column buffers, grown to at least ``n_bits`` and ``n_tbits`` words."""
        if self.bits.shape[0] < n_bits:
            self.bits = np.empty(n_bits, np.uint64)
        if self.tbits.shape[0] < n_tbits:
            self.tbits = np.empty(n_tbits, np.uint64)
        return self.bits, self.tbits

    def cost_grids(self, n_nodes: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """The (g, w) pair and heap-position buffers of the cost-grid searches, for at least ``n_nodes`` nodes."""
        if self.pos.shape[0] < n_nodes:
            self.rec = np.empty(2 * n_nodes, np.float64)
            self.pos = np.empty(n_nodes, np.int64)
        return self.rec, self.pos

    def grow_heap(self) -> None:
        """Double the heap (DFS stack, bucket pool) storage; its contents are discarded."""
        n = 2 * self.keys.shape[0]
        self.keys = np.empty(n, np.float64)
        self.subs = np.empty(n, np.float64)
        self.items = np.empty(n, np.int64)
        self.links = np.empty(n, np.int64)


_local = threading.local()


def get_workspace(n_nodes: int) -> Workspace:
    """The calling thread's workspace with room for ``n_nodes`` nodes (a fresh one above the cache limit)."""
    if n_nodes > MAX_CACHED_NODES:
        return Workspace(n_nodes)
    ws: Workspace | None = getattr(_local, "ws", None)
    if ws is None or ws.capacity < n_nodes:
        ws = Workspace(max(n_nodes, 1024))
        _local.ws = ws
    return ws


def release_workspace() -> None:
    """Drop the calling thread's cached workspace (frees its memory)."""
    _local.ws = None
