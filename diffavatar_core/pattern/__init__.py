"""Garment sewing patterns (paper §4.2.2): the Garment model the simulator consumes, panel
triangulation, parametric specifications, imports, the control cage and the pattern
regularizers. Units: metres."""
from .garment import BOUNDARY_NAMES, Garment, PanelInfo
from .spec import PanelSpec, PatternSpec, Placement, SeamSpec, build_garment
from .triangulate import polygon_area, triangle_quality_2d, triangulate_polygon

__all__ = ["BOUNDARY_NAMES", "Garment", "PanelInfo", "PanelSpec", "PatternSpec", "Placement",
           "SeamSpec", "build_garment", "polygon_area", "triangle_quality_2d", "triangulate_polygon"]
