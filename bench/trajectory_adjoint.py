"""Trajectory-adjoint cost on the mannequin skirt (532 vertices at edge 0.03): forward_s for
`steps` XPBD steps × `iterations` sweeps, trajectory_adjoint_s for the same steps, their ratio,
and peak_tape_mb (total, and per step). Prints JSON. Usage: bench/trajectory_adjoint.py [steps]
[checkpoint_every] [repeats] [edge (m); 0.007 gives ~10k vertices]"""
import json
import sys
import time

import numpy as np

from diffavatar_core import _core
from diffavatar_core.adjoint import trajectory_gradient
from diffavatar_core.sim import drape_job


def main():
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    k = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    reps = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    edge = float(sys.argv[4]) if len(sys.argv) > 4 else 0.03
    cloth, g, body = drape_job.build("mannequin-skirt", edge=edge)
    p = _core.SimParams()
    p.dt, p.iterations = 1 / 120, 100
    cloth.solver.step(cloth.state, p, 20)  # falling onto the body, contacts active
    W = np.random.default_rng(0).standard_normal(np.array(cloth.x).shape)
    fwd, adj, res = [], [], None
    for _ in range(reps):
        s = cloth.state.copy()
        t0 = time.perf_counter()
        cloth.solver.step(s, p, steps)
        fwd.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        res = trajectory_gradient(cloth, steps, W, checkpoint_every=k, dt=p.dt, iterations=p.iterations)
        adj.append(time.perf_counter() - t0)
    f, a = min(fwd), min(adj)
    out = dict(vertices=int(cloth.model.num_vertices), steps=steps, iterations=p.iterations, checkpoint_every=k,
               forward_s=f, trajectory_adjoint_s=a, trajectory_over_forward=a / f,
               peak_tape_mb=res["peak_tape_mb"], step_tape_mb=res.get("step_tape_mb"),
               grad_norm=dict(rest=float(np.linalg.norm(res["rest"])), x0=float(np.linalg.norm(res["x0"])),
                              body=float(np.linalg.norm(res["body_vertices"]))))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
