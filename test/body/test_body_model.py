"""BodyModel API: landmarks of the posed body, OBJ export, the SMPL-format loader (with a small
synthetic model the test writes), input validation."""
import pickle

import numpy as np
import pytest

from diffavatar_core.body import BodyModel, BodyParams
from diffavatar_core.io import load_mesh
from diffavatar_core.landmarks import BodyLandmarks


@pytest.fixture(scope="module")
def model():
    return BodyModel.default()


def test_landmarks_of_default_body_are_anthropometric(model):
    L = model.landmarks(model.zero_params())
    assert isinstance(L, BodyLandmarks)
    assert 1.6 < L.height < 1.85
    assert 0.8 < L.chest_girth < 1.1 and 0.6 < L.waist_girth < 0.9 and 0.85 < L.hip_girth < 1.15
    assert L.waist_girth < L.chest_girth and L.waist_girth < L.hip_girth
    # vertical order and left/right symmetry of the rest body
    assert L.ankle_left[1] < L.knee_left[1] < L.hip_center[1] < L.waist_center[1] < L.chest_center[1] \
        < L.shoulder_left[1] < L.neck_base[1] < L.height
    for a, b in [("shoulder", 1), ("elbow", 1), ("wrist", 1), ("knee", 1), ("ankle", 1)]:
        left, right = getattr(L, f"{a}_left"), getattr(L, f"{a}_right")
        assert left[0] > 0 > right[0]
        np.testing.assert_allclose(left * [-1, 1, 1], right, atol=1e-3)
    BodyLandmarks.from_dict(L.to_dict())


def test_landmarks_follow_the_global_transform_and_shape(model):
    p = model.zero_params()
    L0 = model.landmarks(p)
    q = p.copy()
    q.rotation[:] = [0.0, 0.7, 0.0]
    q.translation[:] = [0.3, -0.1, 2.0]
    L1 = model.landmarks(q)
    from scipy.spatial.transform import Rotation
    R = Rotation.from_rotvec(q.rotation).as_matrix()
    np.testing.assert_allclose(L1.wrist_left, R @ L0.wrist_left + q.translation, atol=1e-9)
    np.testing.assert_allclose([L1.height, L1.chest_girth], [L0.height, L0.chest_girth], rtol=1e-9)
    tall = p.copy()
    tall.shape[0] = -1.5                      # first component: stature (≈ 10 cm per unit)
    assert model.landmarks(tall).height > L0.height + 0.1


def test_export_obj_round_trip(model, tmp_path):
    p = model.zero_params()
    p.pose[model.joint_index("elbow_left")] = [-1.0, 0.0, 0.0]
    model.export_obj(tmp_path / "body.obj", p)
    V, F = load_mesh(tmp_path / "body.obj")
    np.testing.assert_allclose(V, model.pose(p), atol=1e-6)
    np.testing.assert_array_equal(F, model.faces)


def _synthetic_smpl(rng):
    """A 4-joint 'SMPL' chain: a column of vertices skinned to the nearest joint."""
    nv, nj, K = 40, 4, 3
    y = np.linspace(0, 1.5, nv // 4)
    ring = np.array([[0.1, 0, 0], [0, 0, 0.1], [-0.1, 0, 0], [0, 0, -0.1]])
    V = np.concatenate([ring + [0, yi, 0] for yi in y])
    F = []
    for i in range(nv // 4 - 1):
        for k in range(4):
            a, b = 4 * i + k, 4 * i + (k + 1) % 4
            F += [[a, b, b + 4], [a, b + 4, a + 4]]
    joint_y = np.array([0.0, 0.5, 1.0, 1.4])
    Jr = np.zeros((nj, nv))
    W = np.zeros((nv, nj))
    for v in range(nv):
        j = int(np.argmin(np.abs(joint_y - V[v, 1])))
        W[v, j] = 1.0
    for j in range(nj):
        ring_idx = int(np.argmin(np.abs(y - joint_y[j])))
        Jr[j, 4 * ring_idx:4 * ring_idx + 4] = 0.25
    S = rng.normal(scale=0.01, size=(nv, 3, K))
    kin = np.array([[4294967295, 0, 1, 2], [0, 1, 2, 3]], dtype=np.int64)
    return dict(v_template=V, shapedirs=S, J_regressor=Jr, weights=W, kintree_table=kin, f=np.array(F),
                posedirs=np.zeros((nv, 3, 9 * (nj - 1))))


@pytest.mark.parametrize("suffix", [".npz", ".pkl"])
def test_smpl_format_loader(tmp_path, suffix):
    rng = np.random.default_rng(0)
    d = _synthetic_smpl(rng)
    path = tmp_path / f"model{suffix}"
    if suffix == ".npz":
        np.savez(path, **d)
    else:
        import scipy.sparse
        d["J_regressor"] = scipy.sparse.csc_matrix(d["J_regressor"])   # as SMPL ships it
        with open(path, "wb") as fh:
            pickle.dump(d, fh)
    m = BodyModel.from_smpl_file(path)
    assert (m.num_vertices, m.num_joints, m.num_shape) == (40, 4, 3)
    p = m.zero_params()
    p.shape[:] = [1.0, -0.5, 0.2]
    Jr = d["J_regressor"].toarray() if hasattr(d["J_regressor"], "toarray") else d["J_regressor"]
    rest = d["v_template"] + d["shapedirs"] @ p.shape
    np.testing.assert_allclose(m.rest_vertices(p.shape), rest, atol=1e-12)
    np.testing.assert_allclose(m.joints(p), Jr @ rest, atol=1e-12)
    # bending joint 1 by 90° about x rotates every vertex skinned to joints 1.. about joint 1
    p.pose[1] = [np.pi / 2, 0, 0]
    X = m.pose(p)
    J1 = (Jr @ rest)[1]
    moved = d["weights"][:, 1:].sum(axis=1) > 0
    Rx = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    np.testing.assert_allclose(X[moved], (rest[moved] - J1) @ Rx.T + J1, atol=1e-12)
    np.testing.assert_allclose(X[~moved], rest[~moved], atol=1e-12)


def test_smpl_loader_rejects_incomplete_files(tmp_path):
    d = _synthetic_smpl(np.random.default_rng(1))
    del d["J_regressor"]
    np.savez(tmp_path / "bad.npz", **d)
    with pytest.raises(ValueError, match="J_regressor"):
        BodyModel.from_smpl_file(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="weights"):
        BodyModel(np.zeros((3, 3)), np.zeros((3, 3, 1)), np.zeros((1, 3)), np.zeros((1, 3, 1)), [-1],
                  np.zeros((3, 1)), [[0, 1, 2]])
