"""Export of a simulated animation (garment on a moving body): an OBJ sequence, an animated
binary glTF (.glb, morph targets + weights animation) and an .npz of positions per frame.
Positions in m, time in s."""
from __future__ import annotations

import pathlib

import numpy as np

from . import _validate
from .gltf import AnimatedMesh, write_glb

GARMENT_COLOUR = (0.35, 0.55, 0.85)
BODY_COLOUR = (0.85, 0.70, 0.60)


def _frames(name: str, X) -> np.ndarray:
    try:
        a = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: not a numeric array ({exc})") from None
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"{name}: expected shape (T, V, 3) with T, V > 0, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or Inf")
    return a


def _write_obj(path: pathlib.Path, V: np.ndarray, F: np.ndarray, uv=None, header: str = "") -> None:
    """OBJ (1-based indices; with per-vertex UVs the vt index equals the v index)."""
    parts = [f"# {header}\n"] if header else []
    parts.append("".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V.tolist()))
    f1 = np.asarray(F, np.int64) + 1
    if uv is not None:
        parts.append("".join(f"vt {u:.9g} {v:.9g}\n" for u, v in uv.tolist()))
        parts.append("".join(f"f {a}/{a} {b}/{b} {c}/{c}\n" for a, b, c in f1.tolist()))
    else:
        parts.append("".join(f"f {a} {b} {c}\n" for a, b, c in f1.tolist()))
    path.write_text("".join(parts))


def write_animation(out_dir, frames_garment, garment_faces, frames_body=None, body_faces=None, fps: float = 30.0,
                    uv=None) -> dict[str, pathlib.Path | list[pathlib.Path]]:
    """Writes into `out_dir`:
    - obj/garment_NNNN.obj and obj/body_NNNN.obj, one per frame (garment with `uv` as vt);
    - animation.glb: garment and body as morph-target animations at `fps` frames/s;
    - positions.npz: garment (T×V×3, m), garment_faces, body (T×Vb×3, m), body_faces,
      times (T, s), fps [, uv].
    frames_garment: T×V×3 (m); garment_faces: F×3; frames_body: T×Vb×3 (m) or None (then
    body_faces must be None too); uv: V×2 or None. Returns the paths written."""
    G = _frames("frames_garment", frames_garment)
    T = G.shape[0]
    GF = _validate.faces("garment_faces", garment_faces, G.shape[1])
    if (frames_body is None) != (body_faces is None):
        raise ValueError("frames_body: must be given together with body_faces")
    B = BF = None
    if frames_body is not None:
        B = _frames("frames_body", frames_body)
        if B.shape[0] != T:
            raise ValueError(f"frames_body: {B.shape[0]} frames, frames_garment has {T}")
        BF = _validate.faces("body_faces", body_faces, B.shape[1])
    UV = None if uv is None else _validate.points("uv", uv, dims=2)
    if UV is not None and len(UV) != G.shape[1]:
        raise ValueError(f"uv: expected {G.shape[1]} rows (one per garment vertex), got {len(UV)}")
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise ValueError(f"fps: expected a positive number, got {fps!r}") from None
    if not (fps > 0 and np.isfinite(fps)):
        raise ValueError(f"fps: expected a positive number, got {fps!r}")

    out = pathlib.Path(out_dir)
    (out / "obj").mkdir(parents=True, exist_ok=True)
    objs = []
    for t in range(T):
        p = out / "obj" / f"garment_{t:04d}.obj"
        _write_obj(p, G[t], GF, UV, header=f"garment frame {t} t={t / fps:.6g} s (m)")
        objs.append(p)
        if B is not None:
            p = out / "obj" / f"body_{t:04d}.obj"
            _write_obj(p, B[t], BF, header=f"body frame {t} t={t / fps:.6g} s (m)")
            objs.append(p)
    meshes = [AnimatedMesh("garment", G, GF, GARMENT_COLOUR, UV)]
    if B is not None:
        meshes.append(AnimatedMesh("body", B, BF, BODY_COLOUR))
    glb = write_glb(out / "animation.glb", meshes, fps)
    arrays = {"garment": G, "garment_faces": GF, "times": np.arange(T) / fps, "fps": np.float64(fps)}
    if B is not None:
        arrays.update(body=B, body_faces=BF)
    if UV is not None:
        arrays["uv"] = UV
    npz = out / "positions.npz"
    np.savez_compressed(npz, **arrays)
    return {"obj": objs, "glb": glb, "npz": npz}
