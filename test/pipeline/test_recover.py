"""The recovery pipeline (issue 7): the co-optimization objective's gradient against central
differences, an end-to-end recovery of the bundled synthetic scan toward its ground truth,
option handling, cancellation and bad inputs with clear errors."""
import json
import threading
import time

import numpy as np
import pytest

import diffavatar_core as dc
from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pipeline import RecoverOptions, RecoveryError, recover
from diffavatar_core.pipeline.coopt import CoOptObjective
from diffavatar_core.pipeline.facing import facing_yaw, turned_params, yaw_rotation
from diffavatar_core.pipeline.options import Weights
from diffavatar_core.pipeline.output import write_result
from diffavatar_core.demo import SAMPLE, TRUTH
from diffavatar_core.scan import ImplausibleSizeError, LabelError, NoGarmentError, NonFiniteError, ScanError
from diffavatar_core.sim.material import ClothMaterial

from branch_difference import BRANCH_TOL, differences_on_one_branch
from bundled_sample import NO_BENDING_SEARCH, QUICK
from sample_recovery import SAMPLE_GROUP, recovered_sample


@pytest.mark.parametrize("problem,boundary_scale,interior_to", [("skirt_problem", 0.0, "points"),
                                                                ("smooth_skirt_problem", 0.0, "points"),
                                                                ("skirt_problem", 0.01, "points"),
                                                                ("skirt_problem", 0.0, "surface")])
def test_objective_gradient_matches_central_differences(problem, boundary_scale, interior_to, request):
    """dφ/dθ of the full objective (boundary + interior + seam + curvature + body data + body
    prior; handles through W, log10 bending, body shape and pose through the skinning Jacobians)
    against central differences at a fixed warm start (the anchor of the equilibrium; the
    centre's own drape where the sides straddle a basin boundary of Newton from it,
    differences_on_one_branch), with either contact plane (the smooth one: measured ≤ 3e-8
    relative), and with the robust boundary term (boundary_scale 1 cm; the target skirt is 8%
    longer, so its hem lies centimetres away, where the robust pull is a fraction of L2's), and
    with L_interior's garment samples measured to a scan surface (interior_to 'surface': here the
    start's drape scaled by 1.05 about its centre, centimetres from the cloth)."""
    model, p, g, cloth, pts, loops = request.getfixturevalue(problem)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=500, boundary_scale=boundary_scale,
                                      interior_to=interior_to)
    x0 = np.array(cloth.x)
    scan_mesh = (x0.mean(axis=0) + 1.05 * (x0 - x0.mean(axis=0)), g.faces) if interior_to == "surface" else None
    rng = np.random.default_rng(0)
    bv = model.pose(p)   # "visible body": upper-body vertices of the true body, 2 mm noise
    body_pts = bv[bv[:, 1] > np.percentile(bv[:, 1], 70)]
    body_pts = body_pts + rng.normal(scale=0.002, size=body_pts.shape)
    obj = CoOptObjective(cloth, g, pts, loops, opts, cage=build_cage(g), body_model=model, body_params=p,
                         body_points=body_pts, scan_mesh=scan_mesh)
    x_base = np.array(cloth.x)
    theta = obj.initial_params()
    theta["handles"] = theta["handles"] + rng.normal(scale=0.001, size=theta["handles"].shape)
    theta["shape"] = theta["shape"] + 0.05

    def centre(warm):
        obj.x_warm = warm
        _, grads, terms = obj(theta)
        assert all(np.isfinite(v) for v in terms.values()) and terms["body_data"] > 0
        return grads, obj.x_last

    def side(warm, group, k, step):
        t = {kk: np.array(v, float) for kk, v in theta.items()}
        t[group][k] += step
        obj.x_warm = warm
        v, gr, _ = obj(t)
        return v, gr[group][k], obj.x_last

    handles = [("handles", k) for k in rng.choice(len(theta["handles"]), 4, replace=False)]

    def checks(grads):
        # small body steps: the body term's closest points switch faces within larger ones (pose 5
        # at 1e-5 rad); not too small: each drape's Newton stops somewhere under the 1e-8 residual,
        # ~1e-13 of noise in φ — at 1e-6 rad 5e-4 of a 1.7e-4 pose derivative on an AVX-512 machine
        # (stop 47); at 3e-6 the unperturbed run and round-off seeds 1-11 pass there
        h = {"handles": 1e-6, "log_bend": 1e-4, "shape": 1e-6, "pose": 3e-6}
        picks = handles + [("log_bend", 0), ("shape", 0), ("shape", 1), ("pose", 5),
                           ("pose", int(np.argmax(np.abs(grads["pose"]))))]
        return [(group, k, h[group]) for group, k in picks]

    diffs, grads = differences_on_one_branch(centre, side, checks, x_base)
    for group, k, fd, an, gap in diffs:
        assert gap <= BRANCH_TOL, (group, k, gap)
        scale = max(abs(fd), 1e-3 * np.abs(grads[group]).max(), 1e-12)
        assert abs(an - fd) <= 1e-4 * scale, (group, k, an, fd)   # measured ≤ 2e-8


def test_only_committed_iterates_become_warm_starts(skirt_problem):
    """A trial the optimizer rejects must not be the next evaluation's start (a trial can find
    another equilibrium, e.g. a skirt slid off the hips); an accepted one must."""
    model, p, g, cloth, pts, loops = skirt_problem
    obj = CoOptObjective(cloth, g, pts, loops, RecoverOptions.from_config(residual_tol=1e-8, samples=200),
                         cage=build_cage(g))
    x0 = np.array(obj.x_warm)
    theta = obj.initial_params()
    theta["handles"] = theta["handles"] * 1.01    # a 1% larger pattern: a different drape
    obj(theta)
    assert np.array_equal(obj.x_warm, x0) and np.abs(obj.x_last - x0).max() > 1e-4
    obj.commit()
    assert np.array_equal(obj.x_warm, obj.x_last)


def test_value_is_the_objectives_value_without_the_adjoint(skirt_problem, monkeypatch):
    """CoOptObjective.value (the candidate comparisons' evaluation): from the same warm start the
    same drape and the same φ, to the bit, as __call__ — every term, the body's data and prior
    included — and no adjoint solve."""
    import diffavatar_core.pipeline.coopt as coopt
    model, p, g, cloth, pts, loops = skirt_problem
    bv = model.pose(p)
    body_pts = bv[bv[:, 1] > np.percentile(bv[:, 1], 70)]
    obj = CoOptObjective(cloth, g, pts, loops, RecoverOptions.from_config(residual_tol=1e-8, samples=200),
                         cage=build_cage(g), body_model=model, body_params=p, body_points=body_pts)
    theta = obj.initial_params()
    theta["handles"] = theta["handles"] * 1.01
    theta["shape"] = theta["shape"] + 0.05
    x0 = np.array(obj.x_warm)
    v, _, terms = obj(theta)
    x_full = np.array(obj.x_last)
    assert terms["body_data"] > 0 and terms["body_prior"] > 0
    obj.x_warm = x0

    def no_adjoint(*a, **k):
        raise AssertionError("value() solved the adjoint")
    monkeypatch.setattr(coopt, "equilibrium_gradient", no_adjoint)
    assert obj.value(theta) == v
    assert np.array_equal(obj.x_last, x_full) and np.array_equal(obj.x_warm, x0)


def test_h1_metric_step_descends(skirt_problem):
    """The objective's L-BFGS metric on the handles (sobolev_length > 0) has one row per handle
    coordinate; a 1 mm step along −P∇φ lowers φ by what the gradient predicts (first order, ±30%,
    both evaluations anchored at θ's own equilibrium);
    sobolev_length 0 gives no metric (Euclidean L-BFGS)."""
    model, p, g, cloth, pts, loops = skirt_problem
    cage = build_cage(g)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=200, bending="fixed")
    assert CoOptObjective(cloth, g, pts, loops, opts.with_(sobolev_length=0.0), cage=cage).precondition() == {}
    obj = CoOptObjective(cloth, g, pts, loops, opts, cage=cage)
    P = obj.precondition()["handles"]
    theta = obj.initial_params()
    assert P.n == len(cage.handles) and theta["handles"].shape == (2 * P.n,)
    obj(theta)
    obj.commit()
    x_base = np.array(obj.x_warm)
    v0, grads, _ = obj(theta)
    gh = grads["handles"]
    d = -P(gh)
    step = 0.001 * d / np.abs(d).max()
    obj.x_warm = x_base
    v1 = obj({**theta, "handles": theta["handles"] + step})[0]
    predicted = float(gh @ step)
    assert predicted < 0 and v1 < v0
    assert abs((v1 - v0) - predicted) < 0.3 * abs(predicted), (v1 - v0, predicted)


@pytest.fixture(scope="module")
def recovered(tmp_path_factory):
    """The bundled sample recovered with 6 iterations (sample_recovery.py: made once per session),
    written to a result directory."""
    r, stages = recovered_sample(6)
    out = write_result(r, tmp_path_factory.mktemp("recovered") / "res", scan=r.scan_mesh)
    return r, out, list(stages)


@SAMPLE_GROUP
def test_end_to_end_recovery_moves_toward_the_ground_truth(recovered):
    """The bundled sample scan (a skirt with perturbed length and hem): a few iterations reduce
    the Chamfer distance and bring the pattern area closer to the truth; every output is
    written and physically valid."""
    r, out, stages = recovered
    truth = json.loads(TRUTH.read_text())
    m = r.metrics
    assert m["chamfer_final_cm"] < 0.85 * m["chamfer_initial_cm"]
    area_gt = truth["pattern_area_m2"]
    assert abs(m["pattern_area_m2"] - area_gt) < 0.6 * abs(m["template_area_m2"] - area_gt)
    assert m["seam_length_mismatch_max_pct"] <= 5.0
    assert m["fresh_drapes_kept"] in (0, 1)   # 6 iterations, fresh_every 5: one fresh drape tried
    assert m["guided_drapes_kept"] in (0, 1, 2)   # and a guided one then and at the end
    # the template's measurements fitted first, the bending held; then the bending searched at the
    # fitted outline (measurement_fit_bending): from the default 5e-6 N·m nearer the truth's 7.9e-5
    # (stop 48: 5e-5), at a lower φ; then the measurements fitted again from the first fit's, at it
    search = m["measurement_fit_bending"]
    log_truth = np.log10(truth["bend_stiffness_Nm"])
    assert abs(np.log10(search["bending_Nm"]) - log_truth) < abs(np.log10(search["bending_Nm_start"]) - log_truth), search
    assert search["value"] < search["value_start"]
    fit, sizing = m["measurement_fit"], m["template_sizing"]
    rounds = fit["rounds"]
    assert len(rounds) == 2 and rounds[1]["start_m"] == rounds[0]["fitted_m"] and rounds[1]["fitted_m"] == fit["fitted_m"]
    # the second fit starts below where the first ended: the searched fabric explains the scan better
    # (0.0023 against 0.0067, stop 48; the search's own φ there 0.0022: a re-drape from its own drape)
    assert rounds[1]["loss_start"] < rounds[0]["loss_fitted"]
    assert fit["iterations"] == sum(r_["iterations"] for r_ in rounds)
    fitted = [h for h in r.loss_history if h.get("stage") == "measurements"]
    assert len(fitted) == sum(r_["iterations"] + 1 for r_ in rounds)   # both fits' starts and steps, numbered on
    assert [h["iteration"] for h in r.loss_history] == list(range(len(r.loss_history)))
    # each measurement nearer the truth's (length −14%, hem +6%): the error left, as a fraction of
    # the template's, over the unperturbed run and 5 under `--roundoff-seed` (stop 33) was
    # 0.06-0.07 for the length and 0.01-0.50 for the hem width, which the skirt's folds can take up
    # instead. With the fit alone, under the default bending, on an AVX-512 machine (stop 47) the
    # folds that left preferred a skirt 2.4 cm short (0.30 of the template's error; 0.07 after the search)
    assert fit["names"] == ["length", "waist_ease", "hem_width"] and fit["loss_fitted"] < fit["loss_template"]
    for name, true in truth["measurements_m"].items():
        k = fit["names"].index(name)
        left = {"length": 0.25, "hem_width": 0.75}[name]
        assert abs(fit["fitted_m"][k] - true) < left * abs(sizing["template_m"][name] - true), (name, fit, sizing)
    # the fit started from the template re-made at the length the hem's height gives
    # (template_sizing.py): nearer the truth than the template's, and draped nearer the scan
    assert sizing["kept"] and fit["template_m"][0] == pytest.approx(sizing["measurements_m"]["length"])
    true_length = truth["measurements_m"]["length"]
    assert abs(sizing["measurements_m"]["length"] - true_length) < 0.5 * abs(sizing["template_m"]["length"] - true_length)
    assert sizing["chamfer_cm"] < m["chamfer_initial_cm"]
    assert m["mesh_quality_min"] > 0.05
    assert [s for s in ("preprocess", "body", "drape", "optimize", "metrics") if s in stages] == \
        ["preprocess", "body", "drape", "optimize", "metrics"]
    values = [h["value"] for h in r.loss_history]
    assert min(values) < values[0]
    # rest triangles keep their orientation (no inverted pattern triangle)
    R, T = r.pattern.rest_xy, r.pattern.triangles
    e1, e2 = R[T[:, 1]] - R[T[:, 0]], R[T[:, 2]] - R[T[:, 0]]
    assert np.all(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0)
    for f in ("result.json", "pattern.json", "pattern.svg", "pattern.png", "garment_rest.obj",
              "garment_draped.obj", "body.obj", "loss.png", "preview.png"):
        assert (out / f).stat().st_size > 0, f
    j = json.loads((out / "result.json").read_text())
    assert j["garment_type"] == "skirt" and j["template"] == "skirt"
    assert 0 < j["metrics"]["ssim"] <= 1
    n_fit = sum(r_["iterations"] + 1 for r_ in rounds)   # each fit's start and accepted steps
    assert len(j["loss_history"]) == n_fit + r.iterations
    assert [h.get("stage") for h in j["loss_history"][:n_fit]] == ["measurements"] * n_fit


@SAMPLE_GROUP
def test_result_directory_reloads_as_its_own_equilibrium(recovered):
    """The written assets (pattern.json rest shape, material, body parameters) rebuild a cloth
    whose recovered drape is an equilibrium of its own anchors: re-solved without them, no vertex
    moves more than 0.5 mm (without the re-anchoring at the end of co_optimize: 2.6 mm) — or, when
    the re-anchoring rounds did not converge and the result warns that the assets may settle by
    about its last move (metrics.output_drape.self_anchor_move_m), twice that move. Measured: 4e-5
    mm; 7e-5 mm under `--roundoff-seed 10` (0.75 mm before the rounds re-solved with their end
    state's contact planes); under seed 5 the face planes alternate (0.67 mm; the reload moved 0.73
    mm) and the output is re-anchored with valley contacts instead (1.2e-3 mm, test_output_drape)."""
    from diffavatar_core.pipeline.assets import load_result
    r, out, _ = recovered
    a = load_result(out)
    np.testing.assert_allclose(a.body_model.pose(a.body_params), r.body_vertices, atol=1e-9)
    np.testing.assert_allclose(a.garment.rest, r.pattern.rest_xy, atol=0)
    cloth = a.cloth()
    it, res = cloth.refine(keep_anchor=False, residual_tol=1e-7, refine_iterations=100)
    assert res <= 1e-6
    move = r.metrics["output_drape"]["self_anchor_move_m"]   # m: the last re-anchoring round's
    assert (move > 1e-4) == any("still moved" in w for w in r.warnings)
    d = np.linalg.norm(np.array(cloth.x) - r.garment_vertices, axis=1).max()
    assert d < max(5e-4, 2 * move), (d, move)   # self-anchored (Cloth.self_anchor)


@SAMPLE_GROUP
def test_a_reload_uses_the_recoverys_contact_plane(recovered, tmp_path):
    """result.json records the contact plane the drape is an equilibrium of; the reloaded Cloth
    uses it (a valley recovery reloaded with face planes would move); an unknown one is named.
    A face-plane recovery records "face", or "valley" when its output drape was re-anchored with
    valley contacts because the face planes alternated (test_output_drape)."""
    import shutil
    from diffavatar_core.pipeline.assets import load_result
    r, out, _ = recovered
    od = r.metrics["output_drape"]
    planes = json.loads((out / "result.json").read_text())["material"]["contact_normals"]
    assert planes == od["contact_normals"] == ("valley" if "face_plane_move_m" in od else "face")
    m = load_result(out).cloth().model
    assert not m.smooth_contact and m.valley_contact == (planes == "valley")
    for normals, smooth, valley in (("valley", False, True), ("smooth", True, False)):
        d = tmp_path / normals
        shutil.copytree(out, d)
        summary = json.loads((d / "result.json").read_text())
        summary["material"]["contact_normals"] = normals
        (d / "result.json").write_text(json.dumps(summary))
        m = load_result(d).cloth().model
        assert (m.smooth_contact, m.valley_contact) == (smooth, valley)
    summary["material"]["contact_normals"] = "phong"
    (d / "result.json").write_text(json.dumps(summary))
    with pytest.raises(ValueError, match="contact_normals 'phong'"):
        load_result(d)


@SAMPLE_GROUP
def test_animate_a_result_directory(recovered, tmp_path):
    """`diffavatar animate RESULT_DIR`: the recovered skirt stays on the walking recovered body."""
    import subprocess
    import sys
    import trimesh
    _, out, _ = recovered
    anim = tmp_path / "anim"
    p = subprocess.run([sys.executable, "-m", "diffavatar_core", "animate", str(out), "--motion", "walk",
                        "--frames", "6", "--cycles", "0.2", "--out", str(anim)], capture_output=True, text=True,
                       timeout=900)
    assert p.returncode == 0, p.stderr
    info = json.loads((anim / "animate.json").read_text())
    assert info["drape_converged"]
    assert info["max_penetration_mm"] <= 4.0 and info["max_distance_from_body_m"] <= 0.30
    data = np.load(anim / "positions.npz")
    assert data["garment"].shape[0] == 6 and np.all(np.isfinite(data["garment"]))
    assert len(trimesh.load(anim / "animation.glb", force="scene").geometry) == 2


def test_options_from_node_dict_and_config():
    o = RecoverOptions.coerce({"job_id": "j1", "iterations": 7, "garment_type": "", "units": "cm", "up_axis": "z"})
    assert (o.iterations, o.units, o.up, o.garment_type, o.job_id) == (7, "cm", "z", None, "j1")
    # iterations 0 is "drape the template only" in a dict too, as in the config and the CLI (it
    # was read as "the configured 30", so tests whose options said 0 ran 30 iterations); the
    # node maps a scan's 0 to its default_iterations before the dict is made
    assert RecoverOptions.coerce({"iterations": 0}).iterations == 0
    assert RecoverOptions.coerce({}).iterations == RecoverOptions.from_config().iterations == 30
    with pytest.raises(ValueError, match="parametrization"):
        RecoverOptions.from_config(parametrization="mesh")
    with pytest.raises(ValueError, match="newton_solver.*simplicial.*supernodal"):
        RecoverOptions.from_config(newton_solver="cholmod")
    with pytest.raises(ValueError, match="unknown option"):
        RecoverOptions.from_config(iteration=3)
    with pytest.raises(ValueError, match="edge_length"):
        RecoverOptions.from_config(edge_length=5.0)
    with pytest.raises(ValueError, match="output_edge_length"):
        RecoverOptions.from_config(output_edge_length=0.001)
    with pytest.raises(ValueError, match="optimize_body"):
        RecoverOptions.from_config(optimize_body="no")
    with pytest.raises(ValueError, match="masses_follow_rest"):
        RecoverOptions.from_config(masses_follow_rest="yes")
    with pytest.raises(ValueError, match="length_measure"):
        RecoverOptions.from_config(length_measure="smooth")
    with pytest.raises(ValueError, match="length_tolerance_pct"):
        RecoverOptions.from_config(length_tolerance_pct=-1)
    with pytest.raises(ValueError, match="fresh_every"):
        RecoverOptions.from_config(fresh_every=-1)
    with pytest.raises(ValueError, match="sobolev_length"):
        RecoverOptions.from_config(sobolev_length=-0.1)
    with pytest.raises(ValueError, match="reevaluations"):
        RecoverOptions.from_config(reevaluations=-1)
    with pytest.raises(ValueError, match="reevaluate_tol"):
        RecoverOptions.from_config(reevaluate_tol=float("nan"))
    with pytest.raises(ValueError, match="body_after"):
        RecoverOptions.from_config(body_after=1.5)
    with pytest.raises(ValueError, match="output_settle_tol"):
        RecoverOptions.from_config(output_settle_tol=0.0)
    with pytest.raises(ValueError, match="output_drape_steps"):
        RecoverOptions.from_config(output_drape_steps=0)
    with pytest.raises(ValueError, match="drape_rounds"):
        RecoverOptions.from_config(drape_rounds=0)
    with pytest.raises(ValueError, match="output_drape_sweeps"):
        RecoverOptions.from_config(output_drape_sweeps=0)
    with pytest.raises(ValueError, match="length_smoothing"):
        RecoverOptions.from_config(length_smoothing=-0.001)
    for bad in (-0.01, float("inf")):
        with pytest.raises(ValueError, match="boundary_scale"):
            RecoverOptions.from_config(boundary_scale=bad)
    for mu in (-0.1, float("nan"), "0.3"):
        with pytest.raises(ValueError, match="output_friction"):
            RecoverOptions.from_config(output_friction=mu)
    for drag in (-1.0, float("inf"), "20"):
        with pytest.raises(ValueError, match="output_drape_damping"):
            RecoverOptions.from_config(output_drape_damping=drag)
    with pytest.raises(ValueError, match="contact_normals"):
        RecoverOptions.from_config(contact_normals="phong")
    assert RecoverOptions.from_config(contact_normals="smooth").contact_normals == "smooth"
    with pytest.raises(ValueError, match="optimizer"):
        RecoverOptions.from_config(optimizer="sgd")
    with pytest.raises(ValueError, match="interior_to"):
        RecoverOptions.from_config(interior_to="mesh")
    with pytest.raises(ValueError, match="bending_after"):
        RecoverOptions.from_config(bending_after=-1)
    with pytest.raises(ValueError, match="body_trim_distance"):
        RecoverOptions.from_config(body_trim_distance=0)


def test_a_recovery_whose_start_does_not_drape_warns_and_returns_the_template(monkeypatch):
    """Fault injected: the objective cannot be evaluated at all (every drape of the optimizer
    fails). The recovery does not raise: the optimization stops before its first step, the
    result says so in its warnings with the drape's reason, and the assets are the starting
    template's pattern on its equilibrium (what was produced is kept)."""
    from diffavatar_core.pipeline import coopt

    def failing_call(self, params):
        raise ValueError("drape did not converge: injected")
    monkeypatch.setattr(coopt.CoOptObjective, "__call__", failing_call)
    r = recover(SAMPLE, {"units": "cm", "iterations": 2})
    assert r.metrics["stopped"] == "invalid_start" and r.iterations == 0
    assert any("stopped after 0 of 2 iterations" in w and "injected" in w for w in r.warnings), r.warnings
    assert np.isfinite(r.metrics["chamfer_final_cm"]) and r.garment_vertices.shape[1] == 3
    # the pattern the optimization started from: the template as re-made by the sizing (its mesh
    # is r.template), not the one first selected
    assert r.metrics["template_sizing"]["kept"]
    assert abs(r.metrics["pattern_area_m2"] / r.template.total_area() - 1) < 1e-9
    assert abs(r.metrics["pattern_area_m2"] / r.metrics["template_area_m2"] - 1) > 0.01


@SAMPLE_GROUP
def test_a_result_farther_from_the_scan_than_the_template_says_so(recovered, monkeypatch):
    """Fault injected: the final drape's Chamfer distance is measured 1 cm larger than the
    template's initial drape's (as benchmark dress 100 under round-off seed 2 with boundary_scale
    0.01 really ended farther: 0.816 cm against the template's 0.550). The result warns with both
    distances; unperturbed (the module's recovered sample) it does not."""
    from diffavatar_core.pipeline import recovery as rec
    r = recovered[0]
    assert r.metrics["chamfer_final_cm"] < r.metrics["chamfer_initial_cm"]
    assert not any("farther from the scan" in w for w in r.warnings), r.warnings
    real, calls = rec.chamfer_meshes, []

    def final_worse(*args, **kwargs):   # m; the 1st call is the initial drape's, the 2nd the final drape's
        calls.append(real(*args, **kwargs))
        return calls[0] + 0.01 if len(calls) == 2 else calls[-1]
    monkeypatch.setattr(rec, "chamfer_meshes", final_worse)
    r = recover(SAMPLE, QUICK)   # (no template sizing: it measures drapes too)
    assert r.metrics["chamfer_final_cm"] > r.metrics["chamfer_initial_cm"]
    msg = f"farther from the scan (Chamfer {r.metrics['chamfer_final_cm']:.3f} cm) than the template's initial " \
          f"drape ({r.metrics['chamfer_initial_cm']:.3f} cm)"
    assert any(msg in w for w in r.warnings), r.warnings


def test_an_initial_drape_that_face_planes_do_not_converge_continues_with_valley_contacts(monkeypatch, tmp_path):
    """Fault injected: the initial drape with face contact planes reports no convergence (as
    benchmark skirt 103's did, Newton residual 13.4: face planes alternating over concave body
    edges). The recovery re-drapes with valley contacts, warns, optimizes and writes with them:
    the material records 'valley', the reload holds the drape, and the Chamfer distance falls.
    When that drape fails too, the recovery raises, naming the drape."""
    import dataclasses
    from diffavatar_core.pipeline import recovery as rec
    from diffavatar_core.pipeline.assets import load_result
    real = rec._initial_drape
    tried = []

    def face_fails(cloth, opts, cancel):
        r, steps = real(cloth, opts, cancel)
        tried.append(bool(cloth.model.valley_contact))
        if not cloth.model.valley_contact:
            r = dataclasses.replace(r, converged=False, message="injected")
        return r, steps
    monkeypatch.setattr(rec, "_initial_drape", face_fails)
    r = recover(SAMPLE, {"units": "cm", "iterations": 2, **NO_BENDING_SEARCH})
    assert tried[:2] == [False, True] and all(tried[2:])   # then the template sizing's drapes, with valley too
    assert any("did not converge with face contact planes (injected" in w for w in r.warnings), r.warnings
    assert r.material.contact_normals == "valley" == r.metrics["output_drape"]["contact_normals"]
    assert "face_plane_move_m" not in r.metrics["output_drape"]
    assert r.metrics["chamfer_final_cm"] < r.metrics["chamfer_initial_cm"]
    out = write_result(r, tmp_path / "res", scan=r.scan_mesh)
    cloth = load_result(out).cloth()
    assert cloth.model.valley_contact
    _, res = cloth.refine(keep_anchor=False, residual_tol=1e-7, refine_iterations=100)
    assert res <= 1e-6
    assert np.linalg.norm(np.array(cloth.x) - r.garment_vertices, axis=1).max() < 5e-4

    def both_fail(cloth, opts, cancel):
        r, steps = real(cloth, opts, cancel)
        return dataclasses.replace(r, converged=False, message="injected"), steps
    monkeypatch.setattr(rec, "_initial_drape", both_fail)
    with pytest.raises(RecoveryError, match="initial drape of template 'skirt'.*injected.*with valley contacts too: injected"):
        recover(SAMPLE, {"units": "cm", "iterations": 2, **NO_BENDING_SEARCH})


def test_a_sized_template_that_does_not_drape_leaves_the_selected_one(monkeypatch):
    """Fault injected: every drape after the first (the template sizing's) reports no
    convergence. The recovery says so in metrics.template_sizing and goes on from the selected
    template's drape — its measurements are where the fit starts — to a result."""
    import dataclasses
    from diffavatar_core.pipeline import recovery as rec
    real, calls = rec._initial_drape, []

    def later_fail(cloth, opts, cancel):
        r, steps = real(cloth, opts, cancel)
        calls.append(1)
        return (r if len(calls) == 1 else dataclasses.replace(r, converged=False, message="injected")), steps
    monkeypatch.setattr(rec, "_initial_drape", later_fail)
    r = recover(SAMPLE, {"units": "cm", "iterations": 1, **NO_BENDING_SEARCH})
    sizing, fit = r.metrics["template_sizing"], r.metrics["measurement_fit"]
    assert len(calls) == 2 and not sizing["kept"] and sizing["rounds"][0]["converged"] is False
    assert fit["template_m"] == [sizing["template_m"][k] for k in fit["names"]]
    assert r.template.total_area() == pytest.approx(r.metrics["template_area_m2"], rel=1e-12)
    assert np.isfinite(r.metrics["chamfer_final_cm"])


def test_a_cancel_during_the_bending_search_ends_the_job_at_once(monkeypatch):
    """A threading.Event set 0.3 s into the bending search after the measurement fit (re-drapes and
    scan-guided drapes at other fabrics; about 10 s on the sample) ends the recovery within half a
    second."""
    from diffavatar_core.pipeline.coopt import CoOptObjective
    ev, set_at = threading.Event(), []
    real = CoOptObjective.search_bending

    def fire():
        set_at.append(time.monotonic())
        ev.set()

    def search(self, *args, **kwargs):
        threading.Timer(0.3, fire).start()
        return real(self, *args, **kwargs)
    monkeypatch.setattr(CoOptObjective, "search_bending", search)
    with pytest.raises(dc.Cancelled) as err:
        recover(SAMPLE, {"units": "cm", "iterations": 2}, cancel=ev)
    ended = time.monotonic()
    assert set_at and ended - set_at[0] < 0.5, (ended - set_at[0], str(err.value))


def test_cancel_stops_the_job():
    ev = threading.Event()

    def progress(stage, *_):
        if stage == "body":
            ev.set()
    with pytest.raises(dc.Cancelled):
        recover(SAMPLE, {"units": "cm", "iterations": 2}, progress=progress, cancel=ev)


@pytest.mark.parametrize("stage", ["body", "drape", "optimize"])
def test_a_cancel_event_ends_a_long_stage_at_once(stage):
    """A threading.Event set in the middle of the body fit (Python), of the initial drape (one
    long C++ call that watches a CancelToken) or 0.3 s into the optimization (the measurement
    fit's drapes) ends the recovery within half a second."""
    ev, set_at = threading.Event(), []

    def fire():
        set_at.append(time.monotonic())
        ev.set()

    def progress(s, *_):
        if s == stage and not set_at:
            threading.Timer(0.3, fire).start()
    with pytest.raises(dc.Cancelled) as err:
        recover(SAMPLE, {"units": "cm", "iterations": 2}, progress=progress, cancel=ev)
    ended = time.monotonic()
    assert set_at and ended - set_at[0] < 0.5, (ended - set_at[0], str(err.value))


def _sample_arrays():
    from diffavatar_core.scan import read_scan_file
    raw = read_scan_file(SAMPLE)
    return raw.vertices.copy(), raw.faces.copy(), raw.labels.copy()


def test_bad_inputs_give_clear_errors():
    V, F, L = _sample_arrays()
    with pytest.raises(NoGarmentError):                      # only body vertices
        recover((V, F, np.zeros_like(L)), {"units": "cm"})
    with pytest.raises(ScanError, match="label"):            # label array of the wrong length
        recover((V, F, L[:-5]), {"units": "cm"})
    Vn = V.copy()
    Vn[10] = np.nan
    with pytest.raises(NonFiniteError):
        recover((Vn, F, L), {"units": "cm"})
    with pytest.raises(ImplausibleSizeError, match="units"):  # a 1.7 m scan in m declared as cm
        recover((V / 100.0, F, L), {"units": "cm"})
    with pytest.raises(LabelError):
        recover((V, F, L), {"units": "cm", "garment_type": "cape"})


def _flat_sheet(n=13, half=0.3, y0=0.6):
    """A vertical 0.6 m square sheet (m): one boundary loop, no garment's openings."""
    u, v = np.meshgrid(np.linspace(-half, half, n), np.linspace(y0, y0 + 2 * half, n))
    V = np.column_stack([u.ravel(), v.ravel(), np.zeros(n * n)])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    return V, np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])


def test_a_garment_region_without_openings_is_refused_before_any_work():
    """A flat sheet given as a skirt has one boundary loop and neither a waist nor a hem: the
    boundary term would have nothing to match and the body fit nothing to wrap. Refused with
    NO_GARMENT, naming the missing openings, before the template is draped (it used to run 77 s
    and return a skirt 12 m below the body)."""
    V, F = _flat_sheet()
    stages = []
    with pytest.raises(RecoveryError, match="none of a 'skirt' garment's openings.*waist, hem") as err:
        recover((V, F), {"garment_type": "skirt", "units": "m", "iterations": 2},
                progress=lambda stage, *_: stages.append(stage))
    assert err.value.code == "NO_GARMENT" and "drape" not in stages, stages


def test_a_lying_scan_is_refused_with_the_up_axis_named():
    """The sample written Z-up but read as Y-up has a plausible size (0.52 m tall) but lies:
    none of the skirt's openings is horizontal where it should be, and the error says which up
    axis would make it stand."""
    V, F, L = _sample_arrays()
    with pytest.raises(RecoveryError, match=r"0\.524 m tall .* lying\? up=z would make it 1\.67 m tall") as err:
        recover((np.column_stack([V[:, 0], -V[:, 2], V[:, 1]]), F, L),
                RecoverOptions.from_config(units="cm", up="y", iterations=0))
    assert err.value.code == "NO_GARMENT"


def test_a_drape_off_the_body_is_refused(skirt_problem):
    """check_rests_on_body: the skirt's drape rests on the body (a vertex within the contact
    thickness); the same drape 30 cm below the feet — where a template laid out beside the body
    ends, held by the drape's anchors — is refused, with the distance in the message."""
    from diffavatar_core.pipeline.recovery import SUPPORT_GAP, check_rests_on_body
    model, p, g, cloth = skirt_problem[:4]
    bv, bf = model.pose(p), model.faces
    x = np.array(cloth.x)
    assert check_rests_on_body(x, bv, bf, "skirt") < 0.5 * SUPPORT_GAP
    fallen = x - np.array([0.0, x[:, 1].max() - bv[:, 1].min() + 0.3, 0.0])
    with pytest.raises(RecoveryError, match=r"does not rest on the fitted body: its nearest vertex is 3\d\.\d cm") as err:
        check_rests_on_body(fallen, bv, bf, "skirt")
    assert err.value.code == "SIMULATION_FAILED"


@pytest.fixture(scope="module")
def sample_at_rest():
    """The sample's recovery without optimizer steps (body fit, template drape, output drape; a
    dict's iterations 0 means the configured number, as in the node's messages)."""
    V, F, L = _sample_arrays()
    return recover((V, F, L), RecoverOptions.from_config(units="cm", iterations=0))


@pytest.mark.parametrize("yaw_deg,shift_cm", [(0.0, (40.0, 0.0, 25.0)), (90.0, (0.0, 0.0, 0.0)),
                                              (-150.0, (-30.0, 0.0, 10.0))])
def test_a_scan_turned_or_off_the_origin_recovers_as_the_scan_at_rest(sample_at_rest, yaw_deg, shift_cm):
    """A capture rig's subject need not stand at the origin facing +Z: the sample scan turned by
    yaw about the vertical and moved recovers the same skirt — openings named as at rest, the same
    pattern (area), the template's drape as far from the scan — and the outputs overlay the scan
    as given (the garment and body are the scan-at-rest ones moved the same way, within the fold
    states' spread). Before: the skirt's template was laid out at x = 0 beside a body fitted
    elsewhere, and a turned scan lost its waist opening (its rules take +X as the body's left)."""
    at = sample_at_rest
    V, F, L = _sample_arrays()
    Q = yaw_rotation(np.radians(yaw_deg))
    shift = np.array(shift_cm)
    moved = recover((V @ Q.T + shift, F, L), RecoverOptions.from_config(units="cm", iterations=0))
    assert moved.metrics["facing_yaw_rad"] == pytest.approx(np.radians(yaw_deg), abs=0.1)
    assert not any("openings not found" in w for w in moved.warnings), moved.warnings
    assert moved.garment.total_area() == pytest.approx(at.garment.total_area(), rel=1e-3)
    assert moved.metrics["chamfer_initial_cm"] == pytest.approx(at.metrics["chamfer_initial_cm"], rel=0.15)
    expect = lambda X: 100 * X @ Q.T + shift   # noqa: E731  (cm) the at-rest output moved with the scan
    np.testing.assert_allclose(100 * moved.garment_vertices.mean(axis=0), expect(at.garment_vertices).mean(axis=0),
                               atol=0.7)
    assert np.linalg.norm(100 * moved.body_vertices - expect(at.body_vertices), axis=1).mean() < 1.0
    np.testing.assert_allclose(100 * moved.scan_mesh[0], expect(at.scan_mesh[0]), atol=1e-6)   # the cleaned scan


def test_facing_turns_the_body_with_the_world():
    """turned_params: the body posed after the world turns by Q is the body posed, turned —
    for any global rotation and translation (LBS's global transform about the origin)."""
    from diffavatar_core.body import BodyModel
    model = BodyModel.default()
    p = model.zero_params()
    p.rotation[:] = [0.1, -2.2, 0.05]
    p.translation[:] = [0.3, -0.05, -0.4]
    Q = yaw_rotation(0.7)
    np.testing.assert_allclose(model.pose(turned_params(p, Q)), model.pose(p) @ Q.T, atol=1e-12)
    assert facing_yaw(turned_params(p, Q)) == pytest.approx(facing_yaw(p) + 0.7, abs=1e-12)
    assert facing_yaw(model.zero_params()) == 0.0


def test_units_and_up_axis_give_the_same_scan_frame():
    """The sample in mm with Z up preprocesses to the same core-frame scan as in cm with Y up."""
    from diffavatar_core.scan import load_scan
    V, F, L = _sample_arrays()
    a = load_scan((V, F, L), units="cm", up="y")
    core = V / 100.0
    # written out independently of the code under test: Z up means (x, y, z)_core = (x, z, −y)_scan
    mm_z = 1000.0 * np.column_stack([core[:, 0], -core[:, 2], core[:, 1]])
    b = load_scan((mm_z, F, L), units="mm", up="z")
    assert np.allclose(a.vertices, b.vertices, atol=1e-9)
    assert set(a.boundaries) == set(b.boundaries) == {"waist", "hem"}


def test_a_fresh_drape_does_not_depend_on_the_previous_state(skirt_problem):
    """CoOptObjective.fresh_drape_at drapes from the template's layout (sewn, not warm-started):
    the same parameters give the same equilibrium whatever the cloth held before."""
    model, p, g, cloth, pts, loops = skirt_problem
    obj = CoOptObjective(cloth, g, pts, loops, RecoverOptions.from_config(residual_tol=1e-8, samples=200),
                         cage=build_cage(g))
    theta = obj.initial_params()
    rest, bend, _ = obj.unpack(theta)
    obj.fresh_drape_at(rest, bend, None)
    x1 = np.array(cloth.x)
    obj(dict(theta, handles=theta["handles"] * 1.01))   # another equilibrium in the cloth's state
    assert np.abs(np.array(cloth.x) - x1).max() > 1e-4
    obj.fresh_drape_at(rest, bend, None)
    np.testing.assert_array_equal(np.array(cloth.x), x1)
    assert cloth.solver.residual(cloth.x, np.array([0, -9.81, 0.0])) <= 1e-8


def _at_a_larger_skirt(skirt_problem):
    """An objective whose warm start is the drape of the skirt 4% larger than the template, and those parameters."""
    model, p, g, cloth, pts, loops = skirt_problem
    obj = CoOptObjective(cloth, g, pts, loops, RecoverOptions.from_config(residual_tol=1e-8, samples=200),
                         cage=build_cage(g))
    theta = obj.initial_params()
    theta["handles"] = theta["handles"] * 1.04
    obj(theta)
    obj.commit()
    return obj, theta


def test_try_fresh_keeps_the_lower_loss_warm_start(skirt_problem):
    """try_fresh evaluates φ from the current warm start and from a fresh drape of the same
    parameters and keeps the lower as the next warm start: the next evaluation starts from it."""
    obj, theta = _at_a_larger_skirt(skirt_problem)
    x_before = np.array(obj.x_warm)
    used = obj.try_fresh(theta)
    v_warm, v_fresh = obj.last_fresh
    assert np.isfinite(v_warm) and used == (v_fresh < v_warm)
    # the kept start: the fresh equilibrium's evaluation, or the warm start as it was
    assert np.array_equal(obj.x_warm, obj.x_last if used else x_before)


def test_a_remembered_fresh_drape_is_the_one_made_again(skirt_problem):
    """try_fresh's fresh drape is remembered for try_bending's judging (_fresh_value): φ and drape are
    those a fresh drape made again gives, bit for bit (a fresh drape depends on the parameters alone),
    and asking again drapes nothing."""
    obj, theta = _at_a_larger_skirt(skirt_problem)
    obj.try_fresh(theta)
    v_fresh = obj.last_fresh[1]
    made = []
    real = obj.fresh_drape_at
    obj.fresh_drape_at = lambda *a, **k: made.append(1) or real(*a, **k)
    assert obj._fresh_value(theta) == v_fresh and made == []   # remembered
    x_remembered = np.array(obj.x_last)
    obj._fresh_seen.clear()
    assert obj._fresh_value(theta) == v_fresh and made == [1]   # made again: the same
    np.testing.assert_array_equal(obj.x_last, x_remembered)


def test_try_initial_redrapes_from_the_template_drape(skirt_problem):
    """try_initial evaluates φ from the current warm start and from a re-drape of the same
    parameters that starts at the template's initial drape, and keeps the lower: the candidate does
    not depend on where the warm starts have wandered (the same φ from five of them), and a warm
    start left in a worse state — a smaller skirt's drape, which the template's own parameters
    re-drape from into a state farther from the scan — is replaced by it. Which smaller skirt's
    drape is such a state moves with the last bits of the pattern (drapes are chaotic): until stop
    58 the 5% smaller one's was (1.2× the template drape's φ); since Newton's Gauss–Newton hinge
    blocks (stop 59) the 6%, 8% and 10% smaller ones' are (1.6×, 2.2×, 2.2×), and under
    `--roundoff-seed 2` the 8% one's is not — so three are tried and one must be. φ with σ = 1 (the
    interior term's weight this scenario was first measured with)."""
    model, p, g, cloth, pts, loops = skirt_problem
    x_init = np.array(cloth.x)
    o = RecoverOptions.from_config(residual_tol=1e-8, samples=200)
    o = o.with_(weights=Weights(**{**o.weights.__dict__, "interior": 1.0}))
    obj = CoOptObjective(cloth, g, pts, loops, o, cage=build_cage(g))
    theta0 = obj.initial_params()
    candidates, smaller = [], []
    for f in (1.04, 1.08, 0.94, 0.92, 0.90):
        cloth.reset(x_init)
        obj.x_warm = x_init.copy()
        obj(dict(theta0, handles=theta0["handles"] * f))
        obj.commit()   # the warm start: that skirt's drape
        x_before = np.array(obj.x_warm)
        assert np.abs(x_before - x_init).max() > 0.02
        used = obj.try_initial(theta0)
        v_warm, v_init = obj.last_initial
        assert np.isfinite(v_warm) and np.isfinite(v_init) and used == (v_init < v_warm)
        assert np.array_equal(obj.x_warm, obj.x_last if used else x_before)
        candidates.append(v_init)
        if f < 1:
            smaller.append((f, used, v_warm / v_init))
    assert len(set(candidates)) == 1
    # a smaller skirt's state is the worse one, by more than 20%, and it is replaced
    assert any(used and ratio > 1.2 for _, used, ratio in smaller), smaller


def test_body_after_holds_the_body_first(skirt_problem):
    """body_after N: the body's shape and pose stay at their scan fit for the first N iterations
    while the pattern moves; from then on they are co-optimized."""
    from diffavatar_core.pipeline.coopt import co_optimize
    model, p, g, cloth, pts, loops = skirt_problem
    x_keep, rest_keep = np.array(cloth.x), np.array(cloth.control.rest)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=200, iterations=2, fresh_every=0, bending="fixed")
    moved = []
    for body_after in (2, 1):
        cloth.set_control(rest=rest_keep, body_vertices=model.pose(p))
        cloth.reset(x_keep)
        res = co_optimize(cloth, g, pts, loops, opts.with_(body_after=body_after), cage=build_cage(g),
                          body_model=model, body_params=p)
        assert res.iterations == 2 and np.abs(res.rest - g.rest).max() > 1e-4
        moved.append(float(np.abs(res.body_params.shape - p.shape).max() + np.abs(res.body_params.pose - p.pose).max()))
    assert moved[0] == 0.0 and moved[1] > 0.0, moved


def test_a_stage_start_that_no_longer_drapes_ends_the_run_with_the_last_iterate(skirt_problem, monkeypatch):
    """If the re-drape at a stage's start fails (fault injected: every evaluation after the first
    fresh-drape check raises), co_optimize stops with 'invalid_start' and returns the last
    accepted iterate with its equilibrium — no exception, nothing already optimized lost. A
    configuration error (a zero step size) still raises."""
    from diffavatar_core.pipeline import coopt
    model, p, g, cloth, pts, loops = skirt_problem
    broken = {"on": False}
    call, try_fresh = coopt.CoOptObjective.__call__, coopt.CoOptObjective.try_fresh

    def failing_call(self, params):
        if broken["on"]:
            raise ValueError("drape did not converge: injected")
        return call(self, params)

    def breaking_try_fresh(self, params):
        used = try_fresh(self, params)
        broken["on"] = True
        return used
    monkeypatch.setattr(coopt.CoOptObjective, "__call__", failing_call)
    monkeypatch.setattr(coopt.CoOptObjective, "try_fresh", breaking_try_fresh)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=200, iterations=4, fresh_every=2, bending="fixed")
    res = coopt.co_optimize(cloth, g, pts, loops, opts, cage=build_cage(g))
    assert res.stopped == "invalid_start" and res.iterations == 2 and len(res.history) == 3
    assert res.stop_reason == "drape did not converge: injected"
    assert np.abs(res.rest - g.rest).max() > 1e-4
    assert cloth.solver.residual(cloth.x, np.array([0, -9.81, 0.0])) <= 1e-6
    # a configuration error is not a failed drape: it still raises
    from diffavatar_core.pipeline.options import StepSizes
    with pytest.raises(ValueError, match="step"):
        coopt.co_optimize(cloth, g, pts, loops, opts.with_(step_sizes=StepSizes(handles=0.0)), cage=build_cage(g))


def test_revert_undoes_every_commit_of_a_trial(skirt_problem):
    """With reevaluations N a line-search trial commits up to N + 1 warm starts; revert() undoes
    them one by one back to the warm start before the trial."""
    model, p, g, cloth, pts, loops = skirt_problem
    obj = CoOptObjective(cloth, g, pts, loops, RecoverOptions.from_config(samples=200, reevaluations=3),
                         cage=build_cage(g))
    x0 = np.array(obj.x_warm)
    for k in range(4):
        obj.x_last = x0 + 0.001 * (k + 1)
        obj.commit()
    assert np.allclose(obj.x_warm, x0 + 0.004)
    for k in (3, 2, 1, 0):
        obj.revert()
        assert np.allclose(obj.x_warm, x0 + 0.001 * k)


def test_the_current_iterate_follows_commit_and_revert(skirt_problem):
    """What a cancelled run returns (co_optimize): `current` is the (parameters, drape) of the last
    evaluation committed, or of the last mark_current; revert() undoes a commit's, as x_warm's."""
    model, p, g, cloth, pts, loops = skirt_problem
    obj = CoOptObjective(cloth, g, pts, loops, RecoverOptions.from_config(samples=200, reevaluations=3),
                         cage=build_cage(g))
    start = obj.initial_params()
    obj.mark_current(start)
    x0 = np.array(obj.x_warm)
    for k in range(4):
        trial = {**start, "handles": start["handles"] + 0.001 * (k + 1)}
        obj.x_last, obj.params_last = x0 + 0.001 * (k + 1), trial
        obj.commit()
        trial["handles"] += 1.0   # the caller's dict changing later does not change what was kept
    for k in (4, 3, 2, 1):
        params, x = obj.current
        np.testing.assert_array_equal(params["handles"], start["handles"] + 0.001 * k)
        np.testing.assert_array_equal(x, x0 + 0.001 * k)
        obj.revert()
    np.testing.assert_array_equal(obj.current[0]["handles"], start["handles"])
    np.testing.assert_array_equal(obj.current[1], x0)


def test_stretch_compliance_gradient_and_result(skirt_problem):
    """stretch: garment — dφ/dlog10 α of the shared [warp, weft, shear] compliances against
    central differences (the adjoint's dφ/dα chained through α ln10 and summed over the panels),
    and co_optimize returns the compliances its final drape was solved with (10^log_stretch)."""
    from diffavatar_core.pipeline.coopt import co_optimize
    model, p, g, cloth, pts, loops = skirt_problem
    x_keep, rest_keep = np.array(cloth.x), np.array(cloth.control.rest)
    c_keep = np.array(cloth.control.stretch_compliance)
    opts = RecoverOptions.from_config(residual_tol=1e-8, samples=500, bending="fixed", stretch="garment",
                                      optimize_body=False)
    obj = CoOptObjective(cloth, g, pts, loops, opts, cage=build_cage(g))
    theta = obj.initial_params()
    np.testing.assert_allclose(theta["log_stretch"], np.log10(ClothMaterial().compliance))
    theta["log_stretch"] = theta["log_stretch"] + np.array([0.3, -0.2, 0.1])

    def phi(t):
        obj.x_warm = x_keep
        return obj(t)
    _, grads, _ = phi(theta)
    an = grads["log_stretch"]
    assert an.shape == (3,)
    for k in range(3):
        tp = {kk: np.array(v, float) for kk, v in theta.items()}
        tm = {kk: np.array(v, float) for kk, v in theta.items()}
        # steps of 1e-5: from the state body_after's co_optimize left (before fixtures restored the
        # cloth) a contact switched within ±1e-4 of log10 α_warp, the central difference 1.2% off
        # at 1e-4 and 1e-9 off at 3e-5 and below
        tp["log_stretch"][k] += 1e-5
        tm["log_stretch"][k] -= 1e-5
        fd = (phi(tp)[0] - phi(tm)[0]) / 2e-5
        assert abs(an[k] - fd) <= 1e-4 * max(np.abs(an).max(), 1e-12), (k, an[k], fd)
    np.testing.assert_allclose(np.array(cloth.control.stretch_compliance), 10.0 ** np.broadcast_to(
        tm["log_stretch"], c_keep.shape), rtol=1e-12)   # the last evaluation's
    cloth.set_control(rest=rest_keep, stretch_compliance=c_keep)
    cloth.reset(x_keep)
    res = co_optimize(cloth, g, pts, loops, opts.with_(iterations=2, fresh_every=0, guided_stiffness=0.0,
                                                       measurement_fit_iterations=0), cage=build_cage(g))
    assert res.stretch_compliance.shape == c_keep.shape
    np.testing.assert_allclose(res.stretch_compliance, np.array(cloth.control.stretch_compliance))
    with pytest.raises(ValueError, match="stretch"):
        RecoverOptions.from_config(stretch="panel")


def test_upper_garment_template_follows_the_sleeve_length():
    """An upper garment without a named type gets the t-shirt, or the long-sleeved top when its
    sleeve openings reach past 0.95 of the shoulder → wrist segment (sleeve_reach: projected
    opening centroids; a named type always wins)."""
    from types import SimpleNamespace
    from diffavatar_core.pattern.templates import default_landmarks
    from diffavatar_core.pipeline.recovery import select_template, sleeve_reach
    lm = default_landmarks()
    opts = RecoverOptions.from_config()
    ring = 0.03 * np.array([[np.cos(a), 0.0, np.sin(a)] for a in np.linspace(0, 2 * np.pi, 12, endpoint=False)])

    def scan(reach, garment_type=None):
        loops = {f"sleeve_{side}": s + reach * (w - s) + ring
                 for side, s, w in (("left", lm.shoulder_left, lm.wrist_left), ("right", lm.shoulder_right, lm.wrist_right))}
        return SimpleNamespace(garment_type=garment_type, garment_class="upper", boundaries={"hem": ring, **loops})
    assert abs(sleeve_reach(scan(0.65).boundaries, lm) - 0.65) < 1e-12
    assert select_template(scan(0.65), opts, lm) == "tshirt"
    assert select_template(scan(1.3), opts, lm) == "longsleeve"
    assert select_template(scan(1.3), opts) == "tshirt"                       # no landmarks: the class default
    assert select_template(scan(1.3, garment_type="tshirt"), opts, lm) == "tshirt"
    assert sleeve_reach({"hem": ring}, lm) is None
