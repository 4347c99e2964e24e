"""The node's FIFO job queue, without ROS: order, bounded length, cancel (queued and running),
errors never stop the worker. Jobs are real core computations (Chamfer distances) that poll
their cancel token."""
import threading

import numpy as np
import pytest

import diffavatar_core as dc
from diffavatar_ros.job_queue import JobError, JobQueue, JobState

RNG = np.random.default_rng(0)
A, B = RNG.random((300000, 3)), RNG.random((300000, 3))


def _run(job):
    kind = job.payload
    if kind == "bad":
        raise JobError("NO_GARMENT", "no garment vertices")
    if kind == "bug":
        raise RuntimeError("boom")
    if kind == "long":
        gate = threading.Event()
        started.set()
        for _ in range(200):  # about a second per pass; cancel is seen within one
            dc.chamfer_points(A, B, cancel=job.cancel)
            gate.wait(0.0)
        return "finished"
    return dc.chamfer_points(A[:2000] * kind, B[:2000] * kind)


started = threading.Event()


def _queue(**kw):
    finished = []
    q = JobQueue(_run, on_finished=finished.append, **kw)
    return q, finished


def test_jobs_complete_in_fifo_order_with_real_results():
    q, finished = _queue()
    jobs = [q.submit(s, job_id=f"j{s}") for s in (1.0, 2.0, 3.0)]
    for j in jobs:
        assert j.done.wait(30)
    assert [j.job_id for j in finished] == ["j1.0", "j2.0", "j3.0"]
    ref = dc.chamfer_points(A[:2000], B[:2000])
    for s, j in zip((1.0, 2.0, 3.0), jobs):
        assert j.state is JobState.SUCCEEDED and j.result == pytest.approx(s * ref, rel=1e-12)
    q.shutdown()


def test_errors_are_reported_and_the_worker_keeps_going():
    logs = []
    q, finished = _queue(log=logs.append)
    bad, bug, good = q.submit("bad"), q.submit("bug"), q.submit(1.0)
    assert good.done.wait(30)
    assert bad.state is JobState.FAILED and bad.error.code == "NO_GARMENT"
    assert bug.state is JobState.FAILED and bug.error.code == "INTERNAL" and "boom" in bug.error.message
    assert any("boom" in line for line in logs)
    assert good.state is JobState.SUCCEEDED
    assert "NO_GARMENT" in q.last_error or "INTERNAL" in q.last_error
    q.shutdown()


def test_full_queue_rejects_with_an_error_and_duplicate_ids_are_refused():
    started.clear()
    q, finished = _queue(max_length=2)
    running = q.submit("long", job_id="run")
    assert started.wait(30)
    a, b = q.submit(1.0, job_id="a"), q.submit(1.0, job_id="b")
    c = q.submit(1.0, job_id="c")
    assert c.state is JobState.REJECTED and c.error.code == "QUEUE_FULL" and c.done.is_set()
    dup = q.submit(1.0, job_id="a")
    assert dup.state is JobState.REJECTED and "already" in dup.error.message
    assert q.cancel("run")
    for j in (running, a, b):
        assert j.done.wait(30)
    assert running.state is JobState.CANCELLED
    assert a.state is b.state is JobState.SUCCEEDED
    q.shutdown()


def test_cancel_a_queued_job_in_the_middle_of_three():
    started.clear()
    q, finished = _queue()
    first = q.submit("long", job_id="first")
    assert started.wait(30)
    mid, last = q.submit(2.0, job_id="mid"), q.submit(3.0, job_id="last")
    assert q.cancel("mid")
    assert not q.cancel("nope")
    q.cancel("first")
    assert last.done.wait(30)
    assert [j.job_id for j in finished] == ["mid", "first", "last"]  # mid answered at cancel time
    assert mid.state is JobState.CANCELLED and first.state is JobState.CANCELLED
    assert last.state is JobState.SUCCEEDED
    q.shutdown()


def test_on_queued_runs_before_the_job_can_start_and_reject_answers_at_once():
    events = []
    q = JobQueue(lambda job: events.append(("run", job.job_id)), max_length=100,
                 on_finished=lambda job: events.append(("finished", job.job_id)))
    jobs = [q.submit(None, job_id=f"j{i}", on_queued=lambda job: events.append(("queued", job.job_id))) for i in range(20)]
    bad = q.reject(JobError("EMPTY_MESH", "no vertices"), job_id="bad")
    assert bad.done.is_set() and bad.state is JobState.REJECTED and bad.error.code == "EMPTY_MESH"
    for j in jobs:
        assert j.done.wait(10)
    for i in range(20):
        assert events.index(("queued", f"j{i}")) < events.index(("run", f"j{i}")) < events.index(("finished", f"j{i}"))
    assert ("finished", "bad") in events and ("run", "bad") not in events
    q.shutdown()


def test_stopped_says_whether_shutdown_outlived_the_running_job():
    """A job that reaches no cancel check for a while outlives a short shutdown: `stopped` is
    False until it ends (the node then exits at once rather than finalize under it)."""
    release = threading.Event()
    running = threading.Event()

    def stubborn(job):
        running.set()
        release.wait(30)   # ignores its cancel until released
        return "late"
    q = JobQueue(stubborn)
    q.submit(None, job_id="stubborn")
    assert running.wait(30)
    q.shutdown(timeout=0.1)
    assert not q.stopped
    release.set()
    q.shutdown(timeout=30)
    assert q.stopped
