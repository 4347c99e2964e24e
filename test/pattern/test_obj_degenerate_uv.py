"""A template OBJ whose UVs cannot be a sewing pattern (all zero, on a line) was imported with a NaN
rest shape and refused much later as "rest: 454 row(s) contain NaN or Inf"; it is refused at import,
naming the file and the degenerate UV pattern. The same template with its pattern as UVs imports
to that pattern (the control)."""
import warnings

import numpy as np
import pytest

from diffavatar_core.pattern.obj_import import load_obj_pattern
from diffavatar_core.pattern.templates import make_template


@pytest.fixture(scope="module")
def skirt():
    return make_template("skirt", edge_length=0.04)


def _write(path, g, uv, x=None):
    """g's faces with 3D positions x (V, 3) m (default: its 3D layout), written in cm, and
    per-vertex UVs `uv` (V, 2)."""
    x = g.x0 if x is None else x
    lines = [f"v {x * 100} {y * 100} {z * 100}" for x, y, z in x]
    lines += [f"vt {float(u)!r} {float(v)!r}" for u, v in uv]
    lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in g.faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def _areas(X, F):
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    return 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])


def test_the_pattern_as_uvs_imports_to_the_pattern(skirt, tmp_path):
    """The control: 3D positions the flat pattern itself (each panel in its own plane), UVs the
    pattern at a third of its size: every triangle comes back at its rest area."""
    flat = np.column_stack([skirt.rest, 0.1 * skirt.panel])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = load_obj_pattern(_write(tmp_path / "ok.obj", skirt, skirt.rest / 3.0, flat))
    assert np.isfinite(g.rest).all() and len(g.panels) == len(skirt.panels)
    np.testing.assert_allclose(np.sort(_areas(g.rest, g.faces)), np.sort(_areas(skirt.rest, skirt.faces)),
                               rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("how,words", [
    ("zero", ("degenerate UV pattern", "all collapsed", "one point")),
    ("line", ("degenerate UV pattern", "all collapsed", "a line")),
])
def test_collapsed_uvs_are_refused_at_import(skirt, tmp_path, how, words):
    uv = np.zeros((len(skirt.rest), 2)) if how == "zero" else np.column_stack([skirt.rest[:, 0], 0 * skirt.rest[:, 0]])
    p = _write(tmp_path / f"{how}.obj", skirt, uv)
    with pytest.raises(ValueError) as info:
        load_obj_pattern(p)
    for w in (str(p),) + words:
        assert w in str(info.value), (w, str(info.value))
    assert "NaN" not in str(info.value)


def test_many_collapsed_uv_triangles_are_refused(skirt, tmp_path):
    """Some UV triangles collapsed (a few vertices' UVs zeroed): beyond 1% of the triangles the rest
    shape has zero-area triangles the simulation cannot use; named with their count."""
    uv = skirt.rest.copy()
    F = skirt.faces
    for f in F[::10]:                    # one corner of every 10th triangle moved onto another
        uv[f[0]] = uv[f[1]]
    p = _write(tmp_path / "some.obj", skirt, uv)
    with pytest.raises(ValueError, match=r"degenerate UV pattern: \d+ of \d+ triangles have \(near\) zero area in UV"):
        load_obj_pattern(p)


def test_malformed_uv_lines_are_named(skirt, tmp_path):
    p = _write(tmp_path / "nan.obj", skirt, skirt.rest.copy())
    p.write_text(p.read_text().replace("vt ", "vt nan ", 1))
    with pytest.raises(ValueError, match=r"NaN or Inf \(first: UV 1\)"):
        load_obj_pattern(p)
    q = tmp_path / "range.obj"
    q.write_text("v 0 0 0\nv 100 0 0\nv 0 100 0\nvt 0 0\nvt 1 0\nf 1/1 2/2 3/7\n")
    with pytest.raises(ValueError, match=r"names no 'vt' line \(first: 7; 2 UV\(s\)"):
        load_obj_pattern(q)
    r = tmp_path / "word.obj"
    r.write_text("v 0 0 0\nv 100 0 0\nv 0 100 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 x/3\n")
    with pytest.raises(ValueError, match=r"word.obj:7: "):
        load_obj_pattern(r)
