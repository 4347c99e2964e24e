"""Cloth.clone: an independent copy of a cloth (Model, Control, sweep plan, state). Continued from
the same state it drapes to the same positions bit for bit — also while the original runs in
another thread at the same time — and changing one changes nothing in the other."""
import threading

import numpy as np
import pytest

from diffavatar_core.body import BodyModel
from diffavatar_core.pattern.templates import make_template
from diffavatar_core.sim.cloth import Cloth
from diffavatar_core.sim.material import ClothMaterial


@pytest.fixture(scope="module")
def half_draped():
    """A coarse t-shirt 60 XPBD steps into its drape (still moving), masses following its rest
    shape, its pattern then scaled by 2% (so the masses differ from the constructor's)."""
    model = BodyModel.default()
    p = model.zero_params()
    g = make_template("tshirt", landmarks=model.landmarks(p), edge_length=0.07)
    c = Cloth(g.rest, g.faces, g.x0, seams=g.seams, groups=g.panel[g.faces[:, 0]],
              materials=[ClothMaterial(bend_stiffness=5e-6)] * len(g.panels), body=(model.pose(p), model.faces),
              masses_follow_rest=True)
    c.sew()
    c.step(60, iterations=40)
    c.set_control(rest=np.asarray(g.rest) * 1.02)
    return g, c


def _finish(cloth, out):
    r = cloth.drape(max_steps=300, iterations=40, residual_tol=1e-8, refine_iterations=150)
    out.append((r.converged, np.array(cloth.x)))


def test_a_clone_drapes_as_its_original_bit_for_bit(half_draped):
    g, c = half_draped
    x, v = np.array(c.x), np.array(c.state.v)
    assert np.abs(v).max() > 1e-3   # mid-drape: the velocities are part of what is copied
    d = c.clone()
    np.testing.assert_array_equal(d.x, x)
    np.testing.assert_array_equal(d.state.v, v)
    np.testing.assert_array_equal(d.model.mass, c.model.mass)
    np.testing.assert_array_equal(np.asarray(d.control.rest), np.asarray(c.control.rest))
    alone = []
    _finish(d, alone)
    # the original and a second clone from the same state, at the same time in two threads
    e = c.clone()
    both = []
    t = threading.Thread(target=_finish, args=(e, both))
    t.start()
    _finish(c, both)
    t.join()
    assert alone[0][0] and both[0][0] and both[1][0]
    for _, xb in both:
        np.testing.assert_array_equal(xb, alone[0][1])
    assert np.abs(alone[0][1] - x).max() > 1e-3   # the drape did move the cloth


def test_a_clone_shares_nothing_with_its_original(half_draped):
    g, c = half_draped
    d = c.clone()
    bend, x = np.array(c.control.bend_stiffness), np.array(c.x)
    d.set_control(bend_stiffness=np.full(len(bend), 1e-4), rest=np.asarray(g.rest) * 1.05)
    d.step(5, iterations=20)
    np.testing.assert_array_equal(np.asarray(c.control.bend_stiffness), bend)
    np.testing.assert_array_equal(c.x, x)
    assert not np.array_equal(d.model.mass, c.model.mass)   # the clone's masses followed its own rest


def test_a_clone_keeps_the_sweep_plan(half_draped):
    g, c = half_draped
    c.set_sweep_plan(lanes=2, min_constraints=0)
    try:
        d = c.clone()
        assert d.sweep_plan == c.sweep_plan and d.sweep_plan["lanes"] == 2
    finally:
        c.set_sweep_plan(lanes=1)


def test_a_clone_after_the_body_moved_finds_the_same_contacts():
    """The body's BVH is built for its first pose and refit as the body moves (its shape
    optimized); a clone rebuilt it for the new pose, and a cloth vertex nearest a body vertex —
    as near every triangle around it — then got another of those triangles' face planes: the
    Newton solves from the same state went apart (36 / 37 and 54 / 68 iterations here), and with
    them the bending candidates a recovery drapes on clones (benchmark long sleeve 100 ended at
    0.347 instead of 0.343). The clone copies the tree as it is."""
    model = BodyModel.default()
    p = model.zero_params()
    g = make_template("tshirt", landmarks=model.landmarks(p), edge_length=0.04)
    c = Cloth(g.rest, g.faces, g.x0, seams=g.seams, groups=g.panel[g.faces[:, 0]],
              materials=[ClothMaterial(bend_stiffness=5e-6)] * len(g.panels), body=(model.pose(p), model.faces))
    c.sew()
    assert c.drape(max_steps=200, iterations=40, residual_tol=1e-7, refine_iterations=120).converged
    x0 = np.array(c.x)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = model.zero_params()
        q.shape[:4] = rng.normal(scale=0.5, size=4)
        c.set_control(body_vertices=model.pose(q))   # refits the original's tree
        d = c.clone()
        c.reset(x0)
        d.reset(x0)
        a = c.refine(keep_anchor=False, residual_tol=1e-7, refine_iterations=80)
        b = d.refine(keep_anchor=False, residual_tol=1e-7, refine_iterations=80)
        assert a == b
        np.testing.assert_array_equal(d.x, c.x)
        assert d.solver.num_contacts == c.solver.num_contacts
