"""diffavatar_node: the ROS 2 asset service (thin: all computation is diffavatar_core's).

Front doors, both feeding one FIFO JobQueue:
  ~/scans     diffavatar_msgs/SegmentedScan      topic (capture rigs, batch jobs)
  ~/optimize  diffavatar_msgs/action/OptimizeAvatar  action (feedback = progress, cancel)
Outputs:
  ~/progress  diffavatar_msgs/OptimizationProgress  every iteration of every job
  ~/result    diffavatar_msgs/AvatarAssets   RELIABLE + TRANSIENT_LOCAL + KEEP_LAST(result_history)
  ~/status    diagnostic_msgs/DiagnosticArray  queue length, current job, last error (1 Hz)
Control:
  ~/cancel    std_msgs/String  job id to cancel (queued or running)
Every result is also written to <output_dir>/<job_id>/ (the CLI's files), so nothing is lost
when nobody listens. Bad input never stops the node: it is answered with an error result.
"""
from __future__ import annotations

import os
import pathlib
import threading
import time

# Fast DDS drops messages above its 512 KB default shared-memory segment (rmw_fastrtps#576):
# use its documented large-data transport unless the user configured one. Must precede init.
os.environ.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "LARGE_DATA")

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,  # noqa: E402
                                SetParametersResult)
from rclpy.action import ActionServer, CancelResponse, GoalResponse  # noqa: E402
from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from diffavatar_msgs.action import OptimizeAvatar  # noqa: E402
from diffavatar_msgs.msg import AvatarAssets, OptimizationProgress, SegmentedScan  # noqa: E402

from . import convert  # noqa: E402
from .job_queue import Job, JobQueue, JobState  # noqa: E402

NODE_NAME = "diffavatar_node"


def result_qos(depth: int) -> QoSProfile:
    """Latched results: late subscribers get the last `depth` results (Nav2 map_server style)."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


class DiffAvatarNode(Node):
    """run_job(job, progress) -> RecoveryResult is what a job does; the default runs the
    recovery pipeline (diffavatar_ros.jobs.run_recovery). `progress(stage, iteration,
    max_iterations, loss, terms)` publishes an OptimizationProgress."""

    PARAMS = {
        # name: (default, description, read_only, range)
        "queue_length": (8, "maximum jobs waiting (a full queue answers with ERROR_QUEUE_FULL); applies to new submissions", False, (1, 1000)),
        "result_history": (10, "results kept for late subscribers of ~/result (KEEP_LAST depth)", True, (1, 1000)),
        "output_dir": ("diffavatar_results", "directory where every result is also written, one sub-directory per job id", False, None),
        "max_vertices": (2_000_000, "largest scan accepted (vertices); larger scans get ERROR_TOO_LARGE", False, (1, 100_000_000)),
        "default_iterations": (30, "optimization iterations when a scan asks for 0", False, (1, 10_000)),
        "threads": (2, "OpenMP threads of the core (fixed at start-up)", True, (1, 256)),
        "status_period_s": (1.0, "period of ~/status, s", True, (0.05, 60.0)),
    }

    def __init__(self, run_job=None, **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        for name, (default, desc, read_only, rng) in self.PARAMS.items():
            d = ParameterDescriptor(description=desc, read_only=read_only)
            if isinstance(default, int) and rng:
                d.integer_range = [IntegerRange(from_value=rng[0], to_value=rng[1], step=1)]
            elif isinstance(default, float) and rng:
                d.floating_point_range = [FloatingPointRange(from_value=rng[0], to_value=rng[1], step=0.0)]
            self.declare_parameter(name, default, d)
        self.add_on_set_parameters_callback(self._validate_parameters)
        if run_job is None:
            from .jobs import run_recovery
            run_job = run_recovery
        self._run_job = run_job
        import diffavatar_core
        diffavatar_core.set_num_threads(self.get_parameter("threads").value)

        self._group = ReentrantCallbackGroup()
        self._progress_pub = self.create_publisher(OptimizationProgress, "~/progress", 50)
        self._result_pub = self.create_publisher(AvatarAssets, "~/result",
                                                 result_qos(self.get_parameter("result_history").value))
        self._status_pub = self.create_publisher(DiagnosticArray, "~/status", 10)
        self.create_subscription(SegmentedScan, "~/scans", self._on_scan,
                                 QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
                                 callback_group=self._group)
        self.create_subscription(String, "~/cancel", self._on_cancel, 10, callback_group=self._group)
        self._action = ActionServer(self, OptimizeAvatar, "~/optimize", execute_callback=self._execute,
                                    goal_callback=lambda goal: GoalResponse.ACCEPT,
                                    cancel_callback=lambda handle: CancelResponse.ACCEPT,
                                    callback_group=self._group)
        self._queue = JobQueue(self._work, max_length=self.get_parameter("queue_length").value,
                               on_finished=self._on_finished, log=lambda m: self.get_logger().error(m))
        self._latest_progress: dict[str, OptimizationProgress] = {}
        self._lock = threading.Lock()
        self.create_timer(self.get_parameter("status_period_s").value, self._publish_status,
                          callback_group=self._group)
        self.get_logger().info(f"ready: {self.resolve_topic_name('~/scans')}, action "
                               f"{self.resolve_topic_name('~/optimize')}")

    # -- parameters ------------------------------------------------------------------------
    def _validate_parameters(self, params) -> SetParametersResult:
        for p in params:
            if p.name == "output_dir" and not str(p.value).strip():
                return SetParametersResult(successful=False, reason="output_dir must not be empty")
            if p.name == "queue_length":
                self._queue.max_length = int(p.value)  # applies to the next submission
        return SetParametersResult(successful=True)

    # -- intake ----------------------------------------------------------------------------
    def submit(self, scan: SegmentedScan) -> Job:
        payload = {"arrays": convert.msg_to_arrays(scan),
                   "max_vertices": self.get_parameter("max_vertices").value,
                   "default_iterations": self.get_parameter("default_iterations").value,
                   "output_dir": self.get_parameter("output_dir").value}
        job = self._queue.submit(payload, job_id=scan.job_id)
        if job.state is JobState.QUEUED:
            self._publish_progress(job.job_id, "queued", 0, 0, float("nan"), {}, job)
        return job

    def _on_scan(self, msg: SegmentedScan):
        self.submit(msg)

    def _on_cancel(self, msg: String):
        if not self._queue.cancel(msg.data):
            self.get_logger().warn(f"cancel: no queued or running job {msg.data!r}")

    def _execute(self, goal_handle):
        job = self.submit(goal_handle.request.scan)
        sent = None
        while not job.done.wait(0.05):
            if goal_handle.is_cancel_requested:
                self._queue.cancel(job.job_id)
            with self._lock:
                fb = self._latest_progress.get(job.job_id)
            if fb is not None and fb is not sent:
                goal_handle.publish_feedback(OptimizeAvatar.Feedback(progress=fb))
                sent = fb
        result = OptimizeAvatar.Result(assets=job.result_msg)
        if job.state is JobState.SUCCEEDED:
            goal_handle.succeed()
        elif job.state is JobState.CANCELLED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return result

    # -- work (worker thread) ----------------------------------------------------------------
    def _work(self, job: Job):
        t0 = time.monotonic()

        def progress(stage, iteration, max_iterations, loss, terms):
            self._publish_progress(job.job_id, stage, iteration, max_iterations, loss, terms, job, t0)

        return self._run_job(job, progress)

    def _publish_progress(self, job_id, stage, iteration, max_iterations, loss, terms, job, t0=None):
        elapsed = time.monotonic() - (t0 if t0 is not None else job.submitted)
        eta = elapsed / iteration * (max_iterations - iteration) if iteration > 0 and max_iterations else -1.0
        msg = convert.progress_msg(job_id, stage, iteration, max_iterations, loss, terms, elapsed, eta)
        msg.header.stamp = self.get_clock().now().to_msg()
        with self._lock:
            self._latest_progress[job_id] = msg
        self._progress_pub.publish(msg)

    def _on_finished(self, job: Job):
        if job.state is JobState.SUCCEEDED:
            msg = convert.result_to_assets(job.job_id, job.result)
        else:
            msg = convert.error_assets(job.job_id, job.error.code, job.error.message)
            self._write_error(job)
        msg.header.stamp = self.get_clock().now().to_msg()
        job.result_msg = msg
        with self._lock:
            self._latest_progress.pop(job.job_id, None)
        self._result_pub.publish(msg)
        level = "info" if job.state is JobState.SUCCEEDED else "warn"
        getattr(self.get_logger(), level)(f"job {job.job_id}: {job.state.value}"
                                          + (f" ({job.error})" if job.error else ""))

    def _write_error(self, job: Job):
        """An error is part of the record too: <output_dir>/<job_id>/error.json."""
        import json
        try:
            d = pathlib.Path(self.get_parameter("output_dir").value) / _safe_dir_name(job.job_id)
            d.mkdir(parents=True, exist_ok=True)
            (d / "error.json").write_text(json.dumps({"job_id": job.job_id, "state": job.state.value,
                                                      "code": job.error.code, "message": job.error.message}))
        except OSError as exc:
            self.get_logger().error(f"could not write the error record of {job.job_id}: {exc}")

    # -- status ----------------------------------------------------------------------------
    def _publish_status(self):
        cur = self._queue.current
        st = DiagnosticStatus(name=f"{self.get_name()}: job queue", hardware_id="diffavatar")
        st.level = DiagnosticStatus.OK
        st.message = f"running {cur.job_id}" if cur else "idle"
        st.values = [KeyValue(key="queue_length", value=str(self._queue.length)),
                     KeyValue(key="current_job", value=cur.job_id if cur else ""),
                     KeyValue(key="last_error", value=self._queue.last_error)]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = self.get_clock().now().to_msg()
        self._status_pub.publish(arr)

    def destroy_node(self):
        self._queue.shutdown()
        super().destroy_node()


def _safe_dir_name(job_id: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in job_id)
    return keep.strip(".") or "job"


def main(args=None):
    rclpy.init(args=args)
    node = DiffAvatarNode()
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
