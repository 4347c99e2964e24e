"""The checks of a scan that need no cleaning: cheap (O(V + F) numpy, no KD-tree, no mesh
graph; only a scan whose size looks implausible is cleaned to be judged), so the ROS node runs
them on every scan at its front door, and the preprocessing runs the very same function first (preprocess_scan = check_scan + the checks that need the cleaned
mesh + openings and samples). One definition of a bad scan, one message, one error code.

check_scan(scan, ...) → CheckedScan, in this order:
  1. size limit (max_vertices, when given)                     TooLargeError
  2. arrays (loading.scan_from_arrays): shapes, numbers, empty, NaN/Inf, face indices, label
     length / integers / values indexing label_names          VertexArrayError, EmptyScanError,
                                                               NonFiniteError, FaceIndexError, LabelError
  3. units and up axis                                         BadOptionError
  4. garment type name, template name                          UnknownGarmentTypeError, UnknownTemplateError
  5. size: judged on the scan as given (the vertices its triangles use); if that looks
     implausible, the scan is cleaned (as preprocessing does) and the cleaned scan decides,
     with the message preprocessing gives                       ImplausibleSizeError
  6. not every triangle degenerate, total area not negligible DegenerateScanError
  7. garment label on the scan as given: a garment label present (the requested one, or one
     matching the garment type), label names known; label values the label map does not name
     on at most UNKNOWN_LABEL_MAX_FRACTION of the vertices (a warning, CheckedScan.warnings)
                                                               NoGarmentError, LabelError,
                                                               GarmentTypeMissingError

What needs cleaning stays in preprocessing: a choice among several garment labels (a fragment
may carry the extra one), a garment label on vertices but on no whole triangle, the garment
region after merging duplicate vertices, and the size of a scan that is plausible as given but
too small once fragments are dropped. Whenever check 5 or 7 fails on the scan as given it
fails on the cleaned scan too (cleaning only removes vertices and labels), so the
front door never refuses a scan that preprocessing would accept.
"""
from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass

import numpy as np

from . import cleaning
from .errors import (DegenerateScanError, GarmentTypeMissingError, ImplausibleSizeError, LabelError,
                     NoGarmentError, ScanFormatError, TooLargeError, UnknownGarmentTypeError,
                     UnknownTemplateError)
from .frame import ScanTransform, centring_origin, check_plausible_size
from .labels import LabelMap
from .loading import RawScan, read_scan_file, scan_from_arrays, scan_from_message

#: A surface whose total area is at most this × (bounding-box diagonal)² is degenerate: all
#: triangles collinear or collapsed (a scan of a person or garment is ~0.5–5 m² for ~2 m).
MIN_AREA_RATIO = 1e-6
#: Label values the label map does not name (and label= does not choose) are used neither as body
#: nor as garment: a warning names them; covering more than this fraction of the scan's vertices
#: they are refused — as much as the recovery needs of a body to fit it to the body-labelled
#: points (pipeline.recovery.MIN_BODY_FRACTION), so an unnamed body would be silently dropped.
UNKNOWN_LABEL_MAX_FRACTION = 0.2
#: A template_name with one of these suffixes (or a path separator) is a file path.
TEMPLATE_FILE_SUFFIXES = (".obj", ".json", ".yaml", ".yml")


@dataclass(frozen=True, eq=False)
class CheckedScan:
    """A scan that passed check_scan, in the core frame (m, Y up), not yet cleaned.

    raw: the scan as given (its units and frame); transform: p_core = scale · R · p_scan;
    vertices (V, 3) float64 m, core frame (every vertex, in input order); faces (F, 3) int32;
    garment_label: the label value of the garment (None: garment-only, or several garment
    labels present that preprocessing chooses among after cleaning); garment_class ('upper',
    'dress', ...; None as garment_label); garment_type: the type given (label-map spelling:
    'T-Shirt' → 'tshirt'), else the garment label's name when it is a class or type (for a
    garment-only scan: the one garment class or type its label_names name);
    garment_mask (V,) bool: vertices carrying a garment label considered (all for a
    garment-only scan); template_name: '' or as given (checked); height_m: Y extent of the
    vertices the triangles use (of the cleaned scan when the scan as given looked implausible
    and was cleaned to be judged); warnings: what the checks found that the caller should know
    (label values the label map does not name), after raw.warnings in ScanData.warnings. The
    request (units, up, label, requested_garment_type, options, label_map) is kept so
    load_scan(checked) preprocesses exactly this scan."""
    raw: RawScan
    transform: ScanTransform
    vertices: np.ndarray
    faces: np.ndarray
    garment_label: int | None
    garment_class: str | None
    garment_type: str | None
    garment_mask: np.ndarray
    template_name: str
    height_m: float
    label: object = None
    requested_garment_type: str | None = None
    options: object = None
    label_map: LabelMap | None = None
    warnings: tuple[str, ...] = ()   # what the checks found that the caller should know (unnamed labels)

    @property
    def labels(self) -> np.ndarray | None:
        return self.raw.labels

    @property
    def label_names(self) -> dict[int, str]:
        return dict(self.label_map.classes) if self.label_map is not None else {}

    @property
    def source(self) -> str:
        return self.raw.source

    @property
    def source_units(self) -> str:
        return self.transform.units

    @property
    def source_up_axis(self) -> str:
        return self.transform.up

    @property
    def garment_faces(self) -> np.ndarray:
        """(Fg, 3) faces whose three vertices are all in garment_mask."""
        return self.faces[self.garment_mask[self.faces].all(axis=1)]


def check_template(template_name, known_templates=None) -> str:
    """'' (the garment type's built-in template), an existing template file (a path: a separator
    or a .obj/.json/.yaml suffix), or a built-in name (checked against known_templates when
    given). Returns the name stripped; raises UnknownTemplateError."""
    t = str(template_name or "").strip()
    if not t:
        return ""
    looks_like_path = "/" in t or "\\" in t or pathlib.Path(t).suffix.lower() in TEMPLATE_FILE_SUFFIXES
    if looks_like_path:
        try:
            exists = pathlib.Path(t).is_file()
        except (OSError, ValueError):  # a name too long or unrepresentable for the OS
            exists = False
        if not exists:
            raise UnknownTemplateError(f"template_name: template file {t!r} does not exist")
    elif known_templates is not None and t not in known_templates:
        raise UnknownTemplateError(f"template_name: unknown built-in template {t!r}; known: {sorted(known_templates)}")
    return t


def _unknown_type(garment_type, lmap: LabelMap) -> UnknownGarmentTypeError:
    return UnknownGarmentTypeError(f"garment type '{garment_type}' is not known (classes: "
                                   f"{', '.join(lmap.garment_openings)}; types: {', '.join(lmap.garment_types)})")


def choose_garment(raw_labels: np.ndarray, lmap: LabelMap, label=None, garment_type=None,
                   several_ok: bool = False) -> tuple[int | None, str | None, list[int]]:
    """The garment label among per-vertex labels: (value, class, candidate values).

    label: a class name or value (must be a garment, or garment_type gives the class);
    otherwise the only garment label present, or the one matching garment_type. Several
    candidates: NoGarmentError, or (None, None, candidates) with several_ok. Raises LabelError
    (unknown label or type, a label that is not a garment), NoGarmentError (none present) or
    GarmentTypeMissingError (no type given and the present names are no garment names the
    label map knows, e.g. label_names ['body', 'garment'])."""
    present = np.unique(raw_labels)
    listing = ", ".join(f"{lmap.name_of(v)} ({int(v)}): {int(np.count_nonzero(raw_labels == v))}"
                        for v in present)
    type_class = lmap.garment_class(garment_type) if garment_type else None
    if garment_type and type_class is None:
        raise _unknown_type(garment_type, lmap)
    if label is not None:
        value = lmap.value_of(label)
        candidates = [value]
    else:
        garments = [int(v) for v in present if lmap.garment_class(lmap.name_of(v)) is not None]
        if type_class is not None:
            garments = [v for v in garments if lmap.garment_class(lmap.name_of(v)) == type_class]
        if not garments:
            unknown = [lmap.classes[int(v)] for v in present if int(v) in lmap.classes
                       and lmap.garment_class(lmap.classes[int(v)]) is None
                       and not lmap.is_non_garment(lmap.classes[int(v)])]
            if unknown and not garment_type:
                raise GarmentTypeMissingError(
                    f"no label name is a garment class or type the label map knows, so the garment "
                    f"type is needed (garment_type not given; unknown names: {', '.join(map(repr, unknown))}; "
                    f"classes: {', '.join(lmap.garment_openings)}; types: {', '.join(lmap.garment_types)}; "
                    f"vertices per label: {listing})")
            raise NoGarmentError("no garment label present in the scan"
                                 + (f" for garment type '{garment_type}'" if garment_type else "")
                                 + f": no vertex carries a garment label (vertices per label: {listing})")
        if len(garments) > 1:
            if several_ok:
                return None, None, garments
            raise NoGarmentError(f"several garments in the scan ({', '.join(lmap.name_of(v) for v in garments)}): "
                                 f"choose one with label= / --label")
        value = garments[0]
        candidates = garments
    name = f"'{lmap.name_of(value)}' ({value})" if value in lmap.classes else f"{value} (not in the label map)"
    if not np.any(raw_labels == value):   # before its class: a label the scan lacks is the problem to name
        raise NoGarmentError(f"no vertices with label {name} (vertices per label: {listing})")
    cls = type_class or lmap.garment_class(lmap.name_of(value))
    if cls is None:
        raise LabelError(f"label {name} is not a garment class ({', '.join(lmap.garment_openings)}): "
                         f"give the garment type")
    return value, cls, candidates


def unknown_labels(labels: np.ndarray, lmap: LabelMap, garment_values, source: str) -> list[str]:
    """Label values the label map does not name (other than the garment's, which label= may give
    by value): [] when there are none, a warning naming them, their vertex counts and what is done
    with them (nothing: neither body nor garment), or LabelError when together they label more
    than UNKNOWN_LABEL_MAX_FRACTION of the vertices (a body labelled 9 was dropped without a word
    and the scan fitted as garment-only, 1.58 cm Chamfer against 1.20). O(V log V)."""
    vals, counts = np.unique(labels, return_counts=True)
    skip = {int(v) for v in garment_values}
    unknown = [(int(v), int(c)) for v, c in zip(vals, counts) if int(v) not in lmap.classes and int(v) not in skip]
    if not unknown:
        return []
    n = len(labels)
    total = sum(c for _, c in unknown)
    listing = ", ".join(f"{v}: {c} vertices ({100 * c / n:.1f}%)" for v, c in unknown)
    known = ", ".join(f"{k}: {v}" for k, v in sorted(lmap.classes.items()))
    how = ("relabel them with values of the label map, or name them: the scan's class names (label_names, value k "
           "→ label_names[k]: a SegmentedScan message's, or scan_from_arrays(..., label_names=)) or a label map that "
           "lists them (label_map=, the classes of config/labels.yaml; 'body' for the body)")
    if total > UNKNOWN_LABEL_MAX_FRACTION * n:
        raise LabelError(f"{source}: label value(s) not in the label map ({known}) label {total} of the {n} vertices "
                         f"({100 * total / n:.1f}%, more than {100 * UNKNOWN_LABEL_MAX_FRACTION:g}%; {listing}): "
                         f"unnamed, they would be used neither as body nor as garment and the scan fitted from the "
                         f"rest alone — {how}")
    return [f"{source}: label value(s) not in the label map ({known}): {listing}, of the {n} vertices as given: "
            f"used neither as body (the body fit) nor as garment; if they are, {how}"]


def garment_only_class(source: str, lmap: LabelMap, label=None, garment_type=None,
                       label_names=None) -> tuple[str, str]:
    """(garment class, garment type) of a scan without labels: needs a known garment type and
    no label. Without a type, label_names (a message may carry them with no labels) that name
    exactly one garment class or type give it (['body', 'tshirt'] → 'tshirt')."""
    if garment_type and lmap.garment_class(garment_type) is None:
        raise _unknown_type(garment_type, lmap)
    if label is not None:
        raise LabelError(f"{source}: the scan has no per-vertex labels, so label={label!r} "
                         f"cannot select a garment (give the garment type instead)")
    if not garment_type and label_names:
        named = sorted({g for g in map(lmap.canonical_garment_name, label_names) if g is not None})
        if len(named) == 1:
            garment_type = named[0]
    if not garment_type:
        raise GarmentTypeMissingError(f"{source}: a garment-only scan (no per-vertex labels) needs the "
                                      f"garment type (garment_type not given; e.g. garment_type='tshirt' / --garment)")
    return lmap.garment_class(garment_type), garment_type


def _n_vertices(vertices) -> int:
    """Vertex count of (N, 3) or flat (3N,) arrays before they are checked (0 if not an array)."""
    try:
        return int(np.size(vertices)) // 3
    except (TypeError, ValueError):
        return 0


def _raw_scan(scan, max_vertices, label_map: LabelMap | None = None):
    """(RawScan, request overrides from a message dict) from any input load_scan accepts.
    label_map: the one a file's per-face labels are converted with (which labels are garments;
    None: config/labels.yaml). A RawScan given keeps its warnings (what reading it did)."""
    def limit(n):
        if max_vertices is not None and n > max_vertices:
            raise TooLargeError(f"vertices: {n} vertices exceed the limit of {max_vertices}")
    if isinstance(scan, RawScan):
        limit(len(scan.vertices))
        # a RawScan may be made by hand: checked as arrays are (O(V + F))
        checked = scan_from_arrays(scan.vertices, scan.faces, scan.labels, scan.label_names, scan.source)
        notes = scan.warnings
        if isinstance(notes, str):   # one warning given as a string, not a tuple of them
            notes = (notes,)
        return dataclasses.replace(checked, warnings=tuple(str(w) for w in (notes or ()))), {}
    if isinstance(scan, (str, pathlib.Path)):
        raw = read_scan_file(scan, label_map=label_map)
        limit(len(raw.vertices))
        return raw, {}
    if isinstance(scan, dict):
        limit(_n_vertices(scan.get("vertices")))
        return scan_from_message(scan), {"units": scan.get("units"), "up": scan.get("up_axis"),
                                         "garment_type": scan.get("garment_type"),
                                         "template_name": scan.get("template_name")}
    if isinstance(scan, (tuple, list)) and len(scan) in (2, 3):
        limit(_n_vertices(scan[0]))
        return scan_from_arrays(*scan), {}
    raise ScanFormatError(f"scan: expected a path, RawScan, (vertices, faces[, labels]) or a "
                          f"message dict, got {type(scan).__name__}")


def check_scan(scan, units: str = "m", up: str = "y", label=None, garment_type: str | None = None,
               template_name: str = "", options=None, label_map: LabelMap | None = None,
               max_vertices: int | None = None, known_templates=None) -> CheckedScan:
    """The checks that need no cleaning (module docstring), on any input load_scan accepts: a
    file path, a RawScan, (vertices, faces[, labels]) in scan units, or the dict of
    diffavatar_ros.convert.msg_to_arrays (its units, up_axis, garment_type and template_name
    fill in the arguments left at their defaults). options: ScanOptions (default: the
    config's); max_vertices: size limit (None: none). Raises the ScanError subclass naming the
    first problem found."""
    from .preprocess import ScanOptions  # the options live with the preprocessing
    base_map = label_map or LabelMap.load()
    raw, req = _raw_scan(scan, max_vertices, base_map)
    units = req.get("units") or units
    up = req.get("up") or up
    garment_type = garment_type or req.get("garment_type") or None
    template_name = template_name or req.get("template_name") or ""
    opt = options or ScanOptions.from_config()
    lmap = base_map
    if raw.label_names:
        lmap = lmap.with_names(raw.label_names)

    tf = ScanTransform.from_options(units, up)
    if garment_type and lmap.garment_class(garment_type) is None:
        raise _unknown_type(garment_type, lmap)
    template = check_template(template_name, known_templates)

    n = len(raw.vertices)
    V = np.ascontiguousarray(tf.to_core(raw.vertices))
    F = raw.faces
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    origin = centring_origin(V[used]) if used.any() else np.zeros(3)
    if origin.any():   # far from the file's origin: the core frame centred on the subject (frame.py)
        tf = tf.shifted(origin)
        V = np.ascontiguousarray(tf.to_core(raw.vertices))
    Vu = V[used]
    try:
        height = check_plausible_size(Vu, tf, opt.min_height, opt.max_height)
    except ImplausibleSizeError:
        # The rule is the size once floating fragments are dropped (a far fragment must not
        # make a scan implausible, and the message gives the cleaned size): clean and judge
        # that, as preprocessing does. Costly (KD-tree, mesh graph), so only for a scan that
        # looks implausible as given; a cleaned scan is never larger than the scan as given.
        from .preprocess import clean_scan
        Vc, _, _ = clean_scan(raw, V, opt)
        height = check_plausible_size(Vc, tf, opt.min_height, opt.max_height)

    area = cleaning.triangle_areas(V, F)
    repeated = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    if (repeated | (area <= opt.merge_tolerance ** 2)).all():
        raise DegenerateScanError(f"{raw.source}: all {len(F)} triangles are degenerate (zero area "
                                  f"or a repeated vertex)")
    diag = float(np.linalg.norm(Vu.max(axis=0) - Vu.min(axis=0)))
    total = float(area.sum())
    if total <= MIN_AREA_RATIO * diag * diag:
        raise DegenerateScanError(f"{raw.source}: the surface is degenerate: total area {total:.3g} m² "
                                  f"for a {diag:.3g} m extent (all triangles collinear or collapsed)")
    notes = []
    if raw.labels is None:
        cls, gtype = garment_only_class(raw.source, lmap, label, garment_type, raw.label_names)
        value, mask = None, np.ones(n, bool)
    else:
        value, cls, candidates = choose_garment(raw.labels, lmap, label, garment_type, several_ok=True)
        mask = raw.labels == value if value is not None else np.isin(raw.labels, candidates)
        gtype = garment_type or (lmap.name_of(value) if value is not None else None)
        notes = unknown_labels(raw.labels, lmap, candidates, raw.source)
    gtype = lmap.canonical_garment_name(gtype) if gtype else None

    return CheckedScan(raw, tf, V, np.ascontiguousarray(F, dtype=np.int32), value, cls, gtype, mask, template,
                       height, label, garment_type, opt, lmap, tuple(notes))
