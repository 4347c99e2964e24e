"""Upside-down scans: a Y-down file (the camera frame of OpenCV and most photogrammetry) read as
Y-up fitted the body model badly and its drape fell off the body (SIMULATION_FAILED, a message
about the drape). Now `up` takes -y / -z, and a full scan whose body fits far better turned over
is refused naming the up axis to give (recovery._refuse_upside_down)."""
import numpy as np
import pytest

import bundled_sample
from bundled_sample import QUICK
from diffavatar_core.pipeline import recover
from diffavatar_core.pipeline.recovery import RecoveryError
from diffavatar_core.scan import load_scan
from diffavatar_core.scan.frame import UP_ROTATIONS


@pytest.fixture(scope="module")
def sample_arrays():
    return bundled_sample.sample_arrays()


@pytest.mark.parametrize("up", ["-y", "-z", "z"])
def test_a_file_with_another_up_axis_given_as_such_is_the_same_scan_bit_for_bit(sample_arrays, up):
    """The sample written as a file whose up is `up` (core = R·p, so p = Rᵀ·core; R's entries are 0 / ±1:
    exact) and read with that up axis: the same scan, to the last bit, so the same recovery."""
    V, F, L = sample_arrays
    as_file = V @ UP_ROTATIONS[up]   # rows: p = Rᵀ v
    ref = load_scan((V, F, L), units="cm")
    got = load_scan((as_file, F, L), units="cm", up=up)
    np.testing.assert_array_equal(got.vertices, ref.vertices)
    assert sorted(got.boundaries) == sorted(ref.boundaries)
    np.testing.assert_array_equal(got.interior_points, ref.interior_points)


def test_an_upside_down_scan_is_refused_naming_the_up_axis_to_give(sample_arrays):
    V, F, L = sample_arrays
    with pytest.raises(RecoveryError) as e:
        recover((V * [1.0, -1.0, -1.0], F, L), QUICK)   # a Y-down file read as Y-up
    assert e.value.code == "BAD_OPTION"
    assert "upside down" in str(e.value) and "up=-y" in str(e.value) and "--up=-y" in str(e.value)
