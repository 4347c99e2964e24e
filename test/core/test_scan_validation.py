"""Scan validation shared by the CLI and the node: every problem has its own ScanError subclass
(a ValueError) naming the field; a good scan comes back in metres, Y up."""
import numpy as np
import pytest

from diffavatar_core import scan_validation as sv


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
    s = sv.validate_scan(V, F, L, names)
    np.testing.assert_array_equal(s.vertices, V)
    assert s.garment_type == "dress" and s.faces.dtype == np.int32
    np.testing.assert_array_equal(s.garment_mask, V[:, 1] > 0)
    assert len(s.garment_faces) and s.garment_mask[s.garment_faces].all()

    # the same scan stated in cm with Z up: (x, y, z)_yup = (x, z, -y)_zup / 100 exactly back
    Vz = np.column_stack([V[:, 0], -V[:, 2], V[:, 1]]) * 100
    s2 = sv.validate_scan(Vz.ravel(), F.ravel(), L, names, units="cm", up_axis="z", garment_type="Dress")
    np.testing.assert_allclose(s2.vertices, V, rtol=0, atol=1e-15)
    assert (s2.source_units, s2.source_up_axis, s2.garment_type) == ("cm", "z", "dress")


def test_garment_only_scan_and_type_spellings():
    V, F, _, _ = _sphere()
    s = sv.validate_scan(V, F, None, (), garment_type="T-Shirt")
    assert s.garment_type == "tshirt" and s.garment_mask.all() and s.labels is None
    with pytest.raises(sv.UnknownGarmentTypeError, match="not given"):
        sv.validate_scan(V, F, np.zeros(0), ())


@pytest.mark.parametrize("mutate,cls,words", [
    (lambda V, F, L: dict(vertices=np.zeros((0, 3))), sv.EmptyMeshError, "no vertices"),
    (lambda V, F, L: dict(faces=np.zeros((0, 3), int)), sv.EmptyMeshError, "no triangles"),
    (lambda V, F, L: dict(vertices=np.where(np.arange(V.size).reshape(V.shape) == 4, np.nan, V)),
     sv.NonFiniteError, "vertex 1"),
    (lambda V, F, L: dict(vertices=V.ravel()[:-1]), sv.VertexArrayError, "multiple of 3"),
    (lambda V, F, L: dict(vertices=V[:, :2]), sv.VertexArrayError, "shape"),
    (lambda V, F, L: dict(vertices=np.array(["a"] * 9)), sv.VertexArrayError, "numbers"),
    (lambda V, F, L: dict(faces=np.vstack([F, [[0, 1, len(V)]]])), sv.FaceIndexError, "[0, 192)"),
    (lambda V, F, L: dict(faces=np.vstack([F, [[0, -1, 2]]])), sv.FaceIndexError, "outside"),
    (lambda V, F, L: dict(faces=F.ravel()[:-2]), sv.FaceIndexError, "multiple of 3"),
    (lambda V, F, L: dict(faces=F + 0.5), sv.FaceIndexError, "integers"),
    (lambda V, F, L: dict(labels=L[:-3]), sv.LabelsError, "for 192 vertices"),
    (lambda V, F, L: dict(labels=L + 2), sv.LabelsError, "index label_names"),
    (lambda V, F, L: dict(label_names=[]), sv.LabelsError, "label_names is empty"),
    (lambda V, F, L: dict(label_names=["body", "skin"]), sv.NoGarmentError, "no vertex"),
    (lambda V, F, L: dict(garment_type="cape"), sv.UnknownGarmentTypeError, "'cape'"),
    (lambda V, F, L: dict(label_names=["body", "garment"]), sv.UnknownGarmentTypeError, "no label name"),
    (lambda V, F, L: dict(template_name="missing/file.obj"), sv.UnknownTemplateError, "does not exist"),
    (lambda V, F, L: dict(template_name="cape_v2", known_templates={"tshirt"}), sv.UnknownTemplateError, "cape_v2"),
    (lambda V, F, L: dict(units="mm"), sv.BadOptionError, "units"),
    (lambda V, F, L: dict(up_axis="x"), sv.BadOptionError, "up_axis"),
    (lambda V, F, L: dict(units="cm"), sv.ImplausibleSizeError, "units"),  # metres declared as cm
    (lambda V, F, L: dict(vertices=V * 1000), sv.ImplausibleSizeError, "plausible range"),
    (lambda V, F, L: dict(vertices=np.column_stack([V[:, 0]] * 3)), sv.ImplausibleSizeError, "degenerate"),
    (lambda V, F, L: dict(max_vertices=len(V) - 1), sv.TooLargeError, "limit"),
])
def test_each_problem_has_its_error(mutate, cls, words):
    V, F, L, names = _sphere()
    kw = dict(vertices=V, faces=F, labels=L, label_names=names)
    kw.update(mutate(V, F, L))
    with pytest.raises(cls) as info:
        sv.validate_scan(kw.pop("vertices"), kw.pop("faces"), kw.pop("labels"), kw.pop("label_names"), **kw)
    assert isinstance(info.value, ValueError) and words in str(info.value)
    assert cls.code and cls.code.isupper()


def test_error_codes_are_interface_constants():
    """Every code names an AvatarAssets.ERROR_* constant when the interfaces are installed."""
    msgs = pytest.importorskip("diffavatar_msgs.msg", reason="ROS interfaces not installed")
    for cls in sv.ScanError.__subclasses__():
        assert hasattr(msgs.AvatarAssets, f"ERROR_{cls.code}"), cls
