"""`diffavatar drape --garment NAME --out DIR`: sew and drape a garment on the default body."""
import json


def register(sub) -> None:
    from ..sim.drape_job import GARMENTS, NEWTON_SOLVERS, SUBSTEPS, SWEEPS
    p = sub.add_parser("drape", help="sew and drape a garment on the default body (draped.obj, body.obj, drape.json)")
    p.add_argument("--garment", default="tshirt", choices=GARMENTS)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--max-steps", type=int, default=1500, help="XPBD step budget")
    p.add_argument("--iterations", type=int, default=100, help="constraint sweeps per step")
    p.add_argument("--substeps", type=int, default=SUBSTEPS,
                   help="XPBD substeps per 1/120 s step, the sweeps split among them (default %(default)s: finer meshes stay stiff)")
    p.add_argument("--sweeps", default="single", choices=SWEEPS,
                   help="precision of the XPBD phase's sweeps: single (vectorised float, 6x faster with AVX-512) "
                        "or double; the Newton refinement is float64 either way (default %(default)s)")
    p.add_argument("--edge", type=float, default=0.025, help="target edge length of the garment mesh (m)")
    p.add_argument("--no-refine", action="store_true", help="skip the Newton equilibrium refinement")
    p.add_argument("--newton-solver", default="supernodal", choices=NEWTON_SOLVERS,
                   help="the Newton refinement's LDLT: supernodal (1.6x faster drape at 1 cm) or simplicial (Eigen's; "
                        "the same solutions up to round-off; default %(default)s)")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from ..sim import drape_job
    from . import check_out_dir, write_failed
    out = check_out_dir(args.out)   # before the drape, not after
    try:
        info = drape_job.run(out, args.garment, args.max_steps, args.iterations,
                             refine=not args.no_refine, edge=args.edge, substeps=args.substeps,
                             sweeps=args.sweeps, newton_solver=args.newton_solver)
    except OSError as exc:   # the drape reads no files: an OSError is the outputs' writing
        raise write_failed(args.out, exc, "writing the drape") from None
    print(json.dumps(info, indent=2))
    return 0 if not info["diverged"] else 1
