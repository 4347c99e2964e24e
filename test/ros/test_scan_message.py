"""SegmentedScan: pure conversion round trip, and a publish/receive round trip over DDS."""
import threading
import time

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy

from diffavatar_msgs.msg import SegmentedScan
from diffavatar_ros.convert import msg_to_arrays, scan_to_msg


def _scan(n=500, seed=0):
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(n, 3)).astype(np.float32)
    F = rng.integers(0, n, size=(2 * n, 3)).astype(np.uint32)
    L = rng.integers(0, 3, size=n).astype(np.uint8)
    return V, F, L


def test_pure_round_trip_is_bit_exact():
    V, F, L = _scan()
    msg = scan_to_msg(V, F, L, ["body", "upper", "dress"], units="cm", up_axis="z", job_id="j1",
                      garment_type="dress", iterations=7)
    a = msg_to_arrays(msg)
    np.testing.assert_array_equal(a["vertices"].reshape(-1, 3), V)
    np.testing.assert_array_equal(a["faces"].reshape(-1, 3), F)
    np.testing.assert_array_equal(a["labels"], L)
    assert (a["units"], a["up_axis"], a["job_id"], a["garment_type"], a["iterations"]) == ("cm", "z", "j1", "dress", 7)
    assert a["label_names"] == ["body", "upper", "dress"]


@pytest.mark.parametrize("kw,match", [({"units": "inch"}, "units"), ({"up_axis": "x"}, "up_axis")])
def test_converter_rejects_bad_fields(kw, match):
    V, F, L = _scan(10)
    with pytest.raises(ValueError, match=match):
        scan_to_msg(V, F, L, **kw)
    with pytest.raises(ValueError, match="labels"):
        scan_to_msg(V, F, L[:-1])


def test_converter_units_are_the_scan_frames():
    """The message takes every unit and up axis the core's scan frame converts (m, cm, mm)."""
    from diffavatar_core.scan.frame import UNITS, UP_ROTATIONS
    V, F, L = _scan(10)
    for units in UNITS:
        for up in UP_ROTATIONS:
            assert msg_to_arrays(scan_to_msg(V, F, L, units=units, up_axis=up))["units"] == units


def test_publish_and_receive_over_dds(ros_context):
    V, F, L = _scan(20000, seed=1)  # ~0.6 MB, above Fast DDS's default 512 KB SHM segment
    sent = scan_to_msg(V, F, L, ["body", "upper"], units="m", job_id="roundtrip")
    pub_node = rclpy.create_node("scan_pub", context=ros_context)
    sub_node = rclpy.create_node("scan_sub", context=ros_context)
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
    got = []
    done = threading.Event()
    sub_node.create_subscription(SegmentedScan, "scans", lambda m: (got.append(m), done.set()), qos)
    pub = pub_node.create_publisher(SegmentedScan, "scans", qos)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(pub_node)
    ex.add_node(sub_node)
    try:
        deadline = time.monotonic() + 20.0
        while not done.is_set() and time.monotonic() < deadline:
            if pub.get_subscription_count() > 0:
                pub.publish(sent)
            ex.spin_once(timeout_sec=0.2)
        assert done.is_set(), "message not received over DDS within 20 s"
        a = msg_to_arrays(got[0])
        np.testing.assert_array_equal(a["vertices"].reshape(-1, 3), V)
        np.testing.assert_array_equal(a["faces"].reshape(-1, 3), F)
        np.testing.assert_array_equal(a["labels"], L)
        assert a["job_id"] == "roundtrip" and got[0].header.frame_id == "scan"
    finally:
        ex.shutdown()
        pub_node.destroy_node()
        sub_node.destroy_node()
