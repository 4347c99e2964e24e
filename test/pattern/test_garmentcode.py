"""GarmentCode specification import (skipped when the shared data is absent)."""
import json

import numpy as np
import pytest

from shared_data import shared_file
from diffavatar_core.pattern import polygon_area, triangle_quality_2d
from diffavatar_core.pattern.garmentcode import _arc, garmentcode_spec, load_garmentcode


@pytest.mark.parametrize("name", ["shirt_mean", "hoody_mean", "dress_pencil"])
def test_import(name):
    path = shared_file("garmentcode", f"{name}_specification.json")
    spec = json.loads(path.read_text())
    g = load_garmentcode(path, edge_length=0.03)
    assert g.panel_names == list(spec["pattern"].get("panel_order") or spec["pattern"]["panels"])
    # the triangulation tiles every sampled panel outline exactly
    poly = sum(polygon_area(g.rest[p.loop]) for p in g.panels)
    assert abs(g.total_area() - poly) <= 1e-9 * poly
    # ... which is the spec's outline (curves sampled densely) up to the 3 cm chord error
    ps = garmentcode_spec(spec)
    dense = 0.0
    for p in ps.panels:
        pts = np.vstack([p.edge_polyline(k, 200)[:-1] for k in range(len(p.vertices))])
        dense += polygon_area(pts)
    assert abs(poly - dense) < 0.02 * dense
    # every stitch became a seam: sewn chains of equal vertex counts, between boundary vertices
    by = {p.name: p for p in ps.panels}
    assert len(g.seam_edge_pairs()) >= len(ps.seams)
    boundary = np.zeros(len(g.rest), bool)
    for p in g.panels:
        boundary[p.loop] = True
    assert boundary[g.seams].all()
    if name in ("shirt_mean", "hoody_mean"):   # these two sew edges of equal length
        ratios = [by[s.panel_a].edge_length(s.edge_a) / by[s.panel_b].edge_length(s.edge_b) for s in ps.seams]
        assert np.all(np.abs(np.asarray(ratios) - 1) < 0.02)
    # units: an adult garment of about 0.5–2 m² of fabric, placed at body height (m)
    assert 0.4 < g.total_area() < 2.0
    assert 0.3 < g.x0[:, 1].max() < 2.0
    # quality: only corners at source edges much shorter than the target length fall below 0.30
    q = triangle_quality_2d(g.rest, g.faces)
    assert q.min() > 0.05 and np.mean(q < 0.30) < 0.01


def test_arc_passes_through_its_ends_with_its_radius():
    a, b = np.array([0.0, 0.0]), np.array([0.2, 0.0])
    for large in (False, True):
        for right in (False, True):
            arc = _arc(a, b, 0.15, large, right)
            P = arc.points(np.linspace(0, 1, 11))
            assert np.allclose(P[0], a) and np.allclose(P[-1], b)
            assert np.allclose(np.linalg.norm(P - arc.center, axis=1), 0.15)
            side = np.sign(P[5, 1])
            assert side == (-1 if right else 1)          # bulges to the requested side
            span = abs(arc.a1 - arc.a0)
            assert (span > np.pi) == large
