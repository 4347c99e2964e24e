"""The step's contact query cache (sim/contact_query_cache.hpp): a vertex its last query proved far
from the body is skipped, and a vertex searched again starts bounded by its last closest triangle.
Both are exact — the contacts, hence every step, are an uncached detection's bit for bit — so
the test runs the same drapes with the cache on and off and compares every position and contact
after each chunk: a sewn fall onto the body (the fast float sweep and the double one, substeps),
a body that moves under the cloth (the cache's bounds belong to the old pose), a cloth reset far
away and dropped through the body's reach (large jumps between detections), a cloth put on the
body surface (distances ~0), and friction."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.sim import drape_job


def _pair():
    """Two identical sewn 4 cm t-shirts on the default body: cache off (reference) and on."""
    out = []
    for on in (False, True):
        cloth, _, body = drape_job.build("tshirt", edge=0.04)
        cloth.solver.contact_query_cache = on
        cloth.sew()
        out.append(cloth)
    assert np.array_equal(out[0].x, out[1].x)
    return out[0], out[1], body


def _same(ref, cached):
    assert np.array_equal(np.array(ref.x), np.array(cached.x))
    assert np.array_equal(np.array(ref.state.v), np.array(cached.state.v))
    assert np.array_equal(ref.solver.contact_pairs, cached.solver.contact_pairs)


def _run(ref, cached, chunks, **kw):
    for _ in range(chunks):
        for c in (ref, cached):
            c.drape(refine=False, raise_on_divergence=False, **kw)
        _same(ref, cached)


@pytest.mark.parametrize("fast,substeps", [(True, 4), (True, 16), (False, 2)])
def test_a_fall_onto_the_body_is_the_uncached_one_bit_for_bit(fast, substeps):
    ref, cached, _ = _pair()
    _run(ref, cached, 4, max_steps=15, min_steps=15, iterations=40, substeps=substeps, fast=fast)
    assert ref.solver.num_contacts > 100                   # the cloth lies on the body
    searched, skipped = cached.solver.contact_query_stats
    assert searched > 0 and skipped > 0, (searched, skipped)   # both paths taken
    assert ref.solver.contact_query_stats == (0, 0)


def test_a_moving_body_and_a_far_reset_stay_bit_for_bit():
    ref, cached, (bv, bf) = _pair()
    kw = dict(max_steps=10, min_steps=10, iterations=40, substeps=8, fast=True)
    _run(ref, cached, 2, **kw)
    # the body moves 8 mm sideways and 1.5% wider under the held cloth: bounds of the old pose
    # would skip vertices the new one touches
    moved = np.asarray(bv) * np.array([1.015, 1.0, 1.0]) + np.array([0.008, 0.0, 0.0])
    for c in (ref, cached):
        c.set_control(body_vertices=moved)
    _run(ref, cached, 2, **kw)
    # the cloth reset 30 cm up and dropped: vertices far beyond the reach, then falling into it
    x_up = np.array(ref.x) + np.array([0.0, 0.3, 0.0])
    for c in (ref, cached):
        c.reset(x_up)
    _run(ref, cached, 3, **kw)
    assert ref.solver.num_contacts > 100
    # every vertex put on the body surface (its closest point): distances of ~0, where the rounding
    # of a box's distance and a triangle's differ most, relative to the distance itself
    _, on_body, _ = _core.contact_planes(np.ascontiguousarray(moved, np.float64),
                                         np.ascontiguousarray(bf, np.int32),
                                         np.array(ref.x), False)
    for c in (ref, cached):
        c.reset(on_body)
    _run(ref, cached, 2, **kw)


def test_friction_steps_are_the_uncached_ones_bit_for_bit():
    ref, cached, _ = _pair()
    _run(ref, cached, 3, max_steps=10, min_steps=10, iterations=40, substeps=4, fast=True, friction=0.3)
    assert ref.solver.num_contacts > 100


def test_the_cache_is_on_by_default_and_can_be_switched():
    cloth, _, _ = drape_job.build("tshirt", edge=0.04)
    assert cloth.solver.contact_query_cache is True
    cloth.solver.contact_query_cache = False
    assert cloth.solver.contact_query_cache is False
