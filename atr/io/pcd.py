"""Reader for PCL's PCD point-cloud files (v0.6/v0.7): ascii, binary and binary_compressed data.

Open3D reads PCD too, but only x/y/z, normals and colours, and it drops NaN points of organised clouds; descriptor
conformance tests need every field as stored. binary_compressed uses LZF (Marc Lehmann's format, as in liblzf);
no maintained Python LZF package is in this project's dependencies, so the tiny decompressor is written here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from atr.errors import InputError

_TYPES = {
    ("F", 4): np.float32,
    ("F", 8): np.float64,
    ("I", 1): np.int8,
    ("I", 2): np.int16,
    ("I", 4): np.int32,
    ("I", 8): np.int64,
    ("U", 1): np.uint8,
    ("U", 2): np.uint16,
    ("U", 4): np.uint32,
    ("U", 8): np.uint64,
}


@numba.njit(cache=True)
def _lzf_decompress_kernel(src: np.ndarray, dst: np.ndarray) -> int:
    """Decode an LZF stream into dst; returns the number of bytes written, or -1 if the stream is corrupt."""
    ip = 0
    op = 0
    n_in = src.shape[0]
    n_out = dst.shape[0]
    while ip < n_in:
        ctrl = np.int64(src[ip])
        ip += 1
        if ctrl < 32:  # literal run of ctrl + 1 bytes
            length = ctrl + 1
            if op + length > n_out or ip + length > n_in:
                return -1
            for t in range(length):
                dst[op + t] = src[ip + t]
            op += length
            ip += length
        else:  # back reference
            length = ctrl >> 5
            if length == 7:
                if ip >= n_in:
                    return -1
                length += np.int64(src[ip])
                ip += 1
            if ip >= n_in:
                return -1
            ref = op - ((ctrl & 0x1F) << 8) - np.int64(src[ip]) - 1
            ip += 1
            length += 2
            if ref < 0 or op + length > n_out:
                return -1
            for t in range(length):  # byte by byte: the copy may overlap itself
                dst[op + t] = dst[ref + t]
            op += length
    return op


def lzf_decompress(data: bytes, uncompressed_size: int) -> bytes:
    """Decompress an LZF stream.

    Args:
        data: the compressed bytes.
        uncompressed_size: the expected size of the result, bytes.

    Returns:
        The decompressed bytes.

    Raises:
        InputError: the stream is corrupt or does not decode to ``uncompressed_size`` bytes.

    """
    src = np.frombuffer(data, dtype=np.uint8)
    dst = np.empty(uncompressed_size, dtype=np.uint8)
    n = _lzf_decompress_kernel(src, dst)
    if n != uncompressed_size:
        raise InputError(
            f"LZF stream decoded to {n} bytes, expected {uncompressed_size} (-1 means corrupt)"
        )
    return dst.tobytes()


def _parse_header(raw: bytes, path: Path) -> tuple[dict[str, list[str]], int]:
    header: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise InputError(f"{path}: PCD header has no DATA line")
        line = raw[pos:end].decode("ascii", errors="replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == "DATA":
            return header, pos


@dataclass(frozen=True)
class _Layout:
    """What the header says about the data: per field its name, element type and count."""

    names: list[str]
    dtypes: list[np.dtype]
    counts: list[int]
    n_points: int
    kind: str


def _layout(header: dict[str, list[str]], path: Path) -> _Layout:
    try:
        names = header["FIELDS"]
        sizes = [int(v) for v in header["SIZE"]]
        types = [v.upper() for v in header["TYPE"]]
        counts = [int(v) for v in header.get("COUNT", ["1"] * len(names))]
        n_points = (
            int(header["POINTS"][0])
            if "POINTS" in header
            else (int(header["WIDTH"][0]) * int(header["HEIGHT"][0]))
        )
        kind = header["DATA"][0].lower()
    except (KeyError, IndexError, ValueError) as exc:
        raise InputError(f"{path}: malformed PCD header ({exc})") from exc
    if not len(names) == len(sizes) == len(types) == len(counts):
        raise InputError(f"{path}: FIELDS/SIZE/TYPE/COUNT lengths differ")
    dtypes = []
    for name, t, s in zip(names, types, sizes, strict=True):
        if (t, s) not in _TYPES:
            raise InputError(f"{path}: field {name!r} has unsupported TYPE {t} SIZE {s}")
        dtypes.append(np.dtype(_TYPES[(t, s)]).newbyteorder("<"))
    return _Layout(names, dtypes, counts, n_points, kind)


def _ascii_columns(body: bytes, layout: _Layout, path: Path) -> list[np.ndarray]:
    n_points = layout.n_points
    text = body.decode("ascii", errors="replace").split()
    width = sum(layout.counts)
    if len(text) < n_points * width:
        raise InputError(f"{path}: {len(text)} ascii values, expected {n_points * width}")
    table = np.array(text[: n_points * width], dtype=object).reshape(n_points, width)
    columns, col = [], 0
    for dt, c in zip(layout.dtypes, layout.counts, strict=True):
        block = table[:, col : col + c]
        if dt.kind == "f":
            arr = block.astype(np.float64).astype(dt)
        else:  # integers: parse through int to keep full 64-bit precision
            arr = np.vectorize(int, otypes=[np.int64])(block).astype(dt)
        columns.append(arr)
        col += c
    return columns


def _binary_columns(body: bytes, layout: _Layout, path: Path) -> list[np.ndarray]:
    n_points = layout.n_points
    record = np.dtype(
        [
            (f"f{i}", dt, (c,))
            for i, (dt, c) in enumerate(zip(layout.dtypes, layout.counts, strict=True))
        ]
    )
    if len(body) < n_points * record.itemsize:
        raise InputError(
            f"{path}: binary data has {len(body)} bytes, expected {n_points * record.itemsize}"
        )
    rec = np.frombuffer(body, dtype=record, count=n_points)
    return [np.asarray(rec[f"f{i}"]) for i in range(len(layout.names))]


def _compressed_columns(body: bytes, layout: _Layout, path: Path) -> list[np.ndarray]:
    n_points = layout.n_points
    if len(body) < 8:
        raise InputError(f"{path}: binary_compressed data is truncated")
    comp, uncomp = np.frombuffer(body[:8], dtype="<u4")
    if len(body) < 8 + int(comp):
        raise InputError(f"{path}: compressed block has {len(body) - 8} bytes, expected {comp}")
    data = lzf_decompress(body[8 : 8 + int(comp)], int(uncomp))
    expected = n_points * sum(
        dt.itemsize * c for dt, c in zip(layout.dtypes, layout.counts, strict=True)
    )
    if len(data) != expected:
        raise InputError(f"{path}: decompressed {len(data)} bytes, expected {expected}")
    columns, off = [], 0  # column-major: all values of a field, then the next field
    for dt, c in zip(layout.dtypes, layout.counts, strict=True):
        nbytes = n_points * c * dt.itemsize
        columns.append(np.frombuffer(data[off : off + nbytes], dtype=dt).reshape(n_points, c))
        off += nbytes
    return columns


_READERS = {
    "ascii": _ascii_columns,
    "binary": _binary_columns,
    "binary_compressed": _compressed_columns,
}


def read_pcd(path: str | Path) -> dict[str, np.ndarray]:
    """Read every field of a PCD file.

    Args:
        path: a .pcd file (ascii, binary or binary_compressed).

    Returns:
        Field name → array of shape (N,) for COUNT 1 fields, (N, COUNT) otherwise, in the stored type
        (float32 for PCL's usual F 4 fields). N = WIDTH × HEIGHT; organised clouds are returned row-major,
        flattened, NaN points kept. Padding fields named "_" are dropped.

    Raises:
        InputError: the file is missing, truncated, or not a PCD file this reader understands.

    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read PCD file {path}: {exc}") from exc
    header, data_start = _parse_header(raw, path)
    layout = _layout(header, path)
    if layout.kind not in _READERS:
        raise InputError(f"{path}: DATA {layout.kind!r} is not ascii, binary or binary_compressed")
    columns = _READERS[layout.kind](raw[data_start:], layout, path)
    out: dict[str, np.ndarray] = {}
    for name, arr, c in zip(layout.names, columns, layout.counts, strict=True):
        if name == "_":
            continue
        arr = np.ascontiguousarray(arr.astype(arr.dtype.newbyteorder("=")))
        out[name] = arr.reshape(layout.n_points) if c == 1 else arr.reshape(layout.n_points, c)
    return out


def read_pcd_xyz(path: str | Path) -> np.ndarray:
    """Read the x, y, z fields of a PCD file as an (N, 3) float64 array, metres (NaN points kept)."""
    fields = read_pcd(path)
    missing = [f for f in ("x", "y", "z") if f not in fields]
    if missing:
        raise InputError(f"{path}: PCD file has no field(s) {missing}")
    return np.stack([fields["x"], fields["y"], fields["z"]], axis=1).astype(np.float64)
