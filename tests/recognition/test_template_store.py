"""The template store's disk cache: a warm cache serves exactly the bytes a cold build serves."""

from __future__ import annotations

from pathlib import Path

from atr.config import load_config
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
