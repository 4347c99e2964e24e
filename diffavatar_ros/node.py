"""diffavatar_node: the ROS 2 asset service (thin: all computation is diffavatar_core's).

Front doors, both feeding one FIFO JobQueue:
  ~/scans     diffavatar_msgs/SegmentedScan              topic (capture rigs, batch jobs)
  ~/optimize  diffavatar_msgs/action/OptimizeAvatar      action (feedback = progress, cancel)
Outputs:
  ~/progress  diffavatar_msgs/OptimizationProgress  "queued", then every iteration of every job
  ~/result    diffavatar_msgs/AvatarAssets   RELIABLE + TRANSIENT_LOCAL + KEEP_LAST(result_history)
  ~/status    diagnostic_msgs/DiagnosticArray  queue length, current job, last error
Control:
  ~/cancel    std_msgs/String  job id to cancel (queued or running)
Every result is also written to <output_dir>/<job_id>/ (the CLI's files; error.json for an
error), so nothing is lost when nobody listens. Bad input never stops the node: it is answered
with an error result. What is bad is decided by diffavatar_core.scan, the code the recovery
pipeline preprocesses with: its cheap checks (check_scan) run at the front door, before a job
is queued; those that need the cleaned mesh run in the job, where a ScanError ends the job
with its code just the same.

What a job computes is the injectable `runner(scan, options, run_control) -> RecoveryResult`;
the default is diffavatar_core.pipeline.recover, imported when the first job runs.
"""
from __future__ import annotations

import faulthandler
import json
import math
import os
import pathlib
import signal
import sys
import threading
import time

LARGE_DATA_ENV = "FASTDDS_BUILTIN_TRANSPORTS"
EXIT_GRACE_S = 20.0   # s from a stop signal to the end of the process, at most
SPIN_PERIOD_S = 0.1   # s between two checks for a stop signal
RESULT_FLUSH_S = 0.25  # s the executor spins on after the last goal's result is set, before the server goes


def configure_large_data_transport() -> str:
    """Selects Fast DDS's documented large-data transport (rmw_fastrtps README:
    FASTDDS_BUILTIN_TRANSPORTS=LARGE_DATA: UDP for discovery, TCP + shared memory for data)
    unless the user chose a transport. Without it, messages above the 512 KB default shared-memory
    segment can be dropped (rmw_fastrtps#576). Takes effect for DDS participants created
    afterwards, so it runs at import of this module, before any rclpy context makes one.
    Returns the transport in effect."""
    return os.environ.setdefault(LARGE_DATA_ENV, "LARGE_DATA")


configure_large_data_transport()

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,  # noqa: E402
                                SetParametersResult)
from rclpy.action import ActionServer, CancelResponse, GoalResponse  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup  # noqa: E402
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402
from std_msgs.msg import String  # noqa: E402

import diffavatar_core as dc  # noqa: E402
from diffavatar_core.scan import LabelMap, ScanError, ScanOptions, check_scan  # noqa: E402
from diffavatar_core.config import load_config  # noqa: E402
from diffavatar_msgs.action import OptimizeAvatar  # noqa: E402
from diffavatar_msgs.msg import AvatarAssets, OptimizationProgress, SegmentedScan  # noqa: E402

from . import convert  # noqa: E402
from .job_queue import Job, JobError, JobQueue, JobState  # noqa: E402

NODE_NAME = "diffavatar_node"

# name: (description, read_only, (min, max) or None). Defaults come from config/diffavatar.yaml
# (`node:` section; `threads` from the top level).
PARAMETERS = {
    "queue_length": ("jobs waiting at most; a full queue answers ERROR_QUEUE_FULL (applies to the next submission)",
                     False, (1, 1000)),
    "result_history": ("results latched on ~/result for late subscribers (KEEP_LAST depth; fixed at start-up)",
                       True, (1, 1000)),
    "output_dir": ("directory where every result is also written, one sub-directory per job id "
                   "(applies from the next job)", False, None),
    "max_vertices": ("largest scan accepted, vertices; larger scans get ERROR_TOO_LARGE (applies from the next job)",
                     False, (1, 100_000_000)),
    "default_iterations": ("optimization iterations when a scan asks for 0 (applies from the next job)",
                           False, (1, 100_000)),
    "threads": ("OpenMP threads of the core (fixed at start-up)", True, (1, 256)),
    "status_period_s": ("period of ~/status, s (fixed at start-up)", True, (0.05, 60.0)),
}


def parameter_defaults() -> dict:
    """The node's parameter defaults from the project configuration."""
    cfg = load_config()
    out = dict(cfg["node"])
    out["threads"] = int(cfg["threads"])
    return out


def result_qos(depth: int) -> QoSProfile:
    """Latched results: late subscribers get the last `depth` results (Nav2 map_server style);
    subscribers must use the same profile."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


# Scans and cancels are never dropped by DDS: RELIABLE + KEEP_ALL (a burst of scans waits in
# the reader's history until the node queues each; the job queue then answers every one).
SCAN_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
PROGRESS_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)


class RunControl:
    """What a runner gets to report progress and see cancellation (Python twin of the core's
    RunControl): `cancel` is the job's diffavatar_core.CancelToken (pass it to core calls, which
    stop within one iteration); `check(stage)` raises diffavatar_core.Cancelled once cancelled;
    `report(stage, iteration, max_iterations, loss, terms)` publishes an OptimizationProgress
    (loss in loss units, terms: name -> value)."""

    def __init__(self, cancel: dc.CancelToken, report):
        self.cancel = cancel
        self._report = report

    @property
    def cancelled(self) -> bool:
        return self.cancel.cancelled

    def check(self, stage: str = "") -> None:
        if self.cancel.cancelled:
            raise dc.Cancelled(f"cancelled during {stage}" if stage else "cancelled")

    def report(self, stage: str, iteration: int, max_iterations: int, loss: float = math.nan,
               terms: dict | None = None) -> None:
        self._report(stage, iteration, max_iterations, loss, terms or {})


def default_runner(scan, options, run_control):
    """The recovery pipeline (imported on first use: the node starts without it)."""
    try:
        from diffavatar_core.pipeline import recover
    except ImportError as exc:
        raise JobError("INTERNAL", f"the recovery pipeline diffavatar_core.pipeline.recover is not "
                                   f"available in this installation ({exc})") from None
    return recover(scan, options, run_control)


class _Resume:
    """Awaitable that hands control back to the executor once (rclpy resumes in-progress
    coroutines each time the executor wakes; the worker wakes it through a guard condition)."""

    def __await__(self):
        yield


def _safe_dir_name(job_id: str) -> str:
    keep = "".join(c if c.isalnum() or c in "-_." else "_" for c in job_id)
    return keep.strip(".") or "job"


class DiffAvatarNode(Node):
    """The asset service node. `runner(scan, options, run_control) -> RecoveryResult` is what a
    job computes: scan is a diffavatar_core.scan.CheckedScan (passed check_scan; vertices in
    metres, Y up; diffavatar_core.scan.load_scan(scan) preprocesses it), options
    {"job_id", "iterations"}, run_control a RunControl. Create it on an rclpy context and spin it
    with a MultiThreadedExecutor (main() does)."""

    def __init__(self, runner=None, **node_kwargs):
        super().__init__(NODE_NAME, **node_kwargs)
        defaults = parameter_defaults()
        for name, (desc, read_only, rng) in PARAMETERS.items():
            default = defaults[name]
            d = ParameterDescriptor(description=desc, read_only=read_only)
            if isinstance(default, bool):
                pass
            elif isinstance(default, int) and rng:
                d.integer_range = [IntegerRange(from_value=rng[0], to_value=rng[1], step=1)]
            elif isinstance(default, float) and rng:
                d.floating_point_range = [FloatingPointRange(from_value=float(rng[0]), to_value=float(rng[1]),
                                                             step=0.0)]
            self.declare_parameter(name, default, d)
        for name in ("output_dir",):  # parameters given on the command line bypass the callback
            problem = self._parameter_problem(name, self.get_parameter(name).value)
            if problem:
                raise ValueError(f"parameter {name}: {problem}")
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._runner = runner or default_runner
        # what the front door checks with: the same options and label map as the preprocessing
        self._scan_options = ScanOptions.from_config()
        self._label_map = LabelMap.load()
        dc.set_num_threads(self.get_parameter("threads").value)

        # Intake (scans, cancels, goal requests) is one mutually exclusive group: submissions are
        # queued in arrival order. Each is quick; the jobs themselves run on the worker thread.
        self._intake = MutuallyExclusiveCallbackGroup()
        self._group = ReentrantCallbackGroup()
        self._lock = threading.Lock()
        self._latest_progress: dict[str, OptimizationProgress] = {}
        self._goal_jobs: dict[bytes, Job] = {}
        self._wake = self.create_guard_condition(lambda: None, callback_group=self._group)
        self._progress_pub = self.create_publisher(OptimizationProgress, "~/progress", PROGRESS_QOS)
        self._result_pub = self.create_publisher(AvatarAssets, "~/result",
                                                 result_qos(self.get_parameter("result_history").value))
        self._status_pub = self.create_publisher(DiagnosticArray, "~/status", 10)
        self._queue = JobQueue(self._work, max_length=self.get_parameter("queue_length").value,
                               on_finished=self._on_finished, log=lambda m: self.get_logger().error(m))
        self.create_subscription(SegmentedScan, "~/scans", self._on_scan, SCAN_QOS, callback_group=self._intake)
        self.create_subscription(String, "~/cancel", self._on_cancel, SCAN_QOS, callback_group=self._intake)
        self._action = ActionServer(self, OptimizeAvatar, "~/optimize", execute_callback=self._execute,
                                    goal_callback=lambda goal: GoalResponse.ACCEPT,
                                    handle_accepted_callback=self._on_goal_accepted,
                                    cancel_callback=self._on_goal_cancel, callback_group=self._intake)
        self.create_timer(self.get_parameter("status_period_s").value, self.publish_status,
                          callback_group=self._group)
        self.get_logger().info(f"ready: topic {self.resolve_topic_name('~/scans')}, action "
                               f"{self.resolve_topic_name('~/optimize')}, transport "
                               f"{LARGE_DATA_ENV}={os.environ.get(LARGE_DATA_ENV, '')}")

    @property
    def queue(self) -> JobQueue:
        return self._queue

    # -- parameters ------------------------------------------------------------------------
    @staticmethod
    def _parameter_problem(name, value) -> str:
        if name == "output_dir" and not str(value).strip():
            return "must not be empty"
        return ""

    def _validate_parameters(self, params) -> SetParametersResult:
        for p in params:
            problem = self._parameter_problem(p.name, p.value)
            if problem:
                return SetParametersResult(successful=False, reason=f"{p.name}: {problem}")
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params) -> None:
        for p in params:
            if p.name == "queue_length":
                self._queue.max_length = int(p.value)

    # -- intake ----------------------------------------------------------------------------
    def submit(self, msg: SegmentedScan) -> Job:
        """Validates and queues a scan (from the topic, the action or Python); the job's
        parameters are fixed here. Invalid input or a full queue gives a job that is already
        finished with its error result (it never takes a queue slot)."""
        a = convert.msg_to_arrays(msg)
        try:
            scan = check_scan(a, options=self._scan_options, label_map=self._label_map,
                              max_vertices=self.get_parameter("max_vertices").value)
        except ScanError as err:
            return self._queue.reject(JobError(err.code, str(err)), job_id=msg.job_id,
                                      payload={"output_dir": self.get_parameter("output_dir").value})
        except Exception as exc:  # a bug (or MemoryError) must not take the executor down
            self.get_logger().error(f"validating scan {msg.job_id!r} failed unexpectedly: {exc!r}")
            return self._queue.reject(JobError("INTERNAL", f"validation failed: {type(exc).__name__}: {exc}"),
                                      job_id=msg.job_id, payload={"output_dir": self.get_parameter("output_dir").value})
        payload = {"scan": scan,
                   "options": {"iterations": a["iterations"] or self.get_parameter("default_iterations").value},
                   "output_dir": self.get_parameter("output_dir").value}
        return self._queue.submit(payload, job_id=msg.job_id,
                                  on_queued=lambda job: self._publish_progress(job, "queued", 0, 0, math.nan, {}))

    def _on_scan(self, msg: SegmentedScan):
        self.submit(msg)

    def _on_cancel(self, msg: String):
        if not self._queue.cancel(msg.data):
            self.get_logger().warn(f"cancel: no queued or running job {msg.data!r}")

    def _on_goal_accepted(self, goal_handle) -> None:
        """Queues the goal's scan now, in arrival order with the topic's scans, then starts
        the execute coroutine that follows the job."""
        job = self.submit(goal_handle.request.scan)
        with self._lock:
            self._goal_jobs[bytes(goal_handle.goal_id.uuid)] = job
        goal_handle.execute()

    def _on_goal_cancel(self, goal_handle) -> CancelResponse:
        """Accepts; the goal's coroutine, woken once the goal is CANCELING, cancels its job
        (so a cancelled goal always ends CANCELED, never ABORTED by a race)."""
        self._wake.trigger()
        return CancelResponse.ACCEPT

    async def _execute(self, goal_handle):
        """Runs as a coroutine: it never blocks an executor thread while its job waits or runs."""
        key = bytes(goal_handle.goal_id.uuid)
        with self._lock:
            job = self._goal_jobs[key]
        sent = None
        try:
            while not job.done.is_set():
                if goal_handle.is_cancel_requested and not job.cancel.cancelled:
                    self._queue.cancel(job.job_id)
                    continue
                with self._lock:
                    fb = self._latest_progress.get(job.job_id)
                if fb is not None and fb is not sent:
                    goal_handle.publish_feedback(OptimizeAvatar.Feedback(progress=fb))
                    sent = fb
                await _Resume()
        finally:
            with self._lock:
                self._goal_jobs.pop(key, None)
        if job.state is JobState.SUCCEEDED:
            goal_handle.succeed()
        elif job.state is JobState.CANCELLED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
        return OptimizeAvatar.Result(assets=job.result_msg)

    # -- work (worker thread) ----------------------------------------------------------------
    def _work(self, job: Job):
        options = {"job_id": job.job_id, **job.payload["options"]}
        t0 = time.monotonic()

        def report(stage, iteration, max_iterations, loss, terms):
            self._publish_progress(job, stage, iteration, max_iterations, loss, terms, t0)

        try:
            return self._runner(job.payload["scan"], options, RunControl(job.cancel, report))
        except ScanError as err:  # input problems found while preprocessing in the job
            raise JobError(err.code, str(err)) from None
        except ValueError as err:  # the recovery's named problems (no drape on the body, ...): not bugs
            from diffavatar_core.pipeline.recovery import RecoveryError
            if isinstance(err, RecoveryError):
                raise JobError(err.code, str(err)) from None
            raise

    def _publish_progress(self, job, stage, iteration, max_iterations, loss, terms, t0=None):
        elapsed = time.monotonic() - (t0 if t0 is not None else job.submitted)
        eta = elapsed / iteration * (max_iterations - iteration) if iteration > 0 and max_iterations else -1.0
        msg = convert.progress_msg(job.job_id, stage, iteration, max_iterations, loss, terms, elapsed, eta)
        msg.header.stamp = self.get_clock().now().to_msg()
        with self._lock:
            self._latest_progress[job.job_id] = msg
        self._progress_pub.publish(msg)
        self._wake.trigger()

    def _on_finished(self, job: Job):
        out = pathlib.Path(job.payload["output_dir"]) / _safe_dir_name(job.job_id)
        if job.result is not None and job.state in (JobState.SUCCEEDED, JobState.CANCELLED):
            try:
                from diffavatar_core.pipeline.output import write_result
                write_result(job.result, out, scan=getattr(job.result, "scan_mesh", None))
                (out / "error.json").unlink(missing_ok=True)  # from an earlier run of this job id
            except OSError as exc:
                self._queue.last_error = f"{job.job_id}: could not write {out}: {exc}"
                self.get_logger().error(self._queue.last_error)
            msg = convert.result_to_assets(job.job_id, job.result)
            if job.state is JobState.CANCELLED:   # once its optimization had begun: what it produced is kept
                msg.error_code = convert.error_code(job.error.code)
                msg.error_msg = (f"{job.error.message}: the assets are what it had produced (warnings; "
                                 f"result.json metrics.stopped, metrics.cancelled_during)")
        else:
            msg = convert.error_assets(job.job_id, job.error.code, job.error.message)
            other = self._queue.get(job.job_id)
            duplicate = other is not None and other is not job and other.state in (JobState.QUEUED, JobState.RUNNING)
            if not duplicate:  # a refused duplicate id must not write into the live job's directory
                msg.output_dir = self._write_error(job, out)
        msg.header.stamp = self.get_clock().now().to_msg()
        job.result_msg = msg
        with self._lock:
            self._latest_progress.pop(job.job_id, None)
        self._result_pub.publish(msg)
        self._wake.trigger()
        if job.state is JobState.SUCCEEDED:
            self.get_logger().info(f"job {job.job_id}: succeeded in {job.finished - job.started:.2f} s")
        else:
            self.get_logger().warn(f"job {job.job_id}: {job.state.value} ({job.error})")

    def _write_error(self, job: Job, out: pathlib.Path) -> str:
        """An error is part of the record too: <output_dir>/<job_id>/error.json."""
        try:
            out.mkdir(parents=True, exist_ok=True)
            (out / "result.json").unlink(missing_ok=True)  # an earlier success of this job id
            (out / "error.json").write_text(json.dumps({
                "job_id": job.job_id, "state": job.state.value, "error": job.error.code,
                "error_code": convert.error_code(job.error.code), "message": job.error.message}, indent=2))
            return str(out)
        except OSError as exc:
            self.get_logger().error(f"could not write the error record of {job.job_id}: {exc}")
            return ""

    # -- status ----------------------------------------------------------------------------
    def publish_status(self):
        cur = self._queue.current
        last_error = self._queue.last_error
        st = DiagnosticStatus(name=f"{self.get_name()}: job queue", hardware_id="diffavatar")
        st.level = DiagnosticStatus.OK
        st.message = f"running {cur.job_id}" if cur else "idle"
        st.values = [KeyValue(key="queue_length", value=str(self._queue.length)),
                     KeyValue(key="queue_capacity", value=str(self._queue.max_length)),
                     KeyValue(key="current_job", value=cur.job_id if cur else ""),
                     KeyValue(key="last_error", value=last_error)]
        arr = DiagnosticArray(status=[st])
        arr.header.stamp = self.get_clock().now().to_msg()
        self._status_pub.publish(arr)

    def stop_jobs(self, timeout: float = 5.0) -> None:
        """Cancels every job (waiting up to `timeout` s for the running one to stop); goals still
        open get their (cancelled) result while an executor spins the node (up to 1 s more).
        Idempotent; destroy_node calls it."""
        self._queue.shutdown(timeout)
        deadline = time.monotonic() + 1.0
        while self._goal_jobs and time.monotonic() < deadline and self.context.ok():
            self._wake.trigger()
            time.sleep(0.01)
        # a goal leaves _goal_jobs inside its coroutine; the action server sends its result only
        # after the coroutine returns, from a callback of a later spin: spin on a little before the
        # server is destroyed (a CI run lost the stop test's cancelled result to that race)
        flush = time.monotonic() + RESULT_FLUSH_S
        while time.monotonic() < flush and self.context.ok():
            self._wake.trigger()
            time.sleep(0.01)

    def destroy_node(self):
        """stop_jobs(), then the action server goes before the rest of the node. Stop the
        executor spinning this node first (stop_jobs while it still spins, for the goals):
        destroying entities under a spinning executor makes its wait fail."""
        self.stop_jobs()
        self._action.destroy()
        super().destroy_node()


def shutdown_executor(executor, spin_thread: threading.Thread | None = None, timeout: float = 10.0) -> None:
    """Stops `executor`, waits up to `timeout` s for `spin_thread` (the thread spinning it, if not
    the caller) to leave its loop, then joins the executor's worker threads. rclpy's
    MultiThreadedExecutor.shutdown() leaves its thread pool running in this Jazzy (rclpy#893;
    fixed upstream in #1309, backported as #1670): a worker left waiting kept the process from
    exiting after SIGINT (seen here in 6 of 70 runs of the entry-point test). The pool is closed
    only once nothing spins the executor, so no callback is submitted to a closed pool
    (rclpy#1724)."""
    executor.shutdown()
    if spin_thread is not None:
        spin_thread.join(timeout)
    pool = getattr(executor, "_executor", None)   # the ThreadPoolExecutor of MultiThreadedExecutor
    if pool is not None:
        pool.shutdown(wait=True)


def main(args=None):
    """Console entry `diffavatar-node` / `python -m diffavatar_ros` (accepts --ros-args).

    SIGINT and SIGTERM stop the spin loop (within SPIN_PERIOD_S); the jobs are cancelled while
    the executor still spins (open goals get their results), then the node, the executor and its
    threads, and the context are shut down in that order, by this thread; at most EXIT_GRACE_S
    after the signal the process has ended. rclpy's own signal handlers are off: they shut the
    context down under a spinning executor, a race this order avoids."""
    configure_large_data_transport()
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = DiffAvatarNode()
    except Exception as exc:  # a bad --params-file value: say so and exit non-zero
        print(f"diffavatar_node: {exc}", flush=True)
        rclpy.try_shutdown()
        raise SystemExit(2)
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    try:
        while not stop.is_set() and node.context.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD_S)
    except ExternalShutdownException:   # the context was shut down by someone else
        pass
    finally:
        # From here the process must end: if a step below, a thread or the middleware's
        # teardown at interpreter exit hangs, every thread's stack goes to stderr after
        # EXIT_GRACE_S and the process exits with status 1 (a supervisor sees the failure).
        faulthandler.dump_traceback_later(EXIT_GRACE_S, exit=True)
        # the jobs are cancelled while the executor still spins: open goals get their results
        stopper = threading.Thread(target=node.stop_jobs, name="diffavatar-stop", daemon=True)
        stopper.start()
        try:
            while stopper.is_alive() and node.context.ok():
                executor.spin_once(timeout_sec=SPIN_PERIOD_S)
        except Exception as exc:   # (the context went away under it) the shutdown goes on
            print(f"diffavatar_node: while stopping: {exc!r}", file=sys.stderr, flush=True)
        stopper.join()
        node.destroy_node()
        shutdown_executor(executor)
        rclpy.try_shutdown()
        if not node.queue.stopped:
            # a job still inside a long core call: letting the interpreter finalize under it
            # aborts the process ("terminate called..."); say so and leave at once instead
            print("diffavatar_node: the running job did not stop within 5 s of its cancel; exiting "
                  "without waiting for it", file=sys.stderr, flush=True)
            os._exit(1)


if __name__ == "__main__":
    main()
