"""Preview images (PNG) and the render-based SSIM metric of paper §5 / Table 1: the scan and the
recovered result rendered from the same 4 orbit cameras under the same light rig."""
from __future__ import annotations

import pathlib

import numpy as np
from PIL import Image, ImageDraw

from .camera import VIEW_NAMES, orbit_cameras
from .renderer import merge_meshes, render
from .ssim import ssim

SCAN_COLOUR = (0.78, 0.78, 0.80)
GARMENT_COLOUR = (0.35, 0.55, 0.85)
BODY_COLOUR = (0.85, 0.70, 0.60)
#: One neutral albedo for everything in the SSIM renders: the metric compares shape, not labels.
METRIC_COLOUR = (0.8, 0.8, 0.8)


def _as_list(meshes):
    if isinstance(meshes, tuple) and len(meshes) in (2, 3) and np.ndim(meshes[0]) == 2:
        return [meshes]
    return list(meshes)


def _with_colour(m, colour):
    return (m[0], m[1], colour)


def _grid(images, columns: int, gap: int = 4, background=255) -> np.ndarray:
    h, w = images[0].shape[:2]
    rows = (len(images) + columns - 1) // columns
    out = np.full((rows * h + (rows + 1) * gap, columns * w + (columns + 1) * gap, 3), background, np.uint8)
    for k, im in enumerate(images):
        r, c = divmod(k, columns)
        y, x = gap + r * (h + gap), gap + c * (w + gap)
        out[y:y + h, x:x + w] = im
    return out


def _save_png(img: np.ndarray, path, labels=None, cell=None, columns=1, gap=4) -> pathlib.Path:
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    im = Image.fromarray(img, mode="RGB")
    if labels:
        draw = ImageDraw.Draw(im)
        h, w = cell
        for k, text in enumerate(labels):
            r, c = divmod(k, columns)
            draw.text((gap + c * (w + gap) + 4, gap + r * (h + gap) + 3), text, fill=(40, 40, 40))
    im.save(path, format="PNG")
    return path


def render_views(meshes, cameras, size=256, *, smooth: bool = True, supersample: int = 2) -> list[np.ndarray]:
    """Renders `meshes` from each camera of the dict `cameras` (in its order): list of H×W×3 uint8."""
    return [render(meshes, cam, size, smooth=smooth, supersample=supersample) for cam in cameras.values()]


def preview_side_by_side(scan_mesh, result_meshes, path, *, size: int = 256, supersample: int = 2) -> np.ndarray:
    """PNG at `path`: top row the scan (V, F), bottom row the recovered drape (`result_meshes`:
    e.g. [(garment V, F), (body V, F)], optionally with colours), from the 4 orbit views
    front/right/back/left under identical cameras (fitted to both) and lights. Returns the image."""
    scan = [_with_colour(_as_list(scan_mesh)[0], SCAN_COLOUR)]
    result = _as_list(result_meshes)
    default = (GARMENT_COLOUR, BODY_COLOUR)
    result = [m if len(m) == 3 else _with_colour(m, default[min(i, 1)]) for i, m in enumerate(result)]
    cams = orbit_cameras(scan + result)
    images = render_views(scan, cams, size, supersample=supersample) + render_views(result, cams, size,
                                                                                    supersample=supersample)
    sheet = _grid(images, columns=len(cams))
    labels = [f"scan {v}" for v in cams] + [f"result {v}" for v in cams]
    _save_png(sheet, path, labels=labels, cell=(size, size), columns=len(cams))
    return sheet


def contact_sheet(frames, path, *, columns: int | None = None, labels=None) -> np.ndarray:
    """PNG grid of equally sized H×W×3 uint8 `frames` (e.g. renders of an animation), row by row;
    `columns` defaults to ⌈√n⌉; optional text `labels`, one per frame. Returns the image."""
    frames = [np.asarray(f) for f in frames]
    if not frames:
        raise ValueError("frames: is empty")
    shape = frames[0].shape
    for i, f in enumerate(frames):
        if f.ndim != 3 or f.shape[2] != 3 or f.dtype != np.uint8:
            raise ValueError(f"frames[{i}]: expected an H×W×3 uint8 image, got {f.dtype} {f.shape}")
        if f.shape != shape:
            raise ValueError(f"frames[{i}]: shape {f.shape} differs from frames[0]'s {shape}")
    n = len(frames)
    cols = int(np.ceil(np.sqrt(n))) if columns is None else int(columns)
    if cols < 1:
        raise ValueError(f"columns: expected >= 1, got {columns}")
    if labels is not None and len(labels) != n:
        raise ValueError(f"labels: expected {n} labels, got {len(labels)}")
    sheet = _grid(frames, columns=cols)
    _save_png(sheet, path, labels=labels, cell=shape[:2], columns=cols)
    return sheet


def ssim_metric(scan_mesh, garment_mesh, body_mesh=None, *, size: int = 256, supersample: int = 2,
                views=VIEW_NAMES) -> float:
    """Mean SSIM (luminance, Wang et al. 2004) over the 4 orbit views between renders of the
    scan (V, F) and of the result (garment (V, F) plus the body (V, F) when given), with the same
    cameras (fitted to the union of both), the same light rig and one neutral albedo. 1 means
    identical renders."""
    scan = [_with_colour(_as_list(scan_mesh)[0], METRIC_COLOUR)]
    result = [_with_colour(garment_mesh, METRIC_COLOUR)]
    if body_mesh is not None:
        result.append(_with_colour(body_mesh, METRIC_COLOUR))
    merge_meshes(scan), merge_meshes(result)  # validate before rendering
    cams = orbit_cameras(scan + result, views=views)
    a = render_views(scan, cams, size, supersample=supersample)
    b = render_views(result, cams, size, supersample=supersample)
    return float(np.mean([ssim(x, y) for x, y in zip(a, b)]))
