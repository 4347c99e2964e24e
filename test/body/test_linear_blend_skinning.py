"""Linear blend skinning of the default body: analytic Jacobians against central differences,
rest-state identity, joint limits, rigid invariance."""
import numpy as np
import pytest

from diffavatar_core.body import BodyModel, BodyParams


@pytest.fixture(scope="module")
def model():
    return BodyModel.default()


def random_params(model, rng, spread=0.6):
    """Random parameters strictly inside the joint limits (interior: the map is smooth there)."""
    lo, hi = model.limits_lo, model.limits_hi
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    pose = mid + spread * half * rng.uniform(-1, 1, size=lo.shape)
    return BodyParams(rng.normal(size=model.num_shape), pose, rng.uniform(0.9, 1.1, model.num_joints),
                      rng.normal(scale=0.8, size=3), rng.normal(scale=0.3, size=3))


def test_default_body_sizes_and_frame(model):
    assert model.num_vertices == 13380 and len(model.faces) == 26756
    assert model.num_joints == 22 and model.num_shape == 10
    V = model.v_template
    height = V[:, 1].max() - V[:, 1].min()
    assert 1.5 < height < 2.0 and abs(V[:, 1].min()) < 1e-12          # metres, floor at y = 0
    left = model.joints(model.zero_params())[model.joint_index("wrist_left")]
    assert left[0] > 0.3                                               # +X is the body's left
    toes = V[V[:, 1] < 0.05]
    assert toes[:, 2].max() > 0.12                                     # feet point to +Z (facing +Z)


def test_zero_params_reproduce_template(model):
    p = model.zero_params()
    np.testing.assert_allclose(model.pose(p), model.v_template, atol=1e-14)
    np.testing.assert_allclose(model.joints(p), model.j_template, atol=1e-14)


def test_jacobian_matches_central_differences(model):
    rng = np.random.default_rng(3)
    p = random_params(model, rng)
    verts = rng.choice(model.num_vertices, 300, replace=False)
    J = model.jacobian(p, verts)
    x0 = p.to_vector()
    h = 1e-6
    worst = 0.0
    for c in range(model.num_params):
        xp, xm = x0.copy(), x0.copy()
        xp[c] += h
        xm[c] -= h
        fp = model.pose(BodyParams.from_vector(xp, model.num_shape, model.num_joints))[verts]
        fm = model.pose(BodyParams.from_vector(xm, model.num_shape, model.num_joints))[verts]
        fd = (fp - fm) / (2 * h)
        worst = max(worst, np.abs(fd - J[:, :, c]).max())
    assert worst < 1e-6, worst
    # the full Jacobian agrees with the vertex subset
    np.testing.assert_allclose(model.jacobian(p)[verts], J, atol=1e-12)


def test_joint_limits_never_violated(model):
    rng = np.random.default_rng(5)
    p = random_params(model, rng)
    p.pose = p.pose + rng.normal(scale=3.0, size=p.pose.shape)      # far outside the limits
    clamped = p.copy()
    clamped.pose = model.clamp_pose(p.pose)
    assert np.all(clamped.pose >= model.limits_lo) and np.all(clamped.pose <= model.limits_hi)
    np.testing.assert_allclose(model.pose(p), model.pose(clamped), atol=1e-14)
    # a clamped angle has no effect: its Jacobian column is zero
    J = model.jacobian(p, np.arange(0, model.num_vertices, 97))
    sl = model.param_slices()["pose"]
    outside = ((p.pose < model.limits_lo) | (p.pose > model.limits_hi)).reshape(-1)
    assert np.all(J[:, :, sl][:, :, outside] == 0.0)


def test_global_rigid_motion_commutes(model):
    rng = np.random.default_rng(7)
    p = random_params(model, rng)
    base = p.copy()
    base.rotation[:] = 0
    base.translation[:] = 0
    from scipy.spatial.transform import Rotation
    R = Rotation.from_rotvec(p.rotation).as_matrix()
    np.testing.assert_allclose(model.pose(p), model.pose(base) @ R.T + p.translation, atol=1e-12)


def test_bone_scale_lengthens_the_bone(model):
    p = model.zero_params()
    k, a = model.joint_index("knee_left"), model.joint_index("ankle_left")
    p.bone_scales[a] = 1.2
    Jp = model.joints(p)
    J0 = model.j_template
    np.testing.assert_allclose(np.linalg.norm(Jp[a] - Jp[k]), 1.2 * np.linalg.norm(J0[a] - J0[k]), rtol=1e-12)


def test_params_json_round_trip(model):
    p = random_params(model, np.random.default_rng(11))
    q = BodyParams.from_json(p.to_json(model.joint_names))
    np.testing.assert_array_equal(q.to_vector(), p.to_vector())
    with pytest.raises(ValueError, match="bone_scales"):
        BodyParams(p.shape, p.pose, -p.bone_scales)
    with pytest.raises(ValueError, match="params"):
        model.pose(BodyParams.zeros(model.num_shape + 1, model.num_joints))


def test_vjp_chains_a_vertex_loss(model):
    rng = np.random.default_rng(13)
    p = random_params(model, rng)
    target = model.pose(p) + rng.normal(scale=0.01, size=(model.num_vertices, 3))

    def loss(q):
        return 0.5 * np.sum((model.pose(q) - target) ** 2)
    g = model.vjp(p, model.pose(p) - target)
    x0 = p.to_vector()
    h = 1e-6
    for c in rng.choice(model.num_params, 12, replace=False):
        xp, xm = x0.copy(), x0.copy()
        xp[c] += h
        xm[c] -= h
        fd = (loss(BodyParams.from_vector(xp, model.num_shape, model.num_joints))
              - loss(BodyParams.from_vector(xm, model.num_shape, model.num_joints))) / (2 * h)
        assert abs(fd - g[c]) <= 1e-5 * max(1.0, abs(fd)), (c, fd, g[c])


def test_normal_equations_and_damped_step():
    from diffavatar_core import _core
    rng = np.random.default_rng(17)
    J = rng.normal(size=(200, 7))
    w = rng.uniform(0, 2, 200)
    r = rng.normal(size=200)
    H, g = _core.normal_equations(J, w, r)
    np.testing.assert_allclose(H, J.T @ (w[:, None] * J), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(g, J.T @ (w * r), rtol=1e-12, atol=1e-12)
    lam = 0.3
    step = _core.damped_step(H, g, lam)
    np.testing.assert_allclose((H + lam * np.diag(np.diag(H)) + 1e-12 * np.eye(7)) @ step, -g, atol=1e-10)
    with pytest.raises(ValueError):
        _core.normal_equations(J, w[:10], r)
