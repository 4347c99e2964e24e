"""One module per `diffavatar` sub-command. Each defines `register(subparsers)` which adds its
parser and sets `func` (args -> exit code). cli.py discovers them, so adding a command never
touches another command's file."""

import os
import pathlib


def _nearest_existing(p: pathlib.Path) -> pathlib.Path:
    """p itself or its nearest existing ancestor (lexically: `a/../b` is not resolved through a)."""
    q = p
    while not os.path.lexists(q) and q.parent != q:
        q = q.parent
    return q


def check_out_dir(path, option: str = "--out") -> pathlib.Path:
    """The output directory `path`, refused before any work (ValueError naming it and the problem)
    unless it is an existing writable directory or one that can be created: not an existing file,
    not below a file, not in a directory this process cannot write. Nothing is created here."""
    p = pathlib.Path(path)
    if not str(path):
        raise ValueError(f"{option}: empty path")
    if p.exists():
        if not p.is_dir():
            raise ValueError(f"{option} {path}: exists and is not a directory")
        if not os.access(p, os.W_OK | os.X_OK):
            raise ValueError(f"{option} {path}: the directory is not writable")
        return p
    base = _nearest_existing(p.absolute())
    if os.path.islink(base) and not base.exists():
        raise ValueError(f"{option} {path}: cannot create it: {base} is a broken symbolic link")
    if not base.is_dir():
        raise ValueError(f"{option} {path}: cannot create it: {base} is not a directory")
    if not os.access(base, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {path}: cannot create it: {base} is not writable")
    return p


def check_out_file(path, option: str = "--out") -> pathlib.Path:
    """An output file `path` (its directory created when missing), refused before any work unless
    it can be written: not an existing directory, its directory as check_out_dir."""
    p = pathlib.Path(path)
    if not str(path):
        raise ValueError(f"{option}: empty path")
    if p.is_dir():
        raise ValueError(f"{option} {path}: is a directory, not a file")
    if p.exists() and not os.access(p, os.W_OK):
        raise ValueError(f"{option} {path}: the file is not writable")
    check_out_dir(p.absolute().parent, f"{option} {path}: its directory")
    return p


def write_failed(path, exc: OSError, what: str = "writing the outputs") -> ValueError:
    """A clean error for an OSError raised while writing the outputs to `path` (disk full, removed
    directory, ...): the path and the system's reason, for the CLI's `diffavatar: error:`."""
    where = exc.filename if getattr(exc, "filename", None) else path
    reason = exc.strerror or str(exc) or type(exc).__name__
    return ValueError(f"{what} to {path} failed: {where}: {reason}")
