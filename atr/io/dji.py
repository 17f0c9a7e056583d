"""Reader of DJI drone photos: EXIF GPS and focal length, XMP gimbal/flight attitude, and the
camera pose they imply.

Plain-Python parser of the JPEG APP1 segments (EXIF/TIFF and XMP); no imaging library is needed.
World frame of the poses: local ENU (x east, y north, z up, metres) at a chosen geodetic origin;
camera frame: OpenCV (x right, y down, z forward).
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atr.errors import InputError

# WGS84 ellipsoid.
_WGS84_A_M = 6378137.0
_WGS84_F = 1.0 / 298.257223563
_WGS84_E2 = _WGS84_F * (2.0 - _WGS84_F)

# EXIF / TIFF tags.
_TAG_EXIF_IFD = 0x8769
_TAG_GPS_IFD = 0x8825
_TAG_FOCAL_LENGTH = 0x920A
_TAG_PIXEL_X = 0xA002
_TAG_PIXEL_Y = 0xA003
_GPS_LAT_REF, _GPS_LAT, _GPS_LON_REF, _GPS_LON, _GPS_ALT_REF, _GPS_ALT = 1, 2, 3, 4, 5, 6
_TIFF_TYPE_SIZE = {1: 1, 2: 1, 3: 2, 4: 4, 5: 8, 7: 1, 9: 4, 10: 8}

_XMP_ATTRIBUTE = re.compile(rb'drone-dji:(\w+)="([^"]*)"')
_XMP_ELEMENT = re.compile(rb"<drone-dji:(\w+)>([^<]*)</drone-dji:\1>")

# Camera axes (OpenCV: x right, y down, z forward) expressed in the gimbal body frame
# (x forward, y right, z down, the aerospace convention of DJI's yaw/pitch/roll).
_R_GIMBAL_CV = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
# North-east-down to east-north-up.
_R_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class DjiPhotoMeta:
    """Metadata of one DJI photo.

    Attributes:
        latitude_deg, longitude_deg: EXIF GPS position, WGS84 degrees (north, east positive).
        gps_altitude_m: EXIF GPS altitude, metres (DJI writes the barometric absolute altitude).
        relative_altitude_m: XMP RelativeAltitude, metres above the take-off point (barometer).
        focal_length_mm: EXIF focal length, millimetres.
        width_px, height_px: EXIF pixel dimensions.
        gimbal_yaw_deg, gimbal_pitch_deg, gimbal_roll_deg: XMP camera attitude in NED, degrees
            (yaw from north clockwise, pitch -90 = nadir).
        flight_yaw_deg, flight_pitch_deg, flight_roll_deg: XMP airframe attitude, degrees.
        model: camera model (XMP tiff:Model), e.g. "FC300S".

    """

    latitude_deg: float
    longitude_deg: float
    gps_altitude_m: float
    relative_altitude_m: float
    focal_length_mm: float
    width_px: int
    height_px: int
    gimbal_yaw_deg: float
    gimbal_pitch_deg: float
    gimbal_roll_deg: float
    flight_yaw_deg: float
    flight_pitch_deg: float
    flight_roll_deg: float
    model: str


def read_dji_metadata(path: str | Path) -> DjiPhotoMeta:
    """Read GPS, focal length and attitude of a DJI JPEG.

    Args:
        path: the JPEG file.

    Returns:
        The photo's metadata.

    Raises:
        InputError: unreadable file, not a JPEG, or a required EXIF/XMP field missing.

    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read DJI photo {path}: {exc}") from exc
    if data[:2] != b"\xff\xd8":
        raise InputError(f"{path} is not a JPEG (no SOI marker)")
    exif = _parse_exif(_find_exif_segment(data, path), path)
    xmp = _parse_xmp(data)
    model_match = re.search(rb'tiff:Model="([^"]*)"', data)

    def xmp_float(name: str) -> float:
        if name not in xmp:
            raise InputError(f"{path}: XMP field drone-dji:{name} missing")
        return float(xmp[name])

    return DjiPhotoMeta(
        latitude_deg=exif["latitude_deg"],
        longitude_deg=exif["longitude_deg"],
        gps_altitude_m=exif["altitude_m"],
        relative_altitude_m=xmp_float("RelativeAltitude"),
        focal_length_mm=exif["focal_length_mm"],
        width_px=int(exif["width_px"]),
        height_px=int(exif["height_px"]),
        gimbal_yaw_deg=xmp_float("GimbalYawDegree"),
        gimbal_pitch_deg=xmp_float("GimbalPitchDegree"),
        gimbal_roll_deg=xmp_float("GimbalRollDegree"),
        flight_yaw_deg=xmp_float("FlightYawDegree"),
        flight_pitch_deg=xmp_float("FlightPitchDegree"),
        flight_roll_deg=xmp_float("FlightRollDegree"),
        model=model_match.group(1).decode("ascii", "replace") if model_match else "",
    )


def enu_from_geodetic(
    latitude_deg: float,
    longitude_deg: float,
    altitude_m: float,
    origin_latitude_deg: float,
    origin_longitude_deg: float,
    origin_altitude_m: float,
) -> np.ndarray:
    """Local east-north-up coordinates of a WGS84 position relative to an origin.

    Returns:
        (3,) float64, metres (east, north, up).

    """
    ecef = _ecef(latitude_deg, longitude_deg, altitude_m)
    origin = _ecef(origin_latitude_deg, origin_longitude_deg, origin_altitude_m)
    lat, lon = math.radians(origin_latitude_deg), math.radians(origin_longitude_deg)
    R_enu_ecef = np.array(
        [
            [-math.sin(lon), math.cos(lon), 0.0],
            [-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)],
            [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)],
        ]
    )
    return R_enu_ecef @ (ecef - origin)


def R_world_cam_from_gimbal(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """ENU-from-camera rotation of a gimbal attitude (DJI: Z-Y-X yaw, pitch, roll in NED).

    Args:
        yaw_deg: heading of the optical axis from north, clockwise, degrees.
        pitch_deg: elevation of the optical axis, degrees (-90 = looking straight down).
        roll_deg: rotation about the optical axis, degrees.

    Returns:
        (3, 3) float64 rotation taking OpenCV camera axes to ENU world axes.

    """
    y, p, r = (math.radians(a) for a in (yaw_deg, pitch_deg, roll_deg))
    Rz = np.array([[math.cos(y), -math.sin(y), 0.0], [math.sin(y), math.cos(y), 0.0], [0, 0, 1.0]])
    Ry = np.array(
        [[math.cos(p), 0.0, math.sin(p)], [0.0, 1.0, 0.0], [-math.sin(p), 0, math.cos(p)]]
    )
    Rx = np.array(
        [[1.0, 0.0, 0.0], [0.0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]]
    )
    return _R_ENU_NED @ Rz @ Ry @ Rx @ _R_GIMBAL_CV


def T_world_cam_from_meta(meta: DjiPhotoMeta, origin: DjiPhotoMeta) -> np.ndarray:
    """World-from-camera pose of a photo in the local ENU frame of another photo's position.

    Horizontal position from EXIF GPS; height from the barometric relative altitude (steadier than
    GPS height between photos of one flight); attitude from the gimbal.

    Args:
        meta: the photo whose pose is wanted.
        origin: the photo whose GPS position (at take-off height) is the ENU origin.

    Returns:
        (4, 4) float64 T_world_cam; the origin of the world frame is on the take-off ground level.

    """
    enu = enu_from_geodetic(
        meta.latitude_deg, meta.longitude_deg, 0.0, origin.latitude_deg, origin.longitude_deg, 0.0
    )
    T = np.eye(4)
    T[:3, :3] = R_world_cam_from_gimbal(
        meta.gimbal_yaw_deg, meta.gimbal_pitch_deg, meta.gimbal_roll_deg
    )
    T[:3, 3] = [enu[0], enu[1], meta.relative_altitude_m]
    return T


def intrinsics_from_focal(
    focal_length_mm: float, sensor_width_mm: float, width_px: int, height_px: int
) -> np.ndarray:
    """Pinhole camera matrix from the lens focal length and the sensor width (square pixels,
    principal point at the image centre, no distortion).

    Args:
        focal_length_mm: lens focal length, millimetres.
        sensor_width_mm: width of the sensor area that the image spans, millimetres.
        width_px, height_px: image size in pixels.

    Returns:
        (3, 3) float64 K in pixels.

    Raises:
        InputError: non-positive values.

    """
    if not (focal_length_mm > 0 and sensor_width_mm > 0 and width_px > 0 and height_px > 0):
        raise InputError(
            f"focal {focal_length_mm} mm, sensor width {sensor_width_mm} mm and image size "
            f"{width_px}x{height_px} px must all be > 0"
        )
    f_px = focal_length_mm / sensor_width_mm * width_px
    return np.array(
        [[f_px, 0.0, (width_px - 1) / 2], [0.0, f_px, (height_px - 1) / 2], [0, 0, 1.0]]
    )


# Internals


def _ecef(latitude_deg: float, longitude_deg: float, altitude_m: float) -> np.ndarray:
    lat, lon = math.radians(latitude_deg), math.radians(longitude_deg)
    n = _WGS84_A_M / math.sqrt(1.0 - _WGS84_E2 * math.sin(lat) ** 2)
    return np.array(
        [
            (n + altitude_m) * math.cos(lat) * math.cos(lon),
            (n + altitude_m) * math.cos(lat) * math.sin(lon),
            (n * (1.0 - _WGS84_E2) + altitude_m) * math.sin(lat),
        ]
    )


def _find_exif_segment(data: bytes, path: Path) -> bytes:
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            break
        marker = data[pos + 1]
        if marker in (0xD9, 0xDA):  # end of image / start of scan: no more metadata
            break
        length = struct.unpack(">H", data[pos + 2 : pos + 4])[0]
        segment = data[pos + 4 : pos + 2 + length]
        if marker == 0xE1 and segment.startswith(b"Exif\x00\x00"):
            return segment[6:]
        pos += 2 + length
    raise InputError(f"{path}: no EXIF (APP1) segment")


def _parse_exif(tiff: bytes, path: Path) -> dict[str, float]:
    if tiff[:2] == b"II":
        endian = "<"
    elif tiff[:2] == b"MM":
        endian = ">"
    else:
        raise InputError(f"{path}: EXIF block has no TIFF byte-order mark")

    def read_ifd(offset: int) -> dict[int, object]:
        if offset + 2 > len(tiff):
            raise InputError(f"{path}: EXIF IFD offset {offset} beyond the block")
        count = struct.unpack(endian + "H", tiff[offset : offset + 2])[0]
        entries: dict[int, object] = {}
        for i in range(count):
            entry = tiff[offset + 2 + 12 * i : offset + 14 + 12 * i]
            tag, kind, n = struct.unpack(endian + "HHI", entry[:8])
            size = _TIFF_TYPE_SIZE.get(kind, 1) * n
            raw = (
                entry[8:12]
                if size <= 4
                else tiff[struct.unpack(endian + "I", entry[8:12])[0] :][:size]
            )
            entries[tag] = _decode_value(kind, n, raw, endian)
        return entries

    ifd0 = read_ifd(struct.unpack(endian + "I", tiff[4:8])[0])
    out: dict[str, float] = {}
    if _TAG_EXIF_IFD in ifd0:
        exif = read_ifd(int(ifd0[_TAG_EXIF_IFD][0]))
        if _TAG_FOCAL_LENGTH in exif:
            out["focal_length_mm"] = float(exif[_TAG_FOCAL_LENGTH][0])
        if _TAG_PIXEL_X in exif and _TAG_PIXEL_Y in exif:
            out["width_px"] = float(exif[_TAG_PIXEL_X][0])
            out["height_px"] = float(exif[_TAG_PIXEL_Y][0])
    if _TAG_GPS_IFD not in ifd0:
        raise InputError(f"{path}: EXIF has no GPS IFD")
    gps = read_ifd(int(ifd0[_TAG_GPS_IFD][0]))
    for tag in (_GPS_LAT_REF, _GPS_LAT, _GPS_LON_REF, _GPS_LON, _GPS_ALT):
        if tag not in gps:
            raise InputError(f"{path}: EXIF GPS tag {tag} missing")
    lat = _dms(gps[_GPS_LAT]) * (-1.0 if gps[_GPS_LAT_REF] == "S" else 1.0)
    lon = _dms(gps[_GPS_LON]) * (-1.0 if gps[_GPS_LON_REF] == "W" else 1.0)
    below_sea = gps.get(_GPS_ALT_REF, (0,))[0] == 1
    out["latitude_deg"] = lat
    out["longitude_deg"] = lon
    out["altitude_m"] = float(gps[_GPS_ALT][0]) * (-1.0 if below_sea else 1.0)
    for key in ("focal_length_mm", "width_px", "height_px"):
        if key not in out:
            raise InputError(f"{path}: EXIF field {key} missing")
    return out


def _decode_value(kind: int, n: int, raw: bytes, endian: str) -> object:
    if kind == 2:
        return raw[:n].split(b"\x00", 1)[0].decode("ascii", "replace")
    if kind in (1, 7):
        return tuple(raw[:n])
    if kind == 3:
        return struct.unpack(endian + f"{n}H", raw[: 2 * n])
    if kind == 4:
        return struct.unpack(endian + f"{n}I", raw[: 4 * n])
    if kind == 9:
        return struct.unpack(endian + f"{n}i", raw[: 4 * n])
    if kind in (5, 10):
        code = "I" if kind == 5 else "i"
        pairs = struct.unpack(endian + f"{2 * n}{code}", raw[: 8 * n])
        return tuple(pairs[2 * i] / pairs[2 * i + 1] if pairs[2 * i + 1] else 0.0 for i in range(n))
    return raw


def _dms(values: object) -> float:
    d, m, s = (float(v) for v in values)  # type: ignore[union-attr]
    return d + m / 60.0 + s / 3600.0


def _parse_xmp(data: bytes) -> dict[str, str]:
    start = data.find(b"<x:xmpmeta")
    end = data.find(b"</x:xmpmeta>", start)
    if start < 0 or end < 0:
        return {}
    block = data[start:end]
    fields = {k.decode(): v.decode() for k, v in _XMP_ATTRIBUTE.findall(block)}
    fields.update({k.decode(): v.decode() for k, v in _XMP_ELEMENT.findall(block)})
    return fields
