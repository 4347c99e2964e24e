"""`diffavatar`: command line of the DiffAvatar core. Each sub-command lives in
diffavatar_core/commands/<name>.py; `diffavatar --help` lists them."""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from . import commands


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="diffavatar", description=__doc__)
    p.add_argument("--threads", type=int, default=None, help="OpenMP threads of the C++ core")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda i: i.name):
        importlib.import_module(f"{commands.__name__}.{info.name}").register(sub)
    return p


EXIT_CANCELLED = 130   # 128 + SIGINT: the shell's status of a command ended by Ctrl-C


def main(argv=None) -> int:
    """Runs one command; its exit status: 0, 2 for a refused input (`diffavatar: error: ...`), 130
    when interrupted (Ctrl-C / SIGINT, or a run cancelled: `diffavatar: cancelled`, no traceback)."""
    try:
        return _main(argv)
    except KeyboardInterrupt:
        return _cancelled()


def _cancelled() -> int:
    try:
        print("diffavatar: cancelled", file=sys.stderr)
    except KeyboardInterrupt:   # a second Ctrl-C while saying so
        pass
    return EXIT_CANCELLED


def _main(argv) -> int:
    args = build_parser().parse_args(argv)
    from . import Cancelled, set_num_threads
    try:
        if args.threads is not None:
            set_num_threads(args.threads)
        return int(args.func(args) or 0)
    except (KeyboardInterrupt, Cancelled):
        return _cancelled()
    except (ValueError, FileNotFoundError) as exc:
        print(f"diffavatar: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:   # a file or directory that cannot be read or written: named, not a traceback
        print(f"diffavatar: error: {_os_error(exc)}", file=sys.stderr)
        return 2


def _os_error(exc: OSError) -> str:
    """'<path>: <reason>' of an OSError (e.g. 'out/x: Is a directory'), or its text."""
    names = [n for n in (exc.filename, exc.filename2) if n is not None]
    if names and exc.strerror:
        return f"{' -> '.join(map(str, names))}: {exc.strerror}"
    return str(exc) or type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
