"""`diffavatar templates`: the built-in parametric garment templates."""
import json


def run(args) -> int:
    from ..pattern.templates import TEMPLATES
    if args.json:
        print(json.dumps(TEMPLATES, indent=2))
    else:
        for name, desc in TEMPLATES.items():
            print(f"{name:12s} {desc}")
    return 0


def register(sub) -> None:
    p = sub.add_parser("templates", help="list the built-in garment templates")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=run)
