"""Import of a GarmentCode sewing-pattern specification (Korosteleva & Sorkine-Hornung 2023):
``pattern.panels.<name>`` with ``vertices`` (2D), ``edges[].endpoints`` and optional
``curvature`` (quadratic / cubic Bézier with control points relative to the edge, or circle
arcs), ``translation`` + ``rotation`` (Euler xyz, degrees) placing the panel in 3D,
``pattern.stitches`` pairing ``{panel, edge}``, and ``properties.units_in_meter``."""
from __future__ import annotations

import json
import pathlib

import numpy as np
from scipy.spatial.transform import Rotation

from .garment import Garment
from .obj_import import _name_openings
from .spec import Arc, PanelSpec, PatternSpec, Placement, SeamSpec, build_garment
from .triangulate import polygon_area


def _rel_to_abs(a, b, rel):
    """GarmentCode's relative control point (t, s): a + t (b − a) + s · perp(b − a)."""
    e = b - a
    perp = np.array([-e[1], e[0]])
    return a + rel[0] * e + rel[1] * perp


def _arc(a, b, radius, large_arc, right) -> Arc:
    """The circle arc from a to b of the given radius; it bulges to the right of a→b when
    ``right`` (the larger of the two arcs when ``large_arc``)."""
    e = b - a
    c = float(np.linalg.norm(e))
    r = max(float(radius), 0.5 * c)
    n = np.array([-e[1], e[0]]) / c
    bulge = -n if right else n
    h = np.sqrt(max(r * r - 0.25 * c * c, 0.0))
    m = 0.5 * (a + b)
    center = m + h * bulge if large_arc else m - h * bulge
    a0 = np.arctan2(*(a - center)[::-1])
    a1 = np.arctan2(*(b - center)[::-1])
    mid = np.arctan2(*(m + bulge - center)[::-1])       # a direction inside the wanted arc
    # pick the sweep direction whose arc passes through `mid`
    ccw = (a1 - a0) % (2 * np.pi)
    through_ccw = ((mid - a0) % (2 * np.pi)) < ccw
    sweep = ccw if through_ccw else ccw - 2 * np.pi
    return Arc(center, r, a0, a0 + sweep)


def garmentcode_spec(spec: dict, name: str = "garmentcode") -> PatternSpec:
    """PatternSpec of a parsed GarmentCode specification (converted to metres)."""
    pat = spec["pattern"]
    unit = float(spec.get("properties", {}).get("units_in_meter", 100.0))
    order = pat.get("panel_order") or list(pat["panels"])
    panels = []
    for pname in order:
        p = pat["panels"][pname]
        Vraw = np.asarray(p["vertices"], float) / unit
        edges = p["edges"]
        for k, e in enumerate(edges):
            if e["endpoints"][1] != edges[(k + 1) % len(edges)]["endpoints"][0]:
                raise ValueError(f"panel {pname!r}: edges do not form a loop at edge {k}")
        V = np.array([Vraw[e["endpoints"][0]] for e in edges])
        R = Rotation.from_euler("xyz", p.get("rotation", [0, 0, 0]), degrees=True).as_matrix()
        t = np.asarray(p.get("translation", [0, 0, 0]), float) / unit
        ex, ey = R[:, 0].copy(), R[:, 1].copy()
        mirror = polygon_area(V) < 0         # clockwise panel: mirror u so it is counter-clockwise
        if mirror:
            V = V * np.array([-1.0, 1.0])
            ex = -ex
        curves = {}
        for k, e in enumerate(edges):
            cv = e.get("curvature")
            if not cv:
                continue
            a, b = V[k], V[(k + 1) % len(V)]
            if cv["type"] in ("quadratic", "cubic"):
                pts = []
                for rel in cv["params"]:
                    rel = np.asarray(rel, float)
                    if mirror:       # the perpendicular flips with the mirror
                        rel = rel * np.array([1.0, -1.0])
                    pts.append(_rel_to_abs(a, b, rel))
                curves[k] = np.asarray(pts)
            elif cv["type"] == "circle":
                radius, large_arc, right = cv["params"]
                curves[k] = _arc(a, b, float(radius) / unit, bool(large_arc), bool(right) != mirror)
            else:
                raise ValueError(f"panel {pname!r} edge {k}: unsupported curvature {cv['type']!r}")
        panels.append(PanelSpec(pname, V, Placement(t, ex, ey), curves=curves))
    by_name = {p.name: p for p in panels}
    seams = []
    for st in pat.get("stitches", []):
        (pa, ea), (pb, eb) = ((s["panel"], int(s["edge"])) for s in st[:2])
        A, B = by_name[pa], by_name[pb]
        a = A.placement(A.edge_polyline(ea, 1))
        b = B.placement(B.edge_polyline(eb, 1))
        # sew in the orientation that joins the nearer ends in the 3D placement
        rev = np.linalg.norm(a[0] - b[1]) + np.linalg.norm(a[1] - b[0]) < \
            np.linalg.norm(a[0] - b[0]) + np.linalg.norm(a[1] - b[1])
        seams.append(SeamSpec(pa, ea, pb, eb, reverse=bool(rev)))
    return PatternSpec(name, panels, seams)


def load_garmentcode(path, edge_length: float = 0.012) -> Garment:
    """Garment from a GarmentCode ``*_specification.json``, triangulated at edge_length (m)."""
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    with open(path) as fh:
        spec = json.load(fh)
    if "pattern" not in spec or "panels" not in spec["pattern"]:
        raise ValueError(f"{path}: not a GarmentCode specification (no pattern.panels)")
    name = path.name.replace("_specification.json", "").replace(".json", "")
    g = build_garment(garmentcode_spec(spec, name), edge_length=edge_length)
    g.boundaries = _name_openings(g)
    return g
