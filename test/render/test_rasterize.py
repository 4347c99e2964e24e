"""Rasterizer and shaded renderer: coverage against analytic areas, depth ordering, sphere
silhouettes, the documented Lambert light rig, supersampling, determinism, blank images."""
import math

import numpy as np
import pytest
import trimesh

import diffavatar_core as dc
from diffavatar_core.render import Camera, orbit_cameras, rasterize, render

N = 64  # image size (px); the orthographic test camera maps 1 m to 1 px


def ortho_cam(n=N):
    """Looks down −Z at the origin; screen x = n/2 + X, y = n/2 − Y (px, with X, Y in m)."""
    return Camera(eye=(0, 0, 10), target=(0, 0, 0), orthographic=True, ortho_height=float(n))


def to_world(sx, sy, n=N, z=0.0):
    return np.array([sx - n / 2, n / 2 - sy, z])


def centres_inside(tri_screen, n=N):
    """Brute force: pixel centres strictly inside a screen-space triangle (numpy)."""
    (x0, y0), (x1, y1), (x2, y2) = tri_screen
    j, i = np.mgrid[0:n, 0:n]
    px, py = i + 0.5, j + 0.5
    def e(ax, ay, bx, by):
        return (bx - ax) * (py - ay) - (by - ay) * (px - ax)
    e0, e1, e2 = e(x0, y0, x1, y1), e(x1, y1, x2, y2), e(x2, y2, x0, y0)
    return ((e0 > 0) & (e1 > 0) & (e2 > 0)) | ((e0 < 0) & (e1 < 0) & (e2 < 0))


TRI = np.array([(10.3, 5.7), (50.2, 20.1), (20.6, 55.4)])


def tri_area_perimeter(t):
    a = 0.5 * abs((t[1, 0] - t[0, 0]) * (t[2, 1] - t[0, 1]) - (t[1, 1] - t[0, 1]) * (t[2, 0] - t[0, 0]))
    per = sum(np.linalg.norm(t[k] - t[(k + 1) % 3]) for k in range(3))
    return a, per


@pytest.mark.parametrize("winding", [(0, 1, 2), (0, 2, 1)])
def test_triangle_covers_its_analytic_area(winding):
    V = np.array([to_world(x, y) for x, y in TRI])
    face, depth, bary = rasterize(V, np.array([winding]), ortho_cam(), N)
    covered = face == 0
    area, per = tri_area_perimeter(TRI)
    # the pixels whose centre is inside, exactly (no centre lies on an edge here) ...
    np.testing.assert_array_equal(covered, centres_inside(TRI))
    # ... whose count is the analytic area to within one row of pixels along the edges
    assert abs(covered.sum() - area) <= per
    np.testing.assert_allclose(depth[covered], 10.0, rtol=1e-12)
    assert np.all(np.isinf(depth[~covered])) and np.all(face[~covered] == -1)
    # barycentrics reproduce the pixel centres (orthographic: affine)
    j, i = np.nonzero(covered)
    b = bary[j, i]
    np.testing.assert_allclose(b.sum(axis=1), 1.0, atol=1e-12)
    P = b @ TRI[list(winding)]
    np.testing.assert_allclose(P, np.column_stack([i + 0.5, j + 0.5]), atol=1e-9)


def test_perspective_triangle_area_scales_with_focal_over_distance_squared():
    n, fov, d = 128, 0.8, 5.0
    cam = Camera(eye=(0, 0, d), target=(0, 0, 0), fov_y=fov)
    focal = 0.5 * n / math.tan(0.5 * fov)  # px
    Wt = np.array([[-1.2, -0.9, 0.0], [1.3, -0.4, 0.0], [0.1, 1.1, 0.0]])  # m, plane at distance d
    face, depth, _ = rasterize(Wt, np.array([[0, 1, 2]]), cam, n)
    S = np.column_stack([n / 2 + focal * Wt[:, 0] / d, n / 2 - focal * Wt[:, 1] / d])
    area, per = tri_area_perimeter(S)
    assert abs((face == 0).sum() - area) <= per
    np.testing.assert_array_equal(face == 0, centres_inside(S, n))
    np.testing.assert_allclose(depth[face == 0], d, rtol=1e-12)


def test_perspective_barycentrics_are_perspective_correct():
    """A triangle slanted in depth: the 3D point from barycentrics projects back onto the pixel
    centre (screen-linear interpolation would not)."""
    n, fov = 96, 0.9
    cam = Camera(eye=(0, 0, 4), target=(0, 0, 0), fov_y=fov)
    V = np.array([[-1.5, -1.0, 1.5], [1.5, -1.2, -2.0], [0.0, 1.4, 0.5]])
    face, depth, bary = rasterize(V, np.array([[0, 1, 2]]), cam, n)
    j, i = np.nonzero(face == 0)
    X = bary[j, i] @ V
    focal = 0.5 * n / math.tan(0.5 * fov)
    z = 4.0 - X[:, 2]
    np.testing.assert_allclose(n / 2 + focal * X[:, 0] / z, i + 0.5, atol=1e-8)
    np.testing.assert_allclose(n / 2 - focal * X[:, 1] / z, j + 0.5, atol=1e-8)
    np.testing.assert_allclose(depth[j, i], z, rtol=1e-10)


@pytest.mark.parametrize("near_first", [True, False])
def test_near_triangle_occludes_far_one(near_first):
    square = np.array([(8, 8), (56, 8), (56, 56), (8, 56)], float)
    near = np.array([to_world(x, y, z=2.0) for x, y in square])
    far = np.array([to_world(x + 10, y + 10, z=-3.0) for x, y in square])
    quads = [near, far] if near_first else [far, near]
    V = np.concatenate(quads)
    F = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    face, depth, _ = rasterize(V, F, ortho_cam(), N)
    near_faces = (0, 1) if near_first else (2, 3)
    inside_near = np.zeros((N, N), bool)
    inside_near[8:56, 8:56] = True
    assert np.isin(face[inside_near], near_faces).all()
    np.testing.assert_allclose(depth[inside_near], 10.0 - 2.0)
    only_far = np.zeros((N, N), bool)
    only_far[18:64, 18:64] = True
    only_far &= ~inside_near
    assert (~np.isin(face[only_far], near_faces) & (face[only_far] >= 0)).all()
    np.testing.assert_allclose(depth[only_far], 13.0)
    # same in the shaded image: the near quad's colour wins where they overlap
    img = render([(near, F[:2], (1.0, 0.0, 0.0)), (far, F[:2], (0.0, 0.0, 1.0))], ortho_cam(), N)
    assert (img[20:50, 20:50, 2] == 0).all() and (img[20:50, 20:50, 0] > 0).all()


def sphere(r, subdivisions=4):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=r)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_sphere_silhouette_area_orthographic():
    n, r = 128, 40.0
    V, F = sphere(r)
    cam = Camera(eye=(0, 0, 100), target=(0, 0, 0), orthographic=True, ortho_height=float(n))
    face, _, _ = rasterize(V, F, cam, n)
    assert abs((face >= 0).sum() / (math.pi * r * r) - 1) < 0.02


def test_sphere_silhouette_area_perspective():
    """A sphere of radius r at distance d projects to a disc of radius f·r/√(d² − r²) px."""
    n, fov, d, r = 160, 0.7, 3.0, 0.8
    V, F = sphere(r)
    cam = Camera(eye=(0, 0, d), target=(0, 0, 0), fov_y=fov)
    face, depth, _ = rasterize(V, F, cam, n)
    f = 0.5 * n / math.tan(0.5 * fov)
    rho = f * r / math.sqrt(d * d - r * r)
    assert abs((face >= 0).sum() / (math.pi * rho * rho) - 1) < 0.02
    assert abs(depth[n // 2, n // 2] - (d - r)) < 2e-3 * r  # icosphere faces are inscribed


def test_lambert_shading_matches_documented_light_rig():
    """A plane facing the camera: c = albedo · min(1, k_a + Σ I_k max(0, n·l_k)), n = towards
    the camera; l_k from cpp/render/shade.hpp in camera coordinates (r, u, b)."""
    V = np.array([[-30, -30, 0], [30, -30, 0], [30, 30, 0], [-30, 30, 0]], float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    albedo = np.array([0.9, 0.6, 0.3])
    l1 = np.array([-0.5, 0.6, 1.0]) / np.linalg.norm([-0.5, 0.6, 1.0])
    l2 = np.array([0.6, 0.1, 1.0]) / np.linalg.norm([0.6, 0.1, 1.0])
    n = np.array([0.0, 0.0, 1.0])  # camera frame: r = +X, u = +Y, b = +Z here
    for ka in (0.0, 0.1):
        light = min(1.0, ka + 0.65 * max(0, n @ l1) + 0.3 * max(0, n @ l2))
        expect = np.round(255 * albedo * light)
        for Fw in (F, F[:, ::-1]):  # two-sided: the winding does not matter
            for smooth in (False, True):
                img = render([(V, Fw, tuple(albedo))], ortho_cam(), N, ambient=ka, smooth=smooth)
                np.testing.assert_array_equal(img[10:50, 10:50].reshape(-1, 3), np.tile(expect, (1600, 1)))


def test_supersampling_antialiases_edges():
    """A black triangle on white with full ambient light: the summed coverage 1 − I/255 is the
    triangle's area, more accurately with 4×4 samples than with 1."""
    V = np.array([to_world(x, y) for x, y in TRI])
    F = np.array([[0, 1, 2]])
    area, per = tri_area_perimeter(TRI)
    errs = {}
    for s in (1, 4):
        img = render([(V, F, (0.0, 0.0, 0.0))], ortho_cam(), N, ambient=1.0, supersample=s)
        cov = 1.0 - img[..., 0].astype(float) / 255
        errs[s] = abs(cov.sum() - area)
        levels = len(np.unique(img[..., 0]))
        assert levels == 2 if s == 1 else levels > 8
    assert errs[4] < 0.1 * per and errs[4] < errs[1] + 1e-9


def test_render_is_deterministic_for_any_thread_count():
    V, F = sphere(0.5, subdivisions=3)
    rng = np.random.default_rng(3)
    V2 = V + 0.05 * rng.standard_normal(V.shape)  # crumpled: many overlapping depths
    cam = orbit_cameras([(V2, F)])["right"]
    before = dc.num_threads()
    try:
        outs = []
        for t in (2, 2, 1, 3):
            dc.set_num_threads(t)
            outs.append((render([(V2, F), (V + [0.3, 0, 0], F)], cam, 200, smooth=True, supersample=2),
                         rasterize(V2, F, cam, 200)))
    finally:
        dc.set_num_threads(before)
    for img, (face, depth, bary) in outs[1:]:
        np.testing.assert_array_equal(img, outs[0][0])
        np.testing.assert_array_equal(face, outs[0][1][0])
        np.testing.assert_array_equal(depth, outs[0][1][1])
        np.testing.assert_array_equal(bary, outs[0][1][2])


def test_blank_images():
    V, F = sphere(0.5, subdivisions=2)
    bg = (0.2, 0.4, 0.6)
    expect = np.round(255 * np.array(bg))
    away = Camera(eye=(0, 0, 3), target=(0, 0, 6))   # looks away from the sphere
    behind = Camera(eye=(0, 0, 0.2), target=(0, 0, 3))  # eye inside: every face crosses the near plane or is behind
    for cam, meshes in ((away, [(V, F)]), (behind, [(V + [0, 0, -2], F)]), (away, [])):
        img = render(meshes, cam, (40, 30), background=bg)
        assert img.shape == (30, 40, 3)
        assert (img == expect).all()
    img = render([(V, F)], orbit_cameras([(V, F)])["front"], 40, background=bg)
    assert (img != expect).any(axis=2).mean() > 0.1


def test_orbit_cameras_frame_the_scene():
    V, F = sphere(1.0, subdivisions=2)
    V = V * [0.3, 0.9, 0.2] + [5.0, 1.0, -2.0]  # off-centre and tall, like a body
    cams = orbit_cameras([(V, F)])
    assert list(cams) == ["front", "right", "back", "left"]
    for name, d in zip(cams, ([0, 0, 1], [1, 0, 0], [0, 0, -1], [-1, 0, 0])):
        cam = cams[name]
        np.testing.assert_allclose(cam.target, [5.0, 1.0, -2.0], atol=1e-9)
        v = np.subtract(cam.eye, cam.target)
        np.testing.assert_allclose(v / np.linalg.norm(v), d, atol=1e-12)
        face, _, _ = rasterize(V, F, cam, 64)
        on = face >= 0
        assert on.any() and not (on[0].any() or on[-1].any() or on[:, 0].any() or on[:, -1].any())
    for cam in orbit_cameras([(V, F)], orthographic=True).values():
        face, _, _ = rasterize(V, F, cam, 64)
        assert (face >= 0).any() and not (face[0] >= 0).any()


def test_invalid_inputs_raise_value_error_naming_the_argument():
    V, F = sphere(0.5, subdivisions=1)
    cam = orbit_cameras([(V, F)])["front"]
    with pytest.raises(ValueError, match="camera.fov_y"):
        Camera(eye=(0, 0, 1), target=(0, 0, 0), fov_y=4.0)
    with pytest.raises(ValueError, match="camera.up"):
        Camera(eye=(0, 2, 0), target=(0, 0, 0))
    with pytest.raises(ValueError, match="camera.eye"):
        Camera(eye=(0, 0, 0), target=(0, 0, 0))
    with pytest.raises(ValueError, match=r"meshes\[0\].F"):
        render([(V, F + 1000)], cam, 32)
    with pytest.raises(ValueError, match=r"meshes\[0\].colour"):
        render([(V, F, (2, 0, 0))], cam, 32)
    with pytest.raises(ValueError, match="size"):
        render([(V, F)], cam, 0)
    with pytest.raises(ValueError, match="supersample"):
        render([(V, F)], cam, 32, supersample=9)
    with pytest.raises(ValueError, match="camera"):
        render([(V, F)], "front", 32)


def test_triangle_grazing_the_near_plane_is_drawn_without_overflow():
    """A vertex just beyond the near plane projects ~1e9 px off screen (beyond int32): the triangle is still
    clipped to the image correctly (pixel bounds are clamped before integer conversion)."""
    cam = Camera(eye=(0, 0, 1), target=(0, 0, 0), fov_y=1.0, near=1e-11)
    V = np.array([[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.2, 0.3, 1.0 - 1e-9]])
    face, depth, _ = rasterize(V, np.array([[0, 1, 2]]), cam, 32)
    assert (face == 0).sum() > 0 and np.all(depth[face == 0] > 0)


def test_matches_brute_force_zbuffer_on_a_random_triangle_soup():
    """Every pixel × every triangle in numpy (perspective, 1/z interpolation, nearest wins, ties to
    the lower index) against the C++ kernel: same visible face and depth on all but
    edge-coincident pixels."""
    n, fov = 48, 0.9
    rng = np.random.default_rng(7)
    T = 150
    C = rng.uniform(-1, 1, (T, 1, 3))
    V = (C + 0.4 * rng.standard_normal((T, 3, 3))).reshape(-1, 3)
    F = np.arange(3 * T).reshape(T, 3)
    cam = Camera(eye=(0.2, 0.1, 4.0), target=(0, 0, 0), fov_y=fov)
    face, depth, _ = rasterize(V, F, cam, n)

    f = -np.array(cam.eye) / np.linalg.norm(cam.eye)
    r = np.cross(f, cam.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = V - np.array(cam.eye)
    z = d @ f
    foc = 0.5 * n / math.tan(0.5 * fov)
    sx, sy = n / 2 + foc * (d @ r) / z, n / 2 - foc * (d @ u) / z
    j, i = np.mgrid[0:n, 0:n]
    px, py = (i + 0.5).reshape(-1, 1), (j + 0.5).reshape(-1, 1)
    X, Y, Z = sx[F], sy[F], z[F]  # T×3
    area2 = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (Y[:, 1] - Y[:, 0]) * (X[:, 2] - X[:, 0])
    e = [((X[:, (k + 1) % 3] - px) * (Y[:, (k + 2) % 3] - py) - (Y[:, (k + 1) % 3] - py) * (X[:, (k + 2) % 3] - px))
         / area2 for k in range(3)]  # each (n², T)
    inside = (e[0] >= 0) & (e[1] >= 0) & (e[2] >= 0)
    zz = np.where(inside, 1.0 / (e[0] / Z[:, 0] + e[1] / Z[:, 1] + e[2] / Z[:, 2]), np.inf)
    ref_face = np.where(np.isfinite(zz).any(axis=1), np.argmin(zz, axis=1), -1).reshape(n, n)
    ref_depth = zz.min(axis=1).reshape(n, n)
    assert (face >= 0).mean() > 0.3
    assert (face == ref_face).mean() > 0.998
    agree = (face == ref_face) & (face >= 0)
    np.testing.assert_allclose(depth[agree], ref_depth[agree], rtol=1e-10)
