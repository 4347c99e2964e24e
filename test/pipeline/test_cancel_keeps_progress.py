"""A recovery cancelled once its optimization has begun keeps what it produced: recover() raises
RecoveryCancelled (a diffavatar_core.Cancelled) carrying the optimization's current iterate as a
result, and `diffavatar recover` interrupted by Ctrl-C writes it to --out before exiting 130.
The kept iterate is the one its last loss-history entry was evaluated on: the seam and curvature
terms (rest pattern only) and the boundary term (the drape) recomputed from the returned pattern
and drape equal the entry's."""
import json
import threading

import numpy as np
import pytest

import diffavatar_core as dc
from diffavatar_core.loss import boundary_loss
from diffavatar_core.pattern.regularizers import CurvatureRegularizer, SeamLengthRegularizer
from diffavatar_core.pipeline import RecoverOptions, RecoveryCancelled, recover
from diffavatar_core.pipeline.recovery import scan_for_recovery

from bundled_sample import SAMPLE
from interrupted_recovery import interrupt_recovery

STEP = 3   # the optimization step (as progress counts them) at which the cancel comes


def _cancelled_at(step: int, **options):
    ev = threading.Event()

    def progress(stage, iteration, *_):
        if stage == "optimize" and iteration >= step:
            ev.set()   # seen at the optimizer's next check: before the following step
    with pytest.raises(RecoveryCancelled) as err:
        recover(SAMPLE, {"units": "cm", "iterations": 6, **options}, progress=progress, cancel=ev)
    assert isinstance(err.value, dc.Cancelled) and str(err.value) == "cancelled during optimize"
    return err.value.result


@pytest.fixture(scope="module")
def kept():
    return _cancelled_at(STEP)


def test_a_cancel_in_the_optimization_keeps_its_current_iterate(kept):
    r = kept
    m = r.metrics
    assert m["stopped"] == "cancelled" and m["cancelled_during"] == "optimize"
    assert r.loss_history[-1]["iteration"] == STEP   # nothing after the step the cancel came at
    assert r.material.bending_stiffness_range == (None, None)   # not judged
    assert m["output_drape"]["criterion"] == "anchored"
    assert any(w.startswith(f"cancelled during the optimization at step {STEP} of ") for w in r.warnings)
    # the progress made is kept: nearer the scan than the template's drape, a valid pattern
    assert m["chamfer_final_cm"] < m["chamfer_initial_cm"]
    assert m["mesh_quality_min"] > 0 and np.isfinite(r.garment_vertices).all()
    assert m["seam_length_mismatch_max_pct"] <= RecoverOptions.coerce({}).max_seam_mismatch_pct
    assert not np.allclose(r.garment_uv, r.template.rest)   # the pattern moved from the template's


def test_the_kept_iterate_is_the_one_its_last_loss_entry_was_evaluated_on(kept):
    r, last = kept, kept.loss_history[-1]["terms"]
    assert abs(r.metrics["facing_yaw_rad"]) < 0.3 and not any(r.metrics["scan_origin_m"])   # the core frame
    rest = np.asarray(r.garment_uv, np.float64)
    assert SeamLengthRegularizer(r.template).value_and_grad(rest)[0] == pytest.approx(last["seam"], rel=1e-12)
    assert CurvatureRegularizer(r.template).value_and_grad(rest)[0] == pytest.approx(last["curvature"], rel=1e-12)
    data = scan_for_recovery(SAMPLE, RecoverOptions.coerce({"units": "cm"}))
    loops = {k: v for k, v in r.template.boundaries.items() if k in data.boundaries}
    lb = boundary_loss(np.asarray(r.garment_vertices, np.float64), loops, data.boundaries,
                       RecoverOptions.coerce({}).boundary_scale)
    assert lb.value == pytest.approx(last["boundary"], rel=1e-9)


def test_a_cancel_before_the_optimization_keeps_nothing():
    ev = threading.Event()

    def progress(stage, *_):
        if stage == "drape":
            ev.set()
    with pytest.raises(dc.Cancelled) as err:
        recover(SAMPLE, {"units": "cm", "iterations": 2}, progress=progress, cancel=ev)
    assert not isinstance(err.value, RecoveryCancelled)


def _optimize_step(line: str) -> int:
    """The step of a progress line '[  t s] optimize   [###---] k/N ...'; -1 for any other line."""
    parts = line.split("] optimize")
    return int(parts[1].split("]")[1].split("/")[0]) if len(parts) > 1 and "/" in parts[1] else -1


def test_ctrl_c_in_the_optimization_writes_what_it_produced_and_exits_130(tmp_path):
    out = tmp_path / "out"
    r = interrupt_recovery(out, 6, lambda line: _optimize_step(line) >= 2, reach_s=300, end_s=60)
    assert r.rc == 130, r.stderr
    assert "Traceback" not in r.stderr and "KeyboardInterrupt" not in r.stderr, r.stderr
    assert r.messages == [f"diffavatar: cancelled during optimize; what it had produced is in {out}/ (result.json: "
                          f"metrics.stopped, metrics.cancelled_during, warnings)"], r.stderr
    stdout, waited = r.stdout, r.waited
    summary = json.loads(stdout[:stdout.rindex("}") + 1])
    written = json.loads((out / "result.json").read_text())
    assert written["metrics"]["stopped"] == summary["stopped"] == "cancelled"
    assert written["metrics"]["cancelled_during"] == "optimize"
    assert written["metrics"]["chamfer_final_cm"] < written["metrics"]["chamfer_initial_cm"]
    assert written["iterations"] == summary["iterations"] and waited < 30, waited
    assert {"pattern.json", "garment_draped.obj", "body.obj", "loss.png"} <= {f.name for f in out.iterdir()}
