"""The bending search with each candidate's outline fitted again at its bending (search_bending's
refit, option measurement_fit_refit): every candidate is judged at the outline the measurement fit
gives it, on its fresh drapes alone — the same values, bit for bit, as asked directly — the kept
one returns with that outline, the search leaves the objective's undo history as it was, and the
candidates may run at once (the same results as in turn)."""
import numpy as np
import pytest

from diffavatar_core.body import BodyModel
from diffavatar_core.pipeline import RecoverOptions
from diffavatar_core.pipeline.measurement_fit import MeasurementMap, fit_measurements


def _refit_for(obj, calls):
    """A refit as co_optimize makes it (two L-BFGS steps of the skirt's measurements from the
    template's values), recording (bending N·m, the handles it returned)."""
    model = BodyModel.default()
    mm = MeasurementMap("skirt", model.landmarks(model.zero_params()), obj.g, obj.cage)

    def refit(o, p):
        f = fit_measurements(o, mm, p, 2, obj.opts.step_sizes.measurements, start=mm.values0)
        out = {**p, "handles": mm.parameters(f.handles, vertices=False).copy()}
        calls.append((float(10.0 ** np.asarray(p["log_bend"]).reshape(-1)[0]), np.array(out["handles"])))
        return out
    return refit


@pytest.mark.parametrize("workers", [1, 2])
def test_each_candidate_is_judged_at_its_own_fitted_outline(soft_skirt_objective, workers):
    obj, theta = soft_skirt_objective(bending_fresh_drapes=2, bending_margin=0.0, candidate_workers=workers)
    calls = []
    undo = [np.array(u) for u in obj._undo]
    best, report = obj.search_bending(theta, (1.0,), refit=_refit_for(obj, calls))
    assert len(obj._undo) == len(undo) and all(np.array_equal(a, b) for a, b in zip(obj._undo, undo))
    judged = report["judged"][0]
    assert sorted(kb for kb, _ in calls) == sorted(kb for kb, _, _ in judged) and len(judged) == 2
    ref, _ = soft_skirt_objective(bending_fresh_drapes=2)
    v_cur = ref.fresh_min(theta)
    handles = dict(calls)
    for kb, v, against in judged:
        assert not np.array_equal(handles[kb], theta["handles"])   # the fit moved the outline
        cand = {**theta, "log_bend": np.array([np.log10(kb)]), "handles": handles[kb]}
        assert against == v_cur and v == ref.fresh_min(cand)
    if report["kept"][0]:
        kb = report["bending_Nm"]
        np.testing.assert_array_equal(best["handles"], handles[kb])
    else:
        np.testing.assert_array_equal(best["handles"], theta["handles"])


def test_refit_search_at_once_is_the_search_in_turn(soft_skirt_objective):
    out = []
    for workers in (1, 2):
        obj, theta = soft_skirt_objective(bending_fresh_drapes=2, bending_margin=0.0, candidate_workers=workers)
        best, report = obj.search_bending(theta, (1.0,), refit=_refit_for(obj, []))
        out.append((best, report, np.array(obj.x_warm)))
    (b1, r1, x1), (b2, r2, x2) = out
    assert r1 == r2
    for g in b1:
        np.testing.assert_array_equal(b1[g], b2[g])
    np.testing.assert_array_equal(x1, x2)


def test_measurement_fit_refit_is_validated():
    with pytest.raises(ValueError, match="measurement_fit_refit"):
        RecoverOptions.from_config(measurement_fit_refit="yes")
    assert RecoverOptions.from_config().measurement_fit_refit is False
