"""Headless shaded rendering of triangle meshes (C++ z-buffer rasterizer, no display, no GPU)."""
from __future__ import annotations

import numpy as np

from .. import _core, _validate
from .camera import Camera

#: Default per-mesh albedos (linear RGB in [0, 1]) for meshes given without a colour.
PALETTE = ((0.75, 0.75, 0.78), (0.35, 0.55, 0.85), (0.85, 0.55, 0.35), (0.45, 0.75, 0.45))


def _size(size) -> tuple[int, int]:
    if np.isscalar(size):
        w = h = _validate.positive_int("size", size)
    else:
        try:
            w, h = size
        except (TypeError, ValueError):
            raise ValueError(f"size: expected an int or (width, height), got {size!r}") from None
        w, h = _validate.positive_int("size[0]", w), _validate.positive_int("size[1]", h)
    return w, h


def merge_meshes(meshes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One (V, F, face_colors) from a sequence of (V, F) or (V, F, colour) items (colour: RGB in
    [0, 1]); meshes without a colour take PALETTE[i]."""
    if isinstance(meshes, tuple) and len(meshes) in (2, 3) and np.ndim(meshes[0]) == 2:
        meshes = [meshes]
    Vs, Fs, Cs, off = [], [], [], 0
    for i, m in enumerate(meshes):
        if len(m) not in (2, 3):
            raise ValueError(f"meshes[{i}]: expected (V, F) or (V, F, colour)")
        V, F = _validate.mesh(f"meshes[{i}].V", m[0], f"meshes[{i}].F", m[1])
        col = np.asarray(m[2] if len(m) == 3 and m[2] is not None else PALETTE[i % len(PALETTE)], dtype=np.float64)
        if col.shape != (3,) or not np.all((col >= 0) & (col <= 1)):
            raise ValueError(f"meshes[{i}].colour: expected 3 values in [0, 1], got {m[2]!r}")
        Vs.append(V)
        Fs.append(F + off)
        Cs.append(np.broadcast_to(col, (len(F), 3)))
        off += len(V)
    if not Vs:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros((0, 3))
    return (np.ascontiguousarray(np.concatenate(Vs)), np.ascontiguousarray(np.concatenate(Fs), dtype=np.int32),
            np.ascontiguousarray(np.concatenate(Cs)))


def _cam_args(camera: Camera):
    if not isinstance(camera, Camera):
        raise ValueError(f"camera: expected a diffavatar_core.render.Camera, got {type(camera).__name__}")
    return (np.array(camera.eye), np.array(camera.target), np.array(camera.up), bool(camera.orthographic),
            float(camera.fov_y), float(camera.ortho_height))


def rasterize(V, F, camera: Camera, size) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Visibility of one mesh (V: #V×3 m, F: #F×3): (face H×W int32, −1 = background;
    depth H×W m along the view axis, +inf = background; bary H×W×3 perspective-correct
    barycentrics). Pixel centres at (i+½, j+½), nearest triangle wins, ties to the lower face
    index; deterministic for any thread count."""
    V, F = _validate.mesh("V", V, "F", F)
    w, h = _size(size)
    face, depth, bary = _core.rasterize(V, F, *_cam_args(camera), w, h, float(camera.near))
    return face, depth, bary.reshape(h, w, 3)


def render(meshes, camera: Camera, size=256, *, smooth: bool = False, ambient: float = 0.25,
           background=(1.0, 1.0, 1.0), supersample: int = 1) -> np.ndarray:
    """H×W×3 uint8 image of `meshes` ((V, F) or (V, F, colour) items, V in m, colour RGB in
    [0, 1]) seen by `camera`; `size` is an int or (width, height) in pixels.

    Lambert + ambient shading with the fixed camera-attached light rig of cpp/render/shade.hpp
    (two-sided, flat face normals or, with `smooth`, interpolated area-weighted vertex normals);
    `supersample` s renders s×s samples per pixel and averages them (anti-aliasing)."""
    w, h = _size(size)
    V, F, C = merge_meshes(meshes)
    bg = np.asarray(background, dtype=np.float64)
    if bg.shape != (3,) or not np.all((bg >= 0) & (bg <= 1)):
        raise ValueError(f"background: expected 3 values in [0, 1], got {background!r}")
    ss = _validate.positive_int("supersample", supersample)
    if ss > 8:
        raise ValueError(f"supersample: expected 1..8, got {ss}")
    if not 0.0 <= float(ambient) <= 1.0:
        raise ValueError(f"ambient: expected a value in [0, 1], got {ambient}")
    img = _core.render_image(V, F, C, *_cam_args(camera), w, h, float(camera.near), bool(smooth),
                             float(ambient), bg, ss)
    return np.asarray(img).reshape(h, w, 3)
