"""Reading segmented scans: PLY (ascii or binary, per-vertex `label` property), OBJ (and any
other triangle format trimesh reads, without labels), plain arrays, and the flat arrays of a
ROS SegmentedScan message. Everything is validated here, in the scan's own units and frame;
conversion to the core frame happens in preprocessing."""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

from .errors import (EmptyScanError, FaceIndexError, LabelError, NonFiniteError,
                     ScanFormatError, VertexArrayError)

#: PLY vertex properties read as the per-vertex label, first match wins (any letter case).
LABEL_PROPERTIES = ("label", "labels")
#: PLY vertex property names other tools give a segmentation: without a `label`, such a scan is
#: not read as garment-only (its body would become garment) but refused, naming the property.
SEGMENTATION_PROPERTIES = ("class", "classes", "class_id", "label_id", "segment", "segments", "segment_id",
                           "segmentation", "semantic", "semantics", "semantic_id", "part", "parts", "part_id",
                           "category", "category_id", "seg")
#: Scan units; a coordinate this large is garbage (a binary file read with the wrong layout), and
#: the squared distances of cleaning would overflow.
MAX_COORDINATE = 1e100


@dataclass(frozen=True)
class RawScan:
    """A validated scan in its own frame and units.

    vertices: (V, 3) float64 (scan units); faces: (F, 3) int64 indices into vertices;
    labels: (V,) int64 per-vertex class values, or None for a garment-only scan;
    label_names: the scan's own class names (label value k → label_names[k]) or None to use
    config/labels.yaml; source: where it came from (file path or 'arrays'), for messages.
    """
    vertices: np.ndarray
    faces: np.ndarray
    labels: np.ndarray | None = None
    label_names: tuple[str, ...] | None = None
    source: str = "arrays"


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
            if not np.issubdtype(La.dtype, np.integer):
                if not np.issubdtype(La.dtype, np.floating) or not np.all(np.isfinite(La)) \
                        or np.any(np.mod(La, 1) != 0):
                    raise LabelError(f"{source}: labels must be integers, got dtype {La.dtype}")
            L = np.ascontiguousarray(La, dtype=np.int64)
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


def _ply_labels(mesh, source: str) -> np.ndarray | None:
    """The per-vertex labels of a PLY read by trimesh: its LABEL_PROPERTIES property, or None
    (garment-only). LabelError when it has none but a property named as a segmentation is."""
    raw = (mesh.metadata or {}).get("_ply_raw", {}).get("vertex", {}).get("data")
    if raw is None:
        return None
    if getattr(raw, "dtype", None) is not None and raw.dtype.names:
        names = list(raw.dtype.names)
    else:
        names = list(getattr(raw, "keys", lambda: ())())
    by_lower = {str(n).lower(): n for n in names}
    for prop in LABEL_PROPERTIES:
        if prop in by_lower:
            return np.asarray(raw[by_lower[prop]]).reshape(-1)
    seg = [n for n in names if str(n).lower() in SEGMENTATION_PROPERTIES]
    if seg:
        raise LabelError(f"{source}: no per-vertex 'label' property, but one named {seg[0]!r}: if it holds the "
                         f"segmentation, rename it 'label' (its values as config/labels.yaml names the classes); "
                         f"if the scan is garment-only, remove it — read as garment-only, every vertex (a body "
                         f"too) would be taken for the garment")
    return None


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


def read_scan_file(path: str | pathlib.Path) -> RawScan:
    """A RawScan from a mesh file. PLY: the per-vertex `label` property (if present) becomes the
    labels; OBJ (own reader: vertices exactly as stored, seams split in the file are merged
    later, in preprocessing) and other formats trimesh reads: garment-only (labels None)."""
    import trimesh
    p = pathlib.Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir():
        raise ScanFormatError(f"{p}: is a directory, not a mesh file")
    if p.suffix.lower() == ".obj":
        V, F = read_obj(p)
        return scan_from_arrays(V, F, None, None, source=str(p))
    try:
        m = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise ScanFormatError(f"{p}: cannot be read as a triangle mesh ({type(exc).__name__}: {exc})") from None
    V = np.asarray(getattr(m, "vertices", np.zeros((0, 3))))
    F = np.asarray(getattr(m, "faces", np.zeros((0, 3), np.int64)))
    labels = None
    if p.suffix.lower() == ".ply":
        _check_ply_counts(p, len(V), len(F))
        labels = _ply_labels(m, str(p))
    return scan_from_arrays(V, F, labels, None, source=str(p))


def _ply_header(path: pathlib.Path) -> tuple[str, dict[str, int], int] | None:
    """(format, {element name: count}, offset of the body) of a PLY file, or None if there is
    no readable header."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except OSError:
        return None
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return None
    fmt, counts = "", {}
    for line in head[:end].decode("latin-1").splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0] == "format":
            fmt = parts[1]
        if len(parts) == 3 and parts[0] == "element" and parts[2].isdigit():
            counts[parts[1]] = int(parts[2])
    return fmt, counts, head.index(b"\n", end) + 1 if b"\n" in head[end:] else len(head)


def _check_ply_counts(path: pathlib.Path, n_read: int, f_read: int) -> None:
    """What trimesh read against what the header declares: a point cloud, or a truncated file
    or a header that does not match its data. trimesh reads such an ascii file without an error
    but with some of the vertices and no faces, or with faces made of misaligned numbers; an
    ascii body has one line per element."""
    header = _ply_header(path)
    if header is None:
        return
    fmt, counts, body_at = header
    nv, nf = counts.get("vertex", 0), counts.get("face", 0)
    if nv and not nf:
        raise EmptyScanError(f"{path}: the scan has no triangles: the header declares {nv} vertices and no "
                             f"faces (a point cloud?)")
    lines = None
    if fmt == "ascii":
        with open(path, "rb") as fh:
            fh.seek(body_at)
            lines = sum(1 for line in fh if line.strip())
    if n_read != nv or (nf and not f_read) or (lines is not None and lines != sum(counts.values())):
        body = f" in {lines} lines" if lines is not None else ""
        raise ScanFormatError(f"{path}: the header declares {nv} vertices and {nf} faces, but {n_read} vertices "
                              f"and {f_read} triangles were read{body}: the file is truncated or its header does "
                              f"not match its data")


def scan_from_message(arrays: dict) -> RawScan:
    """A RawScan from diffavatar_ros.convert.msg_to_arrays(msg): flat float32 vertices, flat
    uint32 faces, uint8 labels (empty: garment-only) and label_names (empty: the label map)."""
    for key, err in (("vertices", VertexArrayError), ("faces", FaceIndexError)):
        if arrays.get(key) is None:
            raise err(f"message: no '{key}' array")
    return scan_from_arrays(arrays["vertices"], arrays["faces"], arrays.get("labels"),
                            arrays.get("label_names") or None,
                            source=f"message {arrays.get('job_id') or ''}".strip())
