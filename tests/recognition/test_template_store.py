"""The template store's disk cache: a warm cache serves exactly the bytes a cold build serves."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from atr.config import load_config
from atr.recognition.template import message_storage_bytes, template_from_message
from atr.template_store import TemplateStore
from bus import codec


def test_a_cached_template_is_served_byte_for_byte_as_built(tmp_path: Path) -> None:
    config = load_config(None, ["pipeline.targets=[car]"])
    built = codec.encode("Template", TemplateStore(config, tmp_path).message("car", "fpfh"))
    assert [p.suffix for p in tmp_path.iterdir()] == [".npz"]
    cached = codec.encode("Template", TemplateStore(config, tmp_path).message("car", "fpfh"))
    assert cached == built  # same arrays, same fields, same key order on the wire


def test_a_damaged_cache_file_is_rebuilt_not_trusted(tmp_path: Path) -> None:
    config = load_config(None, ["pipeline.targets=[car]"])
    built = codec.encode("Template", TemplateStore(config, tmp_path).message("car", "fpfh"))
    (cache,) = tmp_path.iterdir()
    cache.write_bytes(cache.read_bytes()[:100])
    rebuilt = codec.encode("Template", TemplateStore(config, tmp_path).message("car", "fpfh"))
    assert rebuilt == built


def test_the_store_serves_compact_templates_that_the_schema_accepts(tmp_path: Path) -> None:
    compact = TemplateStore(load_config(None, ["pipeline.targets=[car]"]), tmp_path)
    full = TemplateStore(
        load_config(None, ["pipeline.targets=[car]", "recognition.compact_descriptors=false"]),
        tmp_path,
    )
    small, large = compact.message("car", "fpfh"), full.message("car", "fpfh")
    assert small["descriptors"].dtype == np.uint8 and large["descriptors"].dtype == np.float32
    assert small["cache_key"] != large["cache_key"]  # the setting keys the cache
    codec.encode("Template", small)  # validates against schemas/Template.json
    assert message_storage_bytes(small) < 0.5 * message_storage_bytes(large)
    decoded = template_from_message(small).descriptors
    assert np.abs(decoded - large["descriptors"]).max() <= small["descriptor_step"].max()
