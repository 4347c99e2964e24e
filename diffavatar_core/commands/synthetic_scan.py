"""`diffavatar synthetic-scan --template skirt --seed 1 --out DIR`: a segmented scan with known
ground truth (perturbed template, bending stiffness, random body shape → drape → scan-like
mesh in cm, Y up); writes scan.ply and truth.json (pipeline/synthetic.py)."""
import json

from ..scan.frame import UP_AXES


def register(sub) -> None:
    from ..pipeline.synthetic import PERTURBED
    p = sub.add_parser("synthetic-scan", help="make a segmented scan with known ground truth (scan.ply, truth.json)")
    p.add_argument("--template", default="skirt", choices=sorted(PERTURBED))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--edge", type=float, default=0.04, help="garment mesh edge length (m)")
    p.add_argument("--bend", type=float, default=None, help="bending stiffness (N·m); default log-uniform 1e-6..1e-4")
    p.add_argument("--truth-edge", type=float, default=None,
                   help="m; finer than --edge: the truth is then settled on a mesh of this edge (e.g. 0.01, ~10k vertices)")
    p.add_argument("--compliance-scale", type=float, default=1.0,
                   help="the truth's stretch compliances: the default material's × this")
    p.add_argument("--units", default="cm", choices=("m", "cm", "mm"))
    p.add_argument("--up", default="y", choices=UP_AXES)
    p.add_argument("--out", required=True)
    p.set_defaults(func=_run)


def _run(args) -> int:
    from ..pipeline.synthetic import make_case, write_case
    from . import check_out_dir, write_failed
    check_out_dir(args.out)   # before the drape, not after
    case = make_case(args.template, seed=args.seed, bend_stiffness=args.bend, edge=args.edge, units=args.units,
                     up=args.up, truth_edge=args.truth_edge, compliance_scale=args.compliance_scale)
    try:
        path = write_case(case, args.out)
    except OSError as exc:
        raise write_failed(args.out, exc, "writing the synthetic scan") from None
    print(json.dumps({"scan": str(path), "vertices": int(len(case.scan_vertices)),
                      "faces": int(len(case.scan_faces)), **case.truth_json()}, indent=2))
    return 0
