"""Synthetic ground-truth cases (pipeline/synthetic.py), the benchmark's and the tests' scans:
what each option of make_case changes in the truth."""
import dataclasses
import json

import numpy as np
import pytest

from diffavatar_core.body import BodyModel
from diffavatar_core.metrics import chamfer_meshes
from diffavatar_core.body.params import BodyParams
from diffavatar_core.pattern.templates import make_template
from diffavatar_core.pipeline.synthetic import GARMENT_LABEL, drape_truth, make_case, scan_like, to_scan_frame
from diffavatar_core.scan.frame import ScanTransform
from edge_strain import mean_edge_strain


def test_a_fine_ground_truth_is_the_same_garment_settled_on_a_finer_mesh():
    """make_case(truth_edge=...): the same measurements, bending and body as the coarse truth of
    the same seed, on a mesh of truth_edge settled on the body; the scan is made from that drape
    (its garment surface within the scan's noise of it)."""
    model = BodyModel.default()
    coarse = make_case("skirt", seed=3, edge=0.07, model=model)
    fine = make_case("skirt", seed=3, edge=0.07, truth_edge=0.035, model=model)
    assert fine.measurements == coarse.measurements and fine.bend_stiffness == coarse.bend_stiffness
    np.testing.assert_array_equal(fine.body_params.shape, coarse.body_params.shape)
    assert len(fine.garment.rest) > 2.5 * len(coarse.garment.rest)
    assert fine.garment.total_area() == pytest.approx(coarse.garment.total_area(), rel=0.02)
    assert fine.drape["edge_m"] == 0.035 and fine.drape["settle"]["settled"]
    V, F = fine.garment_scan()
    V = ScanTransform.from_options(fine.units, fine.up).to_core(V)
    d_fine = chamfer_meshes(fine.garment_x, fine.garment.faces, V, F)
    assert d_fine < 0.0025, d_fine   # 2 mm normal noise, holes, fragments: 1.4 mm (the coarse truth: 6.1 mm)



def test_a_softer_ground_truth_hangs_lower():
    """compliance_scale scales the truth's three stretch compliances: the same skirt under the
    same weight stretches further (mean edge strain of the drape against its pattern) and hangs
    lower (mean height, m) the softer it is. Measured over the unperturbed drape and 8 whose
    patterns differ by 1e-13 m of round-off (stop 33): strain 0.25% / 0.28-0.48% / 0.61%, heights
    0.890 / 0.862-0.887 / 0.848 m — the default skirt lands in another state under one
    perturbation (2.4 cm higher, less stretched), so the margins are those of that state."""
    model = BodyModel.default()
    cases = [make_case("skirt", seed=3, edge=0.07, model=model, compliance_scale=s) for s in (0.5, 1.0, 3.0)]
    heights = [float(c.garment_x[:, 1].mean()) for c in cases]
    strains = [mean_edge_strain(c.garment_x, c.garment.rest, c.garment.faces) for c in cases]
    assert strains[1] > 1.05 * strains[0] and strains[2] > 1.05 * strains[1], strains
    assert heights[0] > heights[1] + 0.001 and heights[1] > heights[2] + 0.005, heights
    assert [c.truth_json()["compliance_scale"] for c in cases] == [0.5, 1.0, 3.0]


def test_the_truth_floor_is_the_scans_noise():
    """SyntheticCase.truth_chamfer_cm — the truth's own drape against its scan, the lowest Chamfer
    distance a recovery can reach — is what the scan's making adds: scans of one drape, welded and
    midpoint-subdivided (the same surface) with normal noise σ = 0, 2, 4 mm and floating fragments
    (dropped by the recovery's cleaning), no holes. Noise-free the floor is nil; with noise it
    grows as σ, at a fraction of σ set by the geometry of a displaced surface: a scan point lies
    |n| off the truth (mean σ√(2/π) ≈ 0.80σ), a truth point nearer the noisy surface than that."""
    case = make_case("skirt", seed=3, edge=0.07)
    floors = []
    for sigma in (0.0, 0.002, 0.004):
        V, F, L = scan_like(case.garment_x, case.garment.faces, case.body_vertices, case.body_faces,
                            GARMENT_LABEL["skirt"], np.random.default_rng(7), noise=sigma, holes=0,
                            fragments=3, seams=case.garment.seams)
        noisy = dataclasses.replace(case, scan_vertices=to_scan_frame(V, case.units, case.up), scan_faces=F,
                                    scan_labels=L)
        floors.append(noisy.truth_chamfer_cm())
    s0, s2, s4 = floors
    assert s0 < 0.002, floors                        # cm: the same surface (fragments dropped, seams welded)
    assert 0.3 * 0.2 < s2 < 0.8 * 0.2, floors        # σ = 0.2 cm
    assert 1.8 < s4 / s2 < 2.2, floors               # linear in σ
    assert case.truth_chamfer_cm() > s2 - 0.02, (case.truth_chamfer_cm(), floors)   # + holes: no lower


def test_the_truth_is_remade_from_its_truth_json():
    """truth.json (SyntheticCase.truth_json, through JSON text) holds all the truth is made of:
    the template re-made with its measurements on its body and draped as make_case drapes
    (drape_truth) lands on the case's own drape vertex for vertex. What bench/recover_floor.py's
    re-triangulations rely on: at edge × 1 they re-drape the truth itself, at edge × (1 ± 2.5%)
    only the mesh differs."""
    model = BodyModel.default()
    case = make_case("skirt", seed=3, edge=0.07, model=model)
    t = json.loads(json.dumps(case.truth_json()))
    b = t["body"]
    params = BodyParams(np.array(b["shape"]), np.array(b["pose"]), np.array(b["bone_scales"]),
                        np.array(b["rotation"]), np.array(b["translation"]))
    g = make_template(t["template"], landmarks=model.landmarks(params), edge_length=0.07, **t["measurements_m"])
    cloth, _ = drape_truth(g, (model.pose(params), np.asarray(model.faces)), t["bend_stiffness_Nm"],
                           compliance_scale=t["compliance_scale"])
    np.testing.assert_array_equal(g.faces, case.garment.faces)
    np.testing.assert_allclose(np.asarray(cloth.x), case.garment_x, rtol=0, atol=1e-9)


def test_bad_truth_options_are_named():
    with pytest.raises(ValueError, match="truth_edge"):
        make_case("skirt", seed=0, edge=0.04, truth_edge=0.05)
    with pytest.raises(ValueError, match="compliance_scale"):
        make_case("skirt", seed=0, compliance_scale=0.0)


def test_a_split_benchmark_grid_holds_the_whole_grids_cases():
    """bench/_case_grid.py (recover_floor.py's, material_information.py's cases) split with
    --first-case / --last-case as bench/recover.py's runs are: each part holds the same (template,
    seed, bending) as the whole grid at those indices — the bending of case k is set by --cases,
    10^(−6 + 2k/(n − 1)) N·m — so a split floor run is made of the benchmark's own truths."""
    import importlib.util
    from pathlib import Path
    spec = importlib.util.spec_from_file_location("_case_grid", Path(__file__).parents[2] / "bench" / "_case_grid.py")
    grid = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(grid)
    whole = grid.case_grid(["skirt", "tshirt"], 5)
    assert [c[:2] for c in whole] == [(t, 100 + k) for t in ("skirt", "tshirt") for k in range(5)]
    assert whole[0][2] == pytest.approx(1e-6) and whole[4][2] == pytest.approx(1e-4)
    assert whole[2][2] == pytest.approx(1e-5)
    parts = [grid.case_grid(["skirt", "tshirt"], 5, a, b) for a, b in ((0, 2), (2, 4), (4, None))]
    by_template = {t: [c for part in parts for c in part if c[0] == t] for t in ("skirt", "tshirt")}
    assert by_template["skirt"] + by_template["tshirt"] == whole
    assert grid.case_grid(["tshirt"], 5, 4) == [("tshirt", 104, whole[9][2])]
    assert grid.case_grid(["skirt"], 3, 1, 99) == grid.case_grid(["skirt"], 3)[1:]
