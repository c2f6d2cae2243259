"""nav2 ``map_server`` files of core grids: YAML + binary PGM in trinary mode (``map_saver`` colours).

:func:`write_map_server` writes the pair ``map_server`` loads; :func:`read_map_server` loads any such
pair the way ``map_server`` does. Image row 0 is the top of the map (highest y), grid row 0 the
bottom. The YAML declares ``free_thresh: 0.196`` so that ``map_saver``'s unknown grey 205 stays
unknown (nav2's default 0.25 would read it as free).

Example::

    files = write_map_server(grid, Path("maps"), "L1__navigation")
    assert read_map_server(files.yaml).data.tobytes() == grid.data.tobytes()
"""

from __future__ import annotations

import json
import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from adapters.ros._common import (
    FREE_PIXEL,
    FREE_THRESH,
    OCCUPIED_PIXEL,
    OCCUPIED_THRESH,
    UNKNOWN_PIXEL,
    raw_pixels,
    trinary_pixels,
    write_atomic,
)
from twin.errors import MapError
from twin.maps.grid import GridFrame, OccupancyGrid

__all__ = [
    "FREE_PIXEL",
    "FREE_THRESH",
    "OCCUPIED_PIXEL",
    "OCCUPIED_THRESH",
    "UNKNOWN_PIXEL",
    "MapServerFiles",
    "read_map_server",
    "write_map_server",
]

logger = logging.getLogger(__name__)

_META_PREFIX = "# building-twin map:"
_REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_PGM_WHITESPACE = b" \t\r\n\v\f"
_PLAIN_YAML = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")
_META_FIELD = re.compile(r'(\w+)=("(?:[^"\\]|\\.)*"|\S+)')


@dataclass(frozen=True, slots=True)
class MapServerFiles:
    """The two files nav2 ``map_server`` loads: the YAML (pass it as ``yaml_filename``) and its PGM."""

    yaml: Path
    pgm: Path


def _yaml_str(text: str) -> str:
    """A YAML scalar for ``text``: plain when unambiguous, else double-quoted (JSON escapes are YAML)."""
    return text if _PLAIN_YAML.fullmatch(text) else json.dumps(text, ensure_ascii=False)


def _meta_comment(grid: OccupancyGrid) -> str:
    return (
        f"{_META_PREFIX} storey={json.dumps(grid.storey, ensure_ascii=False)} "
        f"skill={json.dumps(grid.skill, ensure_ascii=False)} elevation={grid.elevation_m!r}"
    )


def _check_stem(stem: str) -> None:
    if not stem or stem in {".", ".."} or "/" in stem or "\\" in stem or "\0" in stem:
        msg = f"Map file stem must be a plain file name, got {stem!r}."
        raise MapError(msg)


def write_map_server(grid: OccupancyGrid, out_dir: Path, stem: str) -> MapServerFiles:
    """Write ``<stem>.yaml`` + ``<stem>.pgm`` for nav2 ``map_server`` (trinary mode; ``raw`` mode for a
    speed mask, whose cells are percents: pixel = value, 255 unknown, what nav2's speed filter loads).

    The PGM is binary (``P5``, maxval 255, ``(height, width)`` bytes) in map_saver colours: occupied 0,
    free 254, unknown 205; image row 0 is the grid's last row (highest y). The YAML names the image
    relatively and starts with a comment carrying storey, skill and elevation for
    :func:`read_map_server` (``map_server`` ignores it). ``out_dir`` is created if needed.

    Example::

        files = write_map_server(grid, Path("maps"), "L1__navigation")
        # ros2 run nav2_map_server map_server --ros-args -p yaml_filename:=maps/L1__navigation.yaml
    """
    _check_stem(stem)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        msg = f"Cannot create map directory {out_dir}: {exc}"
        raise MapError(msg) from exc
    frame = grid.frame
    yaml_path, pgm_path = out_dir / f"{stem}.yaml", out_dir / f"{stem}.pgm"
    header = f"P5\n# building-twin {frame.resolution_m!r} m/pix\n{frame.width} {frame.height}\n255\n"
    trinary = bool(np.isin(grid.data, (-1, 0, 100)).all())
    pixels = trinary_pixels(grid.data) if trinary else raw_pixels(grid.data)
    write_atomic(pgm_path, header.encode("ascii") + pixels.tobytes())
    yaml_text = "\n".join(
        [
            _meta_comment(grid),
            f"image: {_yaml_str(pgm_path.name)}",
            f"mode: {'trinary' if trinary else 'raw'}",
            f"resolution: {frame.resolution_m!r}",
            f"origin: [{float(frame.origin_x)!r}, {float(frame.origin_y)!r}, 0.0]",
            "negate: 0",
            f"occupied_thresh: {OCCUPIED_THRESH!r}",
            f"free_thresh: {FREE_THRESH!r}",
            "",
        ]
    )
    write_atomic(yaml_path, yaml_text.encode("utf-8"))
    logger.debug("Wrote nav2 map %s (%dx%d cells)", yaml_path, frame.width, frame.height)
    return MapServerFiles(yaml=yaml_path, pgm=pgm_path)


def _yaml_scalar(raw: str, path: Path, key: str) -> str:
    """The value of a one-line YAML scalar: quoted (single/double) or plain with a trailing comment cut."""
    text = raw.strip()
    if text.startswith('"'):
        match = re.match(r'"(?:[^"\\]|\\.)*"', text)
        if match is None:
            msg = f"{path}: unterminated double-quoted value for {key!r}."
            raise MapError(msg)
        try:
            value = json.loads(match.group(0))
        except ValueError as exc:
            msg = f"{path}: unsupported escape in the value of {key!r}: {exc}"
            raise MapError(msg) from exc
        return str(value)
    if text.startswith("'"):
        match = re.match(r"'(?:[^']|'')*'", text)
        if match is None:
            msg = f"{path}: unterminated single-quoted value for {key!r}."
            raise MapError(msg)
        return match.group(0)[1:-1].replace("''", "'")
    return re.split(r"\s#", text, maxsplit=1)[0].strip()


def _parse_map_yaml(path: Path) -> tuple[dict[str, str], dict[str, str]]:
    """``(keys, metadata)`` of a map_server YAML: top-level ``key: value`` lines, and our comment's fields."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        msg = f"Cannot read map YAML {path}: {exc}"
        raise MapError(msg) from exc
    keys: dict[str, str] = {}
    meta: dict[str, str] = {}
    for line in text.splitlines():
        if line.startswith(_META_PREFIX):
            for name, value in _META_FIELD.findall(line[len(_META_PREFIX) :]):
                meta[name] = value
            continue
        stripped = line.strip()
        if not stripped or stripped.startswith("#") or line[:1].isspace() or stripped in {"---", "..."}:
            continue
        key, sep, rest = stripped.partition(":")
        if not sep:
            msg = f"{path}: cannot parse line {line!r} (expected 'key: value')."
            raise MapError(msg)
        keys[key.strip()] = _yaml_scalar(rest, path, key.strip())
    return keys, meta


def _yaml_float(keys: dict[str, str], key: str, path: Path) -> float:
    try:
        return float(keys[key])
    except ValueError as exc:
        msg = f"{path}: {key!r} must be a number, got {keys[key]!r}."
        raise MapError(msg) from exc


def _meta_string(meta: dict[str, str], key: str, path: Path) -> str:
    raw = meta.get(key)
    if raw is None:
        return ""
    try:
        value = json.loads(raw) if raw.startswith('"') else raw
    except ValueError as exc:
        msg = f"{path}: bad {key} in the building-twin comment: {raw!r}."
        raise MapError(msg) from exc
    return str(value)


def _read_pgm(path: Path) -> tuple[npt.NDArray[Any], int]:
    """``((height, width) samples, maxval)`` of a binary ``P5`` PGM; header comments are allowed."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        msg = f"Cannot read map image {path}: {exc}"
        raise MapError(msg) from exc
    if raw[:2] != b"P5":
        msg = f"{path}: not a binary PGM (magic {raw[:2]!r}, expected b'P5')."
        raise MapError(msg)
    pos, fields = 2, list[int]()
    while len(fields) < 3:
        start = pos
        while pos < len(raw):
            if raw[pos] in _PGM_WHITESPACE:
                pos += 1
            elif raw[pos] == ord("#"):
                newline = raw.find(b"\n", pos)
                pos = len(raw) if newline < 0 else newline + 1
            else:
                break
        digits = pos
        while pos < len(raw) and 48 <= raw[pos] <= 57:
            pos += 1
        if digits in (pos, start):  # no digits, or no whitespace before them
            msg = f"{path}: malformed PGM header (expected width, height and maxval after 'P5')."
            raise MapError(msg)
        fields.append(int(raw[digits:pos]))
    if pos >= len(raw) or raw[pos] not in _PGM_WHITESPACE:
        msg = f"{path}: malformed PGM header (no whitespace after maxval)."
        raise MapError(msg)
    width, height, maxval = fields
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        msg = f"{path}: unsupported PGM size {width}x{height} or maxval {maxval}."
        raise MapError(msg)
    dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
    body = memoryview(raw)[pos + 1 :]
    expected = width * height * dtype.itemsize
    if len(body) != expected:
        msg = (
            f"{path}: PGM size mismatch: header says {width}x{height} pixels "
            f"({expected} bytes), the file has {len(body)} bytes of pixels."
        )
        raise MapError(msg)
    pixels: npt.NDArray[Any] = np.frombuffer(body, dtype=dtype).reshape(height, width)
    if int(pixels.max()) > maxval:
        msg = f"{path}: PGM has pixel values above its maxval {maxval}."
        raise MapError(msg)
    return pixels, maxval


def read_map_server(yaml_path: Path) -> OccupancyGrid:
    """Load a nav2 ``map_server`` map (YAML + binary PGM) the way ``map_server`` does in trinary mode.

    Each pixel ``v`` becomes ``p = (maxval - v) / maxval`` (``v / maxval`` when ``negate`` is set):
    ``p > occupied_thresh`` -> 100, ``p < free_thresh`` -> 0, otherwise -1; image rows are flipped
    back so row 0 is the lowest y. The image path may be relative to the YAML or absolute. Storey,
    skill and elevation come from the building-twin comment line when present (else ``""``, ``""``,
    ``0.0``). Files from :func:`write_map_server` round-trip exactly.

    Example::

        grid = read_map_server(Path("maps/L1__navigation.yaml"))
        grid.data.shape  # (height, width), int8
    """
    keys, meta = _parse_map_yaml(yaml_path)
    missing = [k for k in _REQUIRED_KEYS if k not in keys]
    if missing:
        msg = f"{yaml_path}: missing map_server key(s) {', '.join(missing)}."
        raise MapError(msg)
    mode = keys.get("mode", "trinary")
    if mode not in ("trinary", "raw"):
        msg = (
            f"{yaml_path}: mode {mode!r} is not supported (building-twin writes trinary maps and raw masks)."
        )
        raise MapError(msg)
    origin_text = keys["origin"]
    if not (origin_text.startswith("[") and origin_text.endswith("]")):
        msg = f"{yaml_path}: origin must be a flow list [x, y, yaw], got {origin_text!r}."
        raise MapError(msg)
    try:
        origin = [float(v) for v in origin_text[1:-1].split(",")]
    except ValueError as exc:
        msg = f"{yaml_path}: origin must hold three numbers, got {origin_text!r}."
        raise MapError(msg) from exc
    if len(origin) != 3:
        msg = f"{yaml_path}: origin must hold three numbers [x, y, yaw], got {origin_text!r}."
        raise MapError(msg)
    if origin[2] != 0.0:
        msg = f"{yaml_path}: origin yaw {origin[2]!r} is not supported (grids are axis-aligned)."
        raise MapError(msg)
    negate_text = keys["negate"].lower()
    if negate_text not in {"0", "1", "true", "false"}:
        msg = f"{yaml_path}: negate must be 0 or 1, got {keys['negate']!r}."
        raise MapError(msg)
    negate = negate_text in {"1", "true"}
    resolution = _yaml_float(keys, "resolution", yaml_path)
    occupied_thresh = _yaml_float(keys, "occupied_thresh", yaml_path)
    free_thresh = _yaml_float(keys, "free_thresh", yaml_path)
    if not negate and free_thresh > (255 - UNKNOWN_PIXEL) / 255:
        logger.warning(
            "%s: free_thresh %s reads map_saver's unknown grey %d as free (nav2 does the same).",
            yaml_path,
            free_thresh,
            UNKNOWN_PIXEL,
        )

    image = Path(keys["image"])
    image_path = image if image.is_absolute() else yaml_path.parent / image
    if not image_path.is_file():
        msg = f"{yaml_path}: map image {image_path} does not exist."
        raise MapError(msg)
    pixels, maxval = _read_pgm(image_path)

    values = np.arange(maxval + 1, dtype=np.float64)
    if mode == "raw":  # map_server's raw mode: the pixel is the value, above 100 unknown
        lut = np.where(values <= 100, values, -1).astype(np.int8)
    else:
        p = values / maxval if negate else (maxval - values) / maxval
        lut = np.where(p > occupied_thresh, 100, np.where(p < free_thresh, 0, -1)).astype(np.int8)
    data = np.ascontiguousarray(lut[pixels[::-1]])

    try:
        elevation = float(meta.get("elevation", "0.0"))
    except ValueError as exc:
        msg = f"{yaml_path}: bad elevation in the building-twin comment: {meta['elevation']!r}."
        raise MapError(msg) from exc
    try:
        frame = GridFrame(origin[0], origin[1], resolution, data.shape[1], data.shape[0])
    except MapError as exc:
        msg = f"{yaml_path}: invalid map frame: {exc}"
        raise MapError(msg) from exc
    if not math.isfinite(elevation):
        msg = f"{yaml_path}: elevation must be finite, got {elevation!r}."
        raise MapError(msg)
    return OccupancyGrid(
        frame,
        data,
        storey=_meta_string(meta, "storey", yaml_path),
        skill=_meta_string(meta, "skill", yaml_path),
        elevation_m=elevation,
    )
