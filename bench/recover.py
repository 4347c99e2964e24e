"""Benchmark of the recovery pipeline (issue 7) on synthetic scans with ground truth, with the
paper's Table 2 ablations on the same cases. Prints JSON (per case and averaged); not a test.

Each case (pipeline/synthetic.py): a built-in template with measurements perturbed by ±5–15%,
a bending stiffness log-uniform in [1e-6, 1e-4] N·m (two orders of magnitude), a body with
random shape → sew + drape → scan-like mesh (subdivided, 2 mm noise, holes, floating
fragments, cm). Recovery starts from the unperturbed template and the default material.
Variants: full; no_cage (every pattern vertex optimized); no_seam (α = 0); no_curvature (β = 0);
euclidean (L-BFGS without the H¹ metric on the pattern, sobolev_length 0: a reference run);
no_cage_euclidean (every pattern vertex optimized with the plain L-BFGS metric: the paper's "w/o control
cage", whose vertices have no smoothing of their own; no_cage keeps the H¹ metric, which smooths them);
--paper-optimizer: every variant optimized as the paper does, with the plain L-BFGS metric and no measurement
fit (the fit moves the outline through the cage, in no_cage too) — Table 2 on the paper's own optimizer;
unguided (no scan-guided drapes, guided_stiffness 0: a reference run); no_measurement_fit (the
handles start on the template's outline, measurement_fit_iterations 0: a reference run);
fixed_masses (the template's masses throughout); stretch (the stretch compliances optimized too,
`stretch: garment`; truths with other compliances by --compliance-scales); robust_boundary (the
boundary term robust beyond 1 cm, boundary_scale 0.01 m); unsized (no template sizing from the scan's openings,
template_sizing false: a reference run); interior_K (σ, the interior Chamfer's weight, = K per m²: interior_1
is the default before stop 41); to_surface / to_points (L_interior's garment samples measured to the scan's
garment surface / to the nearest of its interior samples, `interior_to`); guided_K (the scan-guided drapes'
spring stiffness κ_g = K per s², e.g. guided_1e5); bendtry_D (bending candidates: the bending × 10^d tried at
every check, `bending_candidates`; offsets in decades joined by +, m for minus, e.g. bendtry_1+m1; @M sets
`bending_margin`, e.g. bendtry_1+m1@0); outdrag_K (with --output-edge: the fine output's drape with a velocity
drag of K per s, `output_drape_damping`, e.g. outdrag_4, the simulator's own; the truths keep the default's);
fitbend_D (the bending searched after the measurement fit, which then runs again from its result,
`measurement_fit_bending`: steps in decades joined by +, e.g. fitbend_1+0.5+0.25, the default; fitbend_none:
no search, one fit under the default bending); bendcompare_M (the drapes bending candidates are judged on,
`bending_compare`: bendcompare_unguided, the warm re-drape and a fresh drape for the current bending and the
candidates alike; bendcompare_asymmetric, softer candidates so, stiffer ones on their guided drapes too — stop
49, neither the default; bendcompare_fresh, the current bending and the candidates alike on their fresh drapes
alone; @K: the lowest of K fresh drapes instead of one, `bending_fresh_drapes`, e.g. bendcompare_fresh@3 —
stop 51); fitrefit@K (the search after the measurement fit with each candidate's measurements fitted again at its
bending and judged on the lowest of K fresh drapes, `measurement_fit_refit` — stop 51; fitrefit_M@K: and the
checks' bending candidates judged as bendcompare_M, e.g. fitrefit_fresh@3; fitrefit_none@K: no candidates at the
checks, `bending_candidates: []`); workers_N (the bending candidates of a check draped N at once, `candidate_workers`; the
default 0 is one per CPU: workers_1, one after the other, is the reference of its times — the results are the same
bit for bit); bendrange_D (the recovered bending's range judged at ±d for each d, `bending_range_offsets`: decades
joined by +, e.g. bendrange_0.15+0.5+1, the default; bendrange_none: not judged, the reference of its cost — the
results are the same bit for bit); newton_supernodal / newton_simplicial (Newton's LDLᵀ, `newton_solver`: the
supernodal one or Eigen's, the default — the same solutions up to round-off, so the drapes may find other folds);
hinges_clamp / hinges_gauss_newton (a hinge's block of Newton's projected Hessian, `newton_hinge_blocks`: clamped
to its non-negative eigenvalues, the default before stop 59, or its Gauss–Newton part, the default — the same
equilibria, other paths to them, so other folds);
edge_L (the optimization's mesh at an edge of L cm, `edge_length`, e.g. edge_2; the default 4 — the truths keep theirs).

The floor: each case's truth.chamfer_truth_cm is the truth's own drape against the scan (the scan's
noise, resampling and holes; SyntheticCase.truth_chamfer_cm), so each variant's chamfer_ratio_floor
(that over chamfer_initial_cm) is the lowest Chamfer ratio any recovery can reach on the case, and
chamfer_gap_closed = (initial − final) / (initial − truth) the part of the reachable distance removed.

A case whose recovery fails (RecoveryError: e.g. the initial drape did not converge) is reported with
its message under the variant and counted in "failed"; the means are over the others.

With --output-edge the result is carried to a finer output mesh; --truth-edge settles the ground
truth on a mesh that fine too (a 1 cm cloth does not fold as a 4 cm one: the truth of a 10k output).

Run: `.venv/bin/python bench/recover.py [--cases N] [--iterations N] [--variants full,no_cage]
[--output-edge 0.008] [--truth-edge 0.01] [--first-case K] [--last-case K] [--paper-optimizer] [--roundoff-seed N]`.
--roundoff-seed N perturbs every template pattern by 1e-13 m of seeded noise: runs with a few seeds
give the spread another CPU's round-off could give (the drapes are chaotic).
"""
import argparse
import json
import math
import os
import pathlib
import platform
import sys
import time

import numpy as np

import diffavatar_core as dc
from diffavatar_core.pattern.cage import cage_handles
from diffavatar_core.pipeline import RecoverOptions, RecoveryError, recover
from diffavatar_core.pipeline.options import StepSizes, Weights
from diffavatar_core.pipeline.synthetic import make_case, truth_material

VARIANTS = ("full", "no_cage", "no_seam", "no_curvature")
# not ablations of the paper (but no_cage_euclidean, its "w/o control cage" without our H¹ metric): the reference
# runs of the L-BFGS metric before the H¹ one, of the recovery without
# scan-guided drapes, without the template measurement fit, with the template's masses throughout, with the stretch
# compliances optimized, with a 10× larger L-BFGS unit for the bending (1 decade), with the robust boundary term, without the template sizing,
# and with another weight σ of the interior term
EXTRA_VARIANTS = ("euclidean", "no_cage_euclidean", "unguided", "no_measurement_fit", "fixed_masses", "stretch", "bending_step_1",
                  "robust_boundary", "unsized", "interior_K", "to_surface", "to_points",
                  "guided_K", "bendtry_D", "outdrag_K", "fitbend_D", "bendcompare_M@K", "fitrefit_M@K", "workers_N", "bendrange_D", "edge_L",
                  "newton_supernodal", "newton_simplicial", "hinges_clamp", "hinges_gauss_newton")   # interior_K: σ = K per m², e.g. interior_1; guided_K: κ_g = K per s² (K+L+…: each in turn)


def corner_edge_lengths(g, corners_from=None) -> list:
    """Per panel: lengths (m) of the boundary between consecutive corners (the pattern's edges).
    Corners (turns > 30°) are found on corners_from's rest (same mesh as g, e.g. the template g
    was deformed from) when given, else on g's own rest."""
    out = []
    for p in g.panels:
        P = g.rest[p.loop]
        c = cage_handles((corners_from if corners_from is not None else g).rest[p.loop], 30.0)
        seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
        cum = np.concatenate([[0], np.cumsum(seg)])
        L = [cum[c[(k + 1) % len(c)]] - cum[c[k]] if k + 1 < len(c) else cum[-1] - cum[c[k]] + cum[c[0]]
             for k in range(len(c))]
        out.append(np.asarray(L))
    return out


def pattern_edge_error_cm(rec, gt, template=None) -> float:
    """Mean |edge length − truth's| (cm) over the pattern's corner-to-corner edges. The
    recovered pattern's corners are the template's (its mesh is the template's deformed), so a
    corner rounded off by the optimizer is still measured; NaN when the corner counts differ."""
    same_mesh = template is not None and len(template.rest) == len(rec.rest) and len(template.panels) == len(rec.panels)
    a, b = corner_edge_lengths(rec, template if same_mesh else None), corner_edge_lengths(gt)
    if len(a) != len(b) or any(len(x) != len(y) for x, y in zip(a, b)):
        return float("nan")
    return 100 * float(np.mean(np.abs(np.concatenate(a) - np.concatenate(b))))


def stretch_log10_error(material, case) -> float:
    """Mean |Δlog10| of the warp, weft and shear compliances against the case's truth's."""
    t = truth_material(case.bend_stiffness, case.compliance_scale)
    pairs = ((material.compliance_warp, t.warp_compliance), (material.compliance_weft, t.weft_compliance),
             (material.compliance_shear, t.shear_compliance))
    return float(np.mean([abs(math.log10(r / w)) for r, w in pairs]))


def _fresh_drapes_suffix(variant, o):
    """(the variant without its @K suffix, K): fresh drapes per bending (bending_fresh_drapes), o's without @K."""
    spec, _, k = variant.partition("@")
    try:
        return spec, int(k) if k else o.bending_fresh_drapes
    except ValueError:
        raise ValueError(f"variant {variant!r}: @K needs a whole number K of fresh drapes, e.g. {spec}@3") from None


def _decades_variant(variant: str, prefix: str, what: str, example: str) -> list:
    """The decades of a variant PREFIX + 'D+D+…' (or PREFIX + 'none': []); ValueError naming the form."""
    spec = variant[len(prefix):]
    try:
        return [] if spec == "none" else [float(d) for d in spec.split("+")]
    except ValueError:
        raise ValueError(f"variant {variant!r}: {prefix}D needs {what} in decades joined by +, e.g. "
                         f"{prefix}{example}, or {prefix}none") from None


def options_for(variant, iterations, output_edge=0.0, friction=None, contact_normals=None, paper_optimizer=False):
    o = RecoverOptions.from_config(units="cm", iterations=iterations, output_edge_length=output_edge)
    if paper_optimizer:   # the paper's optimizer: no H¹ metric, no measurement fit (before the variant's change)
        o = o.with_(sobolev_length=0.0, measurement_fit_iterations=0)
    if friction is not None:
        o = o.with_(output_friction=friction)
    if contact_normals is not None:
        o = o.with_(contact_normals=contact_normals)
    if variant == "no_cage":
        return o.with_(parametrization="vertices")
    if variant == "no_seam":
        return o.with_(weights=Weights(**{**o.weights.__dict__, "seam": 0.0}))
    if variant == "no_curvature":
        return o.with_(weights=Weights(**{**o.weights.__dict__, "curvature": 0.0}))
    if variant == "euclidean":
        return o.with_(sobolev_length=0.0)
    if variant == "no_cage_euclidean":
        return o.with_(parametrization="vertices", sobolev_length=0.0)
    if variant == "unguided":
        return o.with_(guided_stiffness=0.0)
    if variant == "no_measurement_fit":
        return o.with_(measurement_fit_iterations=0)
    if variant == "unsized":
        return o.with_(template_sizing=False)
    if variant == "fixed_masses":
        return o.with_(masses_follow_rest=False)
    if variant == "stretch":
        return o.with_(stretch="garment")
    if variant == "robust_boundary":   # an opening hung elsewhere (a cuff over the hand) pulls less beyond 1 cm
        return o.with_(boundary_scale=0.01)
    if variant.startswith("interior_"):   # σ, the interior Chamfer's weight (per m²), set to the number
        try:
            sigma = float(variant[len("interior_"):])
        except ValueError:
            raise ValueError(f"variant {variant!r}: interior_K needs a number K (σ per m²), e.g. interior_1") from None
        return o.with_(weights=Weights(**{**o.weights.__dict__, "interior": sigma}))
    if variant.startswith("guided_"):   # the scan-guided drapes' spring stiffness (1/s²), set to the number
        try:
            kappa = [float(k) for k in variant[len("guided_"):].split("+")]
        except ValueError:
            raise ValueError(f"variant {variant!r}: guided_K needs a number K (1/s²), e.g. guided_1e5, "
                             "or numbers joined by +, e.g. guided_1e4+1e6") from None
        return o.with_(guided_stiffness=kappa)
    if variant.startswith("bendtry_"):   # bending candidates at every check: offsets in decades, e.g. bendtry_1+m1 (m: minus)
        spec, _, margin = variant[len("bendtry_"):].partition("@")
        try:
            offsets = [float(d) for d in spec.replace("m", "-").split("+")]
            margin = float(margin) if margin else o.bending_margin
        except ValueError:
            raise ValueError(f"variant {variant!r}: bendtry_D needs offsets in decades joined by +, "
                             "e.g. bendtry_1+m1 (m: minus), optionally @margin, e.g. bendtry_1+m1@0") from None
        return o.with_(bending_candidates=offsets, bending_margin=margin)
    if variant.startswith("fitbend_"):   # the bending search after the measurement fit: steps in decades, e.g. fitbend_1+0.5
        return o.with_(measurement_fit_bending=_decades_variant(variant, "fitbend_", "steps", "1+0.5+0.25"))
    if variant == "fitrefit" or variant.startswith(("fitrefit@", "fitrefit_")):   # the search's candidates re-fitted
        spec, k = _fresh_drapes_suffix(variant, o)   # fitrefit_M: the checks' candidates judged as bendcompare_M; _none: none
        o = o.with_(measurement_fit_refit=True, bending_fresh_drapes=k)
        checks = spec[len("fitrefit_"):]
        if checks == "none":
            return o.with_(bending_candidates=[])
        return o.with_(bending_compare=checks) if checks else o
    if variant.startswith("bendcompare_"):   # the drapes a bending candidate is judged on: guided | unguided | asymmetric | fresh
        spec, k = _fresh_drapes_suffix(variant, o)
        return o.with_(bending_compare=spec[len("bendcompare_"):], bending_fresh_drapes=k)
    if variant.startswith("bendrange_"):   # the recovered bending's range: ± offsets in decades, or none
        return o.with_(bending_range_offsets=_decades_variant(variant, "bendrange_", "offsets", "0.15+0.5+1"))
    if variant in ("newton_supernodal", "newton_simplicial"):   # Newton's LDLᵀ
        return o.with_(newton_solver=variant[len("newton_"):])
    if variant in ("hinges_clamp", "hinges_gauss_newton"):   # a hinge's block of Newton's projected Hessian
        return o.with_(newton_hinge_blocks=variant[len("hinges_"):])
    if variant.startswith("edge_"):   # the optimization's mesh: edge length in cm, e.g. edge_2 (the default 4)
        try:
            edge = float(variant[len("edge_"):]) / 100.0
        except ValueError:
            raise ValueError(f"variant {variant!r}: edge_L needs a length L in cm, e.g. edge_2") from None
        return o.with_(edge_length=edge)
    if variant.startswith("workers_"):   # bending candidates draped at once (candidate_workers): the same results, other times
        try:
            return o.with_(candidate_workers=int(variant[len("workers_"):]))
        except ValueError:
            raise ValueError(f"variant {variant!r}: workers_N needs a whole number N >= 0, e.g. workers_1") from None
    if variant.startswith("outdrag_"):   # the fine output drape's velocity drag (1/s), set to the number
        try:
            drag = float(variant[len("outdrag_"):])
        except ValueError:
            raise ValueError(f"variant {variant!r}: outdrag_K needs a number K (1/s), e.g. outdrag_4") from None
        return o.with_(output_drape_damping=drag)
    if variant in ("to_surface", "to_points"):   # garment samples measured to the scan's surface / nearest scan point
        return o.with_(interior_to=variant[3:])
    if variant == "bending_step_1":   # L-BFGS's unit of log10 bending: 1 decade instead of 0.1
        return o.with_(step_sizes=StepSizes(**{**o.step_sizes.__dict__, "log10_bending": 1.0}))
    if variant != "full":
        raise ValueError(f"unknown variant {variant!r}: one of {VARIANTS + EXTRA_VARIANTS}")
    return o


def bending_range_fields(bounds, truth: float) -> dict:
    """The recovered bending's range (result.json material.bending_stiffness_range_Nm, N·m; None: open
    on that side) against the truth: whether it holds the truth, and its width in decades (None when
    open or not judged)."""
    lo, hi = bounds
    inside = (lo is None or lo < truth) and (hi is None or truth < hi)
    width = math.log10(hi / lo) if lo is not None and hi is not None else None
    return {"bending_range_n_m": [lo, hi], "bending_in_range": bool(inside), "bending_range_decades": width}


def run_case(case, variant, iterations, output_edge=0.0, friction=None, contact_normals=None, paper_optimizer=False,
             truth_cm=float("nan")):
    """One recovery of `case`; truth_cm: the truth's own drape's Chamfer to the scan (the case's floor)."""
    t0, c0 = time.perf_counter(), time.process_time()
    r = recover((case.scan_vertices, case.scan_faces, case.scan_labels),
                options_for(variant, iterations, output_edge, friction, contact_normals, paper_optimizer))
    m = r.metrics
    area_gt = case.garment.total_area()
    return {
        "chamfer_initial_cm": m["chamfer_initial_cm"], "chamfer_final_cm": m["chamfer_final_cm"],
        "chamfer_ratio": m["chamfer_final_cm"] / m["chamfer_initial_cm"],
        # the lowest ratio any recovery can reach: the truth's own drape, fold for fold (scan noise only)
        "chamfer_ratio_floor": truth_cm / m["chamfer_initial_cm"],
        # the part of the template's distance beyond that floor the recovery removed (1 = the truth's drape)
        "chamfer_gap_closed": (m["chamfer_initial_cm"] - m["chamfer_final_cm"]) / (m["chamfer_initial_cm"] - truth_cm),
        # a fine output (--output-edge): the optimized coarse drape's Chamfer ratio it came from
        "chamfer_ratio_optimized": m.get("chamfer_optimized_cm", m["chamfer_final_cm"]) / m["chamfer_initial_cm"],
        "pattern_area_error_pct": 100 * abs(r.garment.total_area() - area_gt) / area_gt,
        "template_area_error_pct": 100 * abs(m["template_area_m2"] - area_gt) / area_gt,
        "pattern_edge_error_cm": pattern_edge_error_cm(r.garment, case.garment, getattr(r, "template", None)),
        "bending_log10_error": abs(math.log10(r.material.bending_stiffness) - math.log10(case.bend_stiffness)),
        "bending_n_m": r.material.bending_stiffness, "bending_truth_n_m": case.bend_stiffness,
        **bending_range_fields(r.material.bending_stiffness_range, case.bend_stiffness),
        "stretch_log10_error": stretch_log10_error(r.material, case),
        "body_vertex_error_cm": 100 * float(np.linalg.norm(r.body_vertices - case.body_vertices, axis=1).mean()),
        "mesh_quality_min": m["mesh_quality_min"], "seam_length_mismatch_max_pct": m["seam_length_mismatch_max_pct"],
        "garment_vertices": int(len(r.garment_vertices)), "optimized_vertices": m.get("optimized_vertices"),
        "wall_s": time.perf_counter() - t0,
        "cpu_s": time.process_time() - c0,   # all threads of this process: comparable under load
        "warnings": [w for w in r.warnings if "fragment" not in w],
        "iterations": r.iterations, "stopped": m["stopped"],
        "fresh_drapes_kept": m.get("fresh_drapes_kept"), "guided_drapes_kept": m.get("guided_drapes_kept"),
        "initial_drapes_kept": m.get("initial_drapes_kept"),
        "bending_candidates_kept": m.get("bending_candidates_kept"),
        "output_drape": m.get("output_drape"),
        "measurement_fit": m.get("measurement_fit"),
        "measurement_fit_bending": m.get("measurement_fit_bending"),
        # the range's judged offsets [d decades, k_b N·m, φ judged, φ against, verdict] and φ at the recovered k_b:
        # what another point estimate within the range (its centre, a fit of φ over log k_b) would be computed from
        "bending_range_judged": (m.get("bending_range") or {}).get("judged"),
        "bending_range_value": (m.get("bending_range") or {}).get("value"),
        "template_sizing": m.get("template_sizing"),
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", type=int, default=4)
    ap.add_argument("--iterations", type=int, default=30)
    ap.add_argument("--templates", default="skirt", help="comma-separated (skirt, tshirt, longsleeve, dress)")
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--output-edge", type=float, default=0.0,
                    help="m; > 0: the result carried to a finer output mesh (coarse-to-fine; e.g. 0.008 ≈ 10k vertices)")
    ap.add_argument("--first-case", type=int, default=0, help="index of the first case (to split runs)")
    ap.add_argument("--last-case", type=int, default=None, help="index after the last case (default --cases)")
    ap.add_argument("--compliance-scales", default="1",
                    help="comma-separated; case k's truth has the default stretch compliances × scales[k %% len] "
                         "(for the `stretch` variant, which optimizes them)")
    ap.add_argument("--truth-edge", type=float, default=0.0,
                    help="m; > 0: the ground truth is settled on a mesh of this edge (e.g. 0.01, as the output) "
                         "instead of the 0.04 m the optimization runs on (synthetic.make_case truth_edge)")
    ap.add_argument("--friction", type=float, default=None,
                    help="Coulomb μ of the fine drapes (the fine truth's settle and the output's); "
                         "default: the config's output_friction")
    ap.add_argument("--contact-normals", choices=("face", "smooth", "valley"), default=None,
                    help="the contact plane of the truths and the recovery (sim/contact_kernel.hpp); "
                         "default: the config's contact_normals")
    ap.add_argument("--paper-optimizer", action="store_true",
                    help="every variant with the paper's optimizer: plain L-BFGS metric (sobolev_length 0) and no "
                         "measurement fit (Table 2 as the paper ran it)")
    ap.add_argument("--roundoff-seed", type=int, default=None,
                    help="every template pattern (truths' and recoveries') perturbed by 1e-13 m of seeded noise "
                         "(test/roundoff.py): the run another CPU's round-off could give — the benchmark's noise")
    args = ap.parse_args()
    if args.roundoff_seed is not None:
        sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "test"))
        import roundoff
        roundoff.install(args.roundoff_seed)
    templates = args.templates.split(",")
    variants = args.variants.split(",")
    scales = [float(v) for v in args.compliance_scales.split(",")]
    out = {"benchmark": "recover", "threads": dc.num_threads(), "cpus": os.cpu_count(),
           "machine": platform.machine(), "iterations": args.iterations, "output_edge_m": args.output_edge,
           "truth_edge_m": args.truth_edge or None,
           "friction": RecoverOptions.from_config().output_friction if args.friction is None else args.friction,
           "contact_normals": args.contact_normals or RecoverOptions.from_config().contact_normals,
           "optimizer": RecoverOptions.from_config().optimizer, "paper_optimizer": args.paper_optimizer,
           "roundoff_seed": args.roundoff_seed, "cases": []}
    per_variant = {v: [] for v in variants}
    failed = {v: 0 for v in variants}   # cases whose recovery raised RecoveryError (not in the means)
    for k in range(args.first_case, args.cases if args.last_case is None else min(args.last_case, args.cases)):
        tpl = templates[k % len(templates)]
        # bending spread over two decades across the cases
        bend = 10 ** (-6 + 2 * k / max(args.cases - 1, 1))
        scale = scales[k % len(scales)]
        try:
            case = make_case(tpl, seed=100 + k, bend_stiffness=bend, truth_edge=args.truth_edge or None,
                             compliance_scale=scale, friction=args.friction, contact_normals=args.contact_normals)
        except RuntimeError as exc:   # a truth that slid off or did not converge: no case, said so
            skipped = {"template": tpl, "seed": 100 + k, "skipped": str(exc), "compliance_scale": scale}
            out.setdefault("skipped", []).append(skipped)
            print(json.dumps(skipped), flush=True)
            continue
        truth_cm = case.truth_chamfer_cm(options_for("full", args.iterations, contact_normals=args.contact_normals))
        entry = {"template": tpl, "seed": 100 + k, "truth": {"measurements_m": case.measurements,
                                                             "bend_stiffness_Nm": bend, "compliance_scale": scale,
                                                             "chamfer_truth_cm": truth_cm}}
        for v in variants:
            try:
                entry[v] = run_case(case, v, args.iterations, args.output_edge, args.friction, args.contact_normals,
                                    args.paper_optimizer, truth_cm)
            except RecoveryError as exc:   # the pipeline failed on this case: a result to count, not the run's end
                entry[v] = {"failed": str(exc)}
                failed[v] += 1
                continue
            per_variant[v].append(entry[v])
        out["cases"].append(entry)
        print(json.dumps(entry), flush=True)
    keys = ("chamfer_ratio", "chamfer_ratio_floor", "chamfer_gap_closed", "chamfer_ratio_optimized", "chamfer_final_cm", "pattern_area_error_pct", "pattern_edge_error_cm",
            "bending_log10_error", "stretch_log10_error", "body_vertex_error_cm", "mesh_quality_min", "wall_s", "cpu_s", "iterations",
            "garment_vertices")
    out["mean"] = {v: {k: float(np.nanmean([r[k] for r in rs])) if rs else float("nan") for k in keys}
                   for v, rs in per_variant.items()}
    for v, rs in per_variant.items():   # the bending's range: how often it holds the truth, how wide when closed
        widths = [r["bending_range_decades"] for r in rs if r["bending_range_decades"] is not None]
        out["mean"][v].update(bending_in_range=sum(r["bending_in_range"] for r in rs), cases=len(rs),
                              bending_range_closed=len(widths),
                              bending_range_decades=float(np.mean(widths)) if widths else float("nan"))
    out["failed"] = failed
    out["targets"] = {"chamfer_ratio": "<= 0.35", "pattern_area_error_pct": "<= 3", "bending_log10_error": "<= 0.15",
                      "body_vertex_error_cm": "<= 1.5", "wall_s": "<= 300 for a ~10k-vertex garment"}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
