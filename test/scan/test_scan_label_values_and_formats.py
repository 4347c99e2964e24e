"""Errors that named another problem than the scan's (found by fuzzing): label values wrapped by
an integer cast before they were reported, a PLY saved with a .obj name read as an empty OBJ, and
a label name in another letter case refused although names are matched ignoring case."""
import pathlib
import shutil

import numpy as np
import pytest

from diffavatar_core import scan as sv
from refusal import refused as _refused
from tube_mesh import tube as _tube

SAMPLE = pathlib.Path(__file__).resolve().parents[2] / "diffavatar_core" / "data" / "sample_scan.ply"


@pytest.mark.parametrize("dtype,value,shown", [(np.float64, 1e30, "1e+30"),
                                              (np.uint64, 2 ** 64 - 1, "18446744073709551615"),
                                              (np.int64, 2 ** 40, "1099511627776"),
                                              (np.float64, -3e9, "-3000000000.0")])
def test_a_huge_label_is_named_as_given(dtype, value, shown):
    """The cast to int64 wrapped 1e30 to -9223372036854775808 and 2**64 − 1 to -1 before the label
    was reported ("no garment label present ... label -1"): a label outside a class value's range
    is refused as such, with the vertex and the value as given."""
    V, F = _tube()
    labels = np.full(len(V), 3, dtype)
    labels[17] = value
    msg = _refused(sv.LabelError, "BAD_LABELS", "outside the range of a class value", f"vertex 17 = {shown}",
                   call=lambda: sv.load_scan((V, F, labels)))
    assert "-9223372036854775808" not in msg and "label -1" not in msg


def test_a_label_that_is_no_integer_is_named():
    V, F = _tube()
    for bad, shown in ((2.5, "vertex 4 = 2.5"), (np.nan, "vertex 4 = nan"), (np.inf, "vertex 4 = inf")):
        labels = np.full(len(V), 3.0)
        labels[4] = bad
        _refused(sv.LabelError, "BAD_LABELS", "must be integers", shown, call=lambda: sv.load_scan((V, F, labels)))
    # integral floats in range remain labels, as before
    assert sv.load_scan((V, F, np.full(len(V), 3.0))).garment_label == 3


def test_a_huge_label_in_a_ply_is_named_as_given(tmp_path):
    V, F = _tube()
    head = ["ply", "format ascii 1.0", f"element vertex {len(V)}", "property float x", "property float y",
            "property float z", "property double label", f"element face {len(F)}",
            "property list uchar int vertex_indices", "end_header"]
    body = [f"{x} {y} {z} {1e30 if k == 0 else 3.0}" for k, (x, y, z) in enumerate(V)]
    body += [f"3 {a} {b} {c}" for a, b, c in F]
    p = tmp_path / "scan.ply"
    p.write_text("\n".join(head + body) + "\n")
    _refused(sv.LabelError, "BAD_LABELS", "vertex 0 = 1e+30", call=lambda: sv.load_scan(p))


def test_a_ply_saved_as_obj_is_read_as_ply(tmp_path):
    """The sample (a binary PLY) copied to scan.obj said "the scan has no vertices": the file's own
    header decides, and the result is the .ply's, with a warning naming the mismatch."""
    ref = sv.load_scan(SAMPLE, units="cm")
    q = tmp_path / "scan.obj"
    shutil.copy(SAMPLE, q)
    d = sv.load_scan(q, units="cm")
    np.testing.assert_array_equal(d.vertices, ref.vertices)
    np.testing.assert_array_equal(d.labels, ref.labels)
    np.testing.assert_array_equal(d.garment_face_mask, ref.garment_face_mask)
    assert d.boundaries.keys() == ref.boundaries.keys()
    assert any("read as PLY" in w and "'.obj'" in w for w in d.warnings)
    from diffavatar_core.io import load_mesh
    V, F = load_mesh(q)
    assert V.shape == (14167, 3) and len(F) == 28070


def test_a_file_whose_name_and_content_disagree_is_refused_by_name(tmp_path):
    p = tmp_path / "scan.ply"                        # an OBJ named .ply
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    _refused(sv.ScanFormatError, "BAD_VERTEX_ARRAY", "cannot be read as PLY", "does not start with the PLY header",
             call=lambda: sv.read_scan_file(p))
    q = tmp_path / "scan.obj"                        # binary, not PLY (an STL header, say)
    q.write_bytes(b"\x00" * 80 + b"\x01\x00\x00\x00" + b"\x00" * 50)
    _refused(sv.ScanFormatError, "BAD_VERTEX_ARRAY", "cannot be read as OBJ", "binary",
             call=lambda: sv.read_scan_file(q))
    r = tmp_path / "off.obj"                         # text of another format
    r.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    _refused(sv.ScanFormatError, "BAD_VERTEX_ARRAY", "cannot be read as OBJ", "no line of it is an OBJ vertex",
             call=lambda: sv.read_scan_file(r))


def test_a_label_name_in_another_letter_case_is_the_label():
    """docs/scan.md: names are matched ignoring case, spaces, '-' and '_'; --label Skirt was "not in
    the label map". Every spelling selects what 'skirt' does; numeric strings (also negative) are
    values; a name that matches two classes only so is refused, naming both."""
    V, F = _tube()
    labels = np.where(V[:, 1] > 0.75, 0, 3)
    ref = sv.load_scan((V, F, labels), label="skirt")
    for name in ("Skirt", "SKIRT", " skirt ", "s-kirt", "3", "+3"):
        d = sv.load_scan((V, F, labels), label=name)
        assert d.garment_label == ref.garment_label == 3
        np.testing.assert_array_equal(d.garment_face_mask, ref.garment_face_mask)
    assert sv.LabelMap.load().value_of("-1") == -1
    _refused(sv.LabelError, "BAD_LABELS", "'cape' is not in the label map",
             call=lambda: sv.load_scan((V, F, labels), label="cape"))
    lm = sv.LabelMap.load().with_names(["body", "Skirt", "SKIRT"])
    assert lm.value_of("Skirt") == 1                 # the exact spelling first
    _refused(sv.LabelError, "BAD_LABELS", "matches several classes", "1: Skirt", "2: SKIRT",
             call=lambda: lm.value_of("skirt"))
