"""pattern.json round trip, SVG/PNG/OBJ writers and the `templates` / `pattern` commands."""
import json

import numpy as np
import pytest

from diffavatar_core.cli import main
from diffavatar_core.io import load_mesh
from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pattern.export import load_pattern_json, save_pattern_json, write_all
from diffavatar_core.pattern.templates import make_template


@pytest.fixture(scope="module")
def skirt():
    return make_template("skirt", edge_length=0.04)


def test_pattern_json_round_trip_is_exact(tmp_path, skirt):
    cage = build_cage(skirt)
    save_pattern_json(tmp_path / "p.json", skirt, cage.handles)
    g = load_pattern_json(tmp_path / "p.json")
    for f in ("rest", "faces", "x0", "seams", "panel"):
        assert np.array_equal(getattr(g, f), getattr(skirt, f))
    assert g.panel_names == skirt.panel_names
    assert all(np.array_equal(a.loop, b.loop) and a.grain == b.grain for a, b in zip(g.panels, skirt.panels))
    assert {k: v.tolist() for k, v in g.boundaries.items()} == {k: v.tolist() for k, v in skirt.boundaries.items()}
    d = json.loads((tmp_path / "p.json").read_text())
    assert d["units"] == "m" and d["handles"] == cage.handles.tolist()
    d["format"] = "other"
    (tmp_path / "bad.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match="format"):
        load_pattern_json(tmp_path / "bad.json")


def test_writers(tmp_path, skirt):
    from PIL import Image
    cage = build_cage(skirt)
    paths = write_all(tmp_path, skirt, cage.handles)
    svg = (tmp_path / "pattern.svg").read_text()
    assert svg.count("<polygon") == len(skirt.panels)
    assert svg.count("<circle") == len(cage.handles)
    img = Image.open(paths["png"])
    assert img.size[0] > 100 and img.size[1] > 100
    V, F = load_mesh(paths["obj"])
    assert np.allclose(V, skirt.x0, atol=1e-8) and np.array_equal(np.sort(F, 1), np.sort(skirt.faces, 1))
    vt = np.array([l.split()[1:] for l in (tmp_path / "rest.obj").read_text().splitlines()
                   if l.startswith("vt ")], float)
    assert np.allclose(vt, skirt.rest, atol=1e-8)


def test_cli(tmp_path, capsys):
    assert main(["templates"]) == 0
    assert "tshirt" in capsys.readouterr().out
    assert main(["pattern", "skirt", "--edge-length", "0.05", "--out", str(tmp_path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["panels"] == ["front", "back"] and (tmp_path / "pattern.png").exists()
    assert main(["pattern", "--out", str(tmp_path)]) == 2
    assert main(["pattern", "kilt", "--out", str(tmp_path)]) == 2


def test_pattern_assets(skirt):
    from diffavatar_core.pattern.export import pattern_assets
    cage = build_cage(skirt)
    a = pattern_assets(skirt, cage.handles)
    start = a.panel_vertex_start
    assert start[0] == 0 and start[-1] == len(a.rest_xy) and len(start) == len(a.panel_names) + 1
    for p in range(len(a.panel_names)):
        assert np.all(skirt.panel[start[p]:start[p + 1]] == p)
    assert np.array_equal(a.seam_pairs, skirt.seams) and np.array_equal(a.handles, cage.handles)
