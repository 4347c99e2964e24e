"""ROS test isolation: each test gets its own rclpy Context on a domain id reserved by
domain_coordinator, discovery limited to localhost (no launch files involved)."""
import os

import pytest

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
rclpy = pytest.importorskip("rclpy", reason="ROS 2 (rclpy) is not installed in this environment")


@pytest.fixture
def ros_domain():
    """A DDS domain id reserved for this test."""
    import domain_coordinator
    with domain_coordinator.domain_id() as domain:
        yield domain


@pytest.fixture
def ros_context(ros_domain):
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain)
    try:
        yield ctx
    finally:
        rclpy.shutdown(context=ctx)


@pytest.fixture
def client_context(ros_domain, ros_context):
    """A second context on the same domain: its own DDS participant, as a separate client is."""
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain)
    try:
        yield ctx
    finally:
        rclpy.shutdown(context=ctx)
