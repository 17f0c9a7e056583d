"""Write messages straight into an MCAP recording, without a bus (simulation to file, tools, tests).

The file has exactly the layout the recorder writes (topic = key, msgpack, jsonschema, zstd chunks), with
log_time = publish_time = the message's stamp_ns, so the same input always gives the same bytes.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from bus import codec, keys, schemas


class McapChannels:
    """Registers one schema per message type and one channel per key on an mcap Writer, on first use."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer
        self._schema_ids: dict[str, int] = {}
        self._channel_ids: dict[str, int] = {}

    def channel_id(self, key: str) -> int:
        """The channel of `key` (registered on first use; schema-less for keys outside the contract)."""
        if key not in self._channel_ids:
            try:
                type_name = keys.message_type(key)
            except Exception:  # a foreign key is recorded too, without a schema
                type_name = None
            schema_id = 0
            if type_name is not None:
                if type_name not in self._schema_ids:
                    self._schema_ids[type_name] = self.writer.register_schema(
                        name=type_name, encoding="jsonschema", data=schemas.schema_bytes(type_name)
                    )
                schema_id = self._schema_ids[type_name]
            self._channel_ids[key] = self.writer.register_channel(
                topic=key, message_encoding="msgpack", schema_id=schema_id
            )
        return self._channel_ids[key]


def write_messages(path: str | Path, messages: Iterable[tuple[str, dict[str, Any]]]) -> int:
    """Validate, encode and write (key, message) pairs into a new MCAP file; returns the count.

    Raises:
        SchemaError: a message breaks its schema.

    """
    count = 0
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile="", library="passive-atr")
        channels = McapChannels(writer)
        for key, data in messages:
            message = {"stamp_ns": 0, "seq": 0, "version": 1} | data
            payload = codec.encode(keys.message_type(key), message)
            writer.add_message(
                channel_id=channels.channel_id(key),
                log_time=message["stamp_ns"],
                data=payload,
                publish_time=message["stamp_ns"],
                sequence=message["seq"],
            )
            count += 1
        writer.finish()
    return count
