"""One FIFO job queue shared by the node's topic and action front doors (Nav2 pattern: a topic
forwards into the same machinery as the action). Pure Python, no ROS: the node wires it up.

A single worker thread runs jobs one at a time in submission order. The job callable runs the
core, which releases the GIL, so the ROS executor stays responsive. Each job has its own
diffavatar_core.CancelToken; cancelling a queued job removes it (it still gets a result), a
running job is stopped by the core within one iteration. The queue is bounded: a submission
to a full queue is answered at once with a 'queue full' outcome, never dropped silently.
"""
from __future__ import annotations

import collections
import enum
import threading
import time
import traceback
import uuid
from dataclasses import dataclass, field
from typing import Any, Callable

import diffavatar_core as dc


class JobState(enum.Enum):
    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"
    REJECTED = "rejected"


@dataclass
class JobError(Exception):
    """A job outcome that is an error the caller should see: `code` names it (the suffix of an
    AvatarAssets.ERROR_* constant, e.g. 'EMPTY_MESH'), `message` explains it."""
    code: str
    message: str

    def __str__(self):
        return f"{self.code}: {self.message}"


@dataclass
class Job:
    job_id: str
    payload: Any
    cancel: dc.CancelToken = field(default_factory=dc.CancelToken)
    state: JobState = JobState.QUEUED
    result: Any = None
    error: JobError | None = None
    submitted: float = field(default_factory=time.monotonic)
    started: float | None = None
    finished: float | None = None
    done: threading.Event = field(default_factory=threading.Event)
    result_msg: Any = None  # filled by the node: the AvatarAssets answered for this job


class JobQueue:
    """run(job) -> result is called on the worker thread; it may raise JobError, or
    diffavatar_core.Cancelled when job.cancel was set (one carrying `.result` — what the run
    produced until then — leaves it in job.result); any other exception becomes an
    INTERNAL error (with the traceback in the log) and the queue keeps going.
    on_finished(job) is called on the worker thread after every job (also rejected/cancelled)."""

    def __init__(self, run: Callable[[Job], Any], max_length: int = 8,
                 on_finished: Callable[[Job], None] = lambda job: None,
                 log: Callable[[str], None] = lambda msg: None):
        if max_length < 1:
            raise ValueError(f"max_length must be >= 1, got {max_length}")
        self._run, self._on_finished, self._log = run, on_finished, log
        self.max_length = max_length
        self._pending: collections.deque[Job] = collections.deque()
        self._jobs: dict[str, Job] = {}
        self._current: Job | None = None
        self._cv = threading.Condition()
        self._stopping = False
        self._worker = threading.Thread(target=self._loop, name="diffavatar-jobs", daemon=True)
        self._worker.start()
        self.last_error: str = ""

    # -- submission / cancel -------------------------------------------------------------
    def submit(self, payload: Any, job_id: str = "", on_queued: Callable[[Job], None] | None = None) -> Job:
        """Queues a job (job_id assigned when empty). A full queue or a job id already queued or
        running gives a job that is immediately REJECTED with its error set. on_queued(job) runs
        once the job is queued and before the worker can start it (keep it quick)."""
        job = Job(job_id or uuid.uuid4().hex[:12], payload)
        with self._cv:
            busy = job.job_id in self._jobs and self._jobs[job.job_id].state in (JobState.QUEUED, JobState.RUNNING)
            if busy or len(self._pending) >= self.max_length:
                job.state = JobState.REJECTED
                job.error = (JobError("BAD_OPTION", f"job id {job.job_id!r} is already queued or running") if busy
                             else JobError("QUEUE_FULL", f"the job queue is full ({self.max_length} waiting)"))
            else:
                self._jobs[job.job_id] = job
                self._pending.append(job)
                if on_queued is not None:
                    on_queued(job)
                self._cv.notify_all()
        if job.state is JobState.REJECTED:
            self._finish(job)
        return job

    def reject(self, error: JobError, job_id: str = "", payload: Any = None) -> Job:
        """A job refused before queueing (e.g. invalid input): finished at once as REJECTED with
        `error`, through on_finished like every other job; it never takes a queue slot."""
        job = Job(job_id or uuid.uuid4().hex[:12], payload, state=JobState.REJECTED, error=error)
        self._finish(job)
        return job

    def cancel(self, job_id: str) -> bool:
        """Cancels a queued or running job; False if no such job is queued or running."""
        with self._cv:
            job = self._jobs.get(job_id)
            if job is None or job.state not in (JobState.QUEUED, JobState.RUNNING):
                return False
            job.cancel.cancel()
            if job.state is JobState.QUEUED:
                self._pending.remove(job)
                job.state = JobState.CANCELLED
                job.error = JobError("CANCELLED", "cancelled before it started")
            else:
                return True
        self._finish(job)
        return True

    # -- status --------------------------------------------------------------------------
    @property
    def length(self) -> int:
        with self._cv:
            return len(self._pending)

    @property
    def current(self) -> Job | None:
        with self._cv:
            return self._current

    def get(self, job_id: str) -> Job | None:
        with self._cv:
            return self._jobs.get(job_id)

    @property
    def stopped(self) -> bool:
        """True once the worker thread has ended (after shutdown)."""
        return not self._worker.is_alive()

    def shutdown(self, timeout: float = 5.0) -> None:
        """Cancels everything and stops the worker, waiting up to `timeout` s for the running
        job to reach a cancel check (see `stopped`)."""
        with self._cv:
            self._stopping = True
            pending = list(self._pending)
            current = self._current
            self._cv.notify_all()
        for job in pending:
            self.cancel(job.job_id)
        if current is not None:
            current.cancel.cancel()
        self._worker.join(timeout)

    # -- worker --------------------------------------------------------------------------
    def _loop(self):
        while True:
            with self._cv:
                while not self._pending and not self._stopping:
                    self._cv.wait()
                if self._stopping and not self._pending:
                    return
                job = self._pending.popleft()
                job.state, job.started = JobState.RUNNING, time.monotonic()
                self._current = job
            try:
                job.result = self._run(job)
                job.state = JobState.SUCCEEDED
            except dc.Cancelled as exc:   # what it produced until then, when the runner kept it (`.result`)
                why = f"cancelled while running ({exc})" if str(exc) else "cancelled while running"
                job.state, job.error = JobState.CANCELLED, JobError("CANCELLED", why)
                job.result = getattr(exc, "result", None)
            except JobError as err:
                job.state, job.error = JobState.FAILED, err
            except Exception as exc:  # a bug must not take the service down
                self._log(f"job {job.job_id} failed unexpectedly:\n{traceback.format_exc()}")
                job.state, job.error = JobState.FAILED, JobError("INTERNAL", f"{type(exc).__name__}: {exc}")
            with self._cv:
                self._current = None
            self._finish(job)

    def _finish(self, job: Job):
        job.finished = time.monotonic()
        if job.error is not None and job.error.code != "CANCELLED":
            self.last_error = f"{job.job_id}: {job.error}"
        try:
            self._on_finished(job)
        except Exception:
            self._log(f"on_finished for job {job.job_id} raised:\n{traceback.format_exc()}")
        job.done.set()
