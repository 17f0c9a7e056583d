"""RecognitionConfig: three parts, every field reachable by its own name, the template cache keyed on
the template part alone."""

import dataclasses

import pytest

from atr.config import load_config
from atr.errors import ConfigError
from atr.recognition import GroundConfig, MatcherConfig, RecognitionConfig, TemplateConfig


def test_every_field_is_set_and_read_by_its_name_and_lands_in_its_part():
    parts = (("template", TemplateConfig), ("matcher", MatcherConfig), ("ground", GroundConfig))
    names = [(part, f.name) for part, cls in parts for f in dataclasses.fields(cls)]
    assert len({n for _, n in names}) == len(names) == 60  # unique across the parts
    for part, name in names:
        default = getattr(getattr(RecognitionConfig(), part), name)
        if isinstance(default, bool | str | tuple):
            value = default
        else:  # another valid value
            value = default + 1 if isinstance(default, int) else default * 0.5
        for config in (
            load_config(
                overrides=[f"recognition.{name}={value!r}".replace("(", "[").replace(")", "]")]
            ),
            load_config(
                overrides=[
                    f"recognition.{part}.{name}={value!r}".replace("(", "[").replace(")", "]")
                ]
            ),
        ):
            got = config.recognition
            assert getattr(got, name) == getattr(getattr(got, part), name) == pytest.approx(value)
    assert dataclasses.replace(RecognitionConfig(), knndr_k=5).matcher.knndr_k == 5
    assert RecognitionConfig(k_terrain_step=3.0).ground.k_terrain_step == 3.0


def test_bad_names_and_values_are_refused_with_the_name():
    with pytest.raises(ConfigError, match="bogus"):
        RecognitionConfig(bogus=1)
    with pytest.raises(ConfigError, match="bogus"):
        load_config(overrides=["recognition.bogus=1"])
    with pytest.raises(ConfigError, match="sift"):
        load_config(overrides=["recognition.descriptor=sift"])
    with pytest.raises(ConfigError, match="knndr_ratio"):
        RecognitionConfig(knndr_ratio=1.5)


def test_template_cache_key_ignores_matcher_and_ground_settings():
    from atr.sim.vehicles import car
    from atr.template_store import cache_key

    mesh = car()
    base = cache_key(mesh, "shot", load_config())
    for override in (
        "recognition.knndr_k=5",
        "recognition.k_terrain_step=9",
        "recognition.max_clutter=0.9",
    ):
        assert cache_key(mesh, "shot", load_config(overrides=[override])) == base, override
    for override in (
        "recognition.normal_k=6",
        "recognition.template_distance_m=80",
        "recognition.k_ground_cut=2",
    ):
        assert cache_key(mesh, "shot", load_config(overrides=[override])) != base, override
