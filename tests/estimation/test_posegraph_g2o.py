"""g2o files: read, write, round trip, missing vertices, errors; and ``mjnav posegraph`` on a small file."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mjnav.cli import main
from mjnav.estimation import G2OFormatError, PoseGraph, read_g2o, sesync_objective, write_g2o

SMALL = """\
# a square driven once, closed by a loop closure
VERTEX_SE2 10 0 0 0
VERTEX_SE2 11 1.1 0.05 1.5
VERTEX_SE2 12 0.9 1.2 3.0
VERTEX_SE2 13 -0.1 0.9 -1.7
EDGE_SE2 10 11 1 0 1.5707963267948966 100 0 0 100 0 400
EDGE_SE2 11 12 1 0 1.5707963267948966 100 0 0 100 0 400
EDGE_SE2 12 13 1 0 1.5707963267948966 100 0 0 100 0 400
EDGE_SE2 13 10 1 0 1.5707963267948966 50 10 0 80 0 300
FIX 10
"""


def write(tmp_path: Path, text: str, name: str = "g.g2o") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_read_small_file(tmp_path: Path) -> None:
    graph = read_g2o(write(tmp_path, SMALL))
    np.testing.assert_array_equal(graph.ids, [10, 11, 12, 13])
    np.testing.assert_array_equal(graph.edges, [[0, 1], [1, 2], [2, 3], [3, 0]])
    np.testing.assert_allclose(graph.poses[2], [0.9, 1.2, 3.0])
    np.testing.assert_allclose(graph.information[3], [[50, 10, 0], [10, 80, 0], [0, 0, 300]])
    np.testing.assert_allclose(graph.measurements[0], [1, 0, math.pi / 2])


def test_round_trip_is_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    n, m = 30, 45
    edges = np.array([(k, k + 1) for k in range(n - 1)] + [(int(a), int(b)) for a, b in rng.integers(0, n, (16, 2))])
    edges = edges[edges[:, 0] != edges[:, 1]][:m]
    a = rng.standard_normal((edges.shape[0], 3, 3))
    info = a @ np.swapaxes(a, 1, 2) + 3 * np.eye(3)
    graph = PoseGraph(
        rng.standard_normal((n, 3)) * [10, 10, 1],
        edges,
        rng.standard_normal((edges.shape[0], 3)),
        (info + np.swapaxes(info, 1, 2)) / 2,
        ids=np.arange(n) * 3 + 7,
    )
    path = tmp_path / "rt.g2o"
    write_g2o(path, graph)
    back = read_g2o(path)
    for name in ("poses", "edges", "measurements", "information", "ids"):
        np.testing.assert_array_equal(getattr(back, name), getattr(graph, name), err_msg=name)
    # Other poses written in place of the graph's own.
    other = graph.poses + 1.0
    write_g2o(path, graph, other)
    np.testing.assert_array_equal(read_g2o(path).poses, other)
    write_g2o(graph, path)  # either argument order
    np.testing.assert_array_equal(read_g2o(path).poses, graph.poses)


def test_missing_vertices_compose_odometry(tmp_path: Path) -> None:
    text = "\n".join(line for line in SMALL.splitlines() if not line.startswith("VERTEX"))
    graph = read_g2o(write(tmp_path, text))
    expected = [[0, 0, 0], [1, 0, math.pi / 2], [1, 1, math.pi], [0, 1, -math.pi / 2]]
    np.testing.assert_allclose(graph.poses, expected, atol=1e-12)
    assert sesync_objective(graph) == pytest.approx(0.0, abs=1e-20)
    # Some vertices given: the missing one is composed from its predecessor's given pose.
    partial = (
        "VERTEX_SE2 0 5 5 0\nVERTEX_SE2 1 6 5 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 1 2 2 0 0.5 1 0 0 1 0 1\n"
    )
    graph = read_g2o(write(tmp_path, partial, "p.g2o"))
    np.testing.assert_allclose(graph.poses[2], [8, 5, 0.5])
    # An edge listed backwards (2 → 1) is inverted.
    backwards = (
        "VERTEX_SE2 1 0 0 0\nEDGE_SE2 2 1 -1 0 0 1 0 0 1 0 1\nVERTEX_SE2 0 -1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n"
    )
    graph = read_g2o(write(tmp_path, backwards, "b.g2o"))
    np.testing.assert_allclose(graph.poses[2], [1, 0, 0], atol=1e-12)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("VERTEX_SE2 0 1 2\n", r":1: expected 4 fields"),
        ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0\n", r":2: expected 11 fields"),
        ("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 0 1 0 0\n", r"defined twice"),
        ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n", r"unsupported tag"),
        ("VERTEX_SE2 0 a 0 0\n", r":1: could not convert"),
        ("# only a comment\n", r"no VERTEX_SE2 or EDGE_SE2"),
        ("EDGE_SE2 0 1 1 0 0 1 0 0 1 0 -1\n", r"not positive definite"),
        (
            "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 0 2 1 0 0 1 0 0 1 0 1\n",
            r"vertex 2 has no pose and no odometry edge",
        ),
    ],
)
def test_bad_files_raise(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(G2OFormatError, match=message):
        read_g2o(write(tmp_path, text))


def test_unreadable_file_raises(tmp_path: Path) -> None:
    with pytest.raises(G2OFormatError, match="cannot read"):
        read_g2o(tmp_path / "missing.g2o")


def test_cli_json_and_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write(tmp_path, SMALL)
    out = tmp_path / "opt.g2o"
    code = main(["posegraph", str(src), "--out", str(out), "--json"])
    assert code == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("vertices", "edges", "chi2", "sesync_objective", "iterations", "time_s"):
        assert key in res
    assert res["vertices"] == 4 and res["edges"] == 4
    # The loop closes exactly (four quarter turns of 1 m): both objectives vanish, from a noisy start.
    assert res["chi2"] < 1e-12 and res["sesync_objective"] < 1e-12
    assert res["initial_chi2"] > 1.0
    assert res["iterations"] >= 1 and res["time_s"] >= 0.0
    assert res["certified"] is True
    written = read_g2o(out)
    np.testing.assert_array_equal(written.ids, [10, 11, 12, 13])
    np.testing.assert_allclose(written.poses[:, :2], [[0, 0], [1, 0], [1, 1], [0, 1]], atol=1e-9)


def test_cli_robust_and_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = write(tmp_path, SMALL)
    assert main(["posegraph", str(src), "--robust", "huber", "--json"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["robust"] == "huber" and res["certified"] is None
    assert res["sesync_objective"] < 1e-12
    assert main(["posegraph", str(tmp_path / "nope.g2o")]) == 2
    assert "cannot read" in capsys.readouterr().err
    bad = write(tmp_path, "VERTEX_SE2 0 0 0\n", "bad.g2o")
    assert main(["posegraph", str(bad)]) == 2
    assert main(["posegraph", str(src), "--robust-width", "-1"]) == 2
    assert main(["posegraph", str(src)]) == 0
    text = capsys.readouterr().out
    assert "certified" in text and "SE-Sync F" in text


def test_cli_help_teaches(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["posegraph", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for phrase in ("SE-Sync", "chi2", "kappa = I33", "certificate", "GLOBAL", "lambda_min", "chordal"):
        assert phrase in text, phrase
