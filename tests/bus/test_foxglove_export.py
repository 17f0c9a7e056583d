"""The Foxglove export reads back with the mcap library and carries Foxglove's own schemas."""

import numpy as np
from mcap.reader import make_reader

from bus.foxglove_export import export_foxglove
from bus.recording import write_messages


def test_export_lists_foxglove_schemas_and_every_frame(tmp_path):
    T = np.eye(4)
    det = {
        "target": "t72",
        "descriptor": "shot",
        "T_world_target": T,
        "score": 0.8,
        "overlap": 0.7,
        "inliers": 9,
    }
    messages = []
    for k in range(3):
        stamp = 1_000_000_000 + k
        messages += [
            (
                "atr/uav1/camera/image",
                {
                    "stamp_ns": stamp,
                    "seq": k,
                    "frame_seq": k,
                    "encoding": "rgb8",
                    "data": np.full((16, 20, 3), k, np.uint8),
                    "K": np.eye(3),
                },
            ),
            (
                "atr/uav1/pose/camera",
                {"stamp_ns": stamp, "seq": k, "frame_seq": k, "T_world_cam": T},
            ),
            (
                "atr/uav1/sfm/cloud",
                {
                    "stamp_ns": stamp,
                    "seq": k,
                    "source": "sfm-gftt",
                    "frame_seqs": [k],
                    "points_m": np.random.default_rng(k).normal(size=(50, 3)).astype(np.float32),
                },
            ),
            (
                "atr/uav1/detections",
                {"stamp_ns": stamp, "seq": k, "cloud_seq": k, "detections": [det]},
            ),
        ]
    recording, out = tmp_path / "in.mcap", tmp_path / "fox.mcap"
    write_messages(recording, messages)
    counts = export_foxglove(recording, out)
    assert counts == {
        "/uav1/camera/image": 3,
        "/uav1/tf": 3,
        "/uav1/sfm/cloud": 3,
        "/uav1/detections": 3,
    }
    with out.open("rb") as stream:
        reader = make_reader(stream)
        names = {s.name for s in reader.get_summary().schemas.values()}
        assert names == {
            "foxglove.RawImage",
            "foxglove.FrameTransforms",
            "foxglove.PointCloud",
            "foxglove.SceneUpdate",
        }
        cloud_sizes = [
            len(m.data) for _, c, m in reader.iter_messages() if c.topic == "/uav1/sfm/cloud"
        ]
    assert len(cloud_sizes) == 3 and all(size > 50 * 12 for size in cloud_sizes)
    # Deterministic: the same recording exports to the same bytes.
    export_foxglove(recording, tmp_path / "again.mcap")
    assert (tmp_path / "again.mcap").read_bytes() == out.read_bytes()
