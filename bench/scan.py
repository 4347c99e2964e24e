"""Benchmark: segmented-scan preprocessing (diffavatar_core.scan) on a ~300k-triangle labelled
synthetic scan (the tests' generator at a finer grid, 2% of the shirt's labels flipped into small
holes), and its boundary-loop tracing side by side with trimesh's `Trimesh.outline()` on the
same garment region (reference). Both must cover the same boundary edges; trimesh splits
loops touching at a vertex differently, so the loop counts differ. Prints JSON.
Run: `.venv/bin/python bench/scan.py`."""
import json
import pathlib
import platform
import sys
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "test" / "scan"))
import synthetic_scan as ss  # noqa: E402  (the project's own synthetic scan generator)

import diffavatar_core as dc  # noqa: E402
from diffavatar_core.scan import load_scan  # noqa: E402
from diffavatar_core.scan.boundary import boundary_loops  # noqa: E402


def best_of(fn, repeats=3):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    import trimesh
    ss.N_RINGS, ss.N_PHI = 361, 480
    s = ss.make_synthetic_scan()
    rng = np.random.default_rng(0)
    L = s.labels.copy()
    shirt = np.flatnonzero(L == 1)
    L[rng.choice(shirt, size=len(shirt) // 50, replace=False)] = 0
    V = ss.core_to_scan(s.V, "cm", "z")
    data = load_scan((V, s.F, L), units="cm", up="z")
    total = best_of(lambda: load_scan((V, s.F, L), units="cm", up="z"))
    Fg = data.faces[data.garment_face_mask]
    ours = best_of(lambda: boundary_loops(Fg, data.vertices))

    def reference():
        return trimesh.Trimesh(data.vertices, Fg, process=False).outline()

    ref = best_of(reference)
    path = reference()
    n_ref = len(path.entities)
    loops = boundary_loops(Fg, data.vertices)
    n_ours = len(loops)
    edges_ours = sum(len(lp) for lp in loops)              # closed loops: K points = K edges
    edges_ref = sum(len(e.points) - 1 for e in path.entities)
    assert edges_ours == edges_ref, (edges_ours, edges_ref)
    out = {"benchmark": "scan_preprocess", "vertices": int(len(V)), "triangles": int(len(s.F)),
           "threads": dc.num_threads(), "machine": platform.machine(),
           "preprocess_ms": 1e3 * total, "openings": sorted(data.boundaries), "holes": len(data.holes),
           "boundary_loops_ms": 1e3 * ours, "reference": "trimesh Trimesh.outline() (closed entities)",
           "reference_ms": 1e3 * ref, "speedup_vs_reference": ref / ours,
           "loops": n_ours, "reference_loops": n_ref, "boundary_edges": edges_ours}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
