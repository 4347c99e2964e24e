"""The lowest of several fresh drapes (CoOptObjective.fresh_min, option bending_fresh_drapes): the
template layout as it is and moved by seeded noise (FRESH_JITTER), each draped fresh; the lowest φ
and its drape; a drape that fails is remembered as failed; an unguided bending judgment with more
fresh drapes judges every bending at most as high as with one."""
import numpy as np
import pytest

from diffavatar_core.pipeline import RecoverOptions
from diffavatar_core.pipeline.coopt import FRESH_JITTER


def test_fresh_min_is_the_lowest_of_its_fresh_drapes(soft_skirt_objective):
    """Three fresh drapes: the first from the template layout as it is, the others from it moved by
    normal noise of FRESH_JITTER (seeds 1, 2: other starts, bit for bit the same again); fresh_min is
    the lowest φ and leaves its drape as the warm start; each drape made again gives its φ bit for bit."""
    obj, theta = soft_skirt_objective(bending_fresh_drapes=3)
    starts = []
    reset = obj.cloth.reset
    obj.cloth.reset = lambda x, *a, **k: starts.append(np.array(x)) or reset(x, *a, **k)
    v = obj.fresh_min(theta)
    x_min = np.array(obj.x_warm)
    np.testing.assert_array_equal(obj.x_last, x_min)
    x0 = np.asarray(obj.g.x0)
    assert len(starts) == 3 and np.array_equal(starts[0], x0)
    for s in starts[1:]:
        noise = s - x0
        assert 0.8 * FRESH_JITTER < noise.std() < 1.2 * FRESH_JITTER and abs(noise.mean()) < 0.1 * FRESH_JITTER
    assert not np.array_equal(starts[1], starts[2])
    values, drapes = [], []
    obj._fresh_seen.clear()
    for j in range(3):
        values.append(obj._fresh_value(theta, j))
        drapes.append(np.array(obj.x_last))
        np.testing.assert_array_equal(starts[3 + j], starts[j])   # the same start again
    assert np.isfinite(v) and v == min(values)
    np.testing.assert_array_equal(x_min, drapes[int(np.argmin(values))])


def test_a_failed_fresh_drape_is_remembered_as_failed(soft_skirt_objective):
    """A fresh drape that does not converge is φ = ∞, leaves the warm start as it was and is not
    draped again for the same parameters (it would fail again: a fresh drape depends on the
    parameters alone)."""
    obj, theta = soft_skirt_objective()
    x_warm = np.array(obj.x_warm)
    made = []

    def failing(*a, **k):
        made.append(1)
        raise ValueError("fresh drape did not converge: step budget exhausted")
    obj.fresh_drape_at = failing
    assert obj._fresh_value(theta) == np.inf and obj.fresh_min(theta) == np.inf
    assert made == [1]
    np.testing.assert_array_equal(obj.x_warm, x_warm)


def test_more_fresh_drapes_judge_every_bending_no_higher(soft_skirt_objective):
    """Unguided judging (bending_compare 'unguided'): the current bending and each candidate on the
    lower of their warm re-drape and their fresh drapes. With three fresh drapes — the one of the
    single-drape judging among them — no judged value and no reference is higher than with one."""
    judged = []
    for k in (1, 3):
        obj, theta = soft_skirt_objective(bending_candidates=[-1, 1], bending_compare="unguided",
                                          bending_fresh_drapes=k)
        obj.try_bending(theta)
        judged.append(obj.last_bending_judged)
    one, three = judged
    assert len(one) == len(three) == 2
    for (kb1, v1, ref1), (kb3, v3, ref3) in zip(one, three):
        assert kb1 == kb3 and v3 <= v1 and ref3 <= ref1


def test_fresh_judging_compares_fresh_drapes_alone(soft_skirt_objective):
    """bending_compare 'fresh': the current bending and each candidate judged on the lowest φ of
    their fresh drapes and on nothing else — the same values, bit for bit, as fresh_min of each
    asked directly on another objective — and a kept candidate's warm start is the lowest-φ drape
    it was judged with or made (its re-drape, guided drapes, fresh drapes)."""
    obj, theta = soft_skirt_objective(bending_candidates=[-1, 1], bending_compare="fresh", bending_fresh_drapes=2,
                                      bending_margin=0.0)
    best, kept = obj.try_bending(theta)
    judged = obj.last_bending_judged
    ref, _ = soft_skirt_objective(bending_fresh_drapes=2)
    v_cur = ref.fresh_min(theta)
    assert len(judged) == 2
    for (kb, v, against), d in zip(judged, (-1, 1)):
        cand = {**theta, "log_bend": np.asarray(theta["log_bend"], np.float64) + d}
        assert kb == float(10.0 ** cand["log_bend"].reshape(-1)[0])
        assert against == v_cur and v == ref.fresh_min(cand)
    assert kept == (min(v for _, v, _ in judged) < v_cur)
    if kept:
        assert obj.last_bending <= min(v for _, v, _ in judged)


@pytest.mark.parametrize("value", [0, 17, 1.5, True, "3"])
def test_bending_fresh_drapes_is_validated(value):
    with pytest.raises(ValueError, match="bending_fresh_drapes"):
        RecoverOptions.from_config(bending_fresh_drapes=value)
