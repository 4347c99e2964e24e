"""PLY faces stored as triangle strips (read, not taken for a point cloud) or as polygons of mixed
sizes (a binary file of triangles and quads: read, not refused), faces of fewer than 3
vertices (refused by name, not a "truncated file"), label values the label map does not name
(visible: a warning, or refused when they cover a sizeable part of the scan, not silently left
out of both body and garment), a custom label map reaching the per-face conversion through
check_scan, and a RawScan's reading warnings kept (found by fuzzing)."""
import dataclasses
import pathlib

import numpy as np
import pytest
import trimesh

from diffavatar_core import scan as sv
from diffavatar_core.scan.labels import LabelMap
from diffavatar_core.scan.ply_reader import strips_to_triangles
from refusal import refused as _refused
from tube_mesh import tube

SAMPLE = pathlib.Path(__file__).resolve().parents[2] / "diffavatar_core" / "data" / "sample_scan.ply"
N_PHI = 24


def _tube(n_phi=N_PHI, n_y=12, r=0.2, y0=0.4, y1=1.0):
    """tube_mesh.tube, each band's triangles in the order of its triangle strip."""
    return tube(n_phi, n_y, r, y0, y1, interleaved=True)


def _band_strips(n_y, n_phi=N_PHI):
    """One strip per ring band: a0, a0 + n, a1, a1 + n, ..., a0, a0 + n (closing the ring)."""
    out = []
    for i in range(n_y - 1):
        ring = [i * n_phi + j % n_phi for j in range(n_phi + 1)]
        out.append([x for a in ring for x in (a, a + n_phi)])
    return out


def _ply(path, V, faces=None, strips=None, vlabels=None, slabels=None, fmt="ascii", itype="int"):
    """A PLY of V with a `face` element (lists) and/or a `tristrips` element (lists, -1 restarts)."""
    head = ["ply", f"format {fmt} 1.0", f"element vertex {len(V)}",
            "property double x", "property double y", "property double z"]
    if vlabels is not None:
        head.append("property uchar label")
    if faces is not None:
        head += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    if strips is not None:
        head += [f"element tristrips {len(strips)}", f"property list int {itype} vertex_indices"]
        if slabels is not None:
            head.append("property uchar label")
    head.append("end_header")
    if fmt == "ascii":
        rows = [" ".join(map(repr, map(float, v))) + ("" if vlabels is None else f" {int(vlabels[k])}")
                for k, v in enumerate(V)]
        rows += [f"{len(f)} " + " ".join(map(str, f)) for f in (faces if faces is not None else ())]
        rows += [f"{len(s)} " + " ".join(map(str, s)) + ("" if slabels is None else f" {slabels[k]}")
                 for k, s in enumerate(strips if strips is not None else ())]
        path.write_text("\n".join(head + rows) + "\n")
        return path
    e = "<" if "little" in fmt else ">"
    vt = [(c, e + "f8") for c in "xyz"] + ([("label", "u1")] if vlabels is not None else [])
    va = np.zeros(len(V), vt)
    for i, c in enumerate("xyz"):
        va[c] = V[:, i]
    if vlabels is not None:
        va["label"] = vlabels
    body = va.tobytes()
    for f in (faces if faces is not None else ()):
        body += np.uint8(len(f)).tobytes() + np.asarray(f, e + "i4").tobytes()
    it = e + ("u4" if itype == "uint" else "i4")
    for k, s in enumerate(strips if strips is not None else ()):
        body += np.asarray(len(s), e + "i4").tobytes() + np.asarray(s, np.int64).astype(it).tobytes()
        if slabels is not None:
            body += np.uint8(slabels[k]).tobytes()
    path.write_bytes(("\n".join(head) + "\n").encode() + body)
    return path


def _same_scan(d, ref):
    """Two ScanData of the same scan: garment region, openings and interior samples alike."""
    np.testing.assert_array_equal(d.faces, ref.faces)
    np.testing.assert_array_equal(d.garment_face_mask, ref.garment_face_mask)
    assert d.garment_label == ref.garment_label and d.garment_class == ref.garment_class
    assert d.boundaries.keys() == ref.boundaries.keys()
    for k in ref.boundaries:
        np.testing.assert_array_equal(d.boundaries[k], ref.boundaries[k])
    np.testing.assert_array_equal(d.interior_points, ref.interior_points)


def test_strips_alternate_winding_restart_at_minus_one_and_drop_stitches():
    """OpenGL's GL_TRIANGLE_STRIP order: the k-th triangle of a run is (s[k], s[k+1], s[k+2]) for
    even k, (s[k+1], s[k], s[k+2]) for odd k, so a flat strip's triangles all face one way; -1
    starts a new run (its parity anew), and the degenerate triangles that stitch strips are
    dropped."""
    T, of = strips_to_triangles(np.array([0, 1, 2, 3, -1, 4, 5, 6, 7, 8, 9, 10]), np.array([9, 3]))
    np.testing.assert_array_equal(T, [[0, 1, 2], [2, 1, 3], [4, 5, 6], [6, 5, 7], [8, 9, 10]])
    np.testing.assert_array_equal(of, [0, 0, 0, 0, 1])
    # a zig-zag strip in the plane z = 0: every triangle's normal is +z
    x = np.arange(8) // 2
    P = np.column_stack([x, np.arange(8) % 2, np.zeros(8)]).astype(float)
    T, _ = strips_to_triangles(np.arange(8), np.array([8]))
    n = np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])
    assert len(T) == 6 and (n[:, 2] < 0).all() or (n[:, 2] > 0).all()
    assert np.all(np.sign(n[:, 2]) == np.sign(n[0, 2]))
    # stitched: 0 1 2 3 | 3 4 | 4 5 6 7: the same as two runs
    T2, _ = strips_to_triangles(np.array([0, 1, 2, 3, 3, 4, 4, 5, 6, 7]), np.array([10]))
    np.testing.assert_array_equal(T2, [[0, 1, 2], [2, 1, 3], [4, 5, 6], [6, 5, 7]])
    # a run of fewer than 3 indices holds no triangle
    assert strips_to_triangles(np.array([0, 1, -1, 2]), np.array([4]))[0].shape == (0, 3)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("joined", ["one strip per band", "restarts", "stitched"])
def test_a_mesh_written_as_triangle_strips_reads_back_to_its_triangles(tmp_path, fmt, joined):
    """Was "the header declares 288 vertices and no faces (a point cloud?)". A tube written as
    strips reads back to exactly its triangles, in order and winding, and loads to the same scan
    as written as faces (labels per vertex: body below, skirt above). In binary, strips of
    different lengths (which trimesh's binary reader cannot read) too."""
    V, F = _tube()
    L = np.where(V[:, 1] > 0.6, 3, 0)
    bands = _band_strips(12)
    if joined == "restarts":        # two bands per list, -1 between: lists of different lengths
        strips = [a + [-1] + b for a, b in zip(bands[0::2], bands[1::2])] + ([bands[-1]] if len(bands) % 2 else [])
    elif joined == "stitched":      # one list, degenerate triangles between bands
        strips = [bands[0]]
        for b in bands[1:]:
            strips[0] = strips[0] + [strips[0][-1], b[0]] + b
    else:
        strips = bands
    p = _ply(tmp_path / "strips.ply", V, strips=strips, vlabels=L, fmt=fmt)
    raw = sv.read_scan_file(p)
    np.testing.assert_array_equal(raw.faces, F)
    np.testing.assert_array_equal(raw.labels, L)
    ref = sv.load_scan(_ply(tmp_path / "faces.ply", V, faces=F, vlabels=L))
    d = sv.load_scan(p)
    _same_scan(d, ref)
    assert d.boundaries.keys() == {"waist", "hem"}
    from diffavatar_core.io import load_mesh
    Vm, Fm = load_mesh(p)
    np.testing.assert_array_equal(Fm, F)
    np.testing.assert_allclose(Vm, V, rtol=0, atol=0)


def test_the_sample_written_as_strips_with_per_strip_labels(tmp_path):
    """The bundled sample, each triangle a strip (binary, unsigned indices: a restart would be
    2³² − 1) with a per-strip label — the per-face labels of strips — loads as the sample written
    with per-face labels does."""
    m = trimesh.load(SAMPLE, process=False)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    L = np.asarray(m.metadata["_ply_raw"]["vertex"]["data"]["label"]).astype(int)
    FL = L[F].max(axis=1)
    p = _ply(tmp_path / "s.ply", V, strips=F.tolist(), slabels=FL.tolist(), fmt="binary_little_endian",
             itype="uint")
    ref = sv.load_scan(SAMPLE, units="cm")
    d = sv.load_scan(p, units="cm")
    _same_scan(d, ref)
    assert any("per-face labels converted" in w for w in d.warnings)


def test_strips_that_hold_no_triangle_and_elements_that_hold_no_faces_are_named(tmp_path):
    V, _ = _tube()
    p = _ply(tmp_path / "s.ply", V, strips=[[0, 1, -1, 2, 3]])
    _refused(sv.EmptyScanError, "EMPTY_MESH", "triangle strip(s) hold none", call=lambda: sv.read_scan_file(p))
    q = tmp_path / "edges.ply"
    q.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 1\n")
    _refused(sv.EmptyScanError, "EMPTY_MESH", "'edge' (1)", "'face' and 'tristrips'",
             call=lambda: sv.read_scan_file(q))


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_a_mesh_of_triangles_and_quads_reads_back_to_its_triangles(tmp_path, fmt):
    """A grid written as quads on every other cell and as triangle pairs on the rest (a binary
    file of mixed face sizes, which trimesh refuses: 'PLY is unexpected length!') reads as every
    cell's two triangles, a quad (a, b, c, d) fanned to (a, b, c), (a, c, d) — in file order when
    read here (binary); trimesh's order and rotation, (a, b, c), (c, d, a) after the triangles,
    when it reads the file (ascii) —, with its per-vertex labels."""
    n = 6
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    V = np.column_stack([i.ravel() * 0.05, j.ravel() * 0.05 + 0.5, np.zeros(n * n)])
    labels = (i.ravel() >= n // 2).astype(np.uint8) * 3
    faces, expected = [], []
    for a in (ci * n + cj for ci in range(n - 1) for cj in range(n - 1)):
        quad = [a, a + n, a + n + 1, a + 1]
        tris = [quad[:3], [quad[0], quad[2], quad[3]]]
        faces += [quad] if len(faces) % 3 == 0 else tris
        expected += tris
    path = _ply(tmp_path / "mixed.ply", V, faces=faces, vlabels=labels, fmt=fmt)
    raw = sv.read_scan_file(path)
    if fmt == "ascii":   # trimesh's (c, d, a): the same triangle, the same winding
        def canonical(T):
            return sorted(tuple(np.roll(t, -int(np.argmin(t))).tolist()) for t in np.asarray(T))
        assert canonical(raw.faces) == canonical(expected)
    else:
        np.testing.assert_array_equal(raw.faces, expected)
    np.testing.assert_array_equal(raw.vertices, V)
    np.testing.assert_array_equal(raw.labels, labels)


@pytest.mark.parametrize("which", ["all", "one"])
def test_faces_of_fewer_than_3_vertices_are_refused_by_name(tmp_path, which):
    """Faces of 2 vertices were "the file is truncated or its header does not match its data"
    (all of them), or dropped without a word (one among triangles); the mesh loader too."""
    V, F = _tube()
    faces = [f[:2].tolist() for f in F] if which == "all" else F.tolist()
    if which == "one":
        faces[5] = faces[5][:2]
        faces[9] = faces[9][:1]
    p = _ply(tmp_path / "s.ply", V, faces=faces, vlabels=np.full(len(V), 3))
    n = len(F)
    words = ([f"{n} of the {n} faces", f"{n} with 2", f"face 0 = {faces[0]}"] if which == "all"
             else [f"2 of the {n} faces", "1 with 1, 1 with 2", f"face 5 = {faces[5]}"])
    msg = _refused(sv.FaceIndexError, "BAD_FACE_INDEX", "fewer than 3 vertices", *words,
                   call=lambda: sv.load_scan(p))
    assert "truncated" not in msg
    from diffavatar_core.io import load_mesh
    with pytest.raises(ValueError, match="fewer than 3 vertices"):
        load_mesh(p)


def _sample():
    m = trimesh.load(SAMPLE, process=False)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    return V, F, np.asarray(m.metadata["_ply_raw"]["vertex"]["data"]["label"]).astype(np.int64)


def test_a_body_labelled_with_a_value_the_map_lacks_is_refused_naming_it():
    """The sample's body labelled 9 (not in config/labels.yaml) was silently left out of the body
    and the scan fitted as garment-only (Chamfer 1.58 cm against 1.20). Now refused, naming the
    value, its share and how to name it; named — label_names or a label map listing it as the
    body — the scan loads as with the body labelled 0."""
    V, F, L = _sample()
    L9 = np.where(L == 0, 9, L)
    n0 = int((L == 0).sum())
    _refused(sv.LabelError, "BAD_LABELS", "9: ", f"{n0} vertices", "not in the label map", "label_names",
             "label_map", call=lambda: sv.load_scan((V, F, L9), units="cm"))
    _refused(sv.LabelError, "BAD_LABELS", "9: ", call=lambda: sv.check_scan((V, F, L9), units="cm"))
    ref = sv.load_scan((V, F, L), units="cm")
    by_names = sv.load_scan(sv.scan_from_arrays(V, F, L9, ["unused", "upper", "dress", "skirt", "pants", "hair",
                                                          "shoes", "other", "x", "body"]), units="cm")
    lmap = LabelMap.load()
    by_map = sv.load_scan((V, F, L9), units="cm",
                          label_map=dataclasses.replace(lmap, classes={**{k: v for k, v in lmap.classes.items()
                                                                          if k != 0}, 9: "body"}))
    for d in (by_names, by_map):
        _same_scan(d, ref)
        np.testing.assert_array_equal(d.label_vertex_mask("body"), ref.label_vertex_mask("body"))
        assert not any("not in the label map" in w for w in d.warnings)


def test_a_small_part_labelled_with_a_value_the_map_lacks_is_a_warning():
    """Below a fifth of the vertices, unnamed values load with a warning naming each value, its
    vertex count and what is done with it; the garment region is the one of a scan where the
    part is labelled 'other' (7), as neither body nor garment."""
    V, F, L = _sample()
    part = np.flatnonzero(L == 0)[:700]
    L12, L7 = L.copy(), L.copy()
    L12[part[:500]], L12[part[500:]] = 12, 40
    L7[part] = 7
    d = sv.load_scan((V, F, L12), units="cm")
    ref = sv.load_scan((V, F, L7), units="cm")
    _same_scan(d, ref)
    w = [x for x in d.warnings if "not in the label map" in x]
    assert len(w) == 1 and "12: 500 vertices" in w[0] and "40: 200 vertices" in w[0], d.warnings
    assert "neither as body" in w[0] and "nor as garment" in w[0]
    assert not d.label_vertex_mask("body")[part].any()
    # a value chosen as the garment by label= is no unnamed label
    L99 = np.where(L == 3, 99, L)
    g = sv.load_scan((V, F, L99), units="cm", label=99, garment_type="skirt")
    assert g.garment_label == 99 and not any("not in the label map" in x for x in g.warnings)


def test_a_custom_label_map_reaches_the_per_face_conversion(tmp_path):
    """check_scan read files with config/labels.yaml's garments: under a label map where 5 is a
    skirt (config: hair), the per-face conversion did not count 5 as a garment, and faces at the
    border of the skirt labelled 5 were lost. Now load_scan(path, label_map=) converts as
    read_scan_file(path, label_map=) does: the same garment region as the file labelled 3 under
    the default map."""
    V, F = _tube()
    FL = np.where(V[F][:, :, 1].min(axis=1) > 0.65, 3, 0)
    head = ["ply", "format ascii 1.0", f"element vertex {len(V)}", "property double x", "property double y",
            "property double z", f"element face {len(F)}", "property list uchar int vertex_indices",
            "property uchar label", "end_header"]

    def write(path, fl):
        rows = [" ".join(map(repr, map(float, v))) for v in V] + [f"3 {a} {b} {c} {l}" for (a, b, c), l in zip(F, fl)]
        path.write_text("\n".join(head + rows) + "\n")
        return path
    ref = sv.load_scan(write(tmp_path / "three.ply", FL))
    np.testing.assert_array_equal(ref.garment_face_mask, FL == 3)
    lmap = LabelMap({0: "body", 5: "skirt"}, LabelMap.load().garment_openings)
    p = write(tmp_path / "five.ply", np.where(FL == 3, 5, 0))
    for d in (sv.load_scan(p, label_map=lmap), sv.load_scan(sv.check_scan(p, label_map=lmap))):
        assert d.garment_label == 5 and d.garment_class == "skirt"
        np.testing.assert_array_equal(d.garment_face_mask, ref.garment_face_mask)
        np.testing.assert_array_equal(d.labels == 5, ref.labels == 3)


def test_a_raw_scan_keeps_its_reading_warnings(tmp_path):
    """A RawScan passed in (read by hand, or made) was rebuilt by check_scan without its warnings:
    a PLY named .obj read as PLY, per-face labels converted. They now start ScanData.warnings as
    they do when the path is given."""
    V, F, L = _sample()
    q = tmp_path / "scan.obj"
    q.write_bytes(SAMPLE.read_bytes())
    by_path = sv.load_scan(q, units="cm")
    raw = sv.read_scan_file(q)
    assert raw.warnings and "read as PLY" in raw.warnings[0]
    by_raw = sv.load_scan(raw, units="cm")
    assert by_raw.warnings == by_path.warnings and by_raw.warnings[0] == raw.warnings[0]
    made = sv.load_scan(sv.RawScan(V, F, L, None, "made", ("made by hand",)), units="cm")
    assert made.warnings[0] == "made by hand"
    assert sv.check_scan(raw, units="cm").raw.warnings == raw.warnings
