"""Validation of a segmented scan before recovery, shared by the CLI and the ROS node.

`validate_scan(...)` takes the raw fields of a scan (flat or shaped arrays, as they come from a
SegmentedScan message or a file), checks everything a recovery relies on, and returns a
`Scan` in the core's frame: metres, Y up. Every problem raises a subclass of `ScanError`
(itself a `ValueError`) whose message names the field and the problem, so callers map the
class to their own error codes (the node: AvatarAssets.ERROR_<cls.code>) without parsing text.

Pure numpy: no ROS, no C++ call, cheap (O(V + F)).
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

#: Length units a scan may state, with their size in metres.
UNITS = {"m": 1.0, "cm": 0.01}
#: Up axes a scan may state ("" means the default, "y").
UP_AXES = ("y", "z")
#: Garment types the recovery knows (the built-in templates), with accepted spellings.
GARMENT_TYPES = {
    "tshirt": "tshirt", "t-shirt": "tshirt", "t_shirt": "tshirt",
    "shirt": "shirt", "longsleeve": "shirt", "long-sleeve-shirt": "shirt", "long_sleeve_shirt": "shirt",
    "polo": "polo",
    "dress": "dress",
    "skirt": "skirt",
}
#: Label names that are not garment (everything else in label_names is garment).
NON_GARMENT_LABELS = frozenset({"body", "skin", "hair", "face", "hands", "shoes", "background", "unlabeled", "unknown"})
#: Plausible extent of a scan: the bounding-box diagonal in metres after unit conversion.
#: A clothed person is about 2 m; a garment alone at least a few decimetres. A scan in mm or
#: cm declared as metres is 100-1000x off and falls outside.
DIAGONAL_RANGE_M = (0.1, 5.0)


class ScanError(ValueError):
    """A scan that cannot be recovered from; `code` names the problem (AvatarAssets.ERROR_<code>)."""
    code = "BAD_OPTION"


class EmptyMeshError(ScanError):
    code = "EMPTY_MESH"


class NonFiniteError(ScanError):
    code = "NON_FINITE"


class FaceIndexError(ScanError):
    code = "BAD_FACE_INDEX"


class VertexArrayError(ScanError):
    code = "BAD_VERTEX_ARRAY"


class LabelsError(ScanError):
    code = "BAD_LABELS"


class NoGarmentError(ScanError):
    code = "NO_GARMENT"


class UnknownGarmentTypeError(ScanError):
    code = "UNKNOWN_GARMENT_TYPE"


class UnknownTemplateError(ScanError):
    code = "UNKNOWN_TEMPLATE"


class ImplausibleSizeError(ScanError):
    code = "IMPLAUSIBLE_SIZE"


class TooLargeError(ScanError):
    code = "TOO_LARGE"


class BadOptionError(ScanError):
    code = "BAD_OPTION"


@dataclass
class Scan:
    """A validated scan in the core's frame.

    vertices: (V, 3) float64, metres, Y up; faces: (F, 3) int32 (triangles with a repeated
    index or zero area are kept: they are common in scans and harmless to distance queries);
    labels: (V,) uint8 or None for a garment-only scan; garment_mask: (V,) bool, True for
    garment vertices (all True for a garment-only scan); garment_type: canonical name (see
    GARMENT_TYPES); template_name: as given ("" = the garment type's built-in template);
    source_units / source_up_axis: what the scan stated (the conversion applied)."""
    vertices: np.ndarray
    faces: np.ndarray
    labels: np.ndarray | None
    label_names: list
    garment_mask: np.ndarray
    garment_type: str
    template_name: str
    source_units: str
    source_up_axis: str

    @property
    def garment_faces(self) -> np.ndarray:
        """(Fg, 3) faces whose three vertices are all garment."""
        return self.faces[self.garment_mask[self.faces].all(axis=1)]


def _numeric(name: str, a, dtype) -> np.ndarray:
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError) as exc:
        raise VertexArrayError(f"{name}: not an array ({exc})") from None
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise (VertexArrayError if name == "vertices" else FaceIndexError if name == "faces" else LabelsError)(
            f"{name}: expected numbers, got dtype {arr.dtype}")
    return arr


def _vertices(vertices) -> np.ndarray:
    V = _numeric("vertices", vertices, np.float64)
    if V.ndim == 1:
        if V.size % 3:
            raise VertexArrayError(f"vertices: flat array length {V.size} is not a multiple of 3 (xyz interleaved)")
        V = V.reshape(-1, 3)
    elif V.ndim != 2 or V.shape[1] != 3:
        raise VertexArrayError(f"vertices: expected shape (V, 3) or flat (3V,), got {V.shape}")
    if V.shape[0] == 0:
        raise EmptyMeshError("vertices: the scan has no vertices")
    V = V.astype(np.float64)
    finite = np.isfinite(V).all(axis=1)
    if not finite.all():
        bad = np.flatnonzero(~finite)
        raise NonFiniteError(f"vertices: {bad.size} vertex(es) have NaN or Inf coordinates (first: vertex {int(bad[0])})")
    return V


def _faces(faces, n_vertices: int) -> np.ndarray:
    F = _numeric("faces", faces, np.int64)
    if F.ndim == 1:
        if F.size % 3:
            raise FaceIndexError(f"faces: flat array length {F.size} is not a multiple of 3 (triangles)")
        F = F.reshape(-1, 3)
    elif F.ndim != 2 or F.shape[1] != 3:
        raise FaceIndexError(f"faces: expected shape (F, 3) or flat (3F,), got {F.shape}")
    if F.shape[0] == 0:
        raise EmptyMeshError("faces: the scan has no triangles")
    if not np.issubdtype(F.dtype, np.integer):
        if not np.all(np.isfinite(F)) or not np.all(np.mod(F, 1) == 0):
            raise FaceIndexError(f"faces: indices must be integers, got dtype {F.dtype}")
    lo, hi = F.min(), F.max()
    if lo < 0 or hi >= n_vertices:
        bad = np.flatnonzero(((F < 0) | (F >= n_vertices)).any(axis=1))
        raise FaceIndexError(f"faces: {bad.size} face(s) index outside [0, {n_vertices}) "
                             f"(first: face {int(bad[0])} = {F[bad[0]].tolist()})")
    return np.ascontiguousarray(F, dtype=np.int32)


def _labels(labels, label_names, n_vertices: int):
    names = [str(n) for n in (label_names or [])]
    if labels is None:
        return None, names, np.ones(n_vertices, bool)
    L = _numeric("labels", labels, np.int64).ravel()
    if L.size == 0:  # garment-only scan
        return None, names, np.ones(n_vertices, bool)
    if L.size != n_vertices:
        raise LabelsError(f"labels: {L.size} labels for {n_vertices} vertices (one per vertex, or none)")
    if not names:
        raise LabelsError("label_names: labels are given but label_names is empty")
    if not np.issubdtype(L.dtype, np.integer) or L.min() < 0 or L.max() >= len(names):
        raise LabelsError(f"labels: values must index label_names (0..{len(names) - 1}), "
                          f"got range [{L.min()}, {L.max()}]")
    garment_ids = [k for k, n in enumerate(names) if n.strip().lower() not in NON_GARMENT_LABELS]
    mask = np.isin(L, garment_ids)
    if not mask.any():
        raise NoGarmentError(f"labels: no vertex carries a garment label (label_names = {names}; "
                             f"non-garment names: {sorted(NON_GARMENT_LABELS)})")
    return np.ascontiguousarray(L, dtype=np.uint8), names, mask


def _garment_type(garment_type: str, names: list) -> str:
    g = (garment_type or "").strip().lower()
    if g:
        if g not in GARMENT_TYPES:
            raise UnknownGarmentTypeError(f"garment_type: unknown {garment_type!r}; known: {sorted(set(GARMENT_TYPES.values()))}")
        return GARMENT_TYPES[g]
    inferred = {GARMENT_TYPES[n.strip().lower()] for n in names if n.strip().lower() in GARMENT_TYPES}
    if len(inferred) == 1:
        return inferred.pop()
    raise UnknownGarmentTypeError(
        "garment_type: not given and " + (f"ambiguous among labels {sorted(inferred)}" if inferred else
                                          f"no label name is a known garment type ({sorted(set(GARMENT_TYPES.values()))})"))


def _template(template_name: str, known_templates) -> str:
    t = (template_name or "").strip()
    if not t:
        return ""
    looks_like_path = "/" in t or "\\" in t or pathlib.Path(t).suffix.lower() in (".obj", ".json", ".yaml", ".yml")
    if looks_like_path:
        if not pathlib.Path(t).is_file():
            raise UnknownTemplateError(f"template_name: template file {t!r} does not exist")
    elif known_templates is not None and t not in known_templates:
        raise UnknownTemplateError(f"template_name: unknown built-in template {t!r}; known: {sorted(known_templates)}")
    return t


def validate_scan(vertices, faces, labels=None, label_names=(), *, units: str = "m", up_axis: str = "y",
                  garment_type: str = "", template_name: str = "", max_vertices: int = 2_000_000,
                  known_templates=None) -> Scan:
    """Checks a scan and returns it as a `Scan` in metres, Y up.

    vertices: (V, 3) or flat xyz-interleaved (3V,) in `units` ("m" or "cm"; "" = "m");
    faces: (F, 3) or flat (3F,) 0-based indices; labels: (V,) indices into label_names, or
    None/empty for a garment-only scan; up_axis: "y" or "z" ("" = "y"; Z-up (x, y, z) maps to
    Y-up (x, z, -y)); garment_type: a GARMENT_TYPES name, or "" to infer it from a label name;
    template_name: "" (the built-in template of the type), a template file path (must exist),
    or a built-in name (checked against known_templates when given); max_vertices: V limit.

    Raises a ScanError subclass naming the problem (checked in this order: options, vertex
    array, size limit, non-finite values, faces, labels, garment type, template, extent).
    """
    u = (units or "m").strip().lower()
    if u not in UNITS:
        raise BadOptionError(f"units: unknown {units!r}; expected one of {sorted(UNITS)}")
    up = (up_axis or "y").strip().lower()
    if up not in UP_AXES:
        raise BadOptionError(f"up_axis: unknown {up_axis!r}; expected one of {list(UP_AXES)}")
    try:
        n_raw = int(np.size(vertices)) // 3
    except (TypeError, ValueError):
        n_raw = 0
    if n_raw > max_vertices:
        raise TooLargeError(f"vertices: {n_raw} vertices exceed the limit of {max_vertices}")
    V = _vertices(vertices)
    F = _faces(faces, V.shape[0])
    L, names, mask = _labels(labels, label_names, V.shape[0])
    g = _garment_type(garment_type, names)
    t = _template(template_name, known_templates)

    V = V * UNITS[u]
    if up == "z":
        V = np.column_stack([V[:, 0], V[:, 2], -V[:, 1]])
    V = np.ascontiguousarray(V)
    used = np.unique(F)
    diag = float(np.linalg.norm(V[used].max(axis=0) - V[used].min(axis=0)))
    lo, hi = DIAGONAL_RANGE_M
    if not lo <= diag <= hi:
        raise ImplausibleSizeError(f"vertices: bounding-box diagonal {diag:.4g} m (units {u!r}) is outside the "
                                   f"plausible range [{lo}, {hi}] m for a clothed person or garment; "
                                   f"are the units right?")
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    area = 0.5 * float(np.linalg.norm(np.cross(e1, e2), axis=1).sum())
    if area <= 1e-6 * diag * diag:
        raise ImplausibleSizeError(f"faces: the surface is degenerate (total area {area:.3g} m^2 for a "
                                   f"{diag:.3g} m extent: all triangles collinear or collapsed)")
    return Scan(V, F, L, names, mask, g, t, u, up)
