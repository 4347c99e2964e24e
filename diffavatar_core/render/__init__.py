"""Headless rendering (C++ z-buffer rasterizer, no display, no GPU): cameras, shaded renders,
SSIM (Wang et al. 2004) and preview PNGs for comparing a scan with a recovered drape."""
from .camera import VIEW_NAMES, Camera, orbit_cameras, scene_bounds
from .preview import contact_sheet, preview_side_by_side, render_views, ssim_metric
from .renderer import PALETTE, merge_meshes, rasterize, render
from .ssim import luminance, ssim, ssim_map

__all__ = [
    "VIEW_NAMES", "Camera", "orbit_cameras", "scene_bounds",
    "contact_sheet", "preview_side_by_side", "render_views", "ssim_metric",
    "PALETTE", "merge_meshes", "rasterize", "render",
    "luminance", "ssim", "ssim_map",
]
