"""`diffavatar demo`: the main job on the bundled default input (what `make demo` runs)."""
import pathlib

from .. import demo


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the main job on the bundled default input")
    p.add_argument("--out", default="out/demo", help="output directory")
    p.set_defaults(func=lambda args: demo.run(pathlib.Path(args.out)))
