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


def _merge(base: dict, override: dict, where: str) -> dict:
    out = copy.deepcopy(base)
    for k, v in override.items():
        if k not in base:
            raise ValueError(f"config: unknown key '{where}{k}' (known: {', '.join(sorted(base))})")
        if isinstance(base[k], dict):
            if not isinstance(v, dict):
                raise ValueError(f"config: '{where}{k}' must be a mapping")
            out[k] = _merge(base[k], v, f"{where}{k}.")
        else:
            out[k] = v
    return out


def load_config(path: str | pathlib.Path | None = None) -> dict:
    """The default configuration, with the file at `path` (if any) merged over it."""
    with open(default_config_path(), encoding="utf-8") as fh:
        cfg = yaml.safe_load(fh)
    if path is not None:
        with open(path, encoding="utf-8") as fh:
            user = yaml.safe_load(fh) or {}
        if not isinstance(user, dict):
            raise ValueError(f"config: {path} does not hold a mapping")
        cfg = _merge(cfg, user, "")
    return cfg
