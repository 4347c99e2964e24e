"""`diffavatar pattern NAME|--from-obj FILE|--from-garmentcode FILE --out DIR`: builds or
imports a sewing pattern and writes pattern.json, pattern.svg, pattern.png and rest.obj."""
import json


def run(args) -> int:
    from ..pattern.cage import build_cage
    from ..pattern.export import write_all
    from . import check_out_dir, write_failed
    sources = [s for s in (args.name, args.from_obj, args.from_garmentcode) if s]
    if len(sources) != 1:
        raise ValueError("pattern: give exactly one of NAME, --from-obj FILE, --from-garmentcode FILE")
    check_out_dir(args.out)
    if args.from_obj:
        from ..pattern.obj_import import load_obj_pattern
        g = load_obj_pattern(args.from_obj)
    elif args.from_garmentcode:
        from ..pattern.garmentcode import load_garmentcode
        g = load_garmentcode(args.from_garmentcode, edge_length=args.edge_length)
    else:
        from ..pattern.templates import make_template
        g = make_template(args.name, edge_length=args.edge_length)
    cage = build_cage(g, args.handle_angle)
    try:
        paths = write_all(args.out, g, cage.handles)
    except OSError as exc:
        raise write_failed(args.out, exc, "writing the pattern") from None
    print(json.dumps({"name": g.name, "panels": g.panel_names, "vertices": len(g.rest),
                      "triangles": len(g.faces), "seam_pairs": len(g.seams), "handles": len(cage.handles),
                      "area_m2": round(g.total_area(), 6), "boundaries": sorted(g.boundaries),
                      "files": paths}, indent=2))
    return 0


def register(sub) -> None:
    p = sub.add_parser("pattern", help="build a template or import a pattern; write json/svg/png/obj")
    p.add_argument("name", nargs="?", help="built-in template (see `diffavatar templates`)")
    p.add_argument("--from-obj", metavar="FILE", help="OBJ whose UVs are the sewing pattern")
    p.add_argument("--from-garmentcode", metavar="FILE", help="GarmentCode *_specification.json")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--edge-length", type=float, default=0.012, help="target edge length, m")
    p.add_argument("--handle-angle", type=float, default=10.0, help="cage handle turning angle, degrees")
    p.set_defaults(func=run)
