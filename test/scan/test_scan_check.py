"""check_scan, the cheap scan checks shared by the pipeline (preprocess_scan runs them first),
the node's front door and `diffavatar send`: every problem has its own ScanError subclass (a
ValueError) naming the field, with the ROS interface's error code; a good scan comes back in
metres, Y up. (Moved from test/core/test_scan_validation.py when diffavatar_core.scan_validation
was folded into diffavatar_core.scan.)"""
import numpy as np
import pytest

from diffavatar_core import scan as sv


def _check(vertices, faces, labels=None, label_names=(), *, units="m", up_axis="y", garment_type="",
           template_name="", max_vertices=None, known_templates=None):
    """check_scan on the fields of a SegmentedScan message, as the node calls it."""
    msg = {"vertices": vertices, "faces": faces, "labels": labels, "label_names": list(label_names),
           "units": units, "up_axis": up_axis, "garment_type": garment_type, "template_name": template_name}
    return sv.check_scan(msg, max_vertices=max_vertices, known_templates=known_templates)


def _sphere(n_lat=12, n_lon=16, radius=0.4):
    th = np.linspace(0.1, np.pi - 0.1, n_lat)
    ph = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    V = radius * np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_lat - 1), np.arange(n_lon), indexing="ij")
    a, b = (i * n_lon + j).ravel(), (i * n_lon + (j + 1) % n_lon).ravel()
    F = np.concatenate([np.stack([a, a + n_lon, b], 1), np.stack([b, a + n_lon, b + n_lon], 1)])
    labels = (V[:, 1] > 0).astype(np.uint8)
    return V, F, labels, ["body", "dress"]


def test_good_scan_is_converted_to_metres_y_up():
    V, F, L, names = _sphere()
    s = _check(V, F, L, names)
    np.testing.assert_array_equal(s.vertices, V)
    assert s.garment_type == "dress" and s.faces.dtype == np.int32
    np.testing.assert_array_equal(s.garment_mask, V[:, 1] > 0)
    assert len(s.garment_faces) and s.garment_mask[s.garment_faces].all()

    # the same scan stated in cm with Z up: (x, y, z)_yup = (x, z, -y)_zup / 100 exactly back
    Vz = np.column_stack([V[:, 0], -V[:, 2], V[:, 1]]) * 100
    s2 = _check(Vz.ravel(), F.ravel(), L, names, units="cm", up_axis="z", garment_type="Dress")
    np.testing.assert_allclose(s2.vertices, V, rtol=0, atol=1e-15)
    assert (s2.source_units, s2.source_up_axis, s2.garment_type) == ("cm", "z", "dress")


def test_garment_only_scan_and_type_spellings():
    V, F, _, _ = _sphere()
    s = _check(V, F, None, (), garment_type="T-Shirt")
    assert s.garment_type == "tshirt" and s.garment_mask.all() and s.labels is None
    with pytest.raises(sv.UnknownGarmentTypeError, match="not given") as info:
        _check(V, F, np.zeros(0), ())
    assert info.value.code == "UNKNOWN_GARMENT_TYPE" and isinstance(info.value, sv.NoGarmentError)
    # label_names without labels (a message may carry them) naming one garment give the type
    s = _check(V, F, None, ["body", "T-Shirt"])
    assert (s.garment_type, s.garment_class) == ("tshirt", "upper")
    assert sv.load_scan(s).garment_type == "tshirt"
    with pytest.raises(sv.GarmentTypeMissingError, match="not given"):
        _check(V, F, None, ["body", "tshirt", "dress"])


def test_units_and_label_map_defaults_are_the_preprocessing_ones():
    """mm is a unit of the scan frame (and so of the node); labels without label_names are
    named by config/labels.yaml (0 body, 1 upper), as for a PLY file."""
    V, F, L, _ = _sphere()
    s = _check(V * 1000, F, L, (), units="mm", up_axis="")
    np.testing.assert_allclose(s.vertices, V, rtol=0, atol=1e-15)
    assert (s.source_units, s.source_up_axis, s.garment_class, s.garment_type) == ("mm", "y", "upper", "upper")
    with pytest.raises(sv.NoGarmentError, match="no garment label present") as info:
        _check(V, F, L + 5, ())  # hair, shoes
    assert info.value.code == "NO_GARMENT"


#: The node's error code of each class (AvatarAssets.ERROR_<code>).
CODES = {sv.EmptyScanError: "EMPTY_MESH", sv.NonFiniteError: "NON_FINITE", sv.VertexArrayError: "BAD_VERTEX_ARRAY",
         sv.FaceIndexError: "BAD_FACE_INDEX", sv.LabelError: "BAD_LABELS", sv.NoGarmentError: "NO_GARMENT",
         sv.UnknownGarmentTypeError: "UNKNOWN_GARMENT_TYPE", sv.UnknownTemplateError: "UNKNOWN_TEMPLATE",
         sv.BadOptionError: "BAD_OPTION", sv.ImplausibleSizeError: "IMPLAUSIBLE_SIZE",
         sv.DegenerateScanError: "IMPLAUSIBLE_SIZE", sv.TooLargeError: "TOO_LARGE"}


@pytest.mark.parametrize("mutate,cls,words", [
    (lambda V, F, L: dict(vertices=np.zeros((0, 3))), sv.EmptyScanError, "no vertices"),
    (lambda V, F, L: dict(faces=np.zeros((0, 3), int)), sv.EmptyScanError, "no triangles"),
    (lambda V, F, L: dict(vertices=np.where(np.arange(V.size).reshape(V.shape) == 4, np.nan, V)),
     sv.NonFiniteError, "vertex 1"),
    (lambda V, F, L: dict(vertices=V.ravel()[:-1]), sv.VertexArrayError, "multiple of 3"),
    (lambda V, F, L: dict(vertices=V[:, :2]), sv.VertexArrayError, "shape"),
    (lambda V, F, L: dict(vertices=np.array(["a"] * 9)), sv.VertexArrayError, "numbers"),
    (lambda V, F, L: dict(faces=np.vstack([F, [[0, 1, len(V)]]])), sv.FaceIndexError, "[0, 192)"),
    (lambda V, F, L: dict(faces=np.vstack([F, [[0, -1, 2]]])), sv.FaceIndexError, "outside"),
    (lambda V, F, L: dict(faces=F.ravel()[:-2]), sv.FaceIndexError, "multiple of 3"),
    (lambda V, F, L: dict(faces=F + 0.5), sv.FaceIndexError, "integers"),
    (lambda V, F, L: dict(labels=L[:-3]), sv.LabelError, "for 192 vertices"),
    (lambda V, F, L: dict(labels=L + 2), sv.LabelError, "index label_names"),
    (lambda V, F, L: dict(labels=L + 5, label_names=[]), sv.NoGarmentError, "no garment label present"),
    (lambda V, F, L: dict(label_names=["body", "skin"]), sv.NoGarmentError, "no vertex"),
    (lambda V, F, L: dict(garment_type="cape"), sv.UnknownGarmentTypeError, "'cape'"),
    (lambda V, F, L: dict(label_names=["body", "garment"]), sv.UnknownGarmentTypeError, "no label name"),
    (lambda V, F, L: dict(template_name="missing/file.obj"), sv.UnknownTemplateError, "does not exist"),
    (lambda V, F, L: dict(template_name="cape_v2", known_templates={"tshirt"}), sv.UnknownTemplateError, "cape_v2"),
    (lambda V, F, L: dict(units="inch"), sv.BadOptionError, "units"),
    (lambda V, F, L: dict(up_axis="x"), sv.BadOptionError, "up_axis"),
    (lambda V, F, L: dict(units="cm"), sv.ImplausibleSizeError, "units"),  # metres declared as cm
    (lambda V, F, L: dict(vertices=V * 1000), sv.ImplausibleSizeError, "plausible range"),
    (lambda V, F, L: dict(vertices=np.column_stack([V[:, 0]] * 3)), sv.DegenerateScanError, "degenerate"),
    (lambda V, F, L: dict(vertices=np.column_stack([V[:, 0], 2 * V[:, 0], 3 * V[:, 0]]).astype(np.float32)),
     sv.DegenerateScanError, "total area"),  # collinear up to float32 rounding
    (lambda V, F, L: dict(max_vertices=len(V) - 1), sv.TooLargeError, "limit"),
])
def test_each_problem_has_its_error(mutate, cls, words):
    V, F, L, names = _sphere()
    kw = dict(vertices=V, faces=F, labels=L, label_names=names)
    kw.update(mutate(V, F, L))
    with pytest.raises(cls) as info:
        _check(kw.pop("vertices"), kw.pop("faces"), kw.pop("labels"), kw.pop("label_names"), **kw)
    assert isinstance(info.value, ValueError) and words in str(info.value)
    assert cls.code and cls.code.isupper()
    assert info.value.code == CODES[cls], (type(info.value), info.value.code)


def test_error_codes_are_interface_constants():
    """Every code names an AvatarAssets.ERROR_* constant when the interfaces are installed."""
    msgs = pytest.importorskip("diffavatar_msgs.msg", reason="ROS interfaces not installed")
    classes = sv.all_error_classes()
    assert len(classes) == 15
    for cls in classes:
        assert hasattr(msgs.AvatarAssets, f"ERROR_{cls.code}"), cls


def test_size_is_the_cleaned_scans():
    """A far floating fragment makes the scan as given 3 m wide; cleaning drops it, so neither
    check_scan (the node's front door) nor load_scan refuses the scan, and both give the cleaned
    height. The same scan in mm sent as m is refused by both with one message."""
    V, F, L, names = _sphere()
    frag = np.array([[3.0, 0.0, 0.0], [3.01, 0.0, 0.0], [3.0, 0.01, 0.0]])
    V2 = np.vstack([V, frag])
    F2 = np.vstack([F, [[len(V), len(V) + 1, len(V) + 2]]])
    L2 = np.concatenate([L, [0, 0, 0]]).astype(np.uint8)
    s = _check(V2, F2, L2, names)
    height = V[:, 1].max() - V[:, 1].min()
    assert s.height_m == pytest.approx(height) and len(s.vertices) == len(V2)
    data = sv.load_scan(s)
    assert data.height_m == pytest.approx(height) and len(data.vertices) == len(V)
    assert any("floating fragment" in w for w in data.warnings)
    with pytest.raises(sv.ImplausibleSizeError) as front:
        _check(V2 * 1000, F2, L2, names)
    with pytest.raises(sv.ImplausibleSizeError) as core:
        sv.load_scan({"vertices": V2 * 1000, "faces": F2, "labels": L2, "label_names": names})
    assert str(front.value) == str(core.value) and f"{height * 1000:.4g} m tall" in str(core.value)
