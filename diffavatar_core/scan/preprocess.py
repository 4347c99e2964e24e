"""Segmented scan → ScanData: the scan in the core frame, cleaned, with its garment region,
named boundary loops (openings), holes and interior samples (paper §4.2: the boundary and
interior targets of the loss)."""
from __future__ import annotations

import dataclasses
import json
import pathlib
from dataclasses import dataclass, field, fields

import numpy as np

from ..config import load_config
from . import boundary as bnd
from . import cleaning
from .check import CheckedScan, check_scan, choose_garment
from .errors import DegenerateScanError, NoGarmentError
from .frame import ScanTransform, check_plausible_size
from .interior import interior_samples
from .labels import LabelMap
from .loading import RawScan

_MAX_LISTED = 10


def _listed(parts) -> str:
    """The first _MAX_LISTED parts described (cleaning.DroppedComponent), and how many more."""
    more = f"; and {len(parts) - _MAX_LISTED} more" if len(parts) > _MAX_LISTED else ""
    return "; ".join(d.describe() for d in parts[:_MAX_LISTED]) + more


@dataclass(frozen=True)
class ScanOptions:
    """Preprocessing parameters (defaults: the `scan:` section of config/diffavatar.yaml).
    Lengths in m (core frame), areas relative."""
    min_height: float = 0.2
    max_height: float = 2.5
    merge_tolerance: float = 1e-6
    min_component_fraction: float = 0.01
    fragment_keep_fraction: float = 0.0
    min_opening_perimeter: float = 0.10
    interior_margin: float = 0.01
    interior_samples: int = 5000
    seed: int = 0

    def __post_init__(self):
        def bad(name, why):
            raise ValueError(f"scan options: {name} {why}, got {getattr(self, name)!r}")
        for name in ("min_height", "max_height", "merge_tolerance", "min_component_fraction",
                     "fragment_keep_fraction", "min_opening_perimeter", "interior_margin"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v < 0:
                bad(name, "must be a non-negative number")
        if not 0 < self.min_height < self.max_height:
            raise ValueError(f"scan options: need 0 < min_height < max_height, got min_height="
                             f"{self.min_height!r}, max_height={self.max_height!r}")
        if self.min_component_fraction >= 1:
            bad("min_component_fraction", "must be below 1")
        for name in ("interior_samples", "seed"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
                bad(name, "must be a non-negative integer")

    @classmethod
    def from_config(cls, cfg: dict | None = None) -> "ScanOptions":
        """From a loaded configuration (load_config()), default: the project's."""
        section = (cfg if cfg is not None else load_config()).get("scan", {})
        known = {f.name for f in fields(cls)}
        unknown = set(section) - known
        if unknown:
            raise ValueError(f"config: unknown key(s) scan.{', scan.'.join(sorted(unknown))}")
        return cls(**section)


@dataclass
class ScanData:
    """A preprocessed scan, everything in the core frame (m, Y up, faces +Z, +X = left).

    vertices (N, 3) m and faces (M, 3) int64: the cleaned scan (all kept parts, body included);
    labels (N,) int64 or None (garment-only); label_names {value: name};
    garment_face_mask (M,) / garment_vertex_mask (N,) bool: the garment region (faces whose
    three vertices carry the garment label, small islands removed) and the vertices it uses;
    garment_label (int or None), garment_class ('upper', 'dress', 'skirt', 'pants'),
    garment_type (as given, or None);
    boundaries {opening name: (K, 3) ordered closed loop, m} with names among hem, neckline,
    sleeve_left, sleeve_right, waist, leg_left, leg_right; boundary_indices: the same loops as
    vertex indices (K,); holes: loops that are no opening ((K, 3), m);
    interior_points (S, 3) m: area-uniform garment samples ≥ interior_margin from any loop;
    transform: p_core = scale · R · p_scan (to_scan() maps results back); warnings: what
    cleaning dropped or could not find; height_m: Y extent of the cleaned scan.
    """
    vertices: np.ndarray
    faces: np.ndarray
    labels: np.ndarray | None
    label_names: dict[int, str]
    garment_face_mask: np.ndarray
    garment_vertex_mask: np.ndarray
    garment_label: int | None
    garment_class: str
    garment_type: str | None
    boundaries: dict[str, np.ndarray]
    boundary_indices: dict[str, np.ndarray]
    holes: list[np.ndarray]
    interior_points: np.ndarray
    transform: ScanTransform
    height_m: float
    source: str = "arrays"
    warnings: list[str] = field(default_factory=list)
    checked: object = field(default=None, repr=False, compare=False)   # the CheckedScan it came from

    def turned(self, Q) -> "ScanData":
        """The same scan turned by the proper rotation Q (3, 3) about the vertical, preprocessed
        again: the openings are named where the subject faces +Z (their rules take +X as the
        body's left) and `transform` includes the turn, so to_scan() still maps back. Needs the
        CheckedScan it was made from (every ScanData preprocess_checked makes has it)."""
        if self.checked is None:
            raise ValueError("ScanData.turned: this ScanData was not made by preprocess_checked")
        c = self.checked
        Q = np.asarray(Q, np.float64)
        return preprocess_checked(dataclasses.replace(c, transform=c.transform.turned(Q),
                                                      vertices=np.ascontiguousarray(c.vertices @ Q.T)))

    def garment_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """The garment region alone: (V (n, 3) m, F (m, 3) int64), vertex order kept."""
        V, F, _ = cleaning.compact(self.vertices, self.faces, self.garment_face_mask)
        return V, F

    def label_vertex_mask(self, label) -> np.ndarray:
        """(N,) bool: the vertices carrying a label (class name or value), e.g. 'body' for the
        body fitting; all False for a garment-only scan."""
        if self.labels is None:
            return np.zeros(len(self.vertices), bool)
        return self.labels == LabelMap(self.label_names, {}).value_of(label)

    def to_dict(self, points: bool = False) -> dict:
        """JSON-able summary (lengths in m); points=True includes the loop points."""
        def loop(P):
            g = bnd.LoopGeometry.of(P)
            d = {"points": len(P), "perimeter_m": g.perimeter, "centroid_m": g.centroid.tolist(),
                 "normal": g.normal.tolist()}
            if points:
                d["xyz_m"] = P.tolist()
            return d
        Vg, Fg = self.garment_mesh()
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        present = {}
        if self.labels is not None:
            vals, counts = np.unique(self.labels, return_counts=True)
            present = {self.label_names.get(int(v), f"label {int(v)}"): int(c) for v, c in zip(vals, counts)}
        return {
            "source": self.source,
            "transform": self.transform.to_dict(),
            "vertices": int(len(self.vertices)),
            "faces": int(len(self.faces)),
            "height_m": self.height_m,
            "bbox_m": [lo.tolist(), hi.tolist()],
            "labels_present": present,
            "garment": {"label": self.garment_label,
                        "label_name": (self.label_names.get(self.garment_label)
                                       if self.garment_label is not None else None),
                        "class": self.garment_class, "type": self.garment_type,
                        "vertices": int(len(Vg)), "faces": int(len(Fg)),
                        "area_m2": float(cleaning.triangle_areas(Vg, Fg).sum())},
            "boundaries": {k: loop(P) for k, P in self.boundaries.items()},
            "holes": [loop(P) for P in self.holes],
            "interior_samples": int(len(self.interior_points)),
            "warnings": list(self.warnings),
        }

    def to_json(self, points: bool = False) -> str:
        return json.dumps(self.to_dict(points), indent=2)


def preprocess_scan(raw: RawScan, units: str = "m", up: str = "y", label=None,
                    garment_type: str | None = None, options: ScanOptions | None = None,
                    label_map: LabelMap | None = None) -> ScanData:
    """Converts a RawScan (its own units/up axis) into ScanData (core frame, m).

    label: garment label (class name or value); default: the only garment label present (or
    the one matching garment_type). garment_type: e.g. 'tshirt' or a class ('upper'); required
    for a garment-only scan (no labels). Runs check_scan first (the checks the ROS node runs at
    its front door), then the checks that need the cleaned mesh. Raises a ScanError subclass
    naming the problem.
    """
    return preprocess_checked(check_scan(raw, units, up, label, garment_type, options=options,
                                         label_map=label_map))


def clean_scan(raw: RawScan, V0: np.ndarray, opt: ScanOptions, warnings: list | None = None):
    """Steps 1–3 of the preprocessing: duplicate vertices merged, degenerate and duplicate
    triangles dropped, floating fragments dropped. raw: the scan (faces, labels, source); V0:
    its vertices in the core frame (m). Returns (V (N, 3) m, F (M, 3) int64, labels (N,) or
    None); appends what it did to `warnings`. Raises DegenerateScanError when no triangle is
    left. check_scan calls it too, for a scan whose size looks implausible before cleaning
    (the size rule is the cleaned scan's)."""
    warnings = warnings if warnings is not None else []

    # 1. duplicate vertices (split seams, OBJ UV splits)
    V, F, old_to_new = cleaning.merge_duplicate_vertices(V0, raw.faces, opt.merge_tolerance)
    labels = None
    if raw.labels is not None:
        kept = np.zeros(len(V0), bool)
        kept[np.unique(old_to_new, return_index=True)[1]] = True
        labels = raw.labels[kept]
        conflict = np.count_nonzero(labels[old_to_new] != raw.labels)
        if conflict:
            warnings.append(f"{conflict} merged duplicate vertices had a different label than the "
                            f"vertex they were merged into (kept the first's)")
    if len(V) < len(V0):
        warnings.append(f"merged {len(V0) - len(V)} duplicate vertices (closer than {opt.merge_tolerance} m)")

    # 2. degenerate and duplicate triangles
    bad, n_deg, n_dup = cleaning.degenerate_or_duplicate_faces(V, F, opt.merge_tolerance ** 2)
    if bad.all():
        raise DegenerateScanError(f"{raw.source}: all {len(F)} triangles are degenerate (zero area "
                                  f"or a repeated vertex) or duplicates")
    if n_deg or n_dup:
        warnings.append(f"removed {n_deg} degenerate and {n_dup} duplicate triangles")
    F = F[~bad]

    # 3. floating fragments: small parts (with fragment_keep_fraction > 0 only those far from the
    # large ones: near ones are pieces of the subject cut off by occlusion, e.g. a hand beyond a
    # long sleeve's cuff, and are kept)
    drop, dropped, near = cleaning.components_to_drop(V, F, opt.min_component_fraction, opt.fragment_keep_fraction)
    if dropped:
        farther = (f" and farther than {opt.fragment_keep_fraction:g} × its size from the larger parts"
                   if opt.fragment_keep_fraction > 0 else "")
        warnings.append(f"dropped {len(dropped)} floating fragment(s) smaller than "
                        f"{opt.min_component_fraction:g} of the largest part's area{farther}: {_listed(dropped)}")
    if near:
        warnings.append(f"kept {len(near)} small part(s) within {opt.fragment_keep_fraction:g} × the largest "
                        f"part's size of the larger parts (pieces of the subject cut off by occlusion): "
                        f"{_listed(near)}")
    V, F, kept_v = cleaning.compact(V, F, ~drop)
    if labels is not None:
        labels = labels[kept_v]
    return V, F, labels


def preprocess_checked(checked: CheckedScan) -> ScanData:
    """ScanData of a scan that passed check_scan: cleaning, the checks that need the cleaned
    mesh, garment region, openings and interior samples (the costly part)."""
    raw, tf, opt, lmap = checked.raw, checked.transform, checked.options, checked.label_map
    label, garment_type = checked.label, checked.requested_garment_type
    # what reading the file did (loading.RawScan), then what the checks found (unnamed labels)
    warnings: list[str] = list(raw.warnings) + list(checked.warnings)

    # 1.-3. duplicate vertices, degenerate and duplicate triangles, floating fragments (the
    # scan is in the core frame already: check_scan converted it)
    V, F, labels = clean_scan(raw, checked.vertices, opt, warnings)
    height = check_plausible_size(V, tf, opt.min_height, opt.max_height)

    # 4. garment region (garment-only: checked by check_scan; labels: chosen again once
    # fragments are dropped, which may have carried a second garment label)
    if labels is None:
        cls, value = checked.garment_class, None
        gface = np.ones(len(F), bool)
    else:
        try:
            value, cls, _ = choose_garment(labels, lmap, label, garment_type)
        except NoGarmentError:
            given = np.unique(raw.labels[checked.garment_mask])
            if len(given) and not np.isin(given, labels).any():
                # check_scan found the garment label: cleaning removed it, say so (not "no vertex")
                names = ", ".join(f"'{lmap.name_of(v)}' ({int(v)})" for v in given)
                raise NoGarmentError(f"{raw.source}: cleaning removed all {int(checked.garment_mask.sum())} vertices "
                                     f"labelled {names}: the garment region is degenerate or a small floating "
                                     f"fragment ({'; '.join(warnings)})") from None
            raise
        gface = (labels[F] == value).all(axis=1)
        if not gface.any():
            raise NoGarmentError(f"{raw.source}: {int(np.count_nonzero(labels == value))} vertices carry "
                                 f"label '{lmap.name_of(value)}' but no triangle has all three")
    gidx = np.flatnonzero(gface)
    gdrop, gdropped = cleaning.small_components(V, F[gidx], opt.min_component_fraction)
    if gdropped:
        warnings.append(f"dropped {len(gdropped)} small island(s) of the garment region: {_listed(gdropped)}")
        gface[gidx[gdrop]] = False
    gvert = np.zeros(len(V), bool)
    gvert[F[gface].ravel()] = True

    # 5. boundary loops → openings and holes
    loops = [bnd.start_at_front(lp, V) for lp in bnd.boundary_loops(F[gface], V)]
    pts = [V[lp] for lp in loops]
    openings = lmap.garment_openings[cls]
    found, hole_ids = bnd.classify_loops(pts, openings, V[gvert], opt.min_opening_perimeter)
    missing = [n for n in openings if n not in found]
    if missing:
        warnings.append(f"openings not found for a '{cls}' garment: {', '.join(missing)} "
                        f"({len(loops)} boundary loops, {len(hole_ids)} unmatched)")
    boundaries = {n: pts[found[n]] for n in openings if n in found}
    boundary_idx = {n: loops[found[n]] for n in openings if n in found}

    # 6. interior samples
    interior = np.zeros((0, 3))
    if opt.interior_samples > 0:
        Vg, Fg, _ = cleaning.compact(V, F, gface)
        interior = interior_samples(Vg, Fg, pts, opt.interior_samples, opt.interior_margin, opt.seed)
        if len(interior) < opt.interior_samples:
            warnings.append(f"only {len(interior)} of {opt.interior_samples} interior samples lie "
                            f"{opt.interior_margin} m away from the boundary")

    return ScanData(V, F, labels, dict(lmap.classes), gface, gvert, value, cls,
                    checked.garment_type if garment_type or labels is None else None, boundaries, boundary_idx, [pts[i] for i in hole_ids],
                    interior, tf, height, raw.source, warnings, checked)


def load_scan(scan, units: str = "m", up: str = "y", label=None, garment_type: str | None = None,
              options: ScanOptions | None = None, label_map: LabelMap | None = None) -> ScanData:
    """One call from input to ScanData. scan: a file path (PLY with per-vertex or per-face
    `label`, OBJ, ...),
    a RawScan, a (vertices, faces[, labels]) tuple, the dict of
    diffavatar_ros.convert.msg_to_arrays (its units/up_axis/garment_type/template_name fill in
    the arguments left at their defaults), or a CheckedScan (what the ROS node hands its
    runner: preprocessed as it was checked, unless options or label_map are given)."""
    if isinstance(scan, CheckedScan):
        if options is None and label_map is None:
            return preprocess_checked(scan)
        return preprocess_checked(check_scan(scan.raw, scan.transform.units, scan.transform.up, scan.label,
                                             scan.requested_garment_type, scan.template_name,
                                             options=options, label_map=label_map))
    return preprocess_checked(check_scan(scan, units, up, label, garment_type, options=options,
                                         label_map=label_map))
