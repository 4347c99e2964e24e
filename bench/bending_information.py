"""How much a synthetic scan says about the bending stiffness (issue 7's ±0.15-decade target):
for each benchmark case, the ground-truth garment itself — its own triangulation, pattern and
body, i.e. everything but the bending exact — draped fresh (as the truth was) at the true
stiffness × 10^d, and the Chamfer distance of that drape to the scan (cm). d = 0 is the scan's
noise floor; how fast the distance grows with |d| is the information the data holds about the
bending when nothing else is wrong. Prints JSON per case. Not a test.

Run: `.venv/bin/python bench/bending_information.py [--templates skirt,tshirt] [--cases 3]`."""
import time

import numpy as np

from _case_grid import run_grid
from diffavatar_core.metrics import chamfer_meshes
from diffavatar_core.pipeline.synthetic import drape_truth, make_case
from diffavatar_core.scan import load_scan

OFFSETS = (-1.0, -0.5, -0.15, 0.0, 0.15, 0.5, 1.0)   # decades


def case_row(template: str, seed: int, bend: float) -> dict:
    t0 = time.perf_counter()
    case = make_case(template, seed=seed, bend_stiffness=bend)
    scan = load_scan((case.scan_vertices, case.scan_faces, case.scan_labels), units=case.units, up=case.up)
    Vs, Fs = scan.garment_mesh()
    g = case.garment
    row = {"template": template, "seed": seed, "bend_stiffness_Nm": bend, "garment_vertices": len(g.rest),
           "chamfer_cm_by_offset_decades": {}}
    for d in OFFSETS:
        try:
            cloth, _ = drape_truth(g, (case.body_vertices, case.body_faces), bend * 10 ** d)
            cm = 100 * chamfer_meshes(np.asarray(cloth.x), g.faces, Vs, Fs, samples=20000)
            row["chamfer_cm_by_offset_decades"][f"{d:+.2f}"] = round(cm, 4)
        except RuntimeError as exc:   # the truth's drape at that stiffness slid off / did not converge
            row["chamfer_cm_by_offset_decades"][f"{d:+.2f}"] = str(exc)
    row["wall_s"] = time.perf_counter() - t0
    return row


def main():
    run_grid("bending_information", case_row, {"offsets_decades": OFFSETS})


if __name__ == "__main__":
    main()
