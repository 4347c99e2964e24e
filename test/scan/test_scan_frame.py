"""The scan-frame → core-frame transform: a proper rotation and a uniform scale, exact inverse,
Z-up convention (the file's +Z becomes +Y, its -Y (forward) becomes +Z, +X stays the left)."""
import numpy as np
import pytest

from diffavatar_core.scan import ScanTransform


@pytest.mark.parametrize("units,scale", [("m", 1.0), ("cm", 0.01), ("mm", 0.001)])
@pytest.mark.parametrize("up", ["y", "z"])
def test_round_trip_and_proper_rotation(units, scale, up):
    t = ScanTransform.from_options(units, up)
    assert t.scale == scale
    R = t.rotation
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=0)
    assert np.linalg.det(R) == pytest.approx(1.0)
    P = np.random.default_rng(1).normal(size=(50, 3)) * 100
    np.testing.assert_allclose(t.to_scan(t.to_core(P)), P, rtol=1e-14, atol=1e-12)
    # distances scale uniformly
    d_scan = np.linalg.norm(P[1:] - P[:-1], axis=1)
    C = t.to_core(P)
    np.testing.assert_allclose(np.linalg.norm(C[1:] - C[:-1], axis=1), scale * d_scan, rtol=1e-13)


def test_z_up_axes():
    t = ScanTransform.from_options("m", "z")
    np.testing.assert_array_equal(t.to_core([[0, 0, 1]]), [[0, 1, 0]])     # up → +Y
    np.testing.assert_array_equal(t.to_core([[0, -1, 0]]), [[0, 0, 1]])    # forward (-Y) → +Z
    np.testing.assert_array_equal(t.to_core([[1, 0, 0]]), [[1, 0, 0]])     # the left stays +X


def test_options_are_case_and_space_tolerant_and_serialisable():
    t = ScanTransform.from_options(" CM ", "Z")
    assert (t.units, t.up, t.scale) == ("cm", "z", 0.01)
    d = t.to_dict()
    assert d["scale_m_per_unit"] == 0.01 and d["rotation"][1] == [0.0, 0.0, 1.0]
