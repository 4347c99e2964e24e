"""The template measurement fit (pipeline/measurement_fit.py): the measurement map reproduces
the template at its own and at other measurements, its chained gradient dφ/dm against central
differences, a known length recovered from a drape of the longer skirt, and option and input
errors."""
import numpy as np
import pytest

from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pattern.garment import Garment, PanelInfo
from diffavatar_core.pattern.templates import FIT_MEASUREMENTS, make_template, template_spec
from diffavatar_core.pipeline import RecoverOptions
from diffavatar_core.pipeline.coopt import CoOptObjective, co_optimize
from diffavatar_core.pipeline.measurement_fit import MeasurementMap, fit_measurements, measurement_objective
from branch_difference import BRANCH_TOL, differences_on_one_branch



@pytest.mark.parametrize("name", sorted(FIT_MEASUREMENTS))
def test_map_reproduces_the_template_at_other_measurements(name):
    """ζ(m₀) is the template's own cage exactly; at measurements 6% larger, the handles at the
    outline's corners are the corners of the template specified with them (shifted by the
    panel's layout offset), and the pattern W ζ(m) has the area of that template (±0.1%)."""
    g = make_template(name, edge_length=0.06)
    cage = build_cage(g)
    mm = MeasurementMap(name, None, g, cage)
    assert mm.names == FIT_MEASUREMENTS[name]
    assert np.abs(mm.handles(mm.values0) - cage.zeta0).max() < 1e-12
    m = 1.06 * mm.values0
    zeta = mm.handles(m)
    spec = template_spec(name, None, **dict(zip(mm.names, m)))
    corners = np.flatnonzero(mm.t == 0.0)
    assert len(corners) >= 3
    for h in corners:
        p, k = mm.panel[h], mm.edge[h]
        assert np.allclose(zeta[h], spec.panels[p].vertices[k] + mm.offset[h], atol=1e-12)
    target = make_template(name, edge_length=0.06, **dict(zip(mm.names, m))).total_area()
    area = Garment(cage.rest(zeta), g.faces, g.x0, g.seams, g.panel, g.panels).total_area()
    assert abs(area / target - 1) < 1e-3
    assert abs(area / g.total_area() - 1) > 0.005    # and it did change


@pytest.mark.parametrize("name", ["longsleeve", "skirt"])
def test_map_of_a_resized_template_starts_at_its_measurements(name):
    """A template made with other measurements (template_sizing's re-made template) and mapped
    with them: values0 are those measurements, ζ(values0) its own cage, and ζ at the default
    measurements puts the outline's corners on the default template's outline (the same family of
    outlines, entered elsewhere; shifted by this garment's panel layout offsets)."""
    defaults = make_template(name, edge_length=0.06)
    mm0 = MeasurementMap(name, None, defaults, build_cage(defaults))
    sized = {mm0.names[0]: 0.9 * mm0.values0[0]}
    g = make_template(name, edge_length=0.06, **sized)
    cage = build_cage(g)
    mm = MeasurementMap(name, None, g, cage, measurements=sized)
    assert mm.values0[0] == pytest.approx(sized[mm0.names[0]]) and np.allclose(mm.values0[1:], mm0.values0[1:])
    assert np.abs(mm.handles(mm.values0) - cage.zeta0).max() < 1e-12
    spec = template_spec(name, None)
    corners = np.flatnonzero(mm.t == 0.0)
    back = mm.handles(mm0.values0)
    for h in corners:
        assert np.allclose(back[h], spec.panels[mm.panel[h]].vertices[mm.edge[h]] + mm.offset[h], atol=1e-12)


def test_measurement_gradient_matches_central_differences(skirt_problem):
    """dφ/dm = (∂ζ/∂m)ᵀ dφ/dζ (adjoint through the drape, then the outline's Jacobian) against
    central differences of φ(ζ(m)) at a fixed warm start, for the cage and for the 'without
    control cage' parametrization (every rest vertex W ζ(m)). The warm start (with the contact
    planes detected there) defines φ; where Newton from the fixture's drape puts the stencil's
    sides on two equilibria 1 cm apart at every step (round-off seed 17), φ has no derivative
    there, and the differences are taken from the centre's own drape instead — the warm start the
    optimizer's next iteration would use."""
    model, p, g, cloth, pts, loops = skirt_problem
    lm = model.landmarks(p)
    x_keep = np.array(cloth.x)
    cage = build_cage(g)
    mm = MeasurementMap("skirt", lm, g, cage)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=500, bending="fixed")
    m = mm.values0 + np.array([0.01, 0.005, -0.02])
    for c in (cage, None):
        obj = CoOptObjective(cloth, g, pts, loops, opts, cage=c)

        def phi(warm, v):
            obj.x_warm = warm
            value, grad, _ = measurement_objective(obj, mm, {}, v)
            assert grad["measurements"].shape == (3,) and np.isfinite(value)
            return value, grad, np.array(cloth.x)

        def centre(warm):
            _, grad, x = phi(warm, m)
            return grad, x

        def side(warm, group, i, step):
            e = np.zeros(3)
            e[i] = step
            v, grad, x = phi(warm, m + e)
            return v, grad[group][i], x
        # 1e-6 m: at 1e-5 the waist's contact set changes within the stencil (3e-4 off)
        diffs, grad = differences_on_one_branch(centre, side, lambda _: [("measurements", i, 1e-6) for i in range(3)],
                                                x_keep)
        an0 = grad["measurements"]
        for _, i, fd, an, gap in diffs:
            assert gap <= BRANCH_TOL, (c is None, i, gap)
            assert abs(an - fd) <= 1e-5 * max(np.abs(an0).max(), 1e-12), (c is None, i, an, fd)  # measured ≤ 6e-8


def test_fit_recovers_a_known_length(skirt_problem, skirt_true_length):
    """From the template (length 0.55 m), the fit against the 8% longer skirt's drape ends with
    the length within 1 cm of the truth (0.594 m), at a lower φ, the cloth at the fitted
    pattern's equilibrium; the other measurements (waist ease, hem width: the truth's are the
    template's) stay within 3 cm of it."""
    model, p, g, cloth, pts, loops = skirt_problem
    lm = model.landmarks(p)
    cage = build_cage(g)
    mm = MeasurementMap("skirt", lm, g, cage)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=500, bending="fixed", optimize_body=False)
    obj = CoOptObjective(cloth, g, pts, loops, opts, cage=cage)
    seen = []
    res = fit_measurements(obj, mm, obj.initial_params(), 10, 0.01, on_iteration=seen.append)
    assert res.names == ("length", "waist_ease", "hem_width")
    i = res.names.index("length")
    assert abs(res.values[i] - skirt_true_length) < 0.01, res.values
    assert np.abs(np.delete(res.values - res.values0, i)).max() < 0.03, res.values
    assert res.value < res.value0 and res.iterations >= 1 and len(seen) == res.iterations + 1
    assert np.allclose(res.handles, mm.handles(res.values))
    assert np.allclose(np.asarray(cloth.control.rest), cage.rest(res.handles))   # the cloth: the last iterate


def test_a_fit_started_elsewhere_continues_from_there(skirt_problem, skirt_true_length):
    """fit_measurements(start=m): the fit's first point is m (what the co-optimization does after
    the bending search: the measurements fitted again from the first fit's); `then` joins the
    two runs: the template's values and φ from the first, the fitted ones from the second, both
    rounds and their iterations."""
    model, p, g, cloth, pts, loops = skirt_problem
    cage = build_cage(g)
    mm = MeasurementMap("skirt", model.landmarks(p), g, cage)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=500, bending="fixed", optimize_body=False)
    obj = CoOptObjective(cloth, g, pts, loops, opts, cage=cage)
    first = fit_measurements(obj, mm, obj.initial_params(), 3, 0.01)
    assert first.iterations >= 1
    seen = []
    again = fit_measurements(obj, mm, obj.initial_params(), 3, 0.01, start=first.values, on_iteration=seen.append)
    np.testing.assert_array_equal(again.values0, first.values)
    # the same point re-draped from its own equilibrium (the anchors move to it: ~1%)
    assert seen[0]["value"] == again.value0 == pytest.approx(first.value, rel=0.02)
    assert again.value <= again.value0
    both = first.then(again)
    np.testing.assert_array_equal(both.values0, first.values0)
    np.testing.assert_array_equal(both.values, again.values)
    assert both.value0 == first.value0 and both.value == again.value
    assert both.iterations == first.iterations + again.iterations and len(both.history) == len(first.history) + len(again.history)
    j = both.to_json()
    assert [r["start_m"] for r in j["rounds"]] == [list(first.values0), list(first.values)]
    assert j["rounds"][1]["fitted_m"] == j["fitted_m"] and abs(j["fitted_m"][0] - skirt_true_length) < 0.01


def test_bad_inputs_name_the_problem():
    g = make_template("skirt", edge_length=0.07)
    cage = build_cage(g)
    with pytest.raises(ValueError, match="no parametric measurements"):
        MeasurementMap("my_template.obj", None, g, cage)
    mm = MeasurementMap("skirt", None, g, cage)
    for bad in ([0.5, 0.04], [np.nan, 0.04, 1.3], [0.5, -0.01, 1.3]):
        with pytest.raises(ValueError, match="measurements"):
            mm.handles(bad)
    # a garment not built from a spec (an OBJ or exported pattern: its panels carry no outline parameters)
    plain = Garment(g.rest, g.faces, g.x0, g.seams, g.panel, [PanelInfo(p.name, p.loop, p.grain) for p in g.panels])
    with pytest.raises(ValueError, match="outline parameters"):
        MeasurementMap("skirt", None, plain, build_cage(plain))
    with pytest.raises(ValueError, match="measurement_fit_iterations"):
        RecoverOptions.from_config(measurement_fit_iterations=-1)
    with pytest.raises(ValueError, match="step_sizes.measurements"):
        o = RecoverOptions.from_config()
        o.with_(step_sizes=type(o.step_sizes)(measurements=0.0))


def test_co_optimize_runs_the_fit_first(skirt_problem, skirt_true_length):
    """co_optimize with a measurement map: the fit's iterations open the history (stage
    'measurements'), the co-optimization's follow, numbered on without a repeated start; the
    co-optimization's first pattern is the fitted outline."""
    model, p, g, cloth, pts, loops = skirt_problem
    lm = model.landmarks(p)
    cage = build_cage(g)
    mm = MeasurementMap("skirt", lm, g, cage)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=300, bending="fixed", optimize_body=False,
                                      iterations=2, measurement_fit_iterations=3, fresh_every=0,
                                      guided_stiffness=0.0)
    starts = []
    res = co_optimize(cloth, g, pts, loops, opts, cage=cage, measurement_map=mm,
                      on_iteration=lambda h: starts.append(np.array(cloth.control.rest)))
    fit = res.measurement_fit
    assert fit is not None and fit.iterations >= 1 and fit.value < fit.value0
    n_fit = fit.iterations + 1
    assert [h.get("stage") for h in res.history[:n_fit]] == ["measurements"] * n_fit
    assert all("stage" not in h for h in res.history[n_fit:]) and len(res.history) == n_fit + res.iterations
    assert [h["iteration"] for h in res.history] == list(range(len(res.history)))
    np.testing.assert_allclose(starts[n_fit - 1], cage.rest(fit.handles), atol=1e-12)
    assert abs(fit.values[0] - skirt_true_length) < abs(fit.values0[0] - skirt_true_length)
