"""The label map of segmented scans (config/labels.yaml): per-vertex class indices → class
names, which classes are garments and which openings each garment class has."""
from __future__ import annotations

import numbers
import pathlib
from dataclasses import dataclass, field

import numpy as np
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


@dataclass(frozen=True)
class FaceLabelConversion:
    """What face_to_vertex_labels did: labels (V,) int64 per-vertex labels; faces_off: faces
    whose garment-region status differs from their face label under these vertex labels (a
    per-vertex labelling cannot represent every per-face one: a lone body face amid garment faces,
    say); extra / missing: of those, faces in a garment region their label does not name / faces
    labelled a garment but outside its region; garment_faces: faces labelled a garment."""
    labels: np.ndarray
    faces_off: int
    extra: int
    missing: int
    garment_faces: int


def face_to_vertex_labels(faces: np.ndarray, face_labels: np.ndarray, n_vertices: int,
                          is_garment, max_rounds: int = 10) -> FaceLabelConversion:
    """Per-vertex labels from per-face ones, chosen so that the garment regions the pipeline
    derives from them (for garment label g: the faces whose three vertices carry g) match the
    faces labelled g as closely as a per-vertex labelling can.

    faces (F, 3) int, valid indices; face_labels (F,) int64; is_garment(value) -> bool (which
    labels are garments: the label map's classes). Rule:
      1. a vertex whose faces agree takes their label; where labels meet, a garment label wins
         over a non-garment one (so every garment face keeps its three vertices: none is lost at
         a garment–body border); among several, the label of the most faces (ties: the lowest
         value). A vertex no face uses takes the most common non-garment face label (else the
         most common label);
      2. then, vertex by vertex where a face's region status is off (a body face whose three
         vertices are all on the garment's border, two garments meeting), the label among its
         faces' labels that puts the fewest of its faces off is taken if it puts fewer off than
         the current one (at most max_rounds sweeps; each change strictly lowers the count).
    Labels only take values present in face_labels. Cost O(F log F) plus the local sweeps over
    the border vertices that are off."""
    F = np.asarray(faces, np.int64)
    FL = np.asarray(face_labels, np.int64)
    n = int(n_vertices)
    vals, li = np.unique(FL, return_inverse=True)
    li = li.reshape(-1)
    nL = len(vals)
    garm = np.array([bool(is_garment(int(v))) for v in vals])

    # 1. counts per (vertex, label), garment labels first
    key = F.ravel() * nL + np.repeat(li, 3)
    uk, cnt = np.unique(key, return_counts=True)
    kv, kl = uk // nL, uk % nL
    score = cnt + garm[kl] * (3 * len(F) + 1)          # any garment face outweighs all others
    order = np.lexsort((kl, -score, kv))                # per vertex: best score, then lowest value
    first = order[np.r_[True, kv[order][1:] != kv[order][:-1]]]
    face_count = np.bincount(li, minlength=nL)
    fallback = (np.flatnonzero(~garm)[np.argmax(face_count[~garm])] if (~garm).any()
                else int(np.argmax(face_count)))
    lv = np.full(n, fallback, np.int64)                 # label indices into vals
    lv[kv[first]] = kl[first]

    tgt = np.where(garm[li], li, -1)                    # the garment region each face should be in

    def region(lf):                                     # (k, 3) label indices → region label or -1
        same = (lf[:, 0] == lf[:, 1]) & (lf[:, 1] == lf[:, 2])
        return np.where(same & garm[lf[:, 0]], lf[:, 0], -1)

    def off(reg, t):
        return (reg != t).astype(np.int64) + ((reg != t) & (reg >= 0) & (t >= 0))

    # 2. local improvement where faces are off
    from scipy.sparse import csr_matrix
    vf = csr_matrix((np.ones(3 * len(F), np.int8), (F.ravel(), np.repeat(np.arange(len(F)), 3))),
                    shape=(n, len(F)))
    vf.sort_indices()
    ptr, idx = vf.indptr, vf.indices
    dirty = None                                        # faces near last round's changes
    for _ in range(max_rounds):
        bad = np.flatnonzero(region(lv[F]) != tgt)
        if dirty is not None:
            bad = bad[dirty[bad]]
        if not len(bad):
            break
        changed = []
        for v in np.unique(F[bad].ravel()):
            fs = idx[ptr[v]:ptr[v + 1]]
            lf = lv[F[fs]]
            t = tgt[fs]
            here = F[fs] == v
            cur = int(lv[v])
            best, best_err = cur, int(off(region(lf), t).sum())
            opts, c = np.unique(li[fs], return_counts=True)
            ng = opts[~garm[opts]]                      # one non-garment option: the most common
            ng = [int(ng[np.argmax(c[~garm[opts]])])] if len(ng) else []
            for x in [int(o) for o in opts[garm[opts]][np.argsort(-c[garm[opts]], kind="stable")]] + ng:
                if x == cur:
                    continue
                lf2 = np.where(here, x, lf)
                e = int(off(region(lf2), t).sum())
                if e < best_err:
                    best, best_err = x, e
            if best != cur:
                lv[v] = best
                changed.append(v)
        if not changed:
            break
        dirty = np.zeros(len(F), bool)
        dirty[np.concatenate([idx[ptr[v]:ptr[v + 1]] for v in changed])] = True
    reg = region(lv[F])
    extra = int(np.count_nonzero((reg >= 0) & (reg != tgt)))
    missing = int(np.count_nonzero((tgt >= 0) & (reg != tgt)))
    return FaceLabelConversion(vals[lv], int(np.count_nonzero(reg != tgt)), extra, missing,
                               int(np.count_nonzero(tgt >= 0)))
