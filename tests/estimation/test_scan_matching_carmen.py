"""CARMEN reader, ``mjnav scanmatch`` and consecutive-scan matching on the Intel log (refdata)."""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.cli import main
from mjnav.commands.scanmatch import evaluate_consecutive, perturbations, relative_poses
from mjnav.estimation import CarmenFormatError, parse_carmen, read_carmen
from tests.estimation._scans import ROOM, raycast

SAMPLE = """# CARMEN Logfile
PARAM robot_frontlaser_offset 0.0 nohost 0
ODOM 0 0 0 0 0 0 0.000246 pippo 0.000246
FLASER 4 1.0 2.0 81.83 0.5 0.6 -0.03 -0.35 0.61 -0.02 -0.34 32.9 pippo 32.91
NEFF 15
FLASER 4 1.5 2.5 3.5 4.5 0.7 -0.10 -0.94 0.71 -0.11 -0.93 35.1 pippo 35.11
"""


def test_parse_inline_sample() -> None:
    log = parse_carmen(SAMPLE.splitlines())
    assert len(log) == 2
    assert log.ranges.shape == (2, 4)
    assert np.allclose(log.angles, [-math.pi / 2, -math.pi / 4, 0.0, math.pi / 4])
    assert np.allclose(log.poses[1], [0.7, -0.10, -0.94])
    assert np.allclose(log.odometry[0], [0.61, -0.02, -0.34])
    assert np.allclose(log.timestamps, [32.9, 35.1])
    pts = log.points(0, max_range_m=80.0)  # 81.83 is no-return
    assert pts.shape == (3, 2)
    assert np.allclose(pts[0], [0.0, -1.0], atol=1e-12)


@pytest.mark.parametrize(
    "text",
    [
        "ODOM 0 0 0\n",  # no FLASER
        "FLASER 3 1.0 2.0 0 0 0 0 0 0 1.0 h 1.0\n",  # too few fields
        "FLASER 2 1.0 x 0 0 0 0 0 0 1.0 h 1.0\n",  # not a number
        "FLASER 2 1 1 0 0 0 0 0 0 1 h 1\nFLASER 3 1 1 1 0 0 0 0 0 0 1 h 1\n",  # beam count changes
    ],
)
def test_malformed_logs_raise(text: str) -> None:
    with pytest.raises(CarmenFormatError):
        parse_carmen(text.splitlines())


def test_read_real_intel_log(refdata: Path) -> None:
    log = read_carmen(refdata / "laser2d_carmen" / "intel-corrected.log.gz")
    assert len(log) == 910
    assert log.ranges.shape == (910, 180)
    assert np.allclose(log.poses[0], [0.600266, -0.0320327, -0.354665])
    assert log.angles[0] == pytest.approx(-math.pi / 2) and log.angles[-1] == pytest.approx(math.radians(89))


def test_intel_consecutive_scans_plicp(refdata: Path) -> None:
    """First 200 consecutive pairs, initial error 10 cm / 5°: success > 65 % and median error < 2.9 cm."""
    log = read_carmen(refdata / "laser2d_carmen" / "intel-corrected.log.gz")
    summary = evaluate_consecutive(log, "plicp", limit=200, init_error=(0.1, 5.0), seed=0).summary()
    assert summary["pairs"] == 200
    assert summary["success_rate"] > 0.65
    assert summary["median_trans_error_m"] < 0.029


def test_perturbations_have_the_requested_size() -> None:
    d = perturbations(50, (0.1, 5.0), seed=1)
    assert np.allclose(np.hypot(d[:, 0], d[:, 1]), 0.1)
    assert np.allclose(np.abs(d[:, 2]), math.radians(5.0))
    assert np.array_equal(d, perturbations(50, (0.1, 5.0), seed=1))


def test_relative_poses() -> None:
    p = np.array([[1.0, 2.0, math.pi / 2], [1.0, 3.0, math.pi]])
    assert np.allclose(relative_poses(p), [[1.0, 0.0, math.pi / 2]])


def _write_log(path: Path, n: int) -> None:
    """A CARMEN log of a robot driving through the synthetic room, 180 beams over 180°."""
    lines = []
    for i in range(n):
        pose = (2.0 + 0.05 * i, 1.5 + 0.02 * i, 0.3 + 0.01 * i)
        # raycast spreads 180 beams over ±89.5°; turned by −0.5° they fall on CARMEN's −90° + k·1°.
        _, r = raycast(ROOM, (pose[0], pose[1], pose[2] - math.radians(0.5)), 180, fov_rad=math.radians(179))
        r = np.where(np.isfinite(r), r, 81.83)
        vals = " ".join(f"{v:.4f}" for v in r)
        p = f"{pose[0]:.6f} {pose[1]:.6f} {pose[2]:.6f}"
        lines.append(f"FLASER 180 {vals} {p} {p} {i * 0.2:.3f} test {i * 0.2:.3f}")
    with gzip.open(path, "wt") as fh:
        fh.write("\n".join(lines) + "\n")


def test_cli_scanmatch_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "room.log.gz"
    _write_log(log, 6)
    code = main(["scanmatch", str(log), "--method", "plicp", "--init-error", "0.05,2", "--seed", "1", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["pairs"] == 5 and out["method"] == "plicp"
    assert out["success_rate"] == 1.0
    assert out["median_trans_error_m"] < 0.005


def test_cli_scanmatch_limit_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "room.log.gz"
    _write_log(log, 6)
    assert main(["scanmatch", str(log), "--limit", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["pairs"] == 2
    assert main(["scanmatch", str(tmp_path / "missing.log")]) == 2
    bad = tmp_path / "bad.log"
    bad.write_text("FLASER 2 x\n")
    assert main(["scanmatch", str(bad)]) == 2
    assert "error" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["scanmatch", str(log), "--init-error", "0.1"])
    assert exc.value.code == 2
