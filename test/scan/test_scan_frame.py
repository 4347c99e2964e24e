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


@pytest.mark.parametrize("up", ["y", "z"])
def test_a_shifted_transform_round_trips_and_turns_with_its_origin(up):
    """p_core = scale·R·p − origin: to_scan inverts it, and turned(Q) is the same map followed by Q
    (the origin turned with the frame), so results turned back and shifted back land on the scan."""
    from diffavatar_core.pipeline.facing import yaw_rotation
    t = ScanTransform.from_options("cm", up).shifted([30.0, 2.0, -40.0])
    P = np.random.default_rng(2).normal(size=(50, 3)) * 100 + 3000.0
    np.testing.assert_allclose(t.to_core(P), 0.01 * (P @ t.rotation.T) - [30.0, 2.0, -40.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(t.to_scan(t.to_core(P)), P, rtol=0, atol=1e-9)
    Q = yaw_rotation(0.7)
    tq = t.turned(Q)
    np.testing.assert_allclose(tq.to_core(P), t.to_core(P) @ Q.T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tq.to_scan(tq.to_core(P)), P, rtol=0, atol=1e-9)
    assert t.to_dict()["origin_m"] == [30.0, 2.0, -40.0]


def test_a_scan_near_its_origin_keeps_its_coordinates_and_a_far_one_stands_on_the_floor_at_0():
    """centring_origin: zero (no shift, the converted coordinates bit for bit) within FAR_FROM_ORIGIN;
    beyond it the floor below the subject, in whole metres, so the shifted subject stands as one near
    the origin does (a 1.7 m column of points, its lowest at the floor)."""
    from diffavatar_core.scan.frame import FAR_FROM_ORIGIN, centring_origin
    rng = np.random.default_rng(3)
    person = rng.uniform([-0.25, 0.0, -0.15], [0.25, 1.7, 0.15], size=(2000, 3))
    assert not centring_origin(person).any()
    assert not centring_origin(person + [FAR_FROM_ORIGIN - 0.5, 0.0, -(FAR_FROM_ORIGIN - 0.5)]).any()
    for offset in ([30.2, 0.0, 0.0], [0.0, -12.0, 0.0], [-3.4, 5.1, 250.0]):
        o = centring_origin(person + offset)
        np.testing.assert_array_equal(o, np.round(offset))
        shifted = person + offset - o
        assert abs(np.percentile(shifted[:, 1], 1.0)) < 0.5 and np.abs(np.median(shifted[:, [0, 2]], axis=0)).max() < 0.5


def test_an_upside_down_garment_is_hinted_by_its_openings():
    """upside_down_hint: a waist or neckline longer than 1.25 × the hem (a skirt turned over: the
    rules name the top loop 'waist') gets a hint naming both lengths and the up axis to give; a
    garment the right way up, or without both openings, gets none."""
    from diffavatar_core.scan.frame import upside_down_hint

    def ring(radius, y, n=64):
        t = 2 * np.pi * np.arange(n) / n
        return np.column_stack([radius * np.cos(t), np.full(n, y), radius * np.sin(t)])
    t = ScanTransform.from_options("cm", "y")
    upright = {"waist": ring(0.12, 1.0), "hem": ring(0.22, 0.5)}
    assert upside_down_hint(upright, t) == ""
    assert upside_down_hint({"hem": ring(0.22, 0.5)}, t) == ""
    turned = {"waist": ring(0.22, -0.5), "hem": ring(0.12, -1.0)}   # the same skirt read the wrong way up
    h = upside_down_hint(turned, t)
    assert "upside down" in h and "up=-y" in h and "'waist', 138 cm" in h and "'hem', 75 cm" in h
    assert "up=y" in upside_down_hint(turned, ScanTransform.from_options("cm", "-y"))
    assert upside_down_hint({"neckline": ring(0.135, 1.4), "hem": ring(0.12, 0.9)}, t) == ""   # 1.13×: e.g. off-shoulder
