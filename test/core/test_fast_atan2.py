"""The bending kernel's atan2 (common/fast_atan2.hpp) against the correctly rounded one."""
import numpy as np

from diffavatar_core import _core


def test_matches_the_correctly_rounded_atan2_to_a_few_ulp_in_every_quadrant():
    rng = np.random.default_rng(0)
    # magnitudes over 12 decades and every sign combination, plus the reduction boundaries
    y = rng.standard_normal(400_000) * 10.0 ** rng.uniform(-6, 6, 400_000)
    x = rng.standard_normal(400_000) * 10.0 ** rng.uniform(-6, 6, 400_000)
    t8, t38 = np.tan(np.pi / 8), np.tan(3 * np.pi / 8)
    edge = np.array([t8, t38, 1.0, 0.66])
    edge = np.concatenate([np.nextafter(edge, 0), edge, np.nextafter(edge, 2)])
    y = np.concatenate([y, edge, -edge, edge, -edge, [0.0, -0.0, 1.0, -1.0, 0.0, -0.0]])
    x = np.concatenate([x, np.ones_like(edge), np.ones_like(edge), -np.ones_like(edge), -np.ones_like(edge),
                        [1.0, 1.0, 0.0, 0.0, -1.0, -1.0]])
    ref = np.arctan2(y, x)
    got = _core.fast_atan2(y, x)
    ulp = np.abs(got - ref) / np.spacing(np.maximum(np.abs(ref), np.finfo(float).tiny))
    assert ulp.max() <= 4.0, f"max error {ulp.max():.1f} ulp at y={y[ulp.argmax()]}, x={x[ulp.argmax()]}"
    # signed zeros and the axes exactly as atan2 defines them
    assert np.array_equal(np.signbit(got[-6:]), np.signbit(ref[-6:]))
    assert np.array_equal(got[-6:], ref[-6:])


def test_is_odd_in_y_and_reflects_in_x():
    rng = np.random.default_rng(1)
    y, x = rng.uniform(-3, 3, 10_000), rng.uniform(-3, 3, 10_000)
    a = _core.fast_atan2(y, x)
    assert np.array_equal(_core.fast_atan2(-y, x), -a)
    # atan2(y, −x) = sign(y) π − atan2(y, x), exactly up to the rounding of π − t
    np.testing.assert_allclose(_core.fast_atan2(y, -x), np.sign(y) * np.pi - a, rtol=0, atol=4e-16 * np.pi)
