"""Benchmark: the XPBD step's contact detection through its per-vertex query cache
(sim/contact_query_cache.hpp) against the uncached detection it replaced (one bounded BVH search
per free vertex per substep), side by side in this run, on the fine output's drape. Prints JSON.

Run: `.venv/bin/python bench/contact_query.py [--edge 0.01] [--substeps 4 16] [--steps 12]
[--repeats 3]`.

The t-shirt template at `--edge` (m; 0.01 is the recovery's ~10k-vertex output mesh) is sewn and
dropped onto the default body for 60 steps (fast sweep, 4 substeps), so that its shoulders and
back lie on the body; from that state, for each substep count, `--steps` steps of 1/120 s with
the output drape's 200 single-precision sweeps per step (RecoverOptions.output_drape_sweeps),
cache off (reference) and on, interleaved, each run from the same state with an empty cache:
  * ms_per_step (best of --repeats) and the ratio;
  * identical: the final positions and contact sets of the two runs are equal bit for bit
    (test/sim/test_contact_query_cache.py asserts it);
  * searched / skipped: per detection, the vertices searched and skipped by the cached run.
Each substep detects once, so the cache matters the more substeps a step makes. Times in ms on
this machine; quote the ratios (2-core machines are noisy).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time

os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numpy as np  # noqa: E402

import diffavatar_core as dc  # noqa: E402
from diffavatar_core.pipeline.options import RecoverOptions  # noqa: E402
from diffavatar_core.sim.drape_job import build  # noqa: E402


def run(cloth, state, body_vertices, cached, steps, sweeps, substeps):
    """(wall ms per step, final x, contact pairs, (searched, skipped)) from `state`, empty cache."""
    cloth.solver.contact_query_cache = cached
    cloth.set_control(body_vertices=body_vertices)   # the same pose; empties the cache
    before = cloth.solver.contact_query_stats
    cloth.state = state.copy()
    t0 = time.perf_counter()
    cloth.drape(max_steps=steps, min_steps=steps, refine=False, iterations=sweeps, substeps=substeps, fast=True,
                raise_on_divergence=False)
    wall = time.perf_counter() - t0
    after = cloth.solver.contact_query_stats
    return (1e3 * wall / steps, np.array(cloth.x), np.array(cloth.solver.contact_pairs),
            (after[0] - before[0], after[1] - before[1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--edge", type=float, default=0.01, help="template edge length (m)")
    ap.add_argument("--substeps", type=int, nargs="+", default=[4, 16])
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    sweeps = RecoverOptions.output_drape_sweeps
    cloth, _, (bv, bf) = build("tshirt", edge=a.edge)
    cloth.sew()
    cloth.drape(max_steps=60, min_steps=60, refine=False, iterations=sweeps, substeps=4, fast=True,
                raise_on_divergence=False)
    state = cloth.state.copy()
    out = {"benchmark": "contact_query_cache", "date": time.strftime("%Y-%m-%d"),
           "machine": f"{platform.machine()}, {os.cpu_count()} logical cores", "threads": dc.num_threads(),
           "load_average_start": [round(v, 2) for v in os.getloadavg()],
           "vertices": int(cloth.model.num_vertices), "body_triangles": int(len(bf)),
           "contacts_at_start": int(cloth.solver.num_contacts), "sweeps_per_step": sweeps, "steps": a.steps,
           "cases": []}
    for sub in a.substeps:
        ref, ours, same, stats = [], [], True, (0, 0)
        for _ in range(a.repeats):   # interleaved: both see the same load
            r = run(cloth, state, bv, False, a.steps, sweeps, sub)
            o = run(cloth, state, bv, True, a.steps, sweeps, sub)
            ref.append(r[0])
            ours.append(o[0])
            same &= bool(np.array_equal(r[1], o[1]) and np.array_equal(r[2], o[2]))
            stats = o[3]
        n = a.steps * sub
        out["cases"].append({"substeps": sub, "reference_ms_per_step": min(ref), "ours_ms_per_step": min(ours),
                             "speedup_vs_reference": min(ref) / min(ours), "identical": same,
                             "searched_per_detection": stats[0] / n, "skipped_per_detection": stats[1] / n})
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
