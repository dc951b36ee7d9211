"""ROS map_server map files: a YAML description plus an image.

The image may be in any format map_server and Nav2 read: PGM/PPM (P2, P3, P5, P6; read here, 8 and 16 bit) and,
through Pillow, PNG, BMP, JPEG, TIFF, GIF, WebP and the rest Pillow opens (first frame; 8 or 16 bit; palette
images by their colours). Reading follows Nav2's ``map_io`` conversion. For each pixel with channel values v and
maximum value M, shade = mean(v_R, v_G, v_B) / M (a grey pixel counts as R = G = B) and occ = 1 − shade
(``negate: 1``: occ = shade);

* trinary (default): 100 if occ > occupied_thresh, 0 if occ < free_thresh, else −1; an image with an alpha channel
  averages its alpha (opaque = M) in with R, G and B, as map_io does;
* scale: −1 where the pixel is not fully opaque, else as trinary at the extremes and otherwise
  rint(100·(occ − free_thresh) / (occupied_thresh − free_thresh));
* raw: round(255·shade) if in 0..100, else −1.

The image's top row is the map's highest-y row, so it is flipped: :attr:`RosMap.occupancy` has row 0 = lowest
y, the ``nav_msgs/OccupancyGrid`` order, with ``origin`` the pose of the corner of cell (0, 0).

Writing produces a trinary map the way map_saver does: 0 (black) for values >= rint(100·occupied_thresh),
254 (white) for 0 <= value <= rint(100·free_thresh), 205 (grey) for everything else including −1.
"""

from __future__ import annotations

import io
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from mjnav.mapping.errors import InvalidGridError, InvalidParameterError, MapFileError

__all__ = ["RosMap", "read_ros_map", "write_ros_map"]

_MODES = ("trinary", "scale", "raw")
#: Grey level map_saver writes for unknown cells; occ = 50/255 ≈ 0.196 when read back.
UNKNOWN_PIXEL = 205
FREE_PIXEL = 254
OCCUPIED_PIXEL = 0
#: occ value of the unknown grey pixel when read back (1 − 205/255 ≈ 0.19608).
UNKNOWN_PIXEL_OCC = 1.0 - UNKNOWN_PIXEL / 255.0


@dataclass(frozen=True, slots=True, eq=False)
class RosMap:
    """A map read from a map_server YAML + image pair.

    Attributes:
        occupancy: (H, W) int8 ROS values (−1 unknown, 0..100), row 0 = lowest y (read-only array).
        resolution_m: cell size, metres.
        origin_m: (x, y, yaw) of the corner of cell (0, 0) in the map frame, metres and radians.
        occupied_thresh: probability above which a pixel is occupied.
        free_thresh: probability below which a pixel is free.
        negate: whether black means free (``negate: 1``).
        mode: "trinary", "scale" or "raw".
        image_path: the image file the occupancy came from (None if built in memory).
    """

    occupancy: NDArray[np.int8]
    resolution_m: float
    origin_m: tuple[float, float, float]
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196
    negate: bool = False
    mode: str = "trinary"
    image_path: Path | None = None

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.dtype != np.int8 or occ.ndim != 2 or occ.size == 0:
            raise InvalidGridError(
                f"occupancy must be a non-empty 2-D int8 array, got {occ.dtype} with shape {occ.shape}"
            )
        occ = occ.copy()
        occ.setflags(write=False)
        object.__setattr__(self, "occupancy", occ)
        try:
            res = float(self.resolution_m)
        except (TypeError, ValueError) as exc:
            raise InvalidParameterError(f"resolution_m must be a number, got {self.resolution_m!r}") from exc
        if not (math.isfinite(res) and res > 0):
            raise InvalidParameterError(f"resolution_m must be finite and > 0, got {self.resolution_m}")
        object.__setattr__(self, "resolution_m", res)
        try:
            origin = tuple(float(v) for v in self.origin_m)
        except (TypeError, ValueError) as exc:
            raise InvalidParameterError(f"origin_m must be 3 numbers (x, y, yaw), got {self.origin_m}") from exc
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise InvalidParameterError(f"origin_m must be 3 finite numbers (x, y, yaw), got {self.origin_m}")
        object.__setattr__(self, "origin_m", origin)
        if self.mode not in _MODES:
            raise InvalidParameterError(f"mode must be one of {_MODES}, got {self.mode!r}")

    @property
    def width_cells(self) -> int:
        """Number of columns W."""
        return int(self.occupancy.shape[1])

    @property
    def height_cells(self) -> int:
        """Number of rows H."""
        return int(self.occupancy.shape[0])

    def occupied_mask(self, threshold: int = 100, *, unknown_is_occupied: bool = False) -> NDArray[np.bool_]:
        """(H, W) bool obstacle mask.

        Args:
            threshold: cells with value >= threshold are occupied. The default 100 selects exactly the pixels
                darker than ``occupied_thresh`` in trinary and scale maps.
            unknown_is_occupied: also mark unknown (−1) cells.

        Returns:
            (H, W) bool, row 0 = lowest y.
        """
        mask = self.occupancy >= threshold
        if unknown_is_occupied:
            mask |= self.occupancy < 0
        return mask

    def free_mask(self, threshold: int = 0) -> NDArray[np.bool_]:
        """(H, W) bool, True where 0 <= value <= threshold (default 0: the free cells of a trinary map)."""
        return (self.occupancy >= 0) & (self.occupancy <= threshold)


# ---------------------------------------------------------------------------------------------------------
# Netpbm images
# ---------------------------------------------------------------------------------------------------------


#: Netpbm formats read here (the others go through Pillow).
_PNM_MAGIC = (b"P2", b"P3", b"P5", b"P6")


@dataclass(frozen=True)
class _Pixels:
    """An image's pixels for map_io's conversion, as the file's integers: colour (rows, cols, 3; grey repeated),
    alpha (rows, cols; ``maxval`` = opaque) or None; image row 0 at the top."""

    rgb: NDArray[np.float64]
    alpha: NDArray[np.float64] | None
    maxval: float

    def shade(self, with_alpha: bool) -> NDArray[np.float64]:
        """map_io's brightness in [0, 1]: the mean of R, G, B (and alpha) over the maximum. Summed as integers
        first, so a grey pixel's shade is exactly v / maxval."""
        total = self.rgb.sum(axis=2)
        if with_alpha and self.alpha is not None:
            return (total + self.alpha) / 4.0 / self.maxval
        return total / 3.0 / self.maxval

    def opaque(self) -> NDArray[np.bool_] | None:
        """Where the pixel is fully opaque (None without alpha)."""
        return None if self.alpha is None else self.alpha >= self.maxval


def _read_image(path: Path) -> _Pixels:
    """The pixels of a map image, Netpbm here, any other format through Pillow.

    Raises:
        MapFileError: not an image, an unsupported mode, a corrupt or truncated file.
        OSError: the file cannot be read.
    """
    data = path.read_bytes()
    if data[:2] in _PNM_MAGIC:
        return _read_pnm(path, data)
    return _read_pillow(path, data)


def _read_pillow(path: Path, data: bytes) -> _Pixels:
    from PIL import Image, UnidentifiedImageError

    limit = Image.MAX_IMAGE_PIXELS
    try:
        # A map is a big image by design (a building at 5 cm is tens of millions of pixels): no decompression-bomb
        # limit for a file the user named as their map.
        Image.MAX_IMAGE_PIXELS = None
        with warnings.catch_warnings(), Image.open(io.BytesIO(data)) as img:
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            img.load()
            return _pillow_pixels(path, img)
    except MapFileError:
        raise
    except UnidentifiedImageError as exc:
        raise MapFileError(
            f"{path}: not an image map_server reads (PGM, PPM, PNG, BMP, JPEG, TIFF, GIF, ...), or a corrupt one"
        ) from exc
    except (OSError, ValueError, SyntaxError) as exc:  # Pillow's truncated / corrupt file errors
        raise MapFileError(f"{path}: corrupt or truncated image: {exc}") from exc
    finally:
        Image.MAX_IMAGE_PIXELS = limit


def _pillow_pixels(path: Path, img: Any) -> _Pixels:
    mode = img.mode
    if mode in ("I;16", "I;16L", "I;16B", "I;16N", "I"):
        values = np.asarray(img, dtype=np.float64)
        if values.min(initial=0.0) < 0 or values.max(initial=0.0) > 65535:
            raise MapFileError(f"{path}: {mode} pixel values outside 0..65535")
        return _Pixels(np.repeat(values[:, :, None], 3, axis=2), None, 65535.0)
    if mode == "F":
        raise MapFileError(f"{path}: a floating-point image is not a map (mode F)")
    if mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
    elif mode in ("1", "L", "LA", "RGB", "RGBA"):
        pass
    elif mode in ("PA", "RGBa", "La"):
        img = img.convert("RGBA")
    else:  # CMYK, YCbCr, LAB, HSV, RGBX: their colours
        img = img.convert("RGB")
    values = np.asarray(img.convert("L") if img.mode == "1" else img, dtype=np.float64)
    if values.ndim == 2:
        values = values[:, :, None]
    has_alpha = img.mode in ("LA", "RGBA")
    colour = values[:, :, :-1] if has_alpha else values
    rgb = np.repeat(colour, 3, axis=2) if colour.shape[2] == 1 else colour
    return _Pixels(rgb, values[:, :, -1] if has_alpha else None, 255.0)


def _read_pnm(path: Path, data: bytes) -> _Pixels:
    """The pixels of a P2/P3/P5/P6 image (no alpha)."""
    magic = data[:2]
    channels = 3 if magic in (b"P3", b"P6") else 1
    # Header: magic, width, height, maxval, separated by whitespace; '#' starts a comment to end of line.
    fields: list[int] = []
    pos = 2
    n = len(data)
    while len(fields) < 3:
        while pos < n and data[pos : pos + 1].isspace():
            pos += 1
        if pos < n and data[pos : pos + 1] == b"#":
            while pos < n and data[pos : pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < n and not data[pos : pos + 1].isspace() and data[pos : pos + 1] != b"#":
            pos += 1
        if start == pos:
            raise MapFileError(f"{path}: truncated image header")
        try:
            fields.append(int(data[start:pos]))
        except ValueError as exc:
            raise MapFileError(f"{path}: bad image header field {data[start:pos]!r}") from exc
    width, height, maxval = fields
    if width <= 0 or height <= 0:
        raise MapFileError(f"{path}: empty image ({width}×{height})")
    if not 0 < maxval < 65536:
        raise MapFileError(f"{path}: bad maximum value {maxval}")
    count = width * height * channels
    if magic in (b"P5", b"P6"):
        pos += 1  # exactly one whitespace byte after maxval
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        nbytes = count * dtype.itemsize
        if n - pos < nbytes:
            raise MapFileError(f"{path}: image data truncated ({n - pos} of {nbytes} bytes)")
        values = np.frombuffer(data, dtype=dtype, count=count, offset=pos).astype(np.float64)
    else:
        body = b" ".join(line.split(b"#", 1)[0] for line in data[pos:].splitlines())
        try:
            values = np.array(body.split()[:count], dtype=np.float64)
        except ValueError as exc:
            raise MapFileError(f"{path}: bad ASCII image data") from exc
        if values.size < count:
            raise MapFileError(f"{path}: image data truncated ({values.size} of {count} values)")
    if values.max(initial=0.0) > maxval:
        raise MapFileError(f"{path}: pixel value above maxval {maxval}")
    img = values.reshape(height, width, channels)
    return _Pixels(np.repeat(img, 3, axis=2) if channels == 1 else img, None, float(maxval))


def _write_pgm(path: Path, pixels: NDArray[np.uint8], comment: str) -> None:
    height, width = pixels.shape
    header = f"P5\n# {comment}\n{width} {height}\n255\n".encode("ascii")
    path.write_bytes(header + np.ascontiguousarray(pixels, dtype=np.uint8).tobytes())


# ---------------------------------------------------------------------------------------------------------
# YAML
# ---------------------------------------------------------------------------------------------------------


def _yaml_float(doc: dict[str, Any], key: str, path: Path, default: float | None = None) -> float:
    if key not in doc:
        if default is None:
            raise MapFileError(f"{path}: missing key '{key}'")
        return default
    try:
        v = float(doc[key])
    except (TypeError, ValueError) as exc:
        raise MapFileError(f"{path}: '{key}' must be a number, got {doc[key]!r}") from exc
    if not math.isfinite(v):
        raise MapFileError(f"{path}: '{key}' must be finite, got {v}")
    return v


def read_ros_map(yaml_path: str | Path) -> RosMap:
    """Read a map_server map (YAML + image: PGM, PPM, PNG, BMP, JPEG, TIFF, GIF, ...).

    Args:
        yaml_path: the YAML file. Its ``image`` is resolved relative to the YAML's folder unless absolute.

    Returns:
        The :class:`RosMap`; ``occupancy`` is (H, W) int8 with row 0 = lowest y.

    Raises:
        MapFileError: invalid YAML, missing/invalid keys (``image``, ``resolution``, ``origin`` are required;
            ``negate`` defaults to 0, ``occupied_thresh`` to 0.65, ``free_thresh`` to 0.196, ``mode`` to
            trinary), unsupported or corrupt image.
        OSError: a file cannot be opened.
    """
    path = Path(yaml_path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise MapFileError(f"{path}: not a map YAML file: {exc}") from exc
    if not isinstance(doc, dict):
        raise MapFileError(f"{path}: expected a YAML mapping, got {type(doc).__name__}")
    if "image" not in doc or not isinstance(doc["image"], str) or not doc["image"]:
        raise MapFileError(f"{path}: missing or invalid key 'image'")
    resolution = _yaml_float(doc, "resolution", path)
    if resolution <= 0:
        raise MapFileError(f"{path}: resolution must be > 0, got {resolution}")
    origin = doc.get("origin")
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise MapFileError(f"{path}: 'origin' must be a list [x, y, yaw], got {origin!r}")
    try:
        ox, oy, oyaw = (float(v) for v in origin)
    except (TypeError, ValueError) as exc:
        raise MapFileError(f"{path}: 'origin' values must be numbers, got {origin!r}") from exc
    if not all(math.isfinite(v) for v in (ox, oy, oyaw)):
        raise MapFileError(f"{path}: 'origin' values must be finite, got {origin!r}")
    occ_t = _yaml_float(doc, "occupied_thresh", path, 0.65)
    free_t = _yaml_float(doc, "free_thresh", path, 0.196)
    negate_raw = doc.get("negate", 0)
    if negate_raw not in (0, 1, True, False):
        raise MapFileError(f"{path}: 'negate' must be 0 or 1, got {negate_raw!r}")
    negate = bool(negate_raw)
    mode = doc.get("mode", "trinary")
    if mode not in _MODES:
        raise MapFileError(f"{path}: 'mode' must be one of {_MODES}, got {mode!r}")
    if mode != "raw" and not 0.0 <= free_t < occ_t <= 1.0:
        raise MapFileError(f"{path}: need 0 <= free_thresh ({free_t}) < occupied_thresh ({occ_t}) <= 1")

    image_path = Path(doc["image"])
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    pixels = _read_image(image_path)
    shade = pixels.shade(with_alpha=mode == "trinary")  # map_io averages the alpha in, in trinary mode only
    occ = shade if negate else 1.0 - shade
    if mode == "raw":
        # map_server: std::round(shade · 255), kept if within 0..100 (negate does not apply in raw mode).
        v = np.floor(shade * 255.0 + 0.5)
        cells = np.where((v >= 0) & (v <= 100), v, -1).astype(np.int8)
    else:
        cells = np.full(shade.shape, -1, dtype=np.int8)
        if mode == "scale":
            mid = np.rint((occ - free_t) / (occ_t - free_t) * 100.0)
            cells[:] = np.clip(mid, 0, 100).astype(np.int8)
        cells[occ < free_t] = 0
        cells[occ > occ_t] = 100
        opaque = pixels.opaque()
        if mode == "scale" and opaque is not None:
            cells[~opaque] = -1  # map_io: a pixel that is not fully opaque is unknown
    return RosMap(
        occupancy=np.ascontiguousarray(cells[::-1]),
        resolution_m=resolution,
        origin_m=(ox, oy, oyaw),
        occupied_thresh=occ_t,
        free_thresh=free_t,
        negate=negate,
        mode=mode,
        image_path=image_path,
    )


def write_ros_map(
    yaml_path: str | Path,
    occupancy: ArrayLike,
    resolution_m: float,
    origin_m: tuple[float, float] | tuple[float, float, float] | ArrayLike,
    *,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    image_name: str | None = None,
) -> Path:
    """Write a trinary map_server map: a P5 PGM image and a YAML file beside it.

    Args:
        yaml_path: YAML file to write (its folder must exist).
        occupancy: (H, W) integer ROS values (−1 unknown, 0..100), row 0 = lowest y (e.g.
            ``OccupancyGrid.to_ros()``, ``RosMap.occupancy``).
        resolution_m: cell size, metres.
        origin_m: (x, y) or (x, y, yaw) of the corner of cell (0, 0), metres/radians; yaw defaults to 0.
        occupied_thresh: values >= rint(100·occupied_thresh) are written occupied (black).
        free_thresh: values in 0..rint(100·free_thresh) are written free (white). Must be < 50/255 ≈ 0.19608
            so that the grey 205 of unknown cells reads back as unknown (ROS 1 map_saver uses 0.196; Nav2's
            0.25 would read unknown back as free).
        image_name: file name of the image, written in the YAML's folder; default: the YAML's stem + ".pgm".

    Returns:
        Path of the YAML file written (the image lies beside it).

    Raises:
        InvalidGridError: occupancy not a non-empty 2-D integer array of −1/0..100 values.
        InvalidParameterError: bad resolution, origin or thresholds, or an image name with a folder part.
        OSError: a file cannot be written.
    """
    occ = np.asarray(occupancy)
    if occ.dtype.kind not in "iu":
        raise InvalidGridError(f"occupancy must have an integer dtype (int8 ROS values), got {occ.dtype}")
    if occ.ndim != 2 or occ.size == 0:
        raise InvalidGridError(f"occupancy must be a non-empty 2-D array, got shape {occ.shape}")
    if occ.min() < -1 or occ.max() > 100:
        raise InvalidGridError("occupancy values must be -1 (unknown) or 0..100")
    res = float(resolution_m)
    if not (math.isfinite(res) and res > 0):
        raise InvalidParameterError(f"resolution_m must be finite and > 0, got {resolution_m}")
    o = np.asarray(origin_m, dtype=np.float64).reshape(-1)
    if o.shape not in ((2,), (3,)) or not np.all(np.isfinite(o)):
        raise InvalidParameterError(f"origin_m must be 2 or 3 finite numbers, got {origin_m!r}")
    ox, oy = float(o[0]), float(o[1])
    oyaw = float(o[2]) if o.shape == (3,) else 0.0
    if not (0.0 <= free_thresh < UNKNOWN_PIXEL_OCC and free_thresh < occupied_thresh <= 1.0):
        raise InvalidParameterError(
            f"need 0 <= free_thresh ({free_thresh}) < {UNKNOWN_PIXEL_OCC:.5f} (so grey reads back as "
            "unknown) "
            f"and free_thresh < occupied_thresh ({occupied_thresh}) <= 1"
        )
    path = Path(yaml_path)
    name = image_name if image_name is not None else path.stem + ".pgm"
    if Path(name).name != name or not name:
        raise InvalidParameterError(f"image_name must be a bare file name, got {name!r}")
    occ_i = int(np.rint(occupied_thresh * 100.0))
    free_i = int(np.rint(free_thresh * 100.0))
    v = occ.astype(np.int16)
    pixels = np.full(v.shape, UNKNOWN_PIXEL, dtype=np.uint8)
    pixels[(v >= 0) & (v <= free_i)] = FREE_PIXEL
    pixels[v >= occ_i] = OCCUPIED_PIXEL
    image_path = path.parent / name
    _write_pgm(image_path, pixels[::-1], f"mjnav {res:.3f} m/pix")
    doc = {
        "image": name,
        "mode": "trinary",
        "resolution": res,
        "origin": [ox, oy, oyaw],
        "negate": 0,
        "occupied_thresh": float(occupied_thresh),
        "free_thresh": float(free_thresh),
    }
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return path
