"""g2o's text format for SE(2) pose graphs, at the edge of :mod:`mjnav.estimation.posegraph`.

Lines read: ``VERTEX_SE2 id x y θ``; ``EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33`` (the upper triangle of the
information matrix, row-major); ``FIX id`` (accepted and ignored: the optimiser always holds the first vertex);
blank lines and ``#`` comments. Any other tag is an error. Vertices are ordered by id. Where a file lists no
``VERTEX_SE2`` for some vertex (manhattan, CSAIL), its initial pose is composed from the odometry edge of the
previous vertex (``k−1 → k``, or ``k → k−1`` inverted); a file with no vertices at all starts at the origin.
"""

from __future__ import annotations

import math
from os import PathLike
from pathlib import Path

import numpy as np

from mjnav.estimation.posegraph import FloatArray, PoseGraph, PoseGraphError, odometry_guess

__all__ = ["G2OFormatError", "read_g2o", "write_g2o"]


class G2OFormatError(PoseGraphError):
    """A g2o file that cannot be read as an SE(2) pose graph (the message names the line)."""


def read_g2o(path: str | PathLike[str]) -> PoseGraph:
    """Read an SE(2) g2o file.

    Args:
        path: the ``.g2o`` file.

    Returns:
        A :class:`PoseGraph` whose poses are the file's vertices (composed from odometry where missing) and whose
        ``ids`` are the file's vertex ids, sorted.

    Raises:
        G2OFormatError: unreadable file, malformed or unsupported line, or a missing vertex with no odometry edge.
    """
    try:
        text = Path(path).read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise G2OFormatError(f"cannot read {path}: {exc}") from exc
    vertices: dict[int, tuple[float, float, float]] = {}
    edge_ids: list[tuple[int, int]] = []
    edge_vals: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        tag = parts[0]
        try:
            if tag == "VERTEX_SE2":
                if len(parts) != 5:
                    raise ValueError(f"expected 4 fields after VERTEX_SE2, got {len(parts) - 1}")
                vid = int(parts[1])
                if vid in vertices:
                    raise ValueError(f"vertex {vid} defined twice")
                vertices[vid] = (float(parts[2]), float(parts[3]), float(parts[4]))
            elif tag == "EDGE_SE2":
                if len(parts) != 12:
                    raise ValueError(f"expected 11 fields after EDGE_SE2, got {len(parts) - 1}")
                edge_ids.append((int(parts[1]), int(parts[2])))
                edge_vals.append([float(v) for v in parts[3:]])
            elif tag == "FIX":
                int(parts[1])
            else:
                raise ValueError(f"unsupported tag {tag!r} (only VERTEX_SE2, EDGE_SE2, FIX)")
        except (ValueError, IndexError) as exc:
            raise G2OFormatError(f"{path}:{number}: {exc}") from None
    if not vertices and not edge_ids:
        raise G2OFormatError(f"{path}: no VERTEX_SE2 or EDGE_SE2 lines")
    eids = np.asarray(edge_ids, dtype=np.int64).reshape(-1, 2)
    vals = np.asarray(edge_vals, dtype=np.float64).reshape(-1, 9)
    ids = np.unique(np.concatenate([np.fromiter(vertices.keys(), dtype=np.int64, count=len(vertices)), eids.ravel()]))
    edges = np.searchsorted(ids, eids)
    info = np.empty((len(vals), 3, 3))
    upper = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    for k, (a, b) in enumerate(upper):
        info[:, a, b] = vals[:, 3 + k]
        info[:, b, a] = vals[:, 3 + k]
    known = np.isin(ids, np.fromiter(vertices.keys(), dtype=np.int64, count=len(vertices)))
    poses = np.zeros((ids.size, 3))
    for idx in np.flatnonzero(known).tolist():
        poses[idx] = vertices[int(ids[idx])]
    try:
        graph = PoseGraph(poses, edges, vals[:, :3], info, ids)
        if not known.all():
            graph = graph.with_poses(_fill_missing(graph, known))
    except PoseGraphError as exc:
        raise G2OFormatError(f"{path}: {exc}") from None
    return graph


def _fill_missing(graph: PoseGraph, known: np.ndarray) -> FloatArray:
    """Poses of the vertices a file did not list, composed by odometry from the previous vertex."""
    odo = odometry_guess(graph) if not known[1:].any() else None
    if odo is not None:  # no vertex after the first: one vectorised composition
        return odo
    poses = graph.poses.copy()
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    for k in np.flatnonzero(~known):
        if k == 0:
            continue  # the first vertex defaults to the origin
        fwd = np.flatnonzero((i == k - 1) & (j == k))
        if fwd.size:
            dx, dy, dth = graph.measurements[fwd[0]]
        else:
            back = np.flatnonzero((i == k) & (j == k - 1))
            if not back.size:
                raise PoseGraphError(f"vertex {graph.ids[k]} has no pose and no odometry edge from {graph.ids[k - 1]}")
            bx, by, bth = graph.measurements[back[0]]
            c, s = math.cos(bth), math.sin(bth)
            dx, dy, dth = -(c * bx + s * by), -(-s * bx + c * by), -bth
        x, y, th = poses[k - 1]
        c, s = math.cos(th), math.sin(th)
        poses[k] = (x + c * dx - s * dy, y + s * dx + c * dy, math.remainder(th + dth, 2 * math.pi))
    return poses


def write_g2o(
    path: str | PathLike[str] | PoseGraph, graph: PoseGraph | str | PathLike[str], poses: FloatArray | None = None
) -> None:
    """Write a pose graph as g2o text (full precision: reading it back gives the same numbers).

    Args:
        path: the output file (``write_g2o(graph, path)`` is accepted too).
        graph: the pose graph (ids, edges, measurements, information).
        poses: (N, 3) poses to write instead of the graph's own (e.g. an optimiser's result).
    """
    if isinstance(path, PoseGraph) and not isinstance(graph, PoseGraph):
        path, graph = graph, path
    if not isinstance(graph, PoseGraph) or isinstance(path, PoseGraph):
        raise PoseGraphError("write_g2o needs a path and a PoseGraph")
    p = graph.poses if poses is None else np.asarray(poses, dtype=np.float64)
    if p.shape != graph.poses.shape:
        raise PoseGraphError(f"poses must be {graph.poses.shape}, got {p.shape}")
    lines = [
        f"VERTEX_SE2 {vid} {x!r} {y!r} {th!r}" for vid, (x, y, th) in zip(graph.ids.tolist(), p.tolist(), strict=True)
    ]
    info = graph.information
    upper = np.stack([info[:, 0, 0], info[:, 0, 1], info[:, 0, 2], info[:, 1, 1], info[:, 1, 2], info[:, 2, 2]], 1)
    ids = graph.ids[graph.edges]
    for (a, b), z, u in zip(ids.tolist(), graph.measurements.tolist(), upper.tolist(), strict=True):
        lines.append(f"EDGE_SE2 {a} {b} " + " ".join(repr(v) for v in (*z, *u)))
    try:
        Path(path).write_text("\n".join(lines) + "\n")
    except OSError as exc:
        raise G2OFormatError(f"cannot write {path}: {exc}") from exc
