"""The one exception tree of the project: every error raised on purpose derives from AtrError."""


class AtrError(Exception):
    """Root of every error this project raises on purpose."""


class ConfigError(AtrError):
    """A configuration value is missing, out of range, or inconsistent with another."""


class SchemaError(AtrError):
    """A message does not match its JSON Schema, or its bytes cannot be decoded."""


class InputError(AtrError):
    """An input (cloud, image, IMU batch, file) is empty, malformed, or otherwise unusable."""


class CalibrationError(AtrError):
    """Camera or IMU calibration is missing or inconsistent."""


class BusError(AtrError):
    """The Zenoh session could not be opened, or a query or publication failed."""


class RecordingError(AtrError):
    """An MCAP recording is missing, truncated, or inconsistent."""
