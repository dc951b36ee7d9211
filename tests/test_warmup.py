"""``mjnav warmup`` compiles every cached numba kernel; a fresh process then loads them all without compiling."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

REPO = Path(__file__).resolve().parent.parent

_FRESH = """
from numba.core import event
from mjnav.warmup import uncompiled, warm
with event.install_recorder("numba:compile") as recorder:
    warm(lambda _line: None)
print(len(recorder.buffer))
print(",".join(uncompiled()))
"""


def test_warmup_covers_every_kernel_and_a_fresh_process_compiles_nothing() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "mjnav", "warmup", "--list-missing"], cwd=REPO, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "not compiled" not in done.stdout, done.stdout
    fresh = subprocess.run([sys.executable, "-c", _FRESH], cwd=REPO, capture_output=True, text=True)
    assert fresh.returncode == 0, fresh.stderr
    compiles, missing = fresh.stdout.splitlines()
    assert compiles == "0", f"a fresh process compiled {compiles} kernel(s) instead of loading them from the cache"
    assert missing == "", f"kernels with no cache: {missing}"
