"""Export a recording with Foxglove's own schemas, so a person can watch a flight in Foxglove.

Foxglove cannot decode msgpack channels. This writes a second MCAP through the Foxglove SDK with: the camera
images (RawImage), the SfM and LIDAR clouds (PointCloud), the camera trajectory as frame transforms
(world -> camera, estimated and true), and each detection as a labelled 3D box in the world (SceneUpdate).
Message times are the data's stamp_ns, so the export of a recording is the same every time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation

from atr.errors import RecordingError
from bus import codec
from bus.clouds import cloud_points

# Box drawn around a detection, metres (length, width, height of a T-72-sized vehicle, centred 1.1 m up).
DETECTION_BOX_M = (7.0, 3.6, 2.2)


def _parts(T: np.ndarray):  # noqa: ANN202 - (Vector3, Quaternion)
    from foxglove.messages import Quaternion, Vector3

    x, y, z, w = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()
    return (
        Vector3(x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
        Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)),
    )


def _pose(T: np.ndarray):  # noqa: ANN202 - foxglove.messages.Pose
    from foxglove.messages import Pose

    position, orientation = _parts(T)
    return Pose(position=position, orientation=orientation)


def _time(stamp_ns: int):  # noqa: ANN202
    from foxglove.messages import Timestamp

    return Timestamp(sec=int(stamp_ns // 1_000_000_000), nsec=int(stamp_ns % 1_000_000_000))


def _transform(stamp_ns: int, child: str, T: np.ndarray):  # noqa: ANN202
    from foxglove.messages import FrameTransform, FrameTransforms

    translation, rotation = _parts(T)
    return FrameTransforms(
        transforms=[
            FrameTransform(
                timestamp=_time(stamp_ns),
                parent_frame_id="world",
                child_frame_id=child,
                translation=translation,
                rotation=rotation,
            )
        ]
    )


def _cloud(stamp_ns: int, points_m: np.ndarray):  # noqa: ANN202
    from foxglove.messages import PackedElementField, PackedElementFieldNumericType, PointCloud

    f32 = PackedElementFieldNumericType.Float32
    fields = [PackedElementField(name=n, offset=4 * i, type=f32) for i, n in enumerate("xyz")]
    data = np.ascontiguousarray(points_m, np.float32).tobytes()
    return PointCloud(
        timestamp=_time(stamp_ns),
        frame_id="world",
        pose=_pose(np.eye(4)),
        point_stride=12,
        fields=fields,
        data=data,
    )


def _detections(  # noqa: ANN202
    message: dict, ids: list[str] | None = None, texts: list[str] | None = None
):
    from foxglove.messages import (
        Color,
        CubePrimitive,
        SceneEntity,
        SceneUpdate,
        TextPrimitive,
        Vector3,
    )

    entities = []
    for i, det in enumerate(message["detections"]):
        T = np.asarray(det["T_world_target"], np.float64)
        box = T @ np.array(
            [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, DETECTION_BOX_M[2] / 2], [0, 0, 0, 1.0]]
        )
        label = T.copy()
        label[2, 3] += DETECTION_BOX_M[2] + 1.0
        color = (
            Color(r=1.0, g=0.2, b=0.1, a=0.5)
            if det["target"] == "t72"
            else Color(r=0.2, g=0.6, b=1.0, a=0.5)
        )
        entities.append(
            SceneEntity(
                timestamp=_time(message["stamp_ns"]),
                frame_id="world",
                id=ids[i] if ids else f"detection-{i}",
                cubes=[
                    CubePrimitive(
                        pose=_pose(box),
                        size=Vector3(
                            x=DETECTION_BOX_M[0], y=DETECTION_BOX_M[1], z=DETECTION_BOX_M[2]
                        ),
                        color=color,
                    )
                ],
                texts=[
                    TextPrimitive(
                        pose=_pose(label),
                        billboard=True,
                        font_size=14.0,
                        scale_invariant=True,
                        color=Color(r=1, g=1, b=1, a=1),
                        text=texts[i]
                        if texts
                        else f"{det['target']} {det['score']:.2f} ({det['descriptor']})",
                    )
                ],
            )
        )
    return SceneUpdate(entities=entities)


def _tracks(message: dict):  # noqa: ANN202 - the confirmed and lost tracks as boxes labelled with their ids
    shown = [t for t in message["tracks"] if t["state"] != "tentative"]
    return _detections(
        {
            "stamp_ns": message["stamp_ns"],
            "detections": [t | {"score": 0.0, "descriptor": ""} for t in shown],
        },
        ids=[f"track-{t['id']}" for t in shown],
        texts=[f"track {t['id']} {t['target']} {t['state']} ({t['hits']} hits)" for t in shown],
    )


def export_foxglove(in_path: str | Path, out_path: str | Path) -> dict[str, int]:
    """Write `out_path` with Foxglove schemas from recording `in_path`; returns messages per topic.

    Raises:
        RecordingError: the input cannot be read.

    """
    import foxglove
    from foxglove.channels import (
        FrameTransformsChannel,
        PointCloudChannel,
        RawImageChannel,
        SceneUpdateChannel,
    )
    from foxglove.messages import RawImage

    counts: dict[str, int] = {}
    channels: dict[str, object] = {}
    context = foxglove.Context()  # channels of this export only, not the process-wide default

    def log(topic: str, kind: type, message: object, stamp_ns: int) -> None:
        if topic not in channels:
            channels[topic] = kind(topic, context=context)
        channels[topic].log(message, log_time=int(stamp_ns))
        counts[topic] = counts.get(topic, 0) + 1

    try:
        stream = Path(in_path).open("rb")
    except OSError as exc:
        raise RecordingError(f"cannot read {in_path}: {exc}") from exc
    with stream, foxglove.open_mcap(Path(out_path), allow_overwrite=True, context=context):
        for _, channel, record in make_reader(stream).iter_messages(log_time_order=True):
            topic = channel.topic
            parts = topic.split("/")
            try:
                data = codec.unpack(record.data)
            except (
                Exception
            ):  # a bad message stays in the original recording; it has nothing to show
                continue
            stamp = data.get("stamp_ns", 0) if isinstance(data, dict) else 0
            if topic.endswith("/camera/image"):
                image = data["data"]
                log(
                    f"/{parts[1]}/camera/image",
                    RawImageChannel,
                    RawImage(
                        timestamp=_time(stamp),
                        frame_id="camera",
                        width=int(image.shape[1]),
                        height=int(image.shape[0]),
                        encoding="rgb8" if image.ndim == 3 else "mono8",
                        step=int(image.strides[0]),
                        data=image.tobytes(),
                    ),
                    stamp,
                )
            elif topic.endswith("/sfm/cloud") or topic.endswith("/lidar/cloud"):
                log(
                    "/" + "/".join(parts[1:]),
                    PointCloudChannel,
                    _cloud(stamp, cloud_points(data)),
                    stamp,
                )
            elif topic.endswith("/pose/camera"):
                log(
                    f"/{parts[1]}/tf",
                    FrameTransformsChannel,
                    _transform(stamp, "camera", data["T_world_cam"]),
                    stamp,
                )
            elif topic.startswith("sim/") and topic.endswith("/truth"):
                log(
                    f"/{parts[1]}/tf_truth",
                    FrameTransformsChannel,
                    _transform(stamp, "camera_truth", data["T_world_cam"]),
                    stamp,
                )
            elif topic.endswith("/detections"):
                log(f"/{parts[1]}/detections", SceneUpdateChannel, _detections(data), stamp)
            elif topic.endswith("/tracks"):
                log(f"/{parts[1]}/tracks", SceneUpdateChannel, _tracks(data), stamp)
    return counts
