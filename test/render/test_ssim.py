"""SSIM (Wang et al. 2004): identity, symmetry, a hand-computed value, monotonic decrease with
noise, agreement with scikit-image when that happens to be installed."""
import numpy as np
import pytest
import trimesh

from diffavatar_core.render import luminance, orbit_cameras, render, ssim, ssim_map


@pytest.fixture(scope="module")
def rendered():
    m = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    box = trimesh.creation.box(extents=(0.5, 0.2, 0.3))
    Vb = np.asarray(box.vertices) + [0.3, -0.3, 0.1]
    meshes = [(V, F), (Vb, np.asarray(box.faces))]
    return render(meshes, orbit_cameras(meshes)["front"], 96, smooth=True, supersample=2)


def test_identity_and_symmetry(rendered):
    assert ssim(rendered, rendered) == pytest.approx(1.0, abs=1e-12)
    rng = np.random.default_rng(0)
    noisy = np.clip(rendered + rng.normal(0, 20, rendered.shape), 0, 255).astype(np.uint8)
    s = ssim(rendered, noisy)
    assert s < 1.0
    assert s == pytest.approx(ssim(noisy, rendered), abs=1e-12)
    m = ssim_map(rendered, noisy)
    assert m.shape == (96 - 10, 96 - 10) and np.all(m <= 1 + 1e-12)


def test_constant_images_hand_value():
    """Two constant images a, b: σ = 0, so SSIM = (2ab + C1)/(a² + b² + C1) · C2/C2 everywhere."""
    a, b = 100.0, 150.0
    C1 = (0.01 * 255) ** 2
    x, y = np.full((16, 20), a), np.full((16, 20), b)
    assert ssim(x, y) == pytest.approx((2 * a * b + C1) / (a * a + b * b + C1), rel=1e-12)
    # the window is normalized: a constant image is its own mean, so equal constants give 1
    assert ssim(x, x.copy()) == pytest.approx(1.0, abs=1e-12)


def test_decreases_monotonically_with_noise(rendered):
    rng = np.random.default_rng(1)
    z = rng.standard_normal(rendered.shape)
    values = [ssim(rendered, np.clip(rendered + s * z, 0, 255)) for s in (0, 2, 5, 10, 20, 40, 80)]
    assert values[0] == pytest.approx(1.0)
    assert all(b < a for a, b in zip(values, values[1:])), values


def test_luminance_weights():
    img = np.zeros((2, 2, 3))
    img[0, 0] = (255, 0, 0)
    img[0, 1] = (0, 255, 0)
    img[1, 0] = (0, 0, 255)
    img[1, 1] = (255, 255, 255)
    np.testing.assert_allclose(luminance(img), 255 * np.array([[0.299, 0.587], [0.114, 1.0]]))


def test_matches_scikit_image_when_installed(rendered):
    metrics = pytest.importorskip("skimage.metrics", reason="scikit-image not installed (not a dependency)")
    rng = np.random.default_rng(2)
    noisy = np.clip(rendered + rng.normal(0, 15, rendered.shape), 0, 255)
    x, y = luminance(rendered), luminance(noisy)
    ref = metrics.structural_similarity(x, y, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                        data_range=255.0)
    assert ssim(rendered, noisy) == pytest.approx(ref, abs=1e-6)


def test_invalid_inputs():
    with pytest.raises(ValueError, match="img2"):
        ssim(np.zeros((20, 20)), np.zeros((20, 21)))
    with pytest.raises(ValueError, match="img1"):
        ssim(np.zeros((8, 8)), np.zeros((8, 8)))
    with pytest.raises(ValueError, match="img"):
        ssim(np.zeros((20, 20, 4)), np.zeros((20, 20, 4)))
