"""Malformed scans found by fuzzing the loaders and the preprocessing: each is refused with the
ScanError subclass (and the ROS code) naming the problem, or read as it is meant — never a crash,
a hang or a message that names another problem."""
import time

import numpy as np
import pytest

from diffavatar_core import scan as sv
from diffavatar_core.scan.cleaning import merge_duplicate_vertices
from refusal import refused as _refused
from tube_mesh import tube as _tube


def test_coincident_vertices_merge_in_n_log_n():
    """Many vertices at one point (a broken export writing zeros) listed every pair of them: 37 s
    for 20 000 vertices, a MemoryError at 30 000."""
    n = 30000
    V = np.zeros((n, 3))
    V[n // 2:] = [0.0, 1.0, 0.0]
    t = time.perf_counter()
    Vm, Fm, old_to_new = merge_duplicate_vertices(V, np.array([[0, n - 1, 1]]), 1e-6)
    assert time.perf_counter() - t < 5.0
    np.testing.assert_array_equal(Vm, [[0, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(old_to_new, np.repeat([0, 1], n // 2))
    np.testing.assert_array_equal(Fm, [[0, 1, 0]])
    _refused(sv.DegenerateScanError, "IMPLAUSIBLE_SIZE", "degenerate",
             call=lambda: sv.load_scan((np.ones((n, 3)), np.arange(n).reshape(-1, 3)), garment_type="skirt"))


def test_coordinates_too_large_to_compute_with():
    """A vertex at 1e300 (what a binary file read with the wrong layout gives) overflowed the
    squared distances of cleaning: scipy's KD-tree raised its own ValueError."""
    V, F = _tube()
    far = np.vstack([V, [[1e300, 0.0, 0.0]]])                  # not even used by a triangle
    msg = _refused(sv.NonFiniteError, "NON_FINITE", "magnitude", "vertex 240",
                   call=lambda: sv.load_scan((far, F), garment_type="skirt"))
    assert "NaN" not in msg


@pytest.mark.parametrize("dtype,index,shown", [(np.float64, 1e20, "1e+20"),
                                              (np.uint64, 2 ** 64 - 1, "18446744073709551615")])
def test_a_huge_face_index_is_named_as_given(dtype, index, shown):
    """The cast to int64 wrapped the index (shown as -1 or -9223372036854775808) before it was
    reported."""
    V, F = _tube()
    F = F.astype(dtype)
    F[3, 1] = index
    _refused(sv.FaceIndexError, "BAD_FACE_INDEX", "outside [0, 240)", "face 3", shown,
             call=lambda: sv.load_scan((V, F), garment_type="skirt"))


def _message(**kw):
    V, F = _tube()
    msg = {"vertices": V.ravel().astype(np.float32), "faces": F.ravel().astype(np.uint32),
           "labels": np.full(len(V), 1, np.uint8), "label_names": ["body", "skirt"], "units": "m", "up_axis": "y"}
    msg.update(kw)
    return {k: v for k, v in msg.items() if v is not None}


def test_message_fields_missing_or_of_the_wrong_kind():
    """A message dict without vertices or faces raised KeyError; label_names given as one string
    were read one name per character ('b', 'o', ...), naming letters as unknown classes."""
    assert sv.load_scan(_message()).garment_class == "skirt"
    _refused(sv.VertexArrayError, "BAD_VERTEX_ARRAY", "no 'vertices'", call=lambda: sv.load_scan(_message(vertices=None)))
    _refused(sv.FaceIndexError, "BAD_FACE_INDEX", "no 'faces'", call=lambda: sv.check_scan(_message(faces=None)))
    _refused(sv.LabelError, "BAD_LABELS", "list of class names", "'body,skirt'",
             call=lambda: sv.check_scan(_message(label_names="body,skirt")))


def test_a_raw_scan_made_by_hand_is_checked_like_arrays():
    """A RawScan given to load_scan was trusted: NaN reached the KD-tree (scipy's ValueError), a
    face index past the end an IndexError."""
    V, F = _tube()
    Vn = V.copy()
    Vn[5, 1] = np.nan
    _refused(sv.NonFiniteError, "NON_FINITE", "vertex 5",
             call=lambda: sv.load_scan(sv.RawScan(Vn, F), garment_type="skirt"))
    Fb = F.copy()
    Fb[7, 2] = 10 ** 6
    _refused(sv.FaceIndexError, "BAD_FACE_INDEX", "face 7",
             call=lambda: sv.load_scan(sv.RawScan(V, Fb), garment_type="skirt"))


def test_a_numpy_integer_label_is_a_label_value():
    """label=np.int64(1) was refused as "label '1' is not in the label map" by a map that has 1."""
    a = sv.load_scan(_message(), label=np.int64(1))
    assert a.garment_label == 1 and a.garment_label == sv.load_scan(_message(), label=1).garment_label


def _obj_text(V, F, sep=" ", indent=""):
    return ("".join(f"{indent}v{sep}{sep.join(map(repr, map(float, v)))}\n" for v in V)
            + "".join(f"{indent}f{sep}{sep.join(str(i + 1) for i in f)}\n" for f in F))


@pytest.mark.parametrize("sep,indent", [("\t", ""), (" ", "  "), (" \t ", "\t")])
def test_obj_lines_separated_by_any_whitespace(tmp_path, sep, indent):
    """`v\\t...` and indented lines were skipped without a word: "the scan has no vertices", or
    faces pointing past the vertices that were kept."""
    V, F = _tube()
    p = tmp_path / "tabs.obj"
    p.write_text(_obj_text(V, F, sep, indent))
    raw = sv.read_scan_file(p)
    np.testing.assert_array_equal(raw.vertices, V)
    np.testing.assert_array_equal(raw.faces, F)


@pytest.mark.parametrize("face,index", [("f 0 1 2", "index 0 "), ("f 1 2 -4", "index -4 "),
                                        ("f 1 2 99999999999999999999999", "index 99999999999999999999999 "),
                                        ("f 1 -99999999999999999999999 2", "index -99999999999999999999999 ")])
def test_obj_face_indices_that_name_no_vertex(tmp_path, face, index):
    """OBJ index 0 (indices start at 1) was reported converted, as vertex 3 of 3; a relative index
    before the first vertex as -1; a 23-digit index raised OverflowError. Now the line as written."""
    p = tmp_path / "bad.obj"
    p.write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\n{face}\n")
    _refused(sv.FaceIndexError, "BAD_FACE_INDEX", "bad.obj:4:", index, "start at 1", repr(face),
             call=lambda: sv.read_scan_file(p))


def test_a_directory_is_no_scan(tmp_path):
    """A directory named *.obj raised IsADirectoryError (an OSError the CLI does not catch)."""
    for name in ("scan.obj", "scan.ply"):
        (tmp_path / name).mkdir()
        _refused(sv.ScanFormatError, "BAD_VERTEX_ARRAY", "is a directory",
                 call=lambda: sv.load_scan(tmp_path / name, garment_type="skirt"))


def _ply_bytes(V, F, declared_vertices=None, faces=True):
    head = ["ply", "format ascii 1.0", f"element vertex {len(V) if declared_vertices is None else declared_vertices}",
            "property double x", "property double y", "property double z"]
    if faces:
        head += [f"element face {len(F)}", "property list uchar int vertex_indices"]
    body = [" ".join(map(repr, map(float, v))) for v in V] + ([f"3 {a} {b} {c}" for a, b, c in F] if faces else [])
    return ("\n".join(head + ["end_header"] + body) + "\n").encode()


def test_ply_whose_header_does_not_match_its_data(tmp_path):
    """trimesh reads such an ascii PLY without an error but with no faces (or the face lines as
    vertices): "the scan has no triangles (692 vertices)" for a file that declares 444 faces."""
    V, F = _tube()
    p = tmp_path / "scan.ply"
    p.write_bytes(_ply_bytes(V, F))
    assert len(sv.read_scan_file(p).faces) == len(F)
    cases = {"header only": _ply_bytes(V, F).split(b"end_header\n")[0] + b"end_header\n",
             "truncated": _ply_bytes(V, F)[:-len(_ply_bytes(V, F)) // 3],
             "more declared": _ply_bytes(V, F, declared_vertices=10 ** 12),
             "fewer declared": _ply_bytes(V, F, declared_vertices=len(V) - 5)}
    for what, data in cases.items():
        p.write_bytes(data)
        with pytest.raises(sv.ScanError) as info:
            sv.load_scan(p, garment_type="skirt")
        assert type(info.value) is sv.ScanFormatError and info.value.code == "BAD_VERTEX_ARRAY", what
        assert "header" in str(info.value) or "cannot be read" in str(info.value), (what, str(info.value))


def test_a_ply_point_cloud_has_vertices_but_no_triangles(tmp_path):
    """Was "the scan has no vertices" for a file of 240 vertices."""
    V, F = _tube()
    p = tmp_path / "cloud.ply"
    p.write_bytes(_ply_bytes(V, F, faces=False))
    _refused(sv.EmptyScanError, "EMPTY_MESH", "no triangles", "240 vertices", "point cloud",
             call=lambda: sv.load_scan(p, garment_type="skirt"))


def _body_and(Vg, Fg, label=3):
    """A 1.7 m box 'body' (label 0) with a garment part (label `label`), m."""
    import trimesh
    box = trimesh.creation.box(extents=(0.25, 1.7, 0.15))
    Vb, Fb = np.asarray(box.vertices) + [0, 0.85, 0], np.asarray(box.faces)
    return (np.vstack([Vb, Vg]), np.vstack([Fb, Fg + len(Vb)]),
            np.r_[np.zeros(len(Vb), int), np.full(len(Vg), label)])


def test_a_garment_that_cleaning_removes_is_named():
    """The garment label present in the scan but only on a tiny floating part, or only on
    degenerate triangles: cleaning removes it, and the error said "no vertex carries a garment
    label" of a scan whose 240 vertices carry one."""
    V, F = _tube(r=0.01, y0=1.0, y1=1.02)                        # a 12 cm² fragment beside the body
    scan = _body_and(V + [0.5, 0, 0], F)
    assert sv.check_scan(scan).garment_label == 3               # the front door sees the label
    msg = _refused(sv.NoGarmentError, "NO_GARMENT", "cleaning removed all 240 vertices", "'skirt' (3)",
                   "floating fragment", call=lambda: sv.load_scan(scan))
    assert "no vertex carries" not in msg
    V, F = _tube()
    F = F.copy()
    F[:, 2] = F[:, 1]                                            # every garment triangle degenerate
    msg = _refused(sv.NoGarmentError, "NO_GARMENT", "cleaning removed all", "degenerate",
                   call=lambda: sv.load_scan(_body_and(V, F)))
    assert "no vertex carries" not in msg


def test_a_collapsed_cluster_of_distinct_vertices_is_refused_quickly():
    """20 000 distinct vertices within 1e-8 m of a point (a scan collapsed by a wrong scale):
    every pair of them is closer than the merge tolerance, which ran out of memory."""
    V = np.random.default_rng(0).normal(0.0, 1e-8, (20001, 3))
    t = time.perf_counter()
    _refused(sv.ScanError, "IMPLAUSIBLE_SIZE", call=lambda: sv.load_scan((V, np.arange(len(V)).reshape(-1, 3)),
                                                                        garment_type="skirt"))
    assert time.perf_counter() - t < 10.0
    Vm, _, old_to_new = merge_duplicate_vertices(V, np.zeros((0, 3), int), 1e-6)
    assert len(Vm) < len(V) // 10 and old_to_new.max() == len(Vm) - 1


def _ply_with_property(V, F, name, values):
    head = ["ply", "format ascii 1.0", f"element vertex {len(V)}", "property double x", "property double y",
            "property double z", f"property uchar {name}", f"element face {len(F)}",
            "property list uchar int vertex_indices", "end_header"]
    body = [" ".join(map(repr, map(float, v))) + f" {int(k)}" for v, k in zip(V, values)]
    body += [f"3 {a} {b} {c}" for a, b, c in F]
    return ("\n".join(head + body) + "\n").encode()


def test_a_segmentation_under_another_name_is_not_read_as_garment_only(tmp_path):
    """A PLY whose labels are stored as `class` was read as garment-only: with a garment type given,
    every vertex — the body too — became the garment. `Label` (another letter case) was missed so."""
    V, F = _tube()
    labels = np.where(V[:, 1] > 0.75, 3, 1)   # two classes over the tube
    p = tmp_path / "scan.ply"
    p.write_bytes(_ply_with_property(V, F, "class", labels))
    _refused(sv.LabelError, sv.LabelError.code, "'class'", "rename it 'label'", "garment-only",
             call=lambda: sv.load_scan(p, garment_type="skirt"))
    p.write_bytes(_ply_with_property(V, F, "Label", labels))
    np.testing.assert_array_equal(sv.read_scan_file(p).labels, labels)
    p.write_bytes(_ply_with_property(V, F, "quality", labels))   # any other property: garment-only as before
    assert sv.read_scan_file(p).labels is None


def test_a_label_the_scan_lacks_is_named_as_missing():
    """label=99 (absent, and in no label map) said "label 'label 99' (99) is not a garment class:
    give the garment type" — a garment type would not have helped; the scan has no such vertex."""
    V, F = _tube()
    labels = np.where(V[:, 1] > 0.75, 1, 0)   # upper and body
    for lab, shown in ((99, "99 (not in the label map)"), (-1, "-1 (not in the label map)"), ("skirt", "'skirt' (3)")):
        msg = _refused(sv.NoGarmentError, sv.NoGarmentError.code, f"no vertices with label {shown}",
                       "upper (1): ", call=lambda: sv.load_scan((V, F, labels), label=lab))
        assert "garment type" not in msg
    # present but not a garment: still that
    _refused(sv.LabelError, "BAD_LABELS", "'body' (0) is not a garment class",
             call=lambda: sv.load_scan((V, F, labels), label="body"))
