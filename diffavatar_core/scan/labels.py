"""The label map of segmented scans (config/labels.yaml): per-vertex class indices → class
names, which classes are garments and which openings each garment class has."""
from __future__ import annotations

import pathlib
from dataclasses import dataclass, field

import yaml

from ..config import _CANDIDATES
from .errors import LabelError

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
    has; garment_types: garment type name (e.g. 'tshirt') → garment class (e.g. 'upper')."""
    classes: dict[int, str]
    garment_openings: dict[str, tuple[str, ...]]
    garment_types: dict[str, str] = field(default_factory=dict)

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
        except (KeyError, AttributeError, TypeError, ValueError) as exc:
            raise LabelError(f"label map {p}: expected mappings 'classes', 'garment_openings' "
                             f"and 'garment_types' ({exc})") from None
        return cls(classes, openings, types)

    def with_names(self, label_names) -> "LabelMap":
        """This map with the classes replaced by a scan's own names (label value k → names[k]),
        as a ROS SegmentedScan message carries them."""
        return LabelMap({k: str(n) for k, n in enumerate(label_names)}, self.garment_openings,
                        self.garment_types)

    def garment_class(self, name: str) -> str | None:
        """The garment class of a class or garment-type name ('upper', 'tshirt' → 'upper'), or
        None if the name is not a garment (e.g. 'body', 'hair')."""
        if name in self.garment_openings:
            return name
        return self.garment_types.get(name)

    def value_of(self, label: str | int) -> int:
        """Label value of a class name or of an integer (given as int or numeric string)."""
        if isinstance(label, (int,)) or (isinstance(label, str) and label.strip().isdigit()):
            return int(label)
        for k, v in self.classes.items():
            if v == label:
                return k
        raise LabelError(f"label '{label}' is not in the label map "
                         f"({', '.join(f'{k}: {v}' for k, v in sorted(self.classes.items()))})")

    def name_of(self, value: int) -> str:
        return self.classes.get(int(value), f"label {int(value)}")
