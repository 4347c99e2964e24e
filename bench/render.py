"""Benchmark: the C++ headless rasterizer vs a pure-numpy z-buffer reference on the same scene
(a ~20k-triangle bumpy sphere, 512×512, perspective) in the same process. Prints JSON.
Run: `.venv/bin/python bench/render.py`."""
import json
import math
import platform
import time

import numpy as np
import trimesh

import diffavatar_core as dc
from diffavatar_core.render import orbit_cameras, rasterize, render

SIZE = 512


def best_of(fn, repeats=5):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def scene():
    m = trimesh.creation.icosphere(subdivisions=5, radius=0.5)  # 20480 triangles
    V = np.asarray(m.vertices)
    n = V / np.linalg.norm(V, axis=1, keepdims=True)
    bump = 0.04 * np.sin(7 * n[:, 0]) * np.sin(5 * n[:, 1]) * np.sin(6 * n[:, 2] + 1.0)
    return V + bump[:, None] * n, np.asarray(m.faces, np.int32)


def numpy_rasterize(V, F, cam, n):
    """Reference: per-triangle bounding-box z-buffer in numpy (same projection, pixel centres,
    inclusive edge test, 1/z interpolation and lower-index tie rule as the C++ kernel)."""
    f = np.subtract(cam.target, cam.eye)
    f /= np.linalg.norm(f)
    r = np.cross(f, cam.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    focal = 0.5 * n / math.tan(0.5 * cam.fov_y)
    d = V - np.asarray(cam.eye)
    z = d @ f
    sx = 0.5 * n + focal * (d @ r) / z
    sy = 0.5 * n - focal * (d @ u) / z
    depth = np.full((n, n), np.inf)
    face = np.full((n, n), -1, np.int32)
    for t, (a, b, c) in enumerate(F):
        xs, ys = sx[[a, b, c]], sy[[a, b, c]]
        x0, x1 = max(0, math.ceil(xs.min() - 0.5)), min(n - 1, math.floor(xs.max() - 0.5))
        y0, y1 = max(0, math.ceil(ys.min() - 0.5)), min(n - 1, math.floor(ys.max() - 0.5))
        if x0 > x1 or y0 > y1:
            continue
        area2 = (xs[1] - xs[0]) * (ys[2] - ys[0]) - (ys[1] - ys[0]) * (xs[2] - xs[0])
        if area2 == 0:
            continue
        px, py = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5)
        e = [((xs[(k + 1) % 3] - px) * (ys[(k + 2) % 3] - py) - (ys[(k + 1) % 3] - py) * (xs[(k + 2) % 3] - px)) / area2
             for k in range(3)]
        inside = (e[0] >= 0) & (e[1] >= 0) & (e[2] >= 0)
        zz = 1.0 / (e[0] / z[a] + e[1] / z[b] + e[2] / z[c])
        win = inside & (zz < depth[y0:y1 + 1, x0:x1 + 1])
        depth[y0:y1 + 1, x0:x1 + 1][win] = zz[win]
        face[y0:y1 + 1, x0:x1 + 1][win] = t
    return face, depth


def main():
    V, F = scene()
    cam = orbit_cameras([(V, F)], fov_y=0.5, margin=0.8)["front"]  # sphere fills most of the frame
    out = {"benchmark": "render", "triangles": int(len(F)), "size": [SIZE, SIZE], "threads": dc.num_threads(),
           "machine": platform.machine()}
    ras = best_of(lambda: rasterize(V, F, cam, SIZE))
    shaded = best_of(lambda: render([(V, F)], cam, SIZE, smooth=True))
    shaded_ss2 = best_of(lambda: render([(V, F)], cam, SIZE, smooth=True, supersample=2), repeats=3)
    t0 = time.perf_counter()
    ref_face, ref_depth = numpy_rasterize(V, F, cam, SIZE)
    ref = time.perf_counter() - t0
    face, depth, _ = rasterize(V, F, cam, SIZE)
    both = (face >= 0) & (ref_face >= 0)
    out.update(
        ms_rasterize=1e3 * ras, ms_render_shaded=1e3 * shaded, ms_render_shaded_supersample2=1e3 * shaded_ss2,
        covered_fraction=float((face >= 0).mean()),
        reference="pure numpy per-triangle bounding-box z-buffer (same scene, single run)",
        reference_ms=1e3 * ref, speedup_rasterize_vs_reference=ref / ras, speedup_shaded_vs_reference=ref / shaded,
        agreement_face_ids=float((face == ref_face).mean()),
        max_depth_diff_m=float(np.abs(depth[both] - ref_depth[both]).max()))
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
