"""Writers (and the reader) of a Garment: the project's pattern.json (docs/pattern.md), SVG and
PNG pictures of the panels (seams colour-coded by the pair of panels they join, control-cage
handles marked), and an OBJ of the 3D placement whose UVs are the pattern (m)."""
from __future__ import annotations

import colorsys
import json
import pathlib

import numpy as np

from .garment import Garment, PanelInfo

FORMAT = "diffavatar-pattern"
VERSION = 1


def to_dict(g: Garment, handles=None) -> dict:
    d = {
        "format": FORMAT, "version": VERSION, "units": "m", "name": g.name,
        "panels": [{"name": p.name, "grain_rad": float(p.grain), "loop": p.loop.tolist()} for p in g.panels],
        "rest": g.rest.tolist(), "faces": g.faces.tolist(), "x0": g.x0.tolist(),
        "panel": g.panel.tolist(), "seams": g.seams.tolist(),
        "boundaries": {k: v.tolist() for k, v in g.boundaries.items()},
    }
    if handles is not None:
        d["handles"] = np.asarray(handles, int).tolist()
    return d


def from_dict(d: dict) -> Garment:
    if d.get("format") != FORMAT:
        raise ValueError(f"pattern: not a {FORMAT} document (format={d.get('format')!r})")
    if int(d.get("version", 0)) > VERSION:
        raise ValueError(f"pattern: version {d['version']} is newer than this reader ({VERSION})")
    panels = [PanelInfo(p["name"], np.asarray(p["loop"], np.int32), float(p["grain_rad"])) for p in d["panels"]]
    return Garment(rest=np.asarray(d["rest"], float), faces=np.asarray(d["faces"], np.int32).reshape(-1, 3),
                   x0=np.asarray(d["x0"], float), seams=np.asarray(d["seams"], np.int32).reshape(-1, 2),
                   panel=np.asarray(d["panel"], np.int32), panels=panels,
                   boundaries={k: np.asarray(v, np.int32) for k, v in d.get("boundaries", {}).items()},
                   name=d.get("name", "garment"))


def save_pattern_json(path, g: Garment, handles=None) -> None:
    """Writes pattern.json (floats written exactly: the round trip is bit-identical)."""
    pathlib.Path(path).write_text(json.dumps(to_dict(g, handles)))


def load_pattern_json(path) -> Garment:
    return from_dict(json.loads(pathlib.Path(path).read_text()))


def save_rest_obj(path, g: Garment) -> None:
    """OBJ: v = 3D placement x0 (m), vt = pattern coordinates (m), one group per panel."""
    lines = [f"# {g.name}: 3D placement (m), UVs = sewing pattern (m)"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in g.x0]
    lines += [f"vt {u:.9g} {v:.9g}" for u, v in g.rest]
    fp = g.panel[g.faces[:, 0]]
    for p, info in enumerate(g.panels):
        lines.append(f"g {info.name}")
        for a, b, c in g.faces[fp == p] + 1:
            lines.append(f"f {a}/{a} {b}/{b} {c}/{c}")
    pathlib.Path(path).write_text("\n".join(lines) + "\n")


def _seam_groups(g: Garment):
    """Sewn boundary edges grouped by the (unordered) pair of panels they join, and a colour each."""
    P = g.seam_edge_pairs()
    groups: dict = {}
    for a0, a1, b0, b1 in P:
        key = tuple(sorted((int(g.panel[a0]), int(g.panel[b0]))))
        groups.setdefault(key, []).extend([(a0, a1), (b0, b1)])
    keys = sorted(groups)
    colours = {}
    for i, k in enumerate(keys):
        r, gg, b = colorsys.hsv_to_rgb(i / max(len(keys), 1), 0.85, 0.85)
        colours[k] = (int(255 * r), int(255 * gg), int(255 * b))
    return groups, colours


def _frame(g: Garment, px_per_m: float, margin: float):
    lo = g.rest.min(0) - margin
    hi = g.rest.max(0) + margin
    W, H = (hi - lo) * px_per_m

    def to_px(X):
        X = np.atleast_2d(X)
        return np.column_stack([(X[:, 0] - lo[0]) * px_per_m, (hi[1] - X[:, 1]) * px_per_m])
    return int(np.ceil(W)), int(np.ceil(H)), to_px


def save_svg(path, g: Garment, handles=None, px_per_m: float = 1000.0) -> None:
    """SVG of the panels (1 px = 1 mm by default): outlines, seams colour-coded per panel pair,
    handles as red dots, panel names at their centres."""
    W, H, to_px = _frame(g, px_per_m, 0.05)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}">',
           '<rect width="100%" height="100%" fill="white"/>']
    for p in g.panels:
        pts = " ".join(f"{x:.2f},{y:.2f}" for x, y in to_px(g.rest[p.loop]))
        out.append(f'<polygon points="{pts}" fill="#eef2f7" stroke="#333" stroke-width="1.5"/>')
        c = to_px(g.rest[p.loop].mean(0))[0]
        out.append(f'<text x="{c[0]:.1f}" y="{c[1]:.1f}" font-size="{0.03 * px_per_m:.0f}" '
                   f'text-anchor="middle" font-family="sans-serif">{p.name}</text>')
    groups, colours = _seam_groups(g)
    for k, edges in groups.items():
        col = "#%02x%02x%02x" % colours[k]
        for a, b in edges:
            (x0, y0), (x1, y1) = to_px(g.rest[[a, b]])
            out.append(f'<line x1="{x0:.2f}" y1="{y0:.2f}" x2="{x1:.2f}" y2="{y1:.2f}" stroke="{col}" stroke-width="4"/>')
    if handles is not None:
        for x, y in to_px(g.rest[np.asarray(handles, int)]):
            out.append(f'<circle cx="{x:.2f}" cy="{y:.2f}" r="{0.006 * px_per_m:.1f}" fill="red"/>')
    out.append("</svg>")
    pathlib.Path(path).write_text("\n".join(out) + "\n")


def save_png(path, g: Garment, handles=None, px_per_m: float = 500.0) -> None:
    """PNG (Pillow) of the same picture as save_svg, triangulation drawn faintly."""
    from PIL import Image, ImageDraw
    W, H, to_px = _frame(g, px_per_m, 0.05)
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    for p in g.panels:
        d.polygon([tuple(x) for x in to_px(g.rest[p.loop])], fill=(238, 242, 247))
    P = to_px(g.rest)
    for f in g.faces:
        d.line([tuple(P[f[0]]), tuple(P[f[1]]), tuple(P[f[2]]), tuple(P[f[0]])], fill=(200, 205, 215), width=1)
    for p in g.panels:
        loop = to_px(g.rest[p.loop])
        d.line([tuple(x) for x in np.vstack([loop, loop[:1]])], fill=(40, 40, 40), width=2)
    groups, colours = _seam_groups(g)
    for k, edges in groups.items():
        for a, b in edges:
            d.line([tuple(P[a]), tuple(P[b])], fill=colours[k], width=4)
    if handles is not None:
        r = max(2, int(0.006 * px_per_m))
        for x, y in P[np.asarray(handles, int)]:
            d.ellipse([x - r, y - r, x + r, y + r], fill=(220, 0, 0))
    for p in g.panels:
        c = to_px(g.rest[p.loop].mean(0))[0]
        d.text((c[0], c[1]), p.name, fill=(0, 0, 0))
    img.save(str(path))


def write_all(out_dir, g: Garment, handles=None) -> dict:
    """Writes pattern.json, pattern.svg, pattern.png and rest.obj into out_dir; their paths."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {k: out / v for k, v in (("json", "pattern.json"), ("svg", "pattern.svg"),
                                     ("png", "pattern.png"), ("obj", "rest.obj"))}
    save_pattern_json(paths["json"], g, handles)
    save_svg(paths["svg"], g, handles)
    save_png(paths["png"], g, handles)
    save_rest_obj(paths["obj"], g)
    return {k: str(v) for k, v in paths.items()}


def pattern_assets(g: Garment, handles=None):
    """The pipeline's PatternAssets (pipeline/result.py) of a garment and its cage handles."""
    from ..pipeline.result import PatternAssets
    return PatternAssets(rest_xy=g.rest.copy(), triangles=g.faces.copy(),
                         panel_vertex_start=g.panel_vertex_start, panel_names=g.panel_names,
                         panel_grain_rad=np.array([p.grain for p in g.panels], float),
                         seam_pairs=g.seams.copy(),
                         handles=np.zeros(0, np.int32) if handles is None else np.asarray(handles, np.int32))
