"""Reading PLY files (ascii or binary): the vertices, the `face` element's polygons (triangulated)
and the `tristrips` element's triangle strips (OpenGL GL_TRIANGLE_STRIP, restarts at -1), checked
against the header's counts. trimesh reads what it can; binary files whose lists vary in length
(strips, or faces of mixed sizes: triangles and quads) are read here. The label properties are scan/loading.py's (ply_element gives them)."""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

from .errors import EmptyScanError, FaceIndexError, ScanFormatError


def ply_element(elements: dict, element: str):
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


def index_lists(raw, by_lower: dict) -> tuple[np.ndarray, np.ndarray] | None:
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


def fan_polygons(lengths: np.ndarray, flat: np.ndarray) -> np.ndarray:
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
    header = ply_header(p)
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
            try:
                m = trimesh.load(str(p), file_type="ply", force="mesh", process=False)
                elements = (m.metadata or {}).get("_ply_raw") or {}
            except Exception:
                if not (header and header[0].startswith("binary")):
                    raise
                # trimesh reads a binary face list only when every face has one length ("PLY is
                # unexpected length!" for a mesh of triangles and quads): read the elements here,
                # the polygons fanned in file order
                elements, m = _read_binary_ply(p, header), None
    except ScanFormatError:
        raise
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise ScanFormatError(f"{p}: cannot be read as a triangle mesh ({type(exc).__name__}: {exc})") from None
    if m is not None:
        V = np.asarray(getattr(m, "vertices", np.zeros((0, 3))))
        Ff = np.asarray(getattr(m, "faces", np.zeros((0, 3), np.int64)))
    else:
        vraw, vby = ply_element(elements, "vertex")
        try:
            V = (np.column_stack([np.asarray(vraw[vby[c]], np.float64).reshape(-1) for c in "xyz"])
                 if vraw is not None else np.zeros((0, 3)))
        except KeyError:
            raise ScanFormatError(f"{p}: the vertex element has no x, y and z properties") from None
        Ff = np.zeros((0, 3), np.int64)
    _check_ply_counts(p, len(V), None)   # misaligned data first: its numbers would make odd faces
    # faces of fewer than 3 vertices: trimesh drops them (mixed) or reads no triangle at all
    fraw, fby = ply_element(elements, "face")
    polys = index_lists(fraw, fby) if fraw is not None else None
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
            Ff = fan_polygons(lengths, flat)
    T, strip_of = np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    if strips:
        sraw, sby = ply_element(elements, "tristrips")
        lists = index_lists(sraw, sby) if sraw is not None else None
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


def ply_header(path: pathlib.Path) -> tuple[str, dict[str, int], int] | None:
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
    header = ply_header(path)
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
