"""How much a synthetic scan says about the material (issue 7's ±0.15-decade bending target;
the optional stretch compliances): for each benchmark case, the ground-truth garment itself —
its own triangulation, pattern and body, i.e. everything but the material exact — draped fresh
(as the truth was) with one parameter × 10^d, and the Chamfer distance of that drape to the
scan (cm). d = 0 is the scan's noise floor; how fast the distance grows with |d| is the
information the data holds about that parameter when nothing else is wrong.
`--parameter bending` scales the bending stiffness, `stretch` the three stretch compliances
(warp, weft, shear) together. Prints JSON per case. Not a test.

Run: `.venv/bin/python bench/material_information.py [--parameter bending|stretch]
[--templates skirt,tshirt] [--cases 3]`."""
import time

import numpy as np

from _case_grid import run_grid
from diffavatar_core.metrics import chamfer_meshes
from diffavatar_core.pipeline.synthetic import drape_truth, make_case
from diffavatar_core.scan import load_scan

OFFSETS = (-1.0, -0.5, -0.15, 0.0, 0.15, 0.5, 1.0)   # decades


def case_row(template: str, seed: int, bend: float, args) -> dict:
    t0 = time.perf_counter()
    case = make_case(template, seed=seed, bend_stiffness=bend)
    scan = load_scan((case.scan_vertices, case.scan_faces, case.scan_labels), units=case.units, up=case.up)
    Vs, Fs = scan.garment_mesh()
    g = case.garment
    row = {"template": template, "seed": seed, "bend_stiffness_Nm": bend, "parameter": args.parameter,
           "garment_vertices": len(g.rest), "chamfer_cm_by_offset_decades": {}}
    for d in OFFSETS:
        scale = 10 ** d
        try:
            if args.parameter == "bending":
                cloth, _ = drape_truth(g, (case.body_vertices, case.body_faces), bend * scale)
            else:
                cloth, _ = drape_truth(g, (case.body_vertices, case.body_faces), bend, compliance_scale=scale)
            cm = 100 * chamfer_meshes(np.asarray(cloth.x), g.faces, Vs, Fs, samples=20000)
            row["chamfer_cm_by_offset_decades"][f"{d:+.2f}"] = round(cm, 4)
        except RuntimeError as exc:   # the truth's drape with that material slid off / did not converge
            row["chamfer_cm_by_offset_decades"][f"{d:+.2f}"] = str(exc)
    row["wall_s"] = time.perf_counter() - t0
    return row


def _arguments(ap):
    ap.add_argument("--parameter", choices=("bending", "stretch"), default="bending")


def main():
    run_grid("material_information", case_row,
             lambda args: {"parameter": args.parameter, "offsets_decades": OFFSETS}, add_arguments=_arguments)


if __name__ == "__main__":
    main()
