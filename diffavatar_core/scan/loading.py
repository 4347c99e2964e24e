"""Reading segmented scans: PLY (ascii or binary, faces and/or triangle strips, per-vertex `label`
property, or per-face `label` converted to per-vertex labels), OBJ (and any other triangle format trimesh reads,
without labels; a file's format is its content's, a PLY named .obj is read as PLY), plain
arrays, and the flat arrays of a ROS SegmentedScan message. Everything is validated here, in the
scan's own units and frame; conversion to the core frame happens in preprocessing."""
from __future__ import annotations

import dataclasses
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


def _ply_element(elements: dict, element: str):
    """(the raw data of a PLY element as read (trimesh's `_ply_raw`, or _read_binary_ply's), {lower-case
    property name: name}), or (None, {})."""
    raw = (elements or {}).get(element, {}).get("data")
    if raw is None:
        return None, {}
    if getattr(raw, "dtype", None) is not None and raw.dtype.names:
        names = list(raw.dtype.names)
    else:
        names = list(getattr(raw, "keys", lambda: ())())
    return raw, {str(n).lower(): n for n in names}


def _ply_labels(elements: dict, source: str, face_labels: bool = False) -> np.ndarray | None:
    """The per-vertex labels of a PLY read by trimesh: its LABEL_PROPERTIES property, or None
    (garment-only, or per-face labels when face_labels). LabelError when it has none, nor
    per-face labels, but a property named as a segmentation."""
    raw, by_lower = _ply_element(elements, "vertex")
    if raw is None:
        return None
    for prop in LABEL_PROPERTIES:
        if prop in by_lower:
            return np.asarray(raw[by_lower[prop]]).reshape(-1)
    seg = [n for low, n in by_lower.items() if low in SEGMENTATION_PROPERTIES]
    if seg and not face_labels:
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
    (labels.face_to_vertex_labels; which classes are garments: label_map, default
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
    tri_has_labels = any(q in _ply_element(ply.elements, e)[1] for q in LABEL_PROPERTIES for e in ("face", "tristrips"))
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


@dataclass(frozen=True)
class PlyMesh:
    """The triangles of a PLY file: vertices (V, 3) float64 as stored; face_triangles (Ff, 3)
    int64, the `face` element's polygons triangulated (trimesh's order, or fanned in file order
    when trimesh could not read the file); strip_triangles (Fs, 3) int64 and strip_of (Fs,) (the
    strip each came from), the `tristrips` element's; elements: the raw elements read
    (element → {'data': ...}), for the label properties."""
    vertices: np.ndarray
    face_triangles: np.ndarray
    strip_triangles: np.ndarray
    strip_of: np.ndarray
    elements: dict

    @property
    def faces(self) -> np.ndarray:
        return np.concatenate([self.face_triangles, self.strip_triangles])


#: PLY scalar types → numpy (both the PLY 1.0 names and the sized ones).
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
#: PLY list properties that hold a face's / strip's vertex indices.
INDEX_PROPERTIES = ("vertex_indices", "vertex_index")


def _index_lists(raw, by_lower: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """(lengths (N,), the indices of all lists concatenated) of an element's vertex_indices list
    property (as trimesh or _read_binary_ply stored it: a 2-D array when all lists have one
    length, an object array of lists otherwise, a structured ('f0' count, 'f1' values) array),
    or None when it has none."""
    name = next((by_lower[q] for q in INDEX_PROPERTIES if q in by_lower), None)
    if name is None:
        return None
    a = raw[name]
    if getattr(a, "dtype", None) is not None and a.dtype.names and "f1" in a.dtype.names:
        a = a["f1"]
    a = np.asarray(a)
    if a.dtype == object:
        rows = [np.asarray(x).reshape(-1) for x in a]
        lengths = np.fromiter((len(r) for r in rows), np.int64, len(rows))
        flat = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        return lengths, flat
    a = a.reshape(len(a), -1)
    return np.full(len(a), a.shape[1], np.int64), a.reshape(-1)


def strips_to_triangles(flat: np.ndarray, lengths: np.ndarray, restart: int = -1):
    """Triangles of triangle strips (PLY `tristrips`, OpenGL GL_TRIANGLE_STRIP): in each strip, and
    anew after every `restart` index (-1), the k-th triangle of a run s is (s[k], s[k+1], s[k+2])
    for even k and (s[k+1], s[k], s[k+2]) for odd k, so all keep the first one's winding.
    Triangles with a repeated vertex (the degenerate ones that stitch strips together) are
    dropped. flat: the strips' indices concatenated; lengths (N,): each strip's length. Returns
    (triangles (T, 3) int64, strip index of each (T,)). O(total length)."""
    flat = np.asarray(flat, np.int64)
    lengths = np.asarray(lengths, np.int64)
    n = len(flat)
    strip = np.repeat(np.arange(len(lengths)), lengths)
    pos = np.arange(n)
    brk = flat == restart
    begins = np.zeros(n, bool)                          # a run begins at a strip's start or after a restart
    begins[(np.cumsum(lengths) - lengths)[lengths > 0]] = True
    begins[1:] |= brk[:-1]
    run_start = np.maximum.accumulate(np.where(begins, pos, 0)) if n else pos
    k = np.arange(max(n - 2, 0))
    k = k[~brk[k] & ~brk[k + 1] & ~brk[k + 2] & (run_start[k] == run_start[k + 2])]
    odd = (k - run_start[k]) % 2 == 1
    a, b, c = flat[k], flat[k + 1], flat[k + 2]
    T = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], 1)
    keep = (T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 0] != T[:, 2])
    return T[keep], strip[k][keep]


def _fan(lengths: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """Polygons (lengths ≥ 3, indices concatenated) fanned from their first vertex in file order:
    (p0, p1, p2), (p0, p2, p3), ... — as the OBJ reader does."""
    first = np.cumsum(lengths) - lengths
    nt = lengths - 2
    poly = np.repeat(np.arange(len(lengths)), nt)
    j = np.arange(int(nt.sum())) - np.repeat(np.cumsum(nt) - nt, nt) + 1
    base = first[poly]
    return np.stack([flat[base], flat[base + j], flat[base + j + 1]], 1).astype(np.int64)


def _read_binary_ply(path: pathlib.Path, header) -> dict:
    """The elements of a binary PLY ({name: {'data': {property: array}}}; lists as object arrays)
    read here: trimesh's reader cannot read lists of varying lengths in a binary file, which
    triangle strips are. Elements without lists are read at once, the others item by item.
    Raises ScanFormatError when the data is shorter or longer than the header declares."""
    fmt, _, body_at = header
    end = "<" if fmt == "binary_little_endian" else ">"
    with open(path, "rb") as fh:
        fh.seek(body_at)
        buf = fh.read()
    elements, pos = {}, 0
    try:
        for name, count, props in _ply_element_layout(path):
            if all(kind == "scalar" for kind, *_ in props):
                dt = np.dtype([(pn, end + _PLY_TYPES[t]) for _, t, pn in props])
                arr = np.frombuffer(buf, dt, count, pos)
                pos += count * dt.itemsize
                elements[name] = {"data": {pn: arr[pn] for _, _, pn in props}, "length": count}
                continue
            cols = {pn: [] for *_, pn in props}
            for _ in range(count):
                for kind, t, pn in props:
                    if kind == "scalar":
                        dt = np.dtype(end + _PLY_TYPES[t])
                        cols[pn].append(np.frombuffer(buf, dt, 1, pos)[0])
                        pos += dt.itemsize
                    else:
                        ct, it = (np.dtype(end + _PLY_TYPES[x]) for x in t)
                        k = int(np.frombuffer(buf, ct, 1, pos)[0])
                        pos += ct.itemsize
                        cols[pn].append(np.frombuffer(buf, it, k, pos))
                        pos += k * it.itemsize
            data = {}
            for kind, _, pn in props:
                if kind == "scalar":
                    data[pn] = np.asarray(cols[pn])
                else:
                    o = np.empty(count, object)
                    o[:] = cols[pn]
                    data[pn] = o
            elements[name] = {"data": data, "length": count}
    except (ValueError, KeyError, IndexError) as exc:
        raise ScanFormatError(f"{path}: the file is truncated or its header does not match its data "
                              f"({type(exc).__name__}: {exc})") from None
    if pos != len(buf):
        raise ScanFormatError(f"{path}: {len(buf) - pos} bytes follow the data the header declares: the file "
                              f"is truncated or its header does not match its data")
    return elements


def _ply_element_layout(path: pathlib.Path) -> list:
    """[(element name, count, [(‘scalar’, type, name) | (‘list’, (count type, item type), name)])]
    of a PLY header, in file order. ScanFormatError for a type PLY does not have."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    out = []
    for line in head[:head.find(b"end_header")].decode("latin-1").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element":
            out.append((parts[1], int(parts[2]), []))
        elif parts[:1] == ["property"] and out:
            types = parts[2:4] if parts[1:2] == ["list"] else parts[1:2]
            bad = [t for t in types if t not in _PLY_TYPES]
            if bad or len(parts) < (5 if parts[1] == "list" else 3):
                raise ScanFormatError(f"{path}: cannot be read as PLY: bad property line {line.strip()!r}")
            out[-1][2].append(("list", (parts[2], parts[3]), parts[4]) if parts[1] == "list"
                              else ("scalar", parts[1], parts[2]))
    return out


def read_ply(path: str | pathlib.Path) -> PlyMesh:
    """The vertices and triangles of a PLY file (ascii or binary), read with trimesh (as before)
    plus its `tristrips` element (strips_to_triangles: restarts at -1, alternating winding). A
    face with fewer than 3 vertices (an edge or point stored as a face), or a header declaring no
    faces or strips, is refused naming it; the counts read are checked against the header.
    Raises ScanFormatError, FaceIndexError or EmptyScanError."""
    import trimesh
    p = pathlib.Path(path)
    header = _ply_header(p)
    counts = header[1] if header else {}
    strips = counts.get("tristrips", 0) > 0
    try:
        if strips:
            # trimesh makes no mesh of strips (and cannot read a binary file's strips): read the
            # elements themselves
            if header[0].startswith("binary"):
                elements = _read_binary_ply(p, header)
            else:
                from trimesh.exchange.ply import load_ply
                with open(p, "rb") as fh:
                    elements = load_ply(fh, fix_texture=False, skip_materials=True)["metadata"]["_ply_raw"]
            m = None
        else:
            m = trimesh.load(str(p), file_type="ply", force="mesh", process=False)
            elements = (m.metadata or {}).get("_ply_raw") or {}
    except ScanFormatError:
        raise
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise ScanFormatError(f"{p}: cannot be read as a triangle mesh ({type(exc).__name__}: {exc})") from None
    if m is not None:
        V = np.asarray(getattr(m, "vertices", np.zeros((0, 3))))
        Ff = np.asarray(getattr(m, "faces", np.zeros((0, 3), np.int64)))
    else:
        vraw, vby = _ply_element(elements, "vertex")
        try:
            V = (np.column_stack([np.asarray(vraw[vby[c]], np.float64).reshape(-1) for c in "xyz"])
                 if vraw is not None else np.zeros((0, 3)))
        except KeyError:
            raise ScanFormatError(f"{p}: the vertex element has no x, y and z properties") from None
        Ff = np.zeros((0, 3), np.int64)
    _check_ply_counts(p, len(V), None)   # misaligned data first: its numbers would make odd faces
    # faces of fewer than 3 vertices: trimesh drops them (mixed) or reads no triangle at all
    fraw, fby = _ply_element(elements, "face")
    polys = _index_lists(fraw, fby) if fraw is not None else None
    if polys is not None:
        lengths, flat = polys
        short = lengths < 3
        if short.any():
            i = int(np.flatnonzero(short)[0])
            first = flat[int(lengths[:i].sum()):int(lengths[:i + 1].sum())].tolist()
            ks, cs = np.unique(lengths[short], return_counts=True)
            raise FaceIndexError(f"{p}: {int(short.sum())} of the {len(lengths)} faces have fewer than 3 vertices "
                                 f"({', '.join(f'{c} with {k}' for k, c in zip(ks.tolist(), cs.tolist()))}; first: "
                                 f"face {i} = {first}): a face needs 3 or more — edges or points stored as faces? "
                                 f"remove them (or store edges as an 'edge' element)")
        if m is None:
            Ff = _fan(lengths, flat)
    T, strip_of = np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    if strips:
        sraw, sby = _ply_element(elements, "tristrips")
        lists = _index_lists(sraw, sby) if sraw is not None else None
        if lists is None:
            raise ScanFormatError(f"{p}: the tristrips element has no 'vertex_indices' list property")
        lengths, flat = lists
        restart = -1
        if np.issubdtype(flat.dtype, np.unsignedinteger):   # a strip list of unsigned ints restarts at its max
            restart = int(np.iinfo(flat.dtype).max)
        T, strip_of = strips_to_triangles(flat, lengths, restart)
        if not len(T) and not len(Ff):
            raise EmptyScanError(f"{p}: the scan has no triangles: its {len(lengths)} triangle strip(s) hold none "
                                 f"(a strip needs 3 vertices between restarts, -1)")
    _check_ply_counts(p, len(V), len(Ff) + len(T))   # the triangles
    return PlyMesh(np.asarray(V, np.float64), np.asarray(Ff, np.int64).reshape(-1, 3), T, strip_of, elements)


def _ply_strip_labels(ply: PlyMesh, source: str) -> np.ndarray | None:
    """Per-triangle labels of the strips' triangles (each its strip's `label`), or None."""
    raw, by_lower = _ply_element(ply.elements, "tristrips")
    prop = next((by_lower[q] for q in LABEL_PROPERTIES if q in by_lower), None)
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
    raw, by_lower = _ply_element(elements, "face")
    if raw is None:
        return None, F
    prop = next((by_lower[q] for q in LABEL_PROPERTIES if q in by_lower), None)
    if prop is None:
        seg = [n for low, n in by_lower.items() if low in SEGMENTATION_PROPERTIES]
        if seg and not has_vertex_labels:
            raise LabelError(f"{source}: no 'label' property, but a per-face one named {seg[0]!r}: if it holds "
                             f"the segmentation, rename it 'label' (per-face labels are read); if the scan is "
                             f"garment-only, remove it — read as garment-only, every face (a body too) would be "
                             f"taken for the garment")
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
    # polygons: fan them in file order, each triangle with its polygon's label
    idx = raw[by_lower.get("vertex_indices", by_lower.get("vertex_index"))] \
        if ("vertex_indices" in by_lower or "vertex_index" in by_lower) else None
    if idx is None or len(idx) != len(FL):
        raise LabelError(f"{source}: {len(FL)} per-face labels for {len(F)} triangles, and the face element's "
                         f"polygons cannot be matched to them")
    tris, tl = [], []
    for k, poly in enumerate(idx):
        poly = np.asarray(poly, np.int64).reshape(-1)
        if len(poly) < 3:
            raise FaceIndexError(f"{source}: face {k} has {len(poly)} vertices (a face needs 3 or more)")
        j = np.arange(1, len(poly) - 1)
        tris.append(np.stack([np.full(len(j), poly[0]), poly[j], poly[j + 1]], 1))
        tl.append(np.full(len(j), k))
    return FL[np.concatenate(tl)], np.concatenate(tris)


def _with_face_labels(raw: RawScan, face_labels: np.ndarray, label_map) -> tuple[RawScan, str]:
    """The scan with per-vertex labels from its per-face ones (none given), or its own vertex
    labels checked against them; and the note for its warnings."""
    from .labels import LabelMap, face_to_vertex_labels
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


def _check_ply_counts(path: pathlib.Path, n_read: int, f_read: int | None = None) -> None:
    """What was read against what the header declares: a point cloud, or a truncated file or a
    header that does not match its data. trimesh reads such an ascii file without an error but
    with some of the vertices and no faces, or with faces made of misaligned numbers; an ascii
    body has one line per element. f_read None: the vertices and lines (before the faces are
    looked at: misaligned numbers make odd faces); else the triangles read."""
    header = _ply_header(path)
    if header is None:
        return
    fmt, counts, body_at = header
    nv, nf = counts.get("vertex", 0), counts.get("face", 0) + counts.get("tristrips", 0)
    what = " and ".join(f"{counts[e]} {n}" for e, n in (("face", "faces"), ("tristrips", "triangle strips"))
                        if counts.get(e)) or "0 faces"

    def mismatch(read):
        raise ScanFormatError(f"{path}: the header declares {nv} vertices and {what}, but {read} were read: the "
                              f"file is truncated or its header does not match its data")
    if f_read is not None:
        if nf and not f_read:
            mismatch(f"{n_read} vertices and 0 triangles")
        return
    if nv and not nf:
        other = [f"'{e}' ({k})" for e, k in counts.items() if e not in ("vertex", "face", "tristrips")]
        raise EmptyScanError(f"{path}: the scan has no triangles: the header declares {nv} vertices and no "
                             f"faces" + (f"; its other element(s) {', '.join(other)} hold none (triangles are "
                                         f"read from the 'face' and 'tristrips' elements)" if other
                                         else " (a point cloud?)"))
    lines = None
    if fmt == "ascii":
        with open(path, "rb") as fh:
            fh.seek(body_at)
            lines = sum(1 for line in fh if line.strip())
    if n_read != nv or (lines is not None and lines != sum(counts.values())):
        mismatch(f"{n_read} vertices" + (f" in {lines} lines" if lines is not None else ""))


def scan_from_message(arrays: dict) -> RawScan:
    """A RawScan from diffavatar_ros.convert.msg_to_arrays(msg): flat float32 vertices, flat
    uint32 faces, uint8 labels (empty: garment-only) and label_names (empty: the label map)."""
    for key, err in (("vertices", VertexArrayError), ("faces", FaceIndexError)):
        if arrays.get(key) is None:
            raise err(f"message: no '{key}' array")
    return scan_from_arrays(arrays["vertices"], arrays["faces"], arrays.get("labels"),
                            arrays.get("label_names") or None,
                            source=f"message {arrays.get('job_id') or ''}".strip())
