"""`diffavatar demo`: the main job on the bundled default input (what `make demo` runs)."""

from .. import demo


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the main job on the bundled default input")
    p.add_argument("--out", default="out/demo", help="output directory")
    p.set_defaults(func=_run)


def _run(args) -> int:
    from . import check_out_dir
    return demo.run(check_out_dir(args.out))   # the output directory checked before the recovery
