"""Jump point search internals against plain reference implementations: the grid packing, the 63-cells-at-a-time
jumps along bit rows and bit columns, the successor table and the 4-ary heap."""

from __future__ import annotations

import heapq

import numpy as np
import pytest

from mjnav.planning._kernels import MOVE_DC, MOVE_DR, NO_ARRIVAL, heap4_push, heap4_sift_down
from mjnav.planning.jps import SUCCESSORS, grid_layout, jump, prepare_grid


def prepared(occ: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, int]:
    """(grid, bits, words, tbits, twords) of a map, as plan_grid builds them."""
    h, w = occ.shape
    stride, words, twords = grid_layout(h, w)
    grid = np.full((h + 2, stride), 7, np.uint8)  # junk: prepare_grid must overwrite every cell
    bits = np.zeros((h + 2) * words + 5, np.uint64)  # longer than needed, like a reused workspace buffer
    tbits = np.zeros(stride * twords + 5, np.uint64)
    prepare_grid(np.ascontiguousarray(occ), grid, bits, tbits)
    return grid, bits, words, tbits, twords


def unpack(bits: np.ndarray, lines: int, words: int) -> np.ndarray:
    return np.unpackbits(bits[: lines * words].view(np.uint8).reshape(lines, words * 8), axis=1, bitorder="little")


@pytest.mark.parametrize("seed", range(8))
def test_prepare_grid_pads_and_packs_rows_and_columns(seed: int) -> None:
    rng = np.random.default_rng(seed)
    h, w = [(1, 1), (3, 70), (70, 3), (64, 62), (130, 9), (9, 130), (200, 141), (62, 64)][seed]
    occ = rng.random((h, w)) < 0.3
    grid, bits, words, tbits, twords = prepared(occ)
    stride = grid.shape[1]
    assert stride % 8 == 0 and stride >= w + 2
    ref = np.ones((h + 2, stride), np.uint8)
    ref[1:-1, 1 : w + 1] = occ
    assert np.array_equal(grid, ref)
    rows = unpack(bits, h + 2, words)
    assert np.array_equal(rows[:, 64 : 64 + stride], ref)
    assert rows[:, :64].all() and rows[:, 64 + stride :].all()  # guard words and bits past the grid: blocked
    cols = unpack(tbits, stride, twords)
    assert np.array_equal(cols[:, 64 : 64 + h + 2], ref.T)
    assert cols[:, :64].all() and cols[:, 64 + h + 2 :].all()


def scan(padded: np.ndarray, r: int, c: int, dr: int, dc: int, goal: tuple[int, int]) -> tuple[int, int]:
    """Cell-by-cell straight jump (the reference): (stop cell's position along the line or −1, steps)."""
    k = 0
    while True:
        r += dr
        c += dc
        k += 1
        if padded[r, c]:
            return -1, k
        if (r, c) == goal:
            break
        # Forced: a side cell free next to a blocked cell behind it.
        sr, sc = dc, dr
        if (padded[r - dr + sr, c - dc + sc] and not padded[r + sr, c + sc]) or (
            padded[r - dr - sr, c - dc - sc] and not padded[r - sr, c - sc]
        ):
            break
    return (c if dr == 0 else r), k


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("density", [0.02, 0.2, 0.5])
@pytest.mark.parametrize("vertical", [False, True])
def test_bit_jumps_match_cell_by_cell_scan(seed: int, density: float, vertical: bool) -> None:
    rng = np.random.default_rng(seed)
    long_side, short_side = int(rng.integers(60, 300)), int(rng.integers(3, 12))  # lines spanning several words
    shape = (long_side, short_side) if vertical else (short_side, long_side)
    occ = rng.random(shape) < density
    grid, bits, words, tbits, twords = prepared(occ)
    free = np.argwhere(grid == 0)
    for r, c in free[rng.choice(len(free), min(200, len(free)), replace=False)]:
        r, c = int(r), int(c)
        for d in (-1, 1):
            # Goal: on this line (ahead or behind) or elsewhere.
            goal_free = free[rng.integers(len(free))]
            goal = (int(goal_free[0]), int(goal_free[1]))
            if rng.random() < 0.5:
                goal = (goal[0], c) if vertical else (r, goal[1])
            if vertical:
                ref = scan(grid, r, c, d, 0, goal)
                got = jump(tbits, twords, c, r, d, goal[1], goal[0])
            else:
                ref = scan(grid, r, c, 0, d, goal)
                got = jump(bits, words, r, c, d, goal[0], goal[1])
            assert got == ref, (r, c, d, goal)


def reference_successors(arrival: int, nb: int) -> int:
    """Successor moves of a node by the pruning rules, spelt out on a 3×3 window (1 = blocked)."""
    win = np.zeros((3, 3), bool)
    for k in range(8):
        win[1 + MOVE_DR[k], 1 + MOVE_DC[k]] = (nb >> k) & 1

    def free(dr: int, dc: int) -> bool:
        return not win[1 + dr, 1 + dc]

    if arrival == NO_ARRIVAL:
        moves = [(int(MOVE_DR[k]), int(MOVE_DC[k])) for k in range(8)]
    else:
        dr, dc = int(MOVE_DR[arrival]), int(MOVE_DC[arrival])
        if dr and dc:
            moves = [(dr, 0), (0, dc), (dr, dc)]
        elif dc:  # horizontal: rows above and below
            moves = [(0, dc)]
            for side in (-1, 1):
                if not free(side, -dc) and free(side, 0):
                    moves += [(side, 0), (side, dc)]
        else:  # vertical: columns left and right
            moves = [(dr, 0)]
            for side in (-1, 1):
                if not free(-dr, side) and free(0, side):
                    moves += [(0, side), (dr, side)]
    mask = 0
    for dr, dc in moves:
        legal = free(dr, dc) and (not (dr and dc) or (free(dr, 0) and free(0, dc)))
        if legal:
            k = next(k for k in range(8) if (MOVE_DR[k], MOVE_DC[k]) == (dr, dc))
            mask |= 1 << k
    return mask


def test_successor_table_matches_the_pruning_rules() -> None:
    for arrival in range(9):
        for nb in range(256):
            assert SUCCESSORS[arrival * 256 + nb] == reference_successors(arrival, nb), (arrival, nb)


@pytest.mark.parametrize("seed", range(3))
def test_heap4_pops_keys_in_order(seed: int) -> None:
    rng = np.random.default_rng(seed)
    keys = np.empty(600)
    items = np.empty(600, np.int64)
    ref: list[float] = []
    live: dict[int, float] = {}
    size = 0
    for step in range(3000):
        if size < keys.shape[0] and (size == 0 or rng.random() < 0.55):
            key = float(rng.integers(0, 40)) * 0.5  # many ties
            size = heap4_push(keys, items, size, key, step)
            heapq.heappush(ref, key)
            live[step] = key
        else:
            top_key, top_item = float(keys[0]), int(items[0])
            size -= 1
            heap4_sift_down(keys, items, size)
            assert top_key == heapq.heappop(ref)
            assert live.pop(top_item) == top_key
    assert size == len(ref) == len(live)
