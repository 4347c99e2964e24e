"""Bad scans raise the named ScanError subclass (a ValueError) with a message naming the
problem, from files and from arrays; never a crash or silent garbage."""
import numpy as np
import pytest

from diffavatar_core.scan import (DegenerateScanError, EmptyScanError, FaceIndexError,
                                  ImplausibleSizeError, LabelError, NoGarmentError, NonFiniteError,
                                  ScanError, ScanFormatError, load_scan, read_scan_file)
from synthetic_scan import core_to_scan, synthetic, write_ply  # noqa: F401 (fixture)


def _arrays(s, units="m", up="y"):
    return core_to_scan(s.V, units, up), s.F.copy(), s.labels.copy()


def test_every_scan_error_is_a_value_error():
    for cls in (ScanFormatError, EmptyScanError, NonFiniteError, FaceIndexError, LabelError,
                NoGarmentError, DegenerateScanError, ImplausibleSizeError):
        assert issubclass(cls, ScanError) and issubclass(cls, ValueError)


def test_empty_scans(tmp_path):
    with pytest.raises(EmptyScanError, match="no vertices"):
        load_scan((np.zeros((0, 3)), np.zeros((0, 3), int)))
    with pytest.raises(EmptyScanError, match="no triangles"):
        load_scan((np.eye(3), np.zeros((0, 3), int)))
    p = tmp_path / "empty.ply"
    write_ply(p, np.zeros((0, 3)), np.zeros((0, 3), int))
    with pytest.raises(EmptyScanError):
        read_scan_file(p)


def test_nan_and_inf_vertices_are_named(synthetic, tmp_path):
    V, F, L = _arrays(synthetic)
    V[7, 1] = np.nan
    V[9, 0] = np.inf
    with pytest.raises(NonFiniteError, match=r"2 vertex/vertices have NaN or Inf.*first: vertex 7"):
        load_scan((V, F, L))
    p = tmp_path / "nan.ply"
    write_ply(p, V, F, L, binary=True)
    with pytest.raises(NonFiniteError):
        load_scan(p)


def test_face_index_out_of_range(synthetic, tmp_path):
    V, F, L = _arrays(synthetic)
    F[3, 2] = len(V)
    with pytest.raises(FaceIndexError, match=rf"outside \[0, {len(V)}\).*first: face 3"):
        load_scan((V, F, L))
    F[3, 2] = -1
    with pytest.raises(FaceIndexError):
        load_scan((V, F, L))
    p = tmp_path / "bad.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    with pytest.raises(FaceIndexError, match="face 0"):
        read_scan_file(p)
    with pytest.raises(FaceIndexError, match="integers"):
        load_scan((V, F + 0.5, L))


def test_labels_of_the_wrong_length_or_type(synthetic):
    V, F, L = _arrays(synthetic)
    with pytest.raises(LabelError, match=rf"one per vertex, shape \({len(V)},\)"):
        load_scan((V, F, L[:-1]))
    with pytest.raises(LabelError, match="integers"):
        load_scan((V, F, L + 0.5))


def test_no_vertex_with_the_requested_label(synthetic):
    with pytest.raises(NoGarmentError, match=r"no vertices with label 'pants' \(4\).*body \(0\): "):
        load_scan(_arrays(synthetic), label="pants")
    with pytest.raises(LabelError, match="not in the label map"):
        load_scan(_arrays(synthetic), label="cape")
    with pytest.raises(LabelError, match="'body' .* is not a garment"):
        load_scan(_arrays(synthetic), label="body")
    V, F, L = _arrays(synthetic)
    L[L == 1] = 0
    with pytest.raises(NoGarmentError, match="no garment label present"):
        load_scan((V, F, L))


def test_label_on_vertices_but_on_no_whole_triangle(synthetic):
    V, F, L = _arrays(synthetic)
    L[:] = 0
    L[[F[0, 0], F[5000, 1]]] = 3          # two isolated vertices labelled 'skirt'
    with pytest.raises(NoGarmentError, match="but no triangle has all three"):
        load_scan((V, F, L), label="skirt")


def test_several_garments_need_a_choice(synthetic):
    V, F, L = _arrays(synthetic)
    shirt = np.flatnonzero(L == 1)
    L[shirt[V[shirt, 1] < 1.0]] = 4            # the lower part of the shirt relabelled 'pants'
    with pytest.raises(NoGarmentError, match=r"several garments in the scan \(upper, pants\)"):
        load_scan((V, F, L))
    assert load_scan((V, F, L), garment_type="tshirt").garment_label == 1


def test_garment_only_scan_needs_a_known_type(synthetic):
    V, F, _ = _arrays(synthetic)
    with pytest.raises(NoGarmentError, match="needs the garment type"):
        load_scan((V, F))
    with pytest.raises(LabelError, match="garment type 'cape' is not known"):
        load_scan((V, F), garment_type="cape")


def test_all_degenerate_triangles():
    V = np.column_stack([np.linspace(0, 1.5, 6), np.linspace(0, 1.5, 6), np.zeros(6)])   # collinear
    F = np.array([[0, 1, 2], [1, 2, 3], [2, 3, 4], [3, 4, 5], [0, 0, 1]])
    with pytest.raises(DegenerateScanError, match="all 5 triangles are degenerate"):
        load_scan((V, F), garment_type="tshirt")


def test_a_two_metre_shirt_given_in_m_read_as_cm(synthetic):
    V, F, L = _arrays(synthetic, "m")
    with pytest.raises(ImplausibleSizeError, match=r"0\.017 m tall.*units=m would make it 1\.7 m tall"):
        load_scan((V, F, L), units="cm")
    with pytest.raises(ImplausibleSizeError, match="1700 m tall"):
        load_scan((V * 1000, F, L), units="m")


def test_wrong_up_axis_is_hinted(synthetic):
    V, F, L = _arrays(synthetic)
    Vz = core_to_scan(V * [1, 1, 0.5], "m", "z")      # a Z-up file, 0.12 m deep, read as Y-up
    with pytest.raises(ImplausibleSizeError, match=r"0\.12 m tall.*up=z would make it 1\.7 m tall"):
        load_scan((Vz, F, L), up="y")
    assert load_scan((Vz, F, L), up="z").height_m == pytest.approx(1.7)
    V2 = V * [1, 2, 1]                                  # 3.4 m tall: nothing can save it
    with pytest.raises(ImplausibleSizeError, match="3.4 m tall"):
        load_scan((V2, F, L))


def test_unknown_units_up_axis_and_unreadable_files(synthetic, tmp_path):
    with pytest.raises(ScanFormatError, match="units: expected one of m, cm, mm, got 'inch'"):
        load_scan(_arrays(synthetic), units="inch")
    with pytest.raises(ScanFormatError, match="up axis"):
        load_scan(_arrays(synthetic), up="x")
    p = tmp_path / "junk.ply"
    p.write_text("this is not a mesh")
    with pytest.raises(ScanFormatError, match="cannot be read"):
        read_scan_file(p)
    q = tmp_path / "junk.obj"
    q.write_text("v 0 0 zero\n")
    with pytest.raises(ScanFormatError, match="junk.obj:1: not a number"):
        read_scan_file(q)
    with pytest.raises(FileNotFoundError):
        read_scan_file(tmp_path / "missing.ply")
    with pytest.raises(ScanFormatError, match="expected a path"):
        load_scan(42)


def test_label_given_for_an_unlabelled_scan(synthetic):
    V, F, _ = _arrays(synthetic)
    with pytest.raises(LabelError, match="no per-vertex labels"):
        load_scan((V, F), label="upper", garment_type="tshirt")


@pytest.mark.parametrize("field,value", [("min_height", 0.0), ("max_height", 0.1), ("merge_tolerance", -1.0),
                                         ("min_component_fraction", 1.0), ("interior_samples", 2.5),
                                         ("interior_margin", float("nan")), ("seed", -1)])
def test_bad_options_are_named(field, value):
    from diffavatar_core.scan import ScanOptions
    with pytest.raises(ValueError, match=f"scan options: .*{field}"):
        ScanOptions(**{field: value})


def test_options_from_config_reject_unknown_keys():
    from diffavatar_core.scan import ScanOptions
    assert ScanOptions.from_config() == ScanOptions()        # config/diffavatar.yaml = the defaults
    with pytest.raises(ValueError, match="scan.margin"):
        ScanOptions.from_config({"scan": {"margin": 0.1}})
