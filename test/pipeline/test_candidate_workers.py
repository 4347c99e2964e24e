"""Bending candidates draped at once (pipeline/candidate_workers.py): try_bending and
search_bending with the candidates in threads, each on a twin of the objective, decide, judge and
leave the objective exactly as one after the other does (bit for bit); the twins run on clones of
the cloth in other threads; a failing candidate's exception reaches the caller."""
import threading

import numpy as np
import pytest

from diffavatar_core.pipeline import RecoverOptions
from diffavatar_core.pipeline.candidate_workers import run_on_twins, worker_count


def _outcome(obj, best, kept):
    return dict(log_bend=np.array(best["log_bend"]), kept=kept, judged=list(obj.last_bending_judged),
                last=obj.last_bending, x_warm=np.array(obj.x_warm), x=np.array(obj.cloth.x),
                bend=np.array(obj.cloth.control.bend_stiffness), fresh=sorted(obj._fresh_seen))


def _assert_same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        if isinstance(a[k], np.ndarray):
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
        else:
            assert a[k] == b[k], k


@pytest.mark.parametrize("compare,fresh", [("guided", 1), ("unguided", 1), ("asymmetric", 1), ("unguided", 3),
                                           ("fresh", 2)])
def test_try_bending_at_once_is_try_bending_in_turn(soft_skirt_objective, compare, fresh):
    """Three candidates (one 10× softer, two stiffer), one after the other and two or three at
    once: the same judged values, kept candidate, φ, drapes and remembered fresh drapes, bit for
    bit; and φ evaluated next from the warm start they leave is the same. With three fresh drapes
    per bending (bending_fresh_drapes) the current bending's are draped at once too."""
    out = []
    for workers in (1, 2, 3):
        obj, theta = soft_skirt_objective(bending_candidates=[-1, 1, 2], bending_compare=compare,
                                          candidate_workers=workers, bending_fresh_drapes=fresh)
        best, kept = obj.try_bending(theta)
        o = _outcome(obj, best, kept)
        o["next"] = obj.value(best)
        out.append(o)
    assert len(out[0]["judged"]) == 3
    _assert_same(out[0], out[1])
    _assert_same(out[0], out[2])


def test_search_bending_at_once_is_search_bending_in_turn(soft_skirt_objective):
    reports = []
    for workers in (1, 2):
        obj, theta = soft_skirt_objective(candidate_workers=workers)
        best, report = obj.search_bending(theta, (1.0, 0.5))
        reports.append((np.array(best["log_bend"]), report, np.array(obj.x_warm)))
    np.testing.assert_array_equal(reports[0][0], reports[1][0])
    assert reports[0][1] == reports[1][1] and any(reports[0][1]["kept"])
    np.testing.assert_array_equal(reports[0][2], reports[1][2])


def test_each_candidate_but_the_last_runs_on_a_twin_in_another_thread(soft_skirt_objective):
    obj, theta = soft_skirt_objective()
    seen = []

    def task(o, i):
        seen.append((i, threading.get_ident(), o, o.cloth))
        return i * i
    assert run_on_twins(obj, [lambda o, i=i: task(o, i) for i in range(3)], workers=3) == [0, 1, 4]
    by = {i: (tid, o, cloth) for i, tid, o, cloth in seen}
    main = threading.get_ident()
    assert by[2][0] == main and by[2][1] is obj and by[2][2] is obj.cloth
    for i in (0, 1):
        assert by[i][0] != main and by[i][1] is not obj and by[i][2] is not obj.cloth
    assert by[0][2] is not by[1][2]
    seen.clear()   # one worker: all in turn on obj itself
    assert run_on_twins(obj, [lambda o, i=i: task(o, i) for i in range(3)], workers=1) == [0, 1, 4]
    assert all(tid == main and o is obj for _, tid, o, _ in seen)


def test_a_failing_candidate_reaches_the_caller(soft_skirt_objective):
    obj, _ = soft_skirt_objective()

    def task(o, i):
        if i == 0:
            raise RuntimeError("candidate 0 failed")
        return i
    with pytest.raises(RuntimeError, match="candidate 0 failed"):
        run_on_twins(obj, [lambda o, i=i: task(o, i) for i in range(2)], workers=2)


def test_zero_workers_is_one_per_cpu():
    assert worker_count(0) >= 1 and worker_count(3) == 3


@pytest.mark.parametrize("value", [-1, 1.5, True, "2"])
def test_candidate_workers_is_validated(value):
    with pytest.raises(ValueError, match="candidate_workers"):
        RecoverOptions.from_config(candidate_workers=value)
