"""The synthetic benchmark cases shared by bench/recover_floor.py and
bench/material_information.py: per template, seeds 100, 101, ... with the bending stiffness
spread over two decades as in bench/recover.py (10^(−6 + 2k/(n − 1)) N·m for case k of n), and
the common command line (`--templates skirt,tshirt --cases 3 [--first-case K] [--last-case K]`,
the split options as bench/recover.py's: the same template, seed and bending per index) that runs
one function per case and prints JSON. A helper, not a benchmark (scripts/bench.sh skips bench/_*.py)."""
import argparse
import json


def case_grid(templates, cases: int, first: int = 0, last: int | None = None):
    """[(template, seed, bend_stiffness N·m)] for each template, cases first … last − 1 of `cases`
    (last None: all from first on) — the bending of case k depends on `cases`, as in bench/recover.py."""
    end = cases if last is None else min(last, cases)
    return [(tpl, 100 + k, 10 ** (-6 + 2 * k / max(cases - 1, 1))) for tpl in templates for k in range(first, end)]


def run_grid(benchmark: str, case_fn, extra: dict | None = None, add_arguments=None) -> list:
    """Parses --templates/--cases (and what add_arguments(parser) adds), runs
    case_fn(template, seed, bend[, args]) per case (one JSON line each, as it finishes) and
    prints the whole run as one JSON document at the end; `extra` (a dict, or a function of the
    parsed args giving one) goes into that document."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--templates", default="skirt,tshirt")
    ap.add_argument("--cases", type=int, default=3)
    ap.add_argument("--first-case", type=int, default=0, help="index of the first case (to split runs)")
    ap.add_argument("--last-case", type=int, default=None, help="index after the last case (default --cases)")
    if add_arguments is not None:
        add_arguments(ap)
    args = ap.parse_args()
    more = (args,) if add_arguments is not None else ()
    rows = []
    for tpl, seed, bend in case_grid(args.templates.split(","), args.cases, args.first_case, args.last_case):
        rows.append(case_fn(tpl, seed, bend, *more))
        print(json.dumps(rows[-1]), flush=True)
    head = extra(args) if callable(extra) else (extra or {})
    print(json.dumps({"benchmark": benchmark, **head, "cases": rows}, indent=2))
    return rows
