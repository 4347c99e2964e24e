"""Pure conversions between numpy arrays and diffavatar_msgs messages (no ROS graph needed).

Bulk data travels as flat primitive arrays (float32[] / uint32[] / uint8[]) so rclpy takes its
fast buffer path; reading uses np.frombuffer (no per-element Python objects).
"""
from __future__ import annotations

import numpy as np

from diffavatar_msgs.msg import SegmentedScan

UNITS = ("m", "cm")
UP_AXES = ("y", "z")


def scan_to_msg(vertices, faces, labels=None, label_names=(), *, units: str = "m", up_axis: str = "y",
                job_id: str = "", garment_type: str = "", template_name: str = "",
                iterations: int = 0, frame_id: str = "scan") -> SegmentedScan:
    """SegmentedScan from vertices (V, 3) in `units`, faces (F, 3), optional per-vertex labels (V,)."""
    V = np.ascontiguousarray(vertices, dtype=np.float32)
    F = np.ascontiguousarray(faces, dtype=np.uint32)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"vertices: expected shape (V, 3), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"faces: expected shape (F, 3), got {F.shape}")
    if units not in UNITS:
        raise ValueError(f"units: expected one of {UNITS}, got {units!r}")
    if up_axis not in UP_AXES:
        raise ValueError(f"up_axis: expected one of {UP_AXES}, got {up_axis!r}")
    msg = SegmentedScan()
    msg.header.frame_id = frame_id
    msg.job_id = job_id
    msg.vertices = V.ravel()
    msg.faces = F.ravel()
    if labels is not None:
        L = np.ascontiguousarray(labels, dtype=np.uint8)
        if L.shape != (V.shape[0],):
            raise ValueError(f"labels: expected shape ({V.shape[0]},), got {L.shape}")
        msg.labels = L.tobytes()
    msg.label_names = [str(n) for n in label_names]
    msg.units = units
    msg.up_axis = up_axis
    msg.garment_type = garment_type
    msg.template_name = template_name
    msg.iterations = int(iterations)
    return msg


def msg_to_arrays(msg: SegmentedScan) -> dict:
    """Flat arrays of a SegmentedScan as numpy views, unvalidated (validation belongs to the
    core's scan loader, which names every problem): vertices (3V,) float32, faces (3F,) uint32,
    labels (V,) uint8, plus the scalar fields."""
    return {
        "vertices": np.frombuffer(msg.vertices, dtype=np.float32),
        "faces": np.frombuffer(msg.faces, dtype=np.uint32),
        "labels": np.frombuffer(bytes(msg.labels), dtype=np.uint8),
        "label_names": list(msg.label_names),
        "units": msg.units,
        "up_axis": msg.up_axis,
        "job_id": msg.job_id,
        "garment_type": msg.garment_type,
        "template_name": msg.template_name,
        "iterations": int(msg.iterations),
    }
