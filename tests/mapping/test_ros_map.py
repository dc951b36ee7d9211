"""ROS map_server files: write/read round trips, hand-made images in every mode, and malformed files."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from mjnav.mapping import (
    InvalidGridError,
    InvalidParameterError,
    MapFileError,
    OccupancyGrid,
    RosMap,
    read_ros_map,
    write_ros_map,
)


def test_write_then_read_round_trip(tmp_path: Path) -> None:
    occ = np.array([[0, 100, -1, 0], [100, 0, 0, -1], [-1, -1, 100, 100]], dtype=np.int8)
    written = write_ros_map(tmp_path / "office.yaml", occ, 0.05, (-1.5, 2.25, 0.1))
    assert written == tmp_path / "office.yaml"
    m = read_ros_map(written)
    np.testing.assert_array_equal(m.occupancy, occ)
    assert m.occupancy.dtype == np.int8
    assert m.resolution_m == 0.05
    assert m.origin_m == (-1.5, 2.25, 0.1)
    assert (m.occupied_thresh, m.free_thresh, m.negate, m.mode) == (0.65, 0.196, False, "trinary")
    assert m.image_path == tmp_path / "office.pgm"
    assert (m.width_cells, m.height_cells) == (4, 3)
    np.testing.assert_array_equal(m.occupied_mask(), occ == 100)
    np.testing.assert_array_equal(m.occupied_mask(unknown_is_occupied=True), occ != 0)
    np.testing.assert_array_equal(m.free_mask(), occ == 0)


def test_written_files_follow_map_saver_conventions(tmp_path: Path) -> None:
    occ = np.array([[0, 100, -1], [20, 21, 65]], dtype=np.int8)  # row 0 = lowest y
    write_ros_map(tmp_path / "m.yaml", occ, 0.1, (1.0, 2.0))
    doc = yaml.safe_load((tmp_path / "m.yaml").read_text())
    assert doc == {
        "image": "m.pgm",
        "mode": "trinary",
        "resolution": 0.1,
        "origin": [1.0, 2.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    raw = (tmp_path / "m.pgm").read_bytes()
    assert raw.startswith(b"P5\n")
    assert raw.endswith(b"3 2\n255\n" + bytes([254, 205, 0, 254, 0, 205]))
    # Image top row = map row 1 (highest y): 20 ≤ rint(100·0.196) = 20 → free (254); 21 → unknown (205);
    # 65 ≥ rint(100·0.65) → occupied (0). Bottom row = map row 0: 0 → 254, 100 → 0, −1 → 205.


def test_read_hand_made_ascii_pgm_with_comments_and_negate(tmp_path: Path) -> None:
    (tmp_path / "a.pgm").write_text("P2\n# a comment\n3 2 # inline\n10\n0 5 10\n2 # x\n 8 9\n")
    (tmp_path / "a.yaml").write_text(
        "image: a.pgm\nresolution: 0.5\norigin: [0, 0, 0]\nnegate: 1\noccupied_thresh: 0.7\nfree_thresh: 0.3\n"
    )
    m = read_ros_map(tmp_path / "a.yaml")
    # negate: occ = shade = v/10. Top image row (0, .5, 1) → map row 1: 0 < .3 free, .5 unknown, 1 > .7
    # occupied. Bottom image row (.2, .8, .9) → map row 0: free, occupied, occupied.
    np.testing.assert_array_equal(m.occupancy, [[0, 100, 100], [0, -1, 100]])
    assert m.mode == "trinary"
    assert m.negate


def test_read_scale_and_raw_modes(tmp_path: Path) -> None:
    pixels = bytes([255, 230, 128, 60, 0, 100])
    (tmp_path / "s.pgm").write_bytes(b"P5 3 2 255\n" + pixels)
    (tmp_path / "s.yaml").write_text(
        "image: s.pgm\nresolution: 1.0\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.25\nmode: scale\n"
    )
    m = read_ros_map(tmp_path / "s.yaml")
    # occ = 1 − v/255. Top image row (map row 1): 255, 230, 128 → occ 0, 0.098, 0.498 → free, free,
    # rint((0.498 − 0.25)/0.4·100) = 62. Bottom image row (map row 0): 60, 0, 100 → occ 0.765, 1, 0.608 →
    # 100, 100, rint(89.46) = 89.
    np.testing.assert_array_equal(m.occupancy, [[100, 100, 89], [0, 0, 62]])
    (tmp_path / "r.yaml").write_text("image: s.pgm\nresolution: 1.0\norigin: [0.0, 0.0, 0.0]\nmode: raw\n")
    r = read_ros_map(tmp_path / "r.yaml")
    np.testing.assert_array_equal(r.occupancy, [[60, 0, 100], [-1, -1, -1]])


def test_read_16_bit_and_colour_images(tmp_path: Path) -> None:
    (tmp_path / "w.pgm").write_bytes(b"P5\n2 1\n65535\n" + np.array([0, 65535], dtype=">u2").tobytes())
    (tmp_path / "w.yaml").write_text("image: w.pgm\nresolution: 1\norigin: [0, 0, 0]\n")
    np.testing.assert_array_equal(read_ros_map(tmp_path / "w.yaml").occupancy, [[100, 0]])
    (tmp_path / "c.ppm").write_bytes(b"P6\n2 1\n255\n" + bytes([255, 255, 255, 0, 30, 0]))
    (tmp_path / "c.yaml").write_text(f"image: {tmp_path / 'c.ppm'}\nresolution: 1\norigin: [0, 0, 0]\n")
    np.testing.assert_array_equal(read_ros_map(tmp_path / "c.yaml").occupancy, [[0, 100]])


def _map_yaml(tmp_path: Path, image: str, extra: str = "") -> Path:
    path = tmp_path / f"{image}.yaml"
    path.write_text(f"image: {image}\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\n{extra}")
    return path


#: A map image with the trinary palette and every shade in between, including the thresholds' neighbours.
GREYS = np.array([np.arange(256, dtype=np.uint8).reshape(16, 16)[i] for i in range(16)])


@pytest.mark.parametrize("fmt", ["png", "bmp", "tiff", "gif", "webp"])
@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
def test_every_lossless_image_format_reads_exactly_as_its_pgm(tmp_path: Path, fmt: str, mode: str) -> None:
    from PIL import Image

    (tmp_path / "m.pgm").write_bytes(b"P5 16 16 255\n" + GREYS.tobytes())
    save = {"webp": {"lossless": True}}.get(fmt, {})
    Image.fromarray(GREYS, mode="L").save(tmp_path / f"m.{fmt}", **save)
    expected = read_ros_map(_map_yaml(tmp_path, "m.pgm", f"mode: {mode}\n"))
    got = read_ros_map(_map_yaml(tmp_path, f"m.{fmt}", f"mode: {mode}\n"))
    np.testing.assert_array_equal(got.occupancy, expected.occupancy)
    assert got.resolution_m == 0.05 and got.origin_m == (-1.0, 2.0, 0.0) and got.image_path == tmp_path / f"m.{fmt}"


def test_colour_16_bit_palette_and_jpeg_maps(tmp_path: Path) -> None:
    from PIL import Image

    rgb = np.zeros((2, 3, 3), dtype=np.uint8)
    rgb[0] = [[255, 255, 255], [0, 30, 0], [200, 210, 220]]
    rgb[1] = [[10, 0, 0], [255, 250, 255], [120, 130, 140]]
    (tmp_path / "c.ppm").write_bytes(b"P6 3 2 255\n" + rgb.tobytes())
    Image.fromarray(rgb, mode="RGB").save(tmp_path / "c.png")
    np.testing.assert_array_equal(
        read_ros_map(_map_yaml(tmp_path, "c.png")).occupancy, read_ros_map(_map_yaml(tmp_path, "c.ppm")).occupancy
    )
    # Palette: the colours, not the indices.
    Image.fromarray(rgb, mode="RGB").quantize(6).save(tmp_path / "p.png")
    assert Image.open(tmp_path / "p.png").mode == "P"
    np.testing.assert_array_equal(
        read_ros_map(_map_yaml(tmp_path, "p.png")).occupancy, read_ros_map(_map_yaml(tmp_path, "c.ppm")).occupancy
    )
    # 16 bit: the full range, as the 16-bit PGM.
    wide = np.array([[0, 30000, 65535]], dtype=np.uint16)
    (tmp_path / "w.pgm").write_bytes(b"P5 3 1 65535\n" + wide.astype(">u2").tobytes())
    Image.fromarray(wide).save(tmp_path / "w.png")
    assert Image.open(tmp_path / "w.png").mode.startswith("I")
    np.testing.assert_array_equal(read_ros_map(_map_yaml(tmp_path, "w.png")).occupancy, [[100, -1, 0]])
    np.testing.assert_array_equal(
        read_ros_map(_map_yaml(tmp_path, "w.png")).occupancy, read_ros_map(_map_yaml(tmp_path, "w.pgm")).occupancy
    )
    # JPEG is lossy: black, white and unknown grey blocks still read as occupied, free and unknown.
    blocks = np.kron(np.array([[0, 254, 205]], dtype=np.uint8), np.ones((8, 8), dtype=np.uint8))
    Image.fromarray(blocks, mode="L").save(tmp_path / "j.jpg", quality=95)
    occupancy = read_ros_map(_map_yaml(tmp_path, "j.jpg")).occupancy
    assert (occupancy[:, :8] == 100).all() and (occupancy[:, 8:16] == 0).all() and (occupancy[:, 16:] == -1).all()


def test_alpha_is_averaged_in_trinary_mode_and_unknown_in_scale_mode(tmp_path: Path) -> None:
    from PIL import Image

    # Nav2's map_io: trinary averages alpha (opaque = max) with R, G and B; scale makes a pixel that is not fully
    # opaque unknown; raw ignores alpha.
    la = np.array([[[255, 0], [0, 255], [255, 255], [0, 0], [128, 255]]], dtype=np.uint8)  # (grey, alpha)
    Image.fromarray(la, mode="LA").save(tmp_path / "a.png")
    trinary = read_ros_map(_map_yaml(tmp_path, "a.png")).occupancy
    # shade = (3·grey + alpha) / 4 / 255: 0.75 → occ 0.25 unknown; 0.25 → occ 0.75 occupied; 1 → free;
    # 0 → occupied; (384 + 255) / 1020 = 0.626 → occ 0.374 unknown.
    np.testing.assert_array_equal(trinary, [[-1, 100, 0, 100, -1]])
    scale = read_ros_map(_map_yaml(tmp_path, "a.png", "mode: scale\n")).occupancy
    # Opaque ones only: black 100, white 0, 128 → occ 0.498 → rint((0.498 − 0.196) / (0.65 − 0.196) · 100) = 67.
    np.testing.assert_array_equal(scale, [[-1, 100, 0, -1, 67]])
    raw = read_ros_map(_map_yaml(tmp_path, "a.png", "mode: raw\n")).occupancy
    np.testing.assert_array_equal(raw, [[-1, 0, -1, 0, -1]])
    rgba = np.concatenate([np.repeat(la[:, :, :1], 3, axis=2), la[:, :, 1:]], axis=2)
    Image.fromarray(rgba, mode="RGBA").save(tmp_path / "b.png")
    for mode in ("trinary", "scale", "raw"):
        np.testing.assert_array_equal(
            read_ros_map(_map_yaml(tmp_path, "b.png", f"mode: {mode}\n")).occupancy,
            read_ros_map(_map_yaml(tmp_path, "a.png", f"mode: {mode}\n")).occupancy,
        )


@pytest.mark.parametrize(
    ("image", "match"),
    [
        (b"GIF89a not really", "corrupt"),
        (b"\x89PNG\r\n\x1a\n", "corrupt"),
        (b"hello, world", "not an image map_server reads"),
    ],
)
def test_a_bad_image_of_any_format_is_a_map_file_error(tmp_path: Path, image: bytes, match: str) -> None:
    (tmp_path / "x.png").write_bytes(image)
    with pytest.raises(MapFileError, match=match):
        read_ros_map(_map_yaml(tmp_path, "x.png"))


def test_a_floating_point_image_is_named_as_such(tmp_path: Path) -> None:
    from PIL import Image

    Image.fromarray(np.zeros((4, 4), dtype=np.float32), mode="F").save(tmp_path / "f.tiff")
    message = f"{tmp_path / 'f.tiff'}: a floating-point image is not a map (mode F)"
    with pytest.raises(MapFileError, match=f"^{re.escape(message)}$"):
        read_ros_map(_map_yaml(tmp_path, "f.tiff"))


def test_a_truncated_png_is_a_map_file_error(tmp_path: Path) -> None:
    from PIL import Image

    Image.fromarray(np.tile(GREYS, (8, 8)), mode="L").save(tmp_path / "t.png")
    data = (tmp_path / "t.png").read_bytes()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    with pytest.raises(MapFileError, match="corrupt or truncated"):
        read_ros_map(_map_yaml(tmp_path, "t.png"))


def test_grid_round_trip_through_files(tmp_path: Path) -> None:
    g = OccupancyGrid(30, 20, 0.1, (-1.0, -0.5))
    angles = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    for _ in range(6):
        g.integrate_scan((0.4, 0.5, 0.3), angles, np.full(90, 0.7), 5.0)
    states = g.states()
    write_ros_map(tmp_path / "g.yaml", states, g.resolution_m, g.origin_m)
    m = read_ros_map(tmp_path / "g.yaml")
    np.testing.assert_array_equal(m.occupancy, states)
    h = OccupancyGrid.from_ros_map(m)
    assert h.shape == g.shape
    assert h.origin_m == g.origin_m
    np.testing.assert_array_equal(h.states(), states)


def test_ros_map_is_immutable_and_validated() -> None:
    occ = np.zeros((2, 2), dtype=np.int8)
    m = RosMap(occ, 0.1, (0.0, 0.0, 0.0))
    occ[0, 0] = 100
    assert m.occupancy[0, 0] == 0  # copied
    with pytest.raises(ValueError):
        m.occupancy[0, 0] = 100
    with pytest.raises(AttributeError):
        m.resolution_m = 0.2  # type: ignore[misc]
    with pytest.raises(InvalidGridError):
        RosMap(np.zeros((2, 2)), 0.1, (0.0, 0.0, 0.0))
    with pytest.raises(InvalidParameterError):
        RosMap(np.zeros((2, 2), dtype=np.int8), 0.0, (0.0, 0.0, 0.0))
    with pytest.raises(InvalidParameterError):
        OccupancyGrid.from_ros_map(RosMap(np.zeros((2, 2), dtype=np.int8), 0.1, (0.0, 0.0, 0.5)))


@pytest.mark.parametrize(
    ("yaml_text", "image"),
    [
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", b"P5\n4 4\n255\n\x00\x00"),  # truncated
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", b"P5\n0 4\n255\n"),
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", b"P2\n2 1\n10\n3 11\n"),  # above maxval
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", b"P5\n2 a\n255\n\x00\x00"),
        ("resolution: 0.1\norigin: [0, 0, 0]\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\norigin: [0, 0, 0]\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: -0.1\norigin: [0, 0, 0]\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0]\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: 0.1\norigin: [0, nan, 0]\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: fancy\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 2\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.9\n", b"P5\n1 1\n255\n\x00"),
        ("image: x.pgm\nresolution: [0.1\n", b"P5\n1 1\n255\n\x00"),
        ("- just a list\n", b"P5\n1 1\n255\n\x00"),
    ],
)
def test_malformed_files_raise_map_file_error(tmp_path: Path, yaml_text: str, image: bytes) -> None:
    (tmp_path / "x.pgm").write_bytes(image)
    (tmp_path / "m.yaml").write_text(yaml_text)
    with pytest.raises(MapFileError):
        read_ros_map(tmp_path / "m.yaml")


def test_missing_files_raise_os_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        read_ros_map(tmp_path / "nope.yaml")
    (tmp_path / "m.yaml").write_text("image: gone.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    with pytest.raises(FileNotFoundError):
        read_ros_map(tmp_path / "m.yaml")


@pytest.mark.parametrize(
    ("occupancy", "kwargs", "error"),
    [
        (np.zeros((2, 2)), {}, InvalidGridError),
        (np.zeros((0, 2), dtype=np.int8), {}, InvalidGridError),
        (np.full((2, 2), 120, dtype=np.int16), {}, InvalidGridError),
        (
            np.zeros((2, 2), dtype=np.int8),
            {"free_thresh": 0.25},
            InvalidParameterError,
        ),  # 205 would read as free
        (np.zeros((2, 2), dtype=np.int8), {"occupied_thresh": 0.1}, InvalidParameterError),
        (np.zeros((2, 2), dtype=np.int8), {"image_name": "sub/x.pgm"}, InvalidParameterError),
    ],
)
def test_write_rejects_bad_input(tmp_path: Path, occupancy: np.ndarray, kwargs: dict, error: type) -> None:
    with pytest.raises(error):
        write_ros_map(tmp_path / "m.yaml", occupancy, 0.1, (0.0, 0.0), **kwargs)
    with pytest.raises(InvalidParameterError):
        write_ros_map(tmp_path / "m.yaml", np.zeros((2, 2), dtype=np.int8), float("nan"), (0.0, 0.0))
    with pytest.raises(InvalidParameterError):
        write_ros_map(tmp_path / "m.yaml", np.zeros((2, 2), dtype=np.int8), 0.1, (0.0,))


def test_reading_a_binary_file_as_yaml_is_a_map_file_error(tmp_path: Path) -> None:
    bad = tmp_path / "map.pgm"
    bad.write_bytes(b"P5\n2 2\n255\n\xfe\xff\x00\x01")
    with pytest.raises(MapFileError, match="not a map YAML"):
        read_ros_map(bad)
