"""The wire format: msgpack maps, numpy arrays as msgpack extension type 1, checked against the schema.

An array travels as ExtType(1, header + raw little-endian bytes), the header being
`u8 len(dtype) | dtype str | u8 ndim | ndim x u64 shape`. On decode the array is a read-only view on the bytes
msgpack hands over (no further copy). Validation inspects arrays in place (dtype, shape, finiteness).
"""

from __future__ import annotations

import struct
from typing import Any

import msgpack
import numpy as np

from atr.errors import SchemaError
from bus import schemas

NDARRAY_EXT = 1
MAX_MESSAGE_BYTES = 64 * 1024 * 1024  # larger payloads are refused: a 1280x960 RGB frame is 3.7 MB,
# a 262k-point LIDAR scan 3.1 MB, the largest template (T-72, USC or 3DSC: 24 views x ~220 keypoints x
# 1960-1980 floats) 42 MB


def _pack_array(array: np.ndarray) -> msgpack.ExtType:
    if array.dtype.kind not in "biuf" or array.dtype.byteorder == ">":
        raise SchemaError(
            f"array dtype {array.dtype} cannot go on the wire; expected little-endian numbers"
        )
    dtype = array.dtype.str.encode()
    header = struct.pack(
        f"<B{len(dtype)}sB{array.ndim}Q", len(dtype), dtype, array.ndim, *array.shape
    )
    return msgpack.ExtType(NDARRAY_EXT, header + np.ascontiguousarray(array).tobytes())


def _default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return _pack_array(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot encode {type(obj).__name__}")


def _ext_hook(code: int, data: bytes) -> Any:
    if code != NDARRAY_EXT:
        raise SchemaError(
            f"unknown msgpack extension type {code}; expected {NDARRAY_EXT} (ndarray)"
        )
    try:
        (n,) = struct.unpack_from("<B", data, 0)
        dtype = np.dtype(data[1 : 1 + n].decode())
        (ndim,) = struct.unpack_from("<B", data, 1 + n)
        shape = struct.unpack_from(f"<{ndim}Q", data, 2 + n)
        offset = 2 + n + 8 * ndim
        count = int(np.prod(shape)) if ndim else 1
        return np.frombuffer(data, dtype=dtype, count=count, offset=offset).reshape(shape)
    except (struct.error, ValueError, TypeError, UnicodeDecodeError) as exc:
        raise SchemaError(f"malformed ndarray extension ({len(data)} bytes): {exc}") from exc


_LARGE_ARRAY_BYTES = 64 * 1024


def _array_chunks(array: np.ndarray) -> list[bytes | memoryview]:
    # Large top-level arrays are framed by hand (ext 32 header + payload view), so the payload is copied
    # once, by the final join, instead of through msgpack's growing buffer.
    array = np.ascontiguousarray(array)
    dtype = array.dtype.str.encode()
    header = struct.pack(
        f"<B{len(dtype)}sB{array.ndim}Q", len(dtype), dtype, array.ndim, *array.shape
    )
    size = len(header) + array.nbytes
    return [struct.pack(">BIb", 0xC9, size, NDARRAY_EXT), header, memoryview(array).cast("B")]


def pack(message: dict[str, Any]) -> bytes:
    """Msgpack bytes of `message`, without schema validation (tools and tests)."""
    if not isinstance(message, dict):
        return msgpack.packb(message, default=_default, use_bin_type=True)
    packer = msgpack.Packer(default=_default, use_bin_type=True)
    chunks: list[bytes | memoryview] = [packer.pack_map_header(len(message))]
    for key, value in message.items():
        chunks.append(packer.pack(key))
        if isinstance(value, np.ndarray) and value.nbytes >= _LARGE_ARRAY_BYTES:
            if value.dtype.kind not in "biuf" or value.dtype.byteorder == ">":
                raise SchemaError(f"array dtype {value.dtype} cannot go on the wire")
            chunks.extend(_array_chunks(value))
        else:
            chunks.append(packer.pack(value))
    return b"".join(chunks)


def unpack(payload: bytes | bytearray | memoryview) -> Any:
    """Decode msgpack bytes with arrays restored, without schema validation.

    Raises:
        SchemaError: the bytes are not valid msgpack of this format.

    """
    if len(payload) > MAX_MESSAGE_BYTES:
        raise SchemaError(
            f"message of {len(payload)} bytes exceeds the limit of {MAX_MESSAGE_BYTES}"
        )
    try:
        return msgpack.unpackb(payload, ext_hook=_ext_hook, raw=False, strict_map_key=True)
    except SchemaError:
        raise
    except Exception as exc:  # msgpack raises several unrelated types for garbage input
        raise SchemaError(
            f"payload of {len(payload)} bytes is not valid msgpack: {type(exc).__name__} {exc}"
        ) from exc


def encode(message_type: str, message: dict[str, Any]) -> bytes:
    """Validate `message` against the schema of `message_type` and encode it.

    Raises:
        SchemaError: the message breaks its schema.

    """
    schemas.validate(message_type, message)
    return pack(message)


def decode(message_type: str, payload: bytes | bytearray | memoryview) -> dict[str, Any]:
    """Decode `payload` and validate it against the schema of `message_type`.

    Raises:
        SchemaError: the bytes are not msgpack, not a map, or break the schema.

    """
    message = unpack(payload)
    if not isinstance(message, dict):
        raise SchemaError(
            f"{message_type} payload decodes to {type(message).__name__}; expected a map"
        )
    schemas.validate(message_type, message)
    return message


def encode_attachment(seq: int, stamp_ns: int, source: str) -> bytes:
    """The attachment every publication carries: publisher's seq, source stamp and source id."""
    return msgpack.packb([seq, stamp_ns, source])


def decode_attachment(data: bytes | None) -> tuple[int, int, str] | None:
    """(seq, stamp_ns, source) from an attachment, or None when absent or unreadable."""
    if not data:
        return None
    try:
        seq, stamp_ns, source = msgpack.unpackb(data)
        return int(seq), int(stamp_ns), str(source)
    except Exception:  # a foreign publisher's attachment is not ours to trust
        return None
