"""Jump point search internals: the 64-cells-at-a-time horizontal jump equals the cell-by-cell one."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.planning.grid import pad_blocked
from mjnav.planning.jps import _jump_straight, jump_horizontal, pack_rows


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("density", [0.02, 0.2, 0.5])
def test_bit_jump_matches_cell_by_cell_jump(seed: int, density: float) -> None:
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(3, 12)), int(rng.integers(60, 300))  # rows spanning several 64-bit words
    padded = pad_blocked(rng.random((h, w)) < density)
    width = w + 2
    flat = padded.ravel()
    bits, words = pack_rows(padded)
    free = np.argwhere(padded == 0)
    for r, c in free[rng.choice(len(free), min(200, len(free)), replace=False)]:
        r, c = int(r), int(c)
        for dc in (-1, 1):
            # Goal: on this row ahead, on this row behind, or elsewhere.
            gc = int(rng.integers(1, w + 1))
            gr = r if rng.random() < 0.5 else int(rng.integers(1, h + 1))
            goal = gr * width + gc
            node, k_ref = _jump_straight(flat, r * width + c, dc, width, goal)
            col, k = jump_horizontal(bits, words, r, c, dc, gr, gc)
            assert k == k_ref, (r, c, dc, gr, gc)
            assert (col < 0) == (node < 0)
            if node >= 0:
                assert col == node - r * width
