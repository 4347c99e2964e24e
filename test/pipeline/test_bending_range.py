"""The recovered bending's range (pipeline/bending_range.py): with the scan a garment's own drape
(ground truth: its bending) the range holds that bending and is closed within half a decade; from a
bending half a decade off, the true one is not excluded; the objective and co_optimize's results
are the same with and without it, bit for bit; the walk to the first 'worse' offset; validation."""
import numpy as np
import pytest

from diffavatar_core.body import BodyModel
from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pattern.templates import make_template
from diffavatar_core.pipeline import RecoverOptions
from diffavatar_core.pipeline.bending_range import _offsets, bending_range, range_ends, verdict
from diffavatar_core.pipeline.coopt import CoOptObjective, co_optimize
from diffavatar_core.sim.cloth import Cloth
from diffavatar_core.sim.material import ClothMaterial

TRUE_BEND = 5e-6   # N·m: the bending of the skirt whose drape is the scan


@pytest.fixture(scope="module")
def own_drape():
    """A coarse skirt (TRUE_BEND) draped on the default body; its own drape S is the scan."""
    model = BodyModel.default()
    p = model.zero_params()
    g = make_template("skirt", landmarks=model.landmarks(p), edge_length=0.07)
    c = Cloth(g.rest, g.faces, g.x0, seams=g.seams, groups=g.panel[g.faces[:, 0]],
              materials=[ClothMaterial(bend_stiffness=TRUE_BEND)] * len(g.panels), body=(model.pose(p), model.faces))
    c.sew()
    assert c.drape(max_steps=150, iterations=40, residual_tol=1e-8, refine_iterations=150).converged
    return g, c, np.array(c.x)


def _objective(own_drape, offset=0.0, **opts):
    """The objective against the skirt's own drape (L_interior to the scan's surface: zero at the
    truth but for the samples' round-off), committed at the true pattern with the bending ×
    10^offset (re-draped from the true drape)."""
    g, c, S = own_drape
    c.set_control(rest=g.rest, bend_stiffness=np.full(len(np.asarray(c.control.bend_stiffness)), TRUE_BEND))
    c.reset(S)
    o = RecoverOptions.from_config(residual_tol=1e-8, samples=200, interior_to="surface", **opts)
    obj = CoOptObjective(c, g, S, {k: S[v] for k, v in g.boundaries.items()}, o, cage=build_cage(g),
                         scan_mesh=(S, g.faces))
    theta = obj.initial_params()
    obj(theta)
    obj.commit()
    if offset:
        theta = {**theta, "log_bend": np.asarray(theta["log_bend"], np.float64) + offset}
        obj(theta)
        obj.commit()
    return obj, theta


def _state(obj):
    c = obj.cloth
    return [np.array(obj.x_warm), np.array(c.x), np.array(c.control.rest), np.array(c.control.bend_stiffness)] + \
        [np.array(u) for u in obj._undo]


def test_the_scan_of_its_own_drape_closes_the_range_around_the_truth(own_drape):
    obj, theta = _objective(own_drape)
    before = _state(obj)
    r = bending_range(obj, theta, (0.15, 0.5), 0.02)
    assert all(np.array_equal(a, b) for a, b in zip(before, _state(obj)))   # judged on a twin
    assert r["bending_Nm"] == pytest.approx(TRUE_BEND, rel=1e-12)
    assert r["low_Nm"] is not None and r["high_Nm"] is not None   # both sides excluded within half a decade
    assert TRUE_BEND * 10 ** -0.5 * (1 - 1e-12) <= r["low_Nm"] < TRUE_BEND < r["high_Nm"] <= TRUE_BEND * 10 ** 0.5 * (1 + 1e-12)
    judged = {round(j[0], 9): j for j in r["judged"]}
    assert sorted(judged) == [-0.5, -0.15, 0.15, 0.5]
    for d, kb, v, against, what in r["judged"]:
        assert kb == pytest.approx(TRUE_BEND * 10 ** d, rel=1e-12) and against == r["value"]
        assert what == verdict(v, against, 0.02)
        assert what != "better"   # no bending explains the garment's own drape better than its own
    assert judged[0.5][4] == "worse" and judged[-0.5][4] == "worse"


@pytest.mark.parametrize("offset", [0.5, -0.5])
def test_the_truth_is_not_excluded_from_a_bending_half_a_decade_off(own_drape, offset):
    obj, theta = _objective(own_drape, offset)
    r = bending_range(obj, theta, (0.5, 1.0), 0.02)
    b = TRUE_BEND * 10 ** offset
    assert r["bending_Nm"] == pytest.approx(b, rel=1e-12)
    truth = next(j for j in r["judged"] if abs(j[0] + offset) < 1e-9)
    assert truth[4] != "worse"
    assert (r["low_Nm"] is None or r["low_Nm"] < TRUE_BEND) and (r["high_Nm"] is None or TRUE_BEND < r["high_Nm"])
    # the side away from the truth is excluded: a fabric another half decade off drapes worse still
    far = r["high_Nm"] if offset > 0 else r["low_Nm"]
    assert far is not None and far == pytest.approx(b * 10 ** (0.5 if offset > 0 else -0.5), rel=1e-12)


def test_co_optimize_returns_the_same_with_and_without_the_range(own_drape):
    g, c, S = own_drape
    out = []
    for offsets in ((), (0.5,)):
        obj, _ = _objective(own_drape)
        res = co_optimize(c, g, S, {k: S[v] for k, v in g.boundaries.items()},
                          obj.opts.with_(iterations=2, fresh_every=0, bending_range_offsets=offsets,
                                         bending_candidates=(0.5,)),
                          cage=build_cage(g), scan_mesh=(S, g.faces))
        out.append(res)
    a, b = out
    for f in ("rest", "bend_stiffness", "x"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    assert [h["value"] for h in a.history] == [h["value"] for h in b.history]
    assert a.bending_range is None
    r = b.bending_range
    assert r["bending_Nm"] == pytest.approx(float(np.exp(np.log(b.bend_stiffness).mean())), rel=1e-12)
    assert [round(j[0], 9) for j in r["judged"]] == [-0.5, 0.5]


def test_the_range_ends_at_the_first_offset_judged_worse_on_each_side():
    ds = _offsets((1.0, 0.15, 0.5))
    assert ds == [0.15, -0.15, 0.5, -0.5, 1.0, -1.0]
    b = 1e-5
    low, high = range_ends(ds, {0.15: "alike", -0.15: "worse", 0.5: "better", -0.5: "alike", 1.0: "worse"}, b)
    assert low == pytest.approx(b * 10 ** -0.15) and high == pytest.approx(b * 10.0)
    # an offset not judged (outside BENDING_RANGE, no equilibrium) is skipped, not an end
    assert range_ends(ds, {0.5: "worse", -1.0: "worse"}, b) == (pytest.approx(b * 0.1), pytest.approx(b * 10 ** 0.5))
    assert range_ends(ds, {0.15: "alike", -0.15: "better"}, b) == (None, None)
    assert verdict(1.03, 1.0, 0.02) == "worse" and verdict(0.97, 1.0, 0.02) == "better"
    assert verdict(1.02, 1.0, 0.02) == "alike" and verdict(0.98, 1.0, 0.02) == "alike"


def test_offsets_are_validated():
    assert RecoverOptions.from_config(bending_range_offsets=0.5).bending_range_offsets == (0.5,)
    assert RecoverOptions.from_config(bending_range_offsets=[]).bending_range_offsets == ()
    for bad in ([0.0], [-0.5], [4.0], [float("nan")], ["a"]):
        with pytest.raises(ValueError, match="bending_range_offsets"):
            RecoverOptions.from_config(bending_range_offsets=bad)


def test_a_check_that_kept_nothing_lends_the_range_its_judged_candidates(own_drape):
    """co_optimize's last check judges the returned parameters from the same warm start: its φ and
    its candidates at the range's offsets are the range's own, bit for bit — not judged twice."""
    obj, theta = _objective(own_drape)
    best, kept = obj.try_bending(theta, (0.5, -0.5))
    assert not kept   # the scan is this bending's own drape
    known = (obj.last_bending_current, list(obj.last_bending_judged))
    a = bending_range(obj, theta, (0.15, 0.5), 0.02, known)
    b = bending_range(obj, theta, (0.15, 0.5), 0.02)
    assert a["value"] == b["value"] and a["judged"] == b["judged"]
    assert (a["low_Nm"], a["high_Nm"]) == (b["low_Nm"], b["high_Nm"])
