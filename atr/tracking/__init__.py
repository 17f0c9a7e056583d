"""Tracks: per-scene detections fused along the orbit into confirmed targets (docs/tracking.md)."""

from atr.tracking.config import TrackingConfig
from atr.tracking.tracker import Track, Tracker, TrackInput, TrackState

__all__ = ["Track", "TrackInput", "TrackState", "Tracker", "TrackingConfig"]
