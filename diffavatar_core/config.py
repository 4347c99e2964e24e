"""Loads the project's YAML configuration (config/diffavatar.yaml by default) and merges user
overrides; unknown keys are rejected so a typo never silently falls back to a default."""
from __future__ import annotations

import copy
import pathlib

import yaml

PACKAGE_DIR = pathlib.Path(__file__).resolve().parent
_CANDIDATES = (PACKAGE_DIR.parent / "config", PACKAGE_DIR / "data" / "config")


def default_config_path() -> pathlib.Path:
    for d in _CANDIDATES:
        p = d / "diffavatar.yaml"
        if p.exists():
            return p
    raise FileNotFoundError("config/diffavatar.yaml not found next to the package")


def _merge(base: dict, override: dict, where: str, source: str = "") -> dict:
    """override merged over base; an unknown key or a scalar for a section refused by name (and
    by the file it came from, `source`)."""
    out = copy.deepcopy(base)
    src = f" {source}:" if source else ""
    for k, v in override.items():
        if k not in base:
            raise ValueError(f"config:{src} unknown key '{where}{k}' (known: {', '.join(sorted(base))})")
        if isinstance(base[k], dict):
            if not isinstance(v, dict):
                raise ValueError(f"config:{src} '{where}{k}' must be a mapping")
            out[k] = _merge(base[k], v, f"{where}{k}.", source)
        else:
            out[k] = v
    return out


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """A one-line account of a YAML error: what is wrong and where (line, column; 1-based)."""
    if isinstance(exc, yaml.MarkedYAMLError):
        what = " ".join(str(s).strip() for s in (exc.context, exc.problem) if s) or "invalid YAML"
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        return f"{what}{where}"
    return str(exc).strip().replace("\n", " ")


def read_yaml(path: str | pathlib.Path, what: str = "config"):
    """The content of the YAML file at `path` (safe_load: plain data only). Every way the file can
    be bad — missing, a directory, unreadable, not UTF-8 text, not YAML (syntax, tab indent, a tag
    such as !!python/object) — is a ValueError (FileNotFoundError when missing) naming the file."""
    p = pathlib.Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{what}: {path}: no such file")
    if p.is_dir():
        raise ValueError(f"{what}: {path} is a directory, not a YAML file")
    try:
        with open(p, encoding="utf-8") as fh:
            return yaml.safe_load(fh)
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what}: {path} is not UTF-8 text (byte {exc.start}): not a YAML file") from None
    except yaml.constructor.ConstructorError as exc:   # e.g. !!python/object: never constructed
        raise ValueError(f"{what}: {path} holds a YAML tag that is not plain data: {_yaml_problem(exc)}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{what}: {path} is not valid YAML: {_yaml_problem(exc)}") from None
    except OSError as exc:
        raise ValueError(f"{what}: {path} cannot be read: {exc.strerror or exc}") from None


def load_config(path: str | pathlib.Path | None = None) -> dict:
    """The default configuration, with the file at `path` (if any) merged over it. A bad file is
    refused by name (see read_yaml), as is an unknown key (ValueError)."""
    with open(default_config_path(), encoding="utf-8") as fh:
        cfg = yaml.safe_load(fh)
    if path is not None:
        user = read_yaml(path) or {}
        if not isinstance(user, dict):
            raise ValueError(f"config: {path} does not hold a mapping")
        cfg = _merge(cfg, user, "", str(path))
    return cfg
