"""`diffavatar metrics MESH [--against MESH2]`: mesh quality, and symmetric Chamfer distance."""
import json

from .. import metrics
from ..io import load_mesh


def run(args) -> int:
    V, F = load_mesh(args.mesh)
    out = {"mesh": args.mesh, "vertices": len(V), "triangles": len(F)}
    out.update(metrics.mesh_quality(V, F).as_dict())
    if args.against:
        V2, F2 = load_mesh(args.against)
        out["against"] = args.against
        out["chamfer"] = metrics.chamfer_meshes(V, F, V2, F2, samples=args.samples, seed=args.seed)
        out["chamfer_units"] = "units of the input files"
    print(json.dumps(out, indent=2))
    return 0


def register(sub) -> None:
    p = sub.add_parser("metrics", help="mesh quality of a mesh, and Chamfer distance to another")
    p.add_argument("mesh")
    p.add_argument("--against", help="second mesh for the symmetric Chamfer distance")
    p.add_argument("--samples", type=int, default=20000, help="surface samples per mesh")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run)
