"""Candidate drapes at once: the bending candidates of a check (CoOptObjective.try_bending) are
independent — each re-drapes and scan-guides the same warm start at its own bending — so each may
run on its own copy of the objective (CoOptObjective.twin: a clone of the cloth, nothing mutable
shared) in a thread of its own; the C++ drapes release the GIL. Each thread keeps the caller's
OpenMP team size: a candidate's guided drapes gain from a second OpenMP thread (a 665-vertex
t-shirt's pair of candidates: 4.8 + 3.6 s in turn on two threads, 6.5 + 4.7 s on one), and with
both teams on two cores the longer candidate gets both once the shorter one ends — the pair at once
in 6.1 s, against 6.5 s with the threads split between them and 8.6 s in turn. Every result is the
same as one after the other, bit for bit (the drapes do not depend on the thread count;
test_candidate_workers.py)."""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

from .. import _core


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:   # not on Linux
        return max(1, os.cpu_count() or 1)


def worker_count(requested: int) -> int:
    """RecoverOptions.candidate_workers → how many candidates run at once (0: one per CPU)."""
    return requested if requested > 0 else available_cpus()


def run_on_twins(obj, tasks, workers: int) -> list:
    """[task(o) for each task], in order: the last task on `obj` itself (so its cloth ends where one
    after the other would leave it), every other on a twin of obj (obj.twin()), up to `workers` at
    once. With one worker or one task, simply in turn on obj. A task's exception is raised here
    (after the others end). The twins' remembered fresh drapes are added to obj's afterwards."""
    tasks = list(tasks)
    if workers <= 1 or len(tasks) <= 1:
        return [task(obj) for task in tasks]
    threads = _core.openmp_max_threads()   # the caller's: a new thread would start at the process default
    twins = [obj.twin() for _ in tasks[:-1]]

    def on_twin(task, twin):
        _core.set_num_threads(threads)
        return task(twin)
    with ThreadPoolExecutor(max_workers=min(workers, len(tasks)) - 1) as pool:
        futures = [pool.submit(on_twin, task, twin) for task, twin in zip(tasks[:-1], twins)]
        last = tasks[-1](obj)
        results = [f.result() for f in futures] + [last]
    for twin in twins:
        obj.adopt_fresh(twin)
    return results
