"""Animation export: OBJ sequence, animated .glb (parsed by trimesh and by hand: accessor data
round-trips every frame's positions), .npz of positions per frame."""
import json

import numpy as np
import pytest
import trimesh

from diffavatar_core.animation_export import write_animation
from diffavatar_core.gltf import accessor_array, read_glb
from diffavatar_core.io import load_mesh


def motion(T=6):
    """A waving cloth grid over a rotating sphere, T frames (m)."""
    n = 6
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    uv = np.column_stack([u.ravel(), v.ravel()])
    F = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            F += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    F = np.array(F)
    sph = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    Vb0, Fb = np.asarray(sph.vertices), np.asarray(sph.faces)
    G, B = [], []
    for t in range(T):
        wave = 0.05 * np.sin(2 * np.pi * (uv[:, 0] + t / T))
        G.append(np.column_stack([uv[:, 0] - 0.5, 1.2 - uv[:, 1], 0.35 + wave]))
        a = 0.2 * t
        R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        B.append(Vb0 @ R.T + [0, 1.0 + 0.01 * t, 0])
    return np.array(G), F, np.array(B), Fb, uv


def test_write_animation_round_trips(tmp_path):
    G, F, B, Fb, uv = motion()
    T, fps = len(G), 24.0
    paths = write_animation(tmp_path, G, F, B, Fb, fps, uv=uv)
    # OBJ sequence: one garment and one body file per frame, positions to 9 significant digits
    assert len(paths["obj"]) == 2 * T
    for t in (0, T - 1):
        Vg, Fg = load_mesh(tmp_path / "obj" / f"garment_{t:04d}.obj")
        np.testing.assert_allclose(Vg, G[t], rtol=1e-8, atol=1e-9)
        np.testing.assert_array_equal(Fg, F)
        Vb, Fbb = load_mesh(tmp_path / "obj" / f"body_{t:04d}.obj")
        np.testing.assert_allclose(Vb, B[t], rtol=1e-8, atol=1e-9)
        np.testing.assert_array_equal(Fbb, Fb)
    assert "vt " in (tmp_path / "obj" / "garment_0000.obj").read_text()
    # npz: exact
    z = np.load(paths["npz"])
    np.testing.assert_array_equal(z["garment"], G)
    np.testing.assert_array_equal(z["body"], B)
    np.testing.assert_array_equal(z["garment_faces"], F)
    np.testing.assert_allclose(z["times"], np.arange(T) / fps)
    assert float(z["fps"]) == fps
    # glb: trimesh parses it as a scene with both meshes at frame 0
    scene = trimesh.load(paths["glb"], force="scene")
    assert len(scene.geometry) == 2
    counts = sorted(len(g.vertices) for g in scene.geometry.values())
    assert counts == sorted([G.shape[1], B.shape[1]])
    # glb by hand: base + morph target t reproduces frame t to float32 precision
    doc, bin_chunk = read_glb(paths["glb"])
    assert doc["asset"]["version"] == "2.0"
    json.dumps(doc)
    anim = doc["animations"][0]
    for node_idx, (X, faces) in enumerate(((G, F), (B, Fb))):
        mesh = doc["meshes"][doc["nodes"][node_idx]["mesh"]]
        prim = mesh["primitives"][0]
        base = accessor_array(doc, bin_chunk, prim["attributes"]["POSITION"])
        assert len(prim["targets"]) == T - 1  # frame count
        np.testing.assert_array_equal(accessor_array(doc, bin_chunk, prim["indices"]).reshape(-1, 3), faces)
        for t in range(T):
            P = base if t == 0 else base + accessor_array(doc, bin_chunk, prim["targets"][t - 1]["POSITION"])
            np.testing.assert_allclose(P, X[t], rtol=0, atol=4 * np.finfo(np.float32).eps * np.abs(X).max())
        acc = doc["accessors"][prim["attributes"]["POSITION"]]
        np.testing.assert_allclose(acc["min"], base.min(axis=0))
        ch = [c for c in anim["channels"] if c["target"]["node"] == node_idx][0]
        assert ch["target"]["path"] == "weights"
        smp = anim["samplers"][ch["sampler"]]
        times = accessor_array(doc, bin_chunk, smp["input"])
        np.testing.assert_allclose(times, np.arange(T) / fps, rtol=1e-6)
        W = accessor_array(doc, bin_chunk, smp["output"]).reshape(T, T - 1)
        np.testing.assert_array_equal(W, np.eye(T, T - 1, k=-1))  # frame t ↔ target t−1
    uv_gl = accessor_array(doc, bin_chunk, doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"])
    np.testing.assert_allclose(uv_gl, np.column_stack([uv[:, 0], 1 - uv[:, 1]]), atol=1e-7)


def test_single_frame_garment_only(tmp_path):
    G, F, _, _, _ = motion(T=1)
    paths = write_animation(tmp_path, G, F, fps=30)
    assert len(paths["obj"]) == 1
    doc, bin_chunk = read_glb(paths["glb"])
    assert "animations" not in doc and "targets" not in doc["meshes"][0]["primitives"][0]
    scene = trimesh.load(paths["glb"], force="scene")
    assert len(scene.geometry) == 1
    np.testing.assert_allclose(accessor_array(doc, bin_chunk, 0 + doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]),
                               G[0], atol=1e-6)


def test_invalid_inputs(tmp_path):
    G, F, B, Fb, uv = motion(T=3)
    with pytest.raises(ValueError, match="frames_garment"):
        write_animation(tmp_path, G[0], F, B, Fb, 30)
    with pytest.raises(ValueError, match="frames_body"):
        write_animation(tmp_path, G, F, B[:2], Fb, 30)
    with pytest.raises(ValueError, match="frames_body"):
        write_animation(tmp_path, G, F, B, None, 30)
    with pytest.raises(ValueError, match="garment_faces"):
        write_animation(tmp_path, G, F + 100, B, Fb, 30)
    with pytest.raises(ValueError, match="fps"):
        write_animation(tmp_path, G, F, B, Fb, 0)
    with pytest.raises(ValueError, match="uv"):
        write_animation(tmp_path, G, F, B, Fb, 30, uv=uv[:3])
    bad = G.copy()
    bad[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match="frames_garment"):
        write_animation(tmp_path, bad, F, B, Fb, 30)
