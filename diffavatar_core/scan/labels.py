"""The label map of segmented scans (config/labels.yaml): per-vertex class indices → class
names, which classes are garments and which openings each garment class has."""
from __future__ import annotations

import numbers
import pathlib
from dataclasses import dataclass, field

import yaml

from ..config import _CANDIDATES
from .errors import LabelError

#: Class names that are never a garment even when a scan's own label_names are not in the label
#: map (config/labels.yaml may add to them under `non_garment`).
NON_GARMENT_NAMES = ("body", "skin", "hair", "face", "hands", "shoes", "background", "unlabeled",
                     "unknown", "other")


def normalize_name(name) -> str:
    """The spelling a class or garment-type name is looked up by: lower case, without spaces,
    '-' and '_' ('T-Shirt', 't_shirt' → 'tshirt')."""
    return "".join(c for c in str(name).strip().lower() if c not in " -_")

#: The opening names the boundary classification produces (a garment class uses a subset).
OPENING_NAMES = ("hem", "neckline", "sleeve_left", "sleeve_right", "waist", "leg_left", "leg_right")


def default_labels_path() -> pathlib.Path:
    for d in _CANDIDATES:
        p = d / "labels.yaml"
        if p.exists():
            return p
    raise FileNotFoundError("config/labels.yaml not found next to the package")


@dataclass(frozen=True)
class LabelMap:
    """classes: label value → class name; garment_openings: garment class → opening names it
    has; garment_types: garment type name (e.g. 'tshirt') → garment class (e.g. 'upper');
    non_garment: names that are known not to be garments (body, skin, hair, ...). Names are
    matched by normalize_name (case, spaces, '-' and '_' do not matter)."""
    classes: dict[int, str]
    garment_openings: dict[str, tuple[str, ...]]
    garment_types: dict[str, str] = field(default_factory=dict)
    non_garment: tuple[str, ...] = NON_GARMENT_NAMES

    def __post_init__(self):
        for cls, names in self.garment_openings.items():
            bad = [n for n in names if n not in OPENING_NAMES]
            if bad:
                raise LabelError(f"label map: garment class '{cls}' has unknown openings {bad} "
                                 f"(known: {', '.join(OPENING_NAMES)})")
        for t, cls in self.garment_types.items():
            if cls not in self.garment_openings:
                raise LabelError(f"label map: garment type '{t}' maps to '{cls}', which is not a "
                                 f"garment class ({', '.join(self.garment_openings)})")

    @classmethod
    def load(cls, path: str | pathlib.Path | None = None) -> "LabelMap":
        """The label map of `path` (default: config/labels.yaml)."""
        p = pathlib.Path(path) if path is not None else default_labels_path()
        with open(p, encoding="utf-8") as fh:
            d = yaml.safe_load(fh) or {}
        try:
            classes = {int(k): str(v) for k, v in d["classes"].items()}
            openings = {str(k): tuple(v) for k, v in d["garment_openings"].items()}
            types = {str(k): str(v) for k, v in (d.get("garment_types") or {}).items()}
            extra = tuple(str(n) for n in (d.get("non_garment") or ()))
        except (KeyError, AttributeError, TypeError, ValueError) as exc:
            raise LabelError(f"label map {p}: expected mappings 'classes', 'garment_openings' "
                             f"and 'garment_types' ({exc})") from None
        non_garment = NON_GARMENT_NAMES + tuple(n for n in extra if n not in NON_GARMENT_NAMES)
        return cls(classes, openings, types, non_garment)

    def with_names(self, label_names) -> "LabelMap":
        """This map with the classes replaced by a scan's own names (label value k → names[k]),
        as a ROS SegmentedScan message carries them."""
        return LabelMap({k: str(n) for k, n in enumerate(label_names)}, self.garment_openings,
                        self.garment_types, self.non_garment)

    def canonical_garment_name(self, name: str) -> str | None:
        """The label map's own spelling of a garment class or type name ('T-Shirt' → 'tshirt',
        'Dress' → 'dress'), or None if the name is no garment."""
        if name in self.garment_openings or name in self.garment_types:
            return name
        key = normalize_name(name)
        for known in (*self.garment_openings, *self.garment_types):
            if normalize_name(known) == key:
                return known
        return None

    def garment_class(self, name: str) -> str | None:
        """The garment class of a class or garment-type name ('upper', 'tshirt', 'T-Shirt' →
        'upper'), or None if the name is not a garment (e.g. 'body', 'hair')."""
        known = self.canonical_garment_name(name)
        if known is None:
            return None
        return known if known in self.garment_openings else self.garment_types[known]

    def is_non_garment(self, name: str) -> bool:
        """True for a name known not to be a garment (body, skin, hair, ...)."""
        return normalize_name(name) in {normalize_name(n) for n in self.non_garment}

    def value_of(self, label: str | int) -> int:
        """Label value of a class name or of an integer (given as int or numeric string, e.g.
        '3' or '-1'). Names are matched as the docs say: exactly, else by normalize_name (case,
        spaces, '-' and '_' do not matter: 'Skirt' → the value of 'skirt')."""
        if isinstance(label, numbers.Integral):
            return int(label)
        if isinstance(label, str):
            t = label.strip()
            digits = t[1:] if t[:1] in "+-" else t
            if digits.isascii() and digits.isdigit():
                return int(t)
        for k, v in self.classes.items():
            if v == label:
                return k
        key = normalize_name(label)
        matches = sorted(k for k, v in self.classes.items() if normalize_name(v) == key)
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise LabelError(f"label '{label}' matches several classes ignoring case, spaces, '-' and '_' "
                             f"({', '.join(f'{k}: {self.classes[k]}' for k in matches)}): give the value")
        raise LabelError(f"label '{label}' is not in the label map "
                         f"({', '.join(f'{k}: {v}' for k, v in sorted(self.classes.items()))})")

    def name_of(self, value: int) -> str:
        return self.classes.get(int(value), f"label {int(value)}")
