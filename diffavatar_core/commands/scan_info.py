"""`diffavatar scan-info SCAN [--units cm|m|mm] [--up y|z] [--label NAME] [--garment TYPE]`:
loads and preprocesses a segmented scan and prints its ScanData JSON summary (core frame, m)."""
from ..config import load_config
from ..scan import ScanOptions, load_scan
from ..scan.frame import UP_AXES


def run(args) -> int:
    opts = ScanOptions.from_config(load_config(args.config))
    data = load_scan(args.scan, units=args.units, up=args.up, label=args.label,
                     garment_type=args.garment, options=opts)
    print(data.to_json(points=args.points))
    return 0


def register(sub) -> None:
    p = sub.add_parser("scan-info", help="preprocess a segmented scan and print its summary (JSON)")
    p.add_argument("scan", help="PLY (per-vertex `label`), OBJ or other triangle mesh")
    p.add_argument("--units", default="m", choices=["m", "cm", "mm"], help="length unit of the file")
    p.add_argument("--up", default="y", choices=UP_AXES, help="up axis of the file (a Y-down file: --up=-y)")
    p.add_argument("--label", default=None,
                   help="garment label (class name of config/labels.yaml or value); "
                        "default: the only garment label present")
    p.add_argument("--garment", default=None,
                   help="garment type (e.g. tshirt, or a class: upper, dress, skirt, pants); "
                        "required for a garment-only scan")
    p.add_argument("--config", default=None, help="YAML merged over config/diffavatar.yaml")
    p.add_argument("--points", action="store_true", help="include the loop points (m)")
    p.set_defaults(func=run)
