import numpy as np
import pytest

from diffavatar_core.landmarks import BodyLandmarks, _POINTS


def _example():
    rng = np.random.default_rng(3)
    d = {k: rng.normal(size=3) for k in _POINTS}
    d.update(height=1.7, chest_girth=0.95, waist_girth=0.8, hip_girth=1.0)
    return d


def test_dict_round_trip_is_exact():
    lm = BodyLandmarks(**_example())
    back = BodyLandmarks.from_dict(lm.to_dict())
    for k in _POINTS:
        np.testing.assert_array_equal(getattr(lm, k), getattr(back, k))
    assert back.height == lm.height


@pytest.mark.parametrize("field,value", [("neck_base", [0, np.nan, 0]), ("height", -1.0), ("wrist_left", [1, 2])])
def test_bad_values_are_named(field, value):
    d = _example()
    d[field] = value
    with pytest.raises(ValueError, match=field):
        BodyLandmarks(**d)
