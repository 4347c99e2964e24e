"""Reading segmented scans: PLY (ascii or binary, faces and/or triangle strips, per-vertex `label`
property, or per-face `label` converted to per-vertex labels), OBJ (and any other triangle format trimesh reads,
without labels; a file's format is its content's, a PLY named .obj is read as PLY), plain
arrays, and the flat arrays of a ROS SegmentedScan message (a PLY's geometry by ply_reader.py, its
labels here). Everything is validated here, in the scan's own units and frame; conversion to the
core frame happens in preprocessing."""
from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass

import numpy as np

from .errors import (EmptyScanError, FaceIndexError, LabelError, NonFiniteError,
                     ScanFormatError, VertexArrayError)
from .ply_reader import PlyMesh, fan_polygons, index_lists, ply_element, read_ply

#: PLY vertex properties read as the per-vertex label, first match wins (any letter case).
LABEL_PROPERTIES = ("label", "labels")
#: PLY vertex property names other tools give a segmentation: without a `label`, such a scan is
#: not read as garment-only (its body would become garment) but refused, naming the property.
SEGMENTATION_PROPERTIES = ("class", "classes", "class_id", "label_id", "segment", "segments", "segment_id",
                           "segmentation", "semantic", "semantics", "semantic_id", "part", "parts", "part_id",
                           "category", "category_id", "seg")
#: A class value (label) must lie in this range (int32's): a larger one is garbage (a float or a
#: uint64 read as a label), and is reported as given, never after a wrapping cast.
LABEL_RANGE = (-2 ** 31, 2 ** 31 - 1)
#: Scan units; a coordinate this large is garbage (a binary file read with the wrong layout), and
#: the squared distances of cleaning would overflow.
MAX_COORDINATE = 1e100


@dataclass(frozen=True)
class RawScan:
    """A validated scan in its own frame and units.

    vertices: (V, 3) float64 (scan units); faces: (F, 3) int64 indices into vertices;
    labels: (V,) int64 per-vertex class values, or None for a garment-only scan;
    label_names: the scan's own class names (label value k → label_names[k]) or None to use
    config/labels.yaml; source: where it came from (file path or 'arrays'), for messages;
    warnings: what reading it did that the caller should know (a PLY file named .obj read as
    PLY, per-face labels converted to per-vertex ones); preprocessing starts ScanData.warnings
    with them.
    """
    vertices: np.ndarray
    faces: np.ndarray
    labels: np.ndarray | None = None
    label_names: tuple[str, ...] | None = None
    source: str = "arrays"
    warnings: tuple[str, ...] = ()


def _as_rows(name: str, a, dtype_kind: str) -> np.ndarray:
    err = FaceIndexError if dtype_kind == "faces" else VertexArrayError
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError) as exc:
        raise err(f"{name}: not an array ({exc})") from None
    if arr.ndim == 1:  # flat interleaved (ROS message layout)
        if arr.size % 3:
            what = "triangles" if dtype_kind == "faces" else "xyz interleaved"
            raise err(f"{name}: flat array length {arr.size} is not a multiple of 3 ({what})")
        arr = arr.reshape(-1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise err(f"{name}: expected shape (N, 3) or flat (3N,), got {arr.shape}")
    return arr


def label_values(a: np.ndarray, name: str, element: str, source: str) -> np.ndarray:
    """Class values (1-D, any integer dtype, or floats holding integers) as int64, checked before
    the cast, which would wrap a value int64 cannot hold (1e30 → -9223372036854775808, a uint64
    2**64 − 1 → -1): a value that is no integer or outside LABEL_RANGE is reported as given,
    with the element (vertex / face) it belongs to. Raises LabelError."""
    lo, hi = LABEL_RANGE
    if np.issubdtype(a.dtype, np.integer):
        notint = np.zeros(a.shape, bool)
    elif np.issubdtype(a.dtype, np.floating):
        with np.errstate(invalid="ignore"):
            notint = ~np.isfinite(a) | (np.mod(a, 1) != 0)
    else:
        raise LabelError(f"{source}: {name} must be integers (class values), got dtype {a.dtype}")
    if notint.any():
        i = int(np.flatnonzero(notint)[0])
        raise LabelError(f"{source}: {name} must be integers (class values), got dtype {a.dtype} with "
                         f"{int(notint.sum())} value(s) that are not (first: {element} {i} = {a[i].item()!r})")
    out = (a < lo) | (a > hi)   # numpy compares mixed signed/unsigned and float/int exactly enough here
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise LabelError(f"{source}: {name}: {int(out.sum())} value(s) outside the range of a class value "
                         f"[{lo}, {hi}] (first: {element} {i} = {a[i].item()!r})")
    return np.ascontiguousarray(a, dtype=np.int64)


def scan_from_arrays(vertices, faces, labels=None, label_names=None, source: str = "arrays") -> RawScan:
    """A RawScan from arrays: vertices (V, 3) or flat (3V,) in scan units, faces (F, 3) or flat
    (3F,) 0-based, labels (V,) integers or None/empty (garment-only), label_names optional
    (given, every label value must index it). Raises VertexArrayError, EmptyScanError,
    NonFiniteError, FaceIndexError or LabelError naming the problem. Cost O(V + F)."""
    V = _as_rows("vertices", vertices, "vertices")
    F = _as_rows("faces", faces, "faces")
    if V.shape[0] == 0:
        raise EmptyScanError(f"{source}: the scan has no vertices")
    if F.shape[0] == 0:
        raise EmptyScanError(f"{source}: the scan has no triangles ({V.shape[0]} vertices)")
    if not (np.issubdtype(V.dtype, np.floating) or np.issubdtype(V.dtype, np.integer)):
        raise VertexArrayError(f"{source}: vertices must be numbers, got dtype {V.dtype}")
    V = np.ascontiguousarray(V, dtype=np.float64)
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        raise NonFiniteError(f"{source}: {int(bad.sum())} vertex/vertices have NaN or Inf "
                             f"coordinates (first: vertex {int(np.flatnonzero(bad)[0])})")
    huge = (np.abs(V) >= MAX_COORDINATE).any(axis=1)
    if huge.any():
        raise NonFiniteError(f"{source}: {int(huge.sum())} vertex/vertices have coordinates of magnitude "
                             f"≥ {MAX_COORDINATE:g} (first: vertex {int(np.flatnonzero(huge)[0])}): garbage, "
                             f"not a scan (a binary file read with the wrong layout?)")
    if not np.issubdtype(F.dtype, np.integer):
        if not np.issubdtype(F.dtype, np.floating) or not np.all(np.isfinite(F)) or np.any(np.mod(F, 1) != 0):
            raise FaceIndexError(f"{source}: face indices must be integers, got dtype {F.dtype}")
    out = (F < 0) | (F >= V.shape[0])   # before the cast, which would wrap a huge index
    if out.any():
        row = int(np.flatnonzero(out.any(axis=1))[0])
        raise FaceIndexError(f"{source}: {int(out.any(axis=1).sum())} face(s) index vertices outside "
                             f"[0, {V.shape[0]}) (first: face {row} = {F[row].tolist()})")
    F = np.ascontiguousarray(F, dtype=np.int64)
    L = None
    if labels is not None:
        La = np.asarray(labels)
        if La.size > 0:
            La = La.reshape(-1) if La.ndim == 2 and 1 in La.shape else La
            if La.ndim != 1 or La.shape[0] != V.shape[0]:
                raise LabelError(f"{source}: labels: {La.size} labels for {V.shape[0]} vertices: "
                                 f"expected one per vertex, shape ({V.shape[0]},), got {La.shape} "
                                 f"(or none for a garment-only scan)")
            L = label_values(La, "labels", "vertex", source)
    if isinstance(label_names, (str, bytes)):   # would be read as one name per character
        raise LabelError(f"{source}: label_names must be a list of class names (label value k → "
                         f"label_names[k]), got the string {label_names!r}")
    names = tuple(str(n) for n in label_names) if label_names else None
    if L is not None and names is not None:
        lo, hi = int(L.min()), int(L.max())
        if lo < 0 or hi >= len(names):
            raise LabelError(f"{source}: labels: values must index label_names (0..{len(names) - 1}: "
                             f"{', '.join(names)}), got range [{lo}, {hi}]")
    return RawScan(V, F, L, names, source)


def _ply_labels(elements: dict, source: str, face_labels: bool = False) -> np.ndarray | None:
    """The per-vertex labels of a PLY read by trimesh: its LABEL_PROPERTIES property, or None
    (garment-only, or per-face labels when face_labels). LabelError when it has none, nor
    per-face labels, but a property named as a segmentation."""
    raw, by_lower = ply_element(elements, "vertex")
    if raw is None:
        return None
    prop = _label_property(by_lower)
    if prop is not None:
        return np.asarray(raw[prop]).reshape(-1)
    if not face_labels:
        _refuse_other_segmentation(by_lower, source, "vertex")
    return None


def _label_property(by_lower: dict) -> str | None:
    """The element's label property (LABEL_PROPERTIES, first match, any letter case), or None."""
    return next((by_lower[q] for q in LABEL_PROPERTIES if q in by_lower), None)


def _refuse_other_segmentation(by_lower: dict, source: str, element: str) -> None:
    """LabelError when an element without a label property has one named as a segmentation
    (SEGMENTATION_PROPERTIES): read as garment-only, the body too would become the garment."""
    seg = [n for low, n in by_lower.items() if low in SEGMENTATION_PROPERTIES]
    if seg:
        raise LabelError(f"{source}: no per-{element} 'label' property, but a per-{element} one named {seg[0]!r}: "
                         f"if it holds the segmentation, rename it 'label' (its values as config/labels.yaml names "
                         f"the classes); if the scan is garment-only, remove it — read as garment-only, every "
                         f"{element} (a body too) would be taken for the garment")


def read_obj(path: pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    """(V (N, 3), F (M, 3)) of a Wavefront OBJ as stored: `v` lines in order, `f` polygons
    (v, v/vt, v//vn, v/vt/vn; negative = relative) fan-triangulated, everything else ignored.
    Index 0 and a relative index before the first vertex raise FaceIndexError naming the line;
    other indices are checked by the caller (an out-of-range index is reported, not fixed)."""
    verts, faces = [], []
    try:
        fh = open(path, encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ScanFormatError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    with fh:
        for ln, line in enumerate(fh, 1):
            parts = line.split()   # any whitespace separates (tabs, indented lines)
            if parts and parts[0] == "v":
                if len(parts) < 4:
                    raise ScanFormatError(f"{path}:{ln}: a vertex needs 3 coordinates: {line.strip()!r}")
                try:
                    verts.append((float(parts[1]), float(parts[2]), float(parts[3])))
                except ValueError:
                    raise ScanFormatError(f"{path}:{ln}: not a number in {line.strip()!r}") from None
            elif parts and parts[0] == "f":
                try:
                    idx = [int(tok.split("/")[0]) for tok in parts[1:]]
                except ValueError:
                    raise ScanFormatError(f"{path}:{ln}: bad face {line.strip()!r}") from None
                if len(idx) < 3:
                    raise ScanFormatError(f"{path}:{ln}: a face needs 3 or more vertices: {line.strip()!r}")
                n = len(verts)
                # 0 is no OBJ index, nor a relative one before the first vertex: reported with the
                # line as written (converted, it would name another index); a positive index past
                # the end is the caller's (a later `v` line may define it)
                bad = [i for i in idx if i == 0 or i < -n or i >= 2 ** 63]
                if bad:
                    raise FaceIndexError(f"{path}:{ln}: face vertex index {bad[0]} is invalid: OBJ indices "
                                         f"start at 1, negative ones count back from the {n} vertices read "
                                         f"so far: {line.strip()!r}")
                idx = [i - 1 if i > 0 else n + i for i in idx]
                faces.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
    return (np.asarray(verts, np.float64).reshape(-1, 3), np.asarray(faces, np.int64).reshape(-1, 3))


def _file_kind(path: pathlib.Path) -> str:
    """What the file's first bytes say it is: 'ply' (the `ply` magic line), 'binary' (NUL bytes
    early on: no text format such as OBJ), or 'text'."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise ScanFormatError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if head.startswith((b"ply\n", b"ply\r\n")):
        return "ply"
    return "binary" if b"\0" in head else "text"


def read_scan_file(path: str | pathlib.Path, label_map=None) -> RawScan:
    """A RawScan from a mesh file. PLY: the per-vertex `label` property (if present) becomes the
    labels; without one, a per-face `label` property is converted to per-vertex labels
    (face_labels.face_to_vertex_labels; which classes are garments: label_map, default
    config/labels.yaml); with both, the vertex labels are used (refused when the two disagree on
    more than FACE_LABEL_DISAGREEMENT of the faces). A PLY's triangles are its `face` element's
    (polygons triangulated; a face of fewer than 3 vertices is refused) and its `tristrips`
    element's (read_ply; a strip's `label` is its triangles' per-face label). OBJ (own reader: vertices exactly as stored,
    seams split in the file are merged later, in preprocessing) and other formats trimesh reads:
    garment-only (labels None). The format is the file's own: a file starting with the PLY magic
    line is read as PLY whatever its name (with a warning when the name says otherwise); a file
    named .ply without it, or a binary file named .obj, is refused naming the mismatch."""
    import trimesh
    p = pathlib.Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir():
        raise ScanFormatError(f"{p}: is a directory, not a mesh file")
    kind, suffix = _file_kind(p), p.suffix.lower()
    notes = []
    if kind == "ply" and suffix != ".ply":
        notes.append(f"{p}: read as PLY: the file starts with the PLY header although its name ends "
                     f"'{p.suffix or '(no suffix)'}'")
    elif suffix == ".ply" and kind != "ply":
        raise ScanFormatError(f"{p}: cannot be read as PLY: it does not start with the PLY header line 'ply' "
                              f"(named .ply, but {'binary' if kind == 'binary' else 'text'} of another "
                              f"format? save it with its own suffix)")
    if suffix == ".obj" and kind != "ply":
        if kind == "binary":
            raise ScanFormatError(f"{p}: cannot be read as OBJ: named .obj, but binary (an OBJ is text); "
                                  f"save it with its own format's suffix")
        V, F = read_obj(p)
        if not len(V) and p.stat().st_size > 0:
            raise ScanFormatError(f"{p}: cannot be read as OBJ: named .obj, but no line of it is an OBJ vertex "
                                  f"('v x y z'); save it with its own format's suffix")
        return scan_from_arrays(V, F, None, None, source=str(p))
    if kind != "ply":
        try:
            m = trimesh.load(str(p), force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise ScanFormatError(f"{p}: cannot be read as a triangle mesh ({type(exc).__name__}: {exc})") from None
        V = np.asarray(getattr(m, "vertices", np.zeros((0, 3))))
        F = np.asarray(getattr(m, "faces", np.zeros((0, 3), np.int64)))
        return scan_from_arrays(V, F, None, None, source=str(p))
    ply = read_ply(p)
    src = str(p)
    tri_has_labels = any(q in ply_element(ply.elements, e)[1] for q in LABEL_PROPERTIES for e in ("face", "tristrips"))
    labels = _ply_labels(ply.elements, src, face_labels=tri_has_labels)
    face_labels, Ff = _ply_face_labels(ply.elements, src, ply.face_triangles, has_vertex_labels=labels is not None)
    strip_labels = _ply_strip_labels(ply, src)
    F = np.concatenate([np.asarray(Ff, np.int64).reshape(-1, 3), ply.strip_triangles])
    if face_labels is not None or strip_labels is not None:
        parts = [(face_labels, len(Ff), "face"), (strip_labels, len(ply.strip_triangles), "tristrips")]
        unlabelled = [e for lab, k, e in parts if lab is None and k]
        if unlabelled:
            raise LabelError(f"{src}: the '{'tristrips' if unlabelled[0] == 'face' else 'face'}' element has a "
                             f"'label' property but the '{unlabelled[0]}' element has none: every triangle needs "
                             f"its label")
        face_labels = np.concatenate([np.asarray(lab).reshape(-1) for lab, k, _ in parts if lab is not None])
    raw = scan_from_arrays(ply.vertices, F, labels, None, source=src)
    if face_labels is not None:
        raw, note = _with_face_labels(raw, face_labels, label_map)
        notes.append(note)
    return dataclasses.replace(raw, warnings=tuple(notes)) if notes else raw


def _ply_strip_labels(ply: PlyMesh, source: str) -> np.ndarray | None:
    """Per-triangle labels of the strips' triangles (each its strip's `label`), or None."""
    raw, by_lower = ply_element(ply.elements, "tristrips")
    prop = _label_property(by_lower)
    if raw is None or prop is None:
        return None
    SL = np.asarray(raw[prop])
    if SL.dtype == object or SL.size != len(SL):
        raise LabelError(f"{source}: the per-strip property {prop!r} is not one value per strip")
    return SL.reshape(-1)[ply.strip_of]


#: With both per-vertex and per-face labels in a PLY, the vertex labels are used; the file is
#: refused when the face labels contradict them on more than this fraction of the faces whose
#: three vertex labels agree (two different segmentations: which one is meant cannot be told).
FACE_LABEL_DISAGREEMENT = 0.01


def _ply_face_labels(elements: dict, source: str, F: np.ndarray, has_vertex_labels: bool):
    """(per-face labels (F,) as stored or None, the faces they go with). trimesh triangulates
    polygons in its own order; then the faces are fanned here from the face element, in file
    order, one label per triangle of its polygon. A segmentation under another face property name
    (and no label anywhere) is refused as for vertices."""
    raw, by_lower = ply_element(elements, "face")
    if raw is None:
        return None, F
    prop = _label_property(by_lower)
    if prop is None:
        if not has_vertex_labels:
            _refuse_other_segmentation(by_lower, source, "face")
        return None, F
    try:
        FL = np.asarray(raw[prop])
        if FL.dtype == object:
            raise ValueError("a list per face")
        FL = FL.reshape(len(FL), -1)
        if FL.shape[1] != 1:
            raise ValueError(f"{FL.shape[1]} values per face")
        FL = FL[:, 0]
    except (ValueError, TypeError) as exc:
        raise LabelError(f"{source}: the per-face property {prop!r} is not one value per face ({exc})") from None
    if len(FL) == len(F):
        return FL, F
    # polygons (read_ply has refused any of fewer than 3 vertices): fanned in file order as
    # read_ply fans them when trimesh cannot, each triangle with its polygon's label
    polys = index_lists(raw, by_lower)
    if polys is None or len(polys[0]) != len(FL):
        raise LabelError(f"{source}: {len(FL)} per-face labels for {len(F)} triangles, and the face element's "
                         f"polygons cannot be matched to them")
    lengths, flat = polys
    return np.repeat(FL, lengths - 2), fan_polygons(lengths, flat)


def _with_face_labels(raw: RawScan, face_labels: np.ndarray, label_map) -> tuple[RawScan, str]:
    """The scan with per-vertex labels from its per-face ones (none given), or its own vertex
    labels checked against them; and the note for its warnings."""
    from .face_labels import face_to_vertex_labels
    from .labels import LabelMap
    src = raw.source
    FL = label_values(np.asarray(face_labels).reshape(-1), "per-face labels", "face", src)
    if raw.labels is not None:
        lf = raw.labels[raw.faces]
        agree = (lf[:, 0] == lf[:, 1]) & (lf[:, 1] == lf[:, 2])
        contra = agree & (lf[:, 0] != FL)
        n, m = int(contra.sum()), int(agree.sum())
        if n > FACE_LABEL_DISAGREEMENT * max(m, 1):
            i = int(np.flatnonzero(contra)[0])
            raise LabelError(f"{src}: per-vertex and per-face labels disagree on {n} of the {m} faces whose three "
                             f"vertex labels agree ({100 * n / m:.1f}%, more than {100 * FACE_LABEL_DISAGREEMENT:g}%; "
                             f"first: face {i}, vertex label {int(lf[i, 0])}, face label {int(FL[i])}): two different "
                             f"segmentations — remove the one that is not meant")
        return raw, (f"{src}: has per-vertex and per-face labels: the per-vertex ones are used (the per-face ones "
                     f"disagree on {n} of the {m} faces whose three vertex labels agree)")
    lmap = label_map if label_map is not None else LabelMap.load()
    conv = face_to_vertex_labels(raw.faces, FL, len(raw.vertices),
                                 lambda v: lmap.garment_class(lmap.name_of(v)) is not None)
    note = (f"{src}: per-face labels converted to per-vertex ones (a vertex takes its faces' label; a garment "
            f"label where garment and other faces meet, docs/scan.md)")
    if conv.faces_off:
        note += (f": {conv.faces_off} of {len(FL)} faces cannot keep their face label's garment region with "
                 f"per-vertex labels ({conv.missing} of the {conv.garment_faces} garment faces left out, "
                 f"{conv.extra} other faces taken in)")
    return dataclasses.replace(raw, labels=conv.labels), note


def scan_from_message(arrays: dict) -> RawScan:
    """A RawScan from diffavatar_ros.convert.msg_to_arrays(msg): flat float32 vertices, flat
    uint32 faces, uint8 labels (empty: garment-only) and label_names (empty: the label map)."""
    for key, err in (("vertices", VertexArrayError), ("faces", FaceIndexError)):
        if arrays.get(key) is None:
            raise err(f"message: no '{key}' array")
    return scan_from_arrays(arrays["vertices"], arrays["faces"], arrays.get("labels"),
                            arrays.get("label_names") or None,
                            source=f"message {arrays.get('job_id') or ''}".strip())
