"""Benchmark: nearest-point distances / Chamfer of the C++ core vs scipy's cKDTree (reference),
side by side in the same process on the same data. Prints JSON. Run: `.venv/bin/python bench/metrics.py`."""
import json
import platform
import time

import numpy as np
from scipy.spatial import cKDTree

import diffavatar_core as dc


def best_of(fn, repeats=5):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    rng = np.random.default_rng(0)
    n = 200_000
    A, B = rng.random((n, 3)), rng.random((n, 3))
    out = {"benchmark": "chamfer_points", "points_per_set": n, "threads": dc.num_threads(),
           "machine": platform.machine()}
    ours = best_of(lambda: dc.chamfer_points(A, B))

    def reference():
        return 0.5 * (cKDTree(B).query(A, workers=dc.num_threads())[0].mean()
                      + cKDTree(A).query(B, workers=dc.num_threads())[0].mean())

    ref = best_of(reference)
    assert abs(dc.chamfer_points(A, B) - reference()) < 1e-12
    out.update(ms=1e3 * ours, reference="scipy.spatial.cKDTree (build + query, same threads)",
               reference_ms=1e3 * ref, speedup_vs_reference=ref / ours)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
