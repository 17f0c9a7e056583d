"""Compact templates: uint8 descriptors with a per-row offset and step keep what matching needs, in a quarter
of the bytes, and a malformed compact template is refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from atr.errors import InputError
from atr.recognition.template import (
    Template,
    dequantize_descriptors,
    message_storage_bytes,
    quantize_descriptors,
    template_from_message,
)


def _histograms(rng: np.random.Generator, rows: int, bins: int = 352) -> np.ndarray:
    """SHOT-like rows: sparse non-negative histograms of unit norm."""
    h = rng.dirichlet(np.full(bins, 0.2), size=rows).astype(np.float32)
    return h / np.linalg.norm(h, axis=1, keepdims=True)


def test_decoded_descriptors_lie_within_half_a_step_of_the_originals() -> None:
    d = _histograms(np.random.default_rng(1), 200)
    d[0] = 0.25  # a constant row: no range to spread over
    d[1, :] = np.linspace(-3.0, 5.0, d.shape[1])  # negative values (RoPS' moments have them)
    codes, low, step = quantize_descriptors(d)
    assert codes.dtype == np.uint8 and low.shape == step.shape == (len(d),)
    decoded = dequantize_descriptors(codes, low, step)
    assert np.all(np.abs(decoded - d) <= 0.5 * step[:, None] * (1 + 1e-5) + 1e-7)
    assert np.array_equal(decoded[0], d[0])


def test_nearest_template_descriptors_are_kept() -> None:
    rng = np.random.default_rng(2)
    template = _histograms(rng, 2000)
    # scene descriptors: template rows seen again with noise, as a matched scene vertex is
    scene = template[rng.choice(len(template), 300)] + rng.normal(0, 0.01, (300, 352))
    decoded = dequantize_descriptors(*quantize_descriptors(template))

    def nearest(rows: np.ndarray) -> np.ndarray:
        d2 = (scene**2).sum(1)[:, None] - 2 * scene @ rows.T + (rows**2).sum(1)[None]
        return np.argmin(d2, axis=1)

    assert np.mean(nearest(decoded) == nearest(template)) >= 0.99


def _template(descriptors: np.ndarray) -> Template:
    k = len(descriptors)
    return Template(
        target="car",
        descriptor="shot",
        points_m=np.zeros((4, 3), np.float32),
        normals=np.tile(np.float32([0, 0, 1]), (4, 1)),
        keypoints_m=np.arange(3 * k, dtype=np.float32).reshape(k, 3),
        descriptors=descriptors,
        radius_m=3.0,
    )


def test_a_compact_message_decodes_to_the_template_in_a_quarter_of_the_bytes() -> None:
    template = _template(_histograms(np.random.default_rng(3), 500))
    full = template.to_dict() | {"resolution_m": 0.3}
    compact = template.to_dict(compact=True) | {"resolution_m": 0.3}
    assert compact["descriptors"].dtype == np.uint8
    decoded = template_from_message(compact)
    assert decoded.descriptors.dtype == np.float32
    assert (
        np.abs(decoded.descriptors - template.descriptors).max() <= compact["descriptor_step"].max()
    )
    assert np.array_equal(decoded.keypoints_m, template.keypoints_m)
    descriptors_full = full["descriptors"].nbytes
    descriptors_compact = message_storage_bytes(compact) - compact["keypoints_m"].nbytes
    assert descriptors_compact <= 0.26 * descriptors_full


def test_compact_descriptors_without_their_offsets_are_refused_by_name() -> None:
    compact = _template(_histograms(np.random.default_rng(4), 5)).to_dict(compact=True)
    del compact["descriptor_step"]
    with pytest.raises(InputError, match="descriptor_step"):
        Template.from_dict(compact)
    with pytest.raises(InputError, match="one offset and one step per row"):
        dequantize_descriptors(np.zeros((3, 4), np.uint8), np.zeros(3), np.zeros(2))
