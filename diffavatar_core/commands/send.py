"""`diffavatar send SCAN [SCAN ...] --garment TYPE --out DIR`: send scans to a running
diffavatar_node (ROS 2), show progress, write each result into DIR/<job_id>/."""

from ..scan.frame import UP_AXES


def run(args) -> int:
    from . import check_out_dir
    check_out_dir(args.out)   # before the jobs run: their results are written there as they arrive
    try:
        from diffavatar_ros.client import send
    except ImportError as exc:
        raise ValueError(f"send needs ROS 2 (rclpy) and the diffavatar_msgs interfaces: {exc}") from None
    names = [n for n in (args.label_names or "").split(",") if n]
    return send(args.scans, args.out, garment=args.garment, units=args.units, up_axis=args.up,
                template=args.template, iterations=args.iterations, label_names=names,
                use_action=args.action, node=args.node, discovery_timeout=args.wait,
                timeout=args.timeout or None, quiet=args.quiet)


def register(sub) -> None:
    p = sub.add_parser("send", help="send scans to a running diffavatar_node and collect the results",
                       description=__doc__)
    p.add_argument("scans", nargs="+", help="scan files (.ply with an optional per-vertex 'label' property, "
                                            ".obj, ...) or directories of them (a batch)")
    p.add_argument("--out", required=True, help="results go to OUT/<job_id>/ (job id: file stem + random suffix)")
    p.add_argument("--garment", default="", help="garment type (tshirt, shirt, polo, dress, skirt); "
                                                 "default: inferred from the label names")
    p.add_argument("--units", default="m", choices=["m", "cm", "mm"], help="length unit of the scan files")
    p.add_argument("--up", default="y", choices=UP_AXES, help="up axis of the scan files (Y down: --up=-y)")
    p.add_argument("--template", default="", help="template name or file (default: the garment type's)")
    p.add_argument("--iterations", type=int, default=0, help="optimization iterations (0: the node's default)")
    p.add_argument("--label-names", default="", help="comma-separated names of the label values, e.g. body,dress")
    p.add_argument("--action", action="store_true", help="send action goals instead of publishing on ~/scans")
    p.add_argument("--node", default="/diffavatar_node", help="the node's fully qualified name")
    p.add_argument("--wait", type=float, default=30.0, help="seconds to wait for the node to appear")
    p.add_argument("--timeout", type=float, default=0.0, help="seconds to wait for all results (0: no limit)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)
