"""A strict reader for PLY files (ascii, binary little- and big-endian): vertex positions and triangles.

Open3D's reader keeps what it parsed before an error (an `inf` in an ascii file, random bytes, a malformed
header) and returns a partial cloud with only a warning, so the matcher ran on the part. This reader refuses
such a file, naming it and the reason: a header that breaks the format, fewer values than the header
declares, a value that is not a number, a non-finite position, or a face index outside the vertex list.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atr.errors import InputError

_SCALARS = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_FACE_LISTS = ("vertex_indices", "vertex_index")


@dataclass
class _Property:
    name: str
    dtype: str  # numpy type code without byte order
    count_dtype: str | None = None  # set for a list property: the type of its length


@dataclass
class _Element:
    name: str
    count: int
    properties: list[_Property]


@dataclass(frozen=True)
class PlyGeometry:
    """What a PLY file held.

    Attributes:
        points: (N, 3) float64 vertex positions, metres, all finite.
        triangles: (M, 3) int64 vertex indices (polygons fanned into triangles); (0, 3) for a point cloud.

    """

    points: np.ndarray
    triangles: np.ndarray


def _header(raw: bytes, path: Path) -> tuple[str, list[_Element], int]:
    if not raw.startswith((b"ply\n", b"ply\r\n")):
        raise InputError(f"{path}: not a PLY file (it does not start with the line 'ply')")
    end = raw.find(b"end_header")
    if end < 0:
        raise InputError(f"{path}: PLY header has no 'end_header' line")
    newline = raw.find(b"\n", end)
    body_start = len(raw) if newline < 0 else newline + 1
    lines = raw[:end].decode("ascii", errors="replace").splitlines()[1:]
    fmt: str | None = None
    elements: list[_Element] = []
    for number, line in enumerate(lines, start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        bad = InputError(f"{path}: PLY header line {number} {line.strip()!r} is malformed")
        if words[0] == "format":
            if len(words) != 3 or words[1] not in _FORMATS:
                raise InputError(
                    f"{path}: PLY format {' '.join(words[1:])!r}; expected one of {sorted(_FORMATS)}"
                )
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise bad
            elements.append(_Element(words[1], int(words[2]), []))
        elif words[0] == "property":
            if not elements:
                raise bad
            if len(words) == 5 and words[1] == "list":
                if words[2] not in _SCALARS or words[3] not in _SCALARS:
                    raise bad
                prop = _Property(words[4], _SCALARS[words[3]], _SCALARS[words[2]])
            elif len(words) == 3 and words[1] in _SCALARS:
                prop = _Property(words[2], _SCALARS[words[1]])
            else:
                raise bad
            elements[-1].properties.append(prop)
        else:
            raise bad
    if fmt is None:
        raise InputError(f"{path}: PLY header has no 'format' line")
    return fmt, elements, body_start


class _Body:
    """The data after the header, read element by element."""

    def __init__(self, raw: bytes, start: int, fmt: str, path: Path) -> None:
        self.path = path
        self.order = _FORMATS[fmt]
        if self.order is None:
            self.tokens = raw[start:].split()
            self.pos = 0
        else:
            self.raw = raw
            self.pos = start

    def _short(self, element: _Element, got: str) -> InputError:
        return InputError(
            f"{self.path}: the data ends inside element {element.name!r} ({element.count} declared; {got})"
        )

    def read(self, element: _Element) -> dict[str, np.ndarray | list[np.ndarray]]:
        """Every property of `element`: a (count,) array, or for a list property one array per row."""
        if any(p.count_dtype for p in element.properties):
            triangles = self._read_triangles(element)
            return triangles if triangles is not None else self._read_rows(element)
        if self.order is None:
            width = len(element.properties)
            block = self.tokens[self.pos : self.pos + element.count * width]
            if len(block) < element.count * width:
                raise self._short(element, f"{len(block)} of {element.count * width} values")
            self.pos += len(block)
            table = self._numbers(block, element).reshape(element.count, width)
            return {p.name: table[:, i] for i, p in enumerate(element.properties)}
        record = np.dtype([(p.name, self.order + p.dtype) for p in element.properties])
        size = element.count * record.itemsize
        if self.pos + size > len(self.raw):
            raise self._short(element, f"{len(self.raw) - self.pos} of {size} bytes")
        rows = np.frombuffer(self.raw, record, element.count, self.pos)
        self.pos += size
        return {p.name: rows[p.name].astype(np.float64) for p in element.properties}

    def _numbers(self, tokens: list[bytes], element: _Element) -> np.ndarray:
        try:
            return np.array(tokens, dtype=np.float64)
        except ValueError:
            bad = next(t for t in tokens if not _is_number(t))
            raise InputError(
                f"{self.path}: element {element.name!r} holds {bad.decode(errors='replace')!r}, "
                "which is not a number"
            ) from None

    def _scalar(self, dtype: str, element: _Element) -> float:
        if self.order is None:
            if self.pos >= len(self.tokens):
                raise self._short(element, "fewer values than declared")
            value = self._numbers(self.tokens[self.pos : self.pos + 1], element)[0]
            self.pos += 1
            return float(value)
        item = np.dtype(self.order + dtype)
        if self.pos + item.itemsize > len(self.raw):
            raise self._short(element, "fewer bytes than declared")
        value = np.frombuffer(self.raw, item, 1, self.pos)[0]
        self.pos += item.itemsize
        return float(value)

    def _read_triangles(self, element: _Element) -> dict[str, list[np.ndarray]] | None:
        """The common case at array speed: one list property, every row of length 3; else None."""
        if len(element.properties) != 1:
            return None
        prop = element.properties[0]
        if self.order is None:
            block = self.tokens[self.pos : self.pos + 4 * element.count]
            if len(block) < 4 * element.count:
                return None
            try:
                table = np.array(block, np.float64).reshape(element.count, 4)
            except ValueError:
                return None
            size = len(block)
        else:
            record = np.dtype(
                [("n", self.order + prop.count_dtype), ("i", self.order + prop.dtype, (3,))]
            )
            size = element.count * record.itemsize
            if self.pos + size > len(self.raw):
                return None
            rows = np.frombuffer(self.raw, record, element.count, self.pos)
            table = np.column_stack([rows["n"], rows["i"]]).astype(np.float64)
        if not (table[:, 0] == 3).all():
            return None
        self.pos += size
        return {prop.name: list(table[:, 1:])}

    def _read_rows(self, element: _Element) -> dict[str, np.ndarray | list[np.ndarray]]:
        columns: dict[str, list] = {p.name: [] for p in element.properties}
        for _ in range(element.count):
            for p in element.properties:
                if p.count_dtype is None:
                    columns[p.name].append(self._scalar(p.dtype, element))
                    continue
                length = self._scalar(p.count_dtype, element)
                if not 0 <= length < 2**20 or length != int(length):
                    raise InputError(
                        f"{self.path}: element {element.name!r} has a list of length {length}"
                    )
                values = [self._scalar(p.dtype, element) for _ in range(int(length))]
                columns[p.name].append(np.asarray(values, np.float64))
        return {
            p.name: columns[p.name] if p.count_dtype else np.asarray(columns[p.name], np.float64)
            for p in element.properties
        }


def _is_number(token: bytes) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _triangles(polygons: list[np.ndarray], n_vertices: int, path: Path) -> np.ndarray:
    """Polygons (vertex index lists) fanned into triangles; polygons of fewer than 3 vertices are dropped."""
    if polygons and all(len(poly) == 3 for poly in polygons):
        out = np.asarray(polygons, np.float64).reshape(-1, 3)
    else:
        triangles = [
            (poly[0], poly[i], poly[i + 1]) for poly in polygons for i in range(1, len(poly) - 1)
        ]
        out = np.asarray(triangles, np.float64).reshape(-1, 3)
    bad = (out < 0) | (out >= n_vertices) | (out != np.floor(out))
    if bad.any():
        value = out[bad][0]
        raise InputError(
            f"{path}: a face refers to vertex {value:g}; expected an index in 0..{n_vertices - 1}"
        )
    return out.astype(np.int64)


def read_ply(path: str | Path) -> PlyGeometry:
    """Read a PLY file's vertex positions and faces, refusing any file it cannot read whole.

    Args:
        path: a .ply file, ascii or binary.

    Returns:
        The vertices (x, y, z of element `vertex`) and the faces' triangles.

    Raises:
        InputError: naming the file and the reason: not a PLY file, a malformed header, no vertex element
            or no x/y/z, data shorter than the header declares, a value that is not a number, a non-finite
            position, or a face index out of range.

    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{p}: cannot read the PLY file ({exc.strerror})") from exc
    fmt, elements, start = _header(raw, p)
    body = _Body(raw, start, fmt, p)
    points: np.ndarray | None = None
    polygons: list[np.ndarray] = []
    for element in elements:
        values = body.read(element)
        if element.name == "vertex":
            missing = [axis for axis in "xyz" if axis not in values]
            if missing:
                raise InputError(f"{p}: the PLY vertex element has no property {missing}")
            points = np.stack([np.asarray(values[axis], np.float64) for axis in "xyz"], axis=1)
        elif element.name == "face":
            key = next((k for k in _FACE_LISTS if k in values), None)
            if key is None:
                raise InputError(f"{p}: the PLY face element has no list {list(_FACE_LISTS)}")
            polygons = list(values[key])
    if points is None:
        raise InputError(f"{p}: the PLY file has no vertex element")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{p}: vertex {row} is {points[row].tolist()}; positions must be finite numbers"
        )
    return PlyGeometry(points, _triangles(polygons, len(points), p))
