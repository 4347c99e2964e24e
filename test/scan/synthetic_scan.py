"""Synthetic segmented scans (and the pytest fixtures `synthetic`, `synthetic_ply` the tests import) with known ground truth, built here: a closed "body" capsule
(label 0) inside a "shirt" (label 1) — a tube along X whose open ends are the sleeves and whose
torso is cut open at the bottom (hem) and top (neckline) — plus small holes, one larger
"under-arm" occlusion hole and floating fragments. Geometry is made in the core frame (m,
Y up, +X = the body's left) and written in the scan's frame; the ground truth stays in the
core frame."""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np
import pytest

N_RINGS, N_PHI = 73, 96          # rings along X (1 cm apart), cells around the tube
HALF_SPAN = 0.36                 # m, sleeve end at x = ±0.36
SHIRT_Y = 1.2                    # m, height of the tube's axis
HEM_CUT, NECK_CUT = -0.30, 0.24  # m below / above the axis


def shared_file(*parts: str):
    """test/conftest.py's shared_file (path of a reference file, or skip the test). Loaded by
    path: with several conftest.py files the plain name `conftest` is ambiguous."""
    import importlib.util
    import pathlib
    import sys
    name = "_diffavatar_root_conftest"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, pathlib.Path(__file__).parents[1] / "conftest.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        sys.modules[name] = mod
    return sys.modules[name].shared_file(*parts)


def _smooth_plateau(x):
    t = np.clip((np.abs(x) - 0.14) / 0.10, 0.0, 1.0)
    return 1.0 - t * t * (3 - 2 * t)


def _shirt_grid():
    """(V (R·P, 3), cell centres (R-1, P, 3)) of the tube, vertex (i, j) at index i·P + j."""
    x = np.linspace(HALF_SPAN, -HALF_SPAN, N_RINGS)
    phi = 2 * np.pi * np.arange(N_PHI) / N_PHI
    s = _smooth_plateau(x)
    h_bot = 0.06 + 0.34 * s
    h_top = 0.06 + (0.14 + 0.08 * np.exp(-(x / 0.06) ** 2)) * s
    rz = 0.06 + 0.06 * s
    X, PHI = np.meshgrid(x, phi, indexing="ij")
    c = np.cos(PHI)
    H = np.where(c > 0, h_top[:, None], h_bot[:, None])
    Y = SHIRT_Y + H * c
    Z = rz[:, None] * np.sin(PHI)
    V = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    return V


def _cell_faces(i, j):
    P = N_PHI
    a, b = i * P + j, i * P + (j + 1) % P
    c, d = (i + 1) * P + (j + 1) % P, (i + 1) * P + j
    return [[a, b, c], [a, c, d]]


def _cell_boundary_vertices(cells: set) -> set:
    """Vertices on the boundary of a union of grid cells that touch a cell outside it."""
    P = N_PHI
    out = set()
    for (i, j) in cells:
        for di, dj in ((0, 0), (0, 1), (1, 1), (1, 0)):
            vi, vj = i + di, (j + dj) % P
            around = [(vi - 1, (vj - 1) % P), (vi - 1, vj), (vi, (vj - 1) % P), (vi, vj)]
            if any(0 <= a < N_RINGS - 1 and (a, b) not in cells for a, b in around):
                out.add(vi * P + vj)
    return out


@dataclass
class SyntheticScan:
    """Ground truth in the core frame (m): V (N, 3) and F of the main mesh (body then shirt,
    only referenced vertices) followed by the fragments; labels (N,); openings {name: (K, 3)
    point set}; holes: list of (K, 3) point sets; n_main: vertices before the fragments;
    shirt_vertex_mask (n_main,)."""
    V: np.ndarray
    F: np.ndarray
    labels: np.ndarray
    n_main: int
    n_main_faces: int
    shirt_vertex_mask: np.ndarray
    openings: dict
    holes: list


def make_synthetic_scan(fragments: bool = True, holes: bool = True) -> SyntheticScan:
    import trimesh
    Vs = _shirt_grid()
    x = Vs.reshape(N_RINGS, N_PHI, 3)
    centre = 0.25 * (x[:-1] + np.roll(x[:-1], -1, axis=1) + x[1:] + np.roll(x[1:], -1, axis=1))
    rel = centre[..., 1] - SHIRT_Y
    hem = {(i, j) for i, j in zip(*np.nonzero(rel < HEM_CUT))}
    neck = {(i, j) for i, j in zip(*np.nonzero(rel > NECK_CUT))}
    ring = lambda i: set(range(i * N_PHI, (i + 1) * N_PHI))  # noqa: E731
    i_front = N_RINGS // 2 + 5                      # x ≈ -0.05, front (φ ≈ 90°) torso
    hole_sets = []
    if holes:
        j_front = N_PHI // 4
        hole_sets = [{(i_front, j_front)},                                   # 1 cell
                     {(i_front + a, 3 * N_PHI // 4 + b) for a in range(3) for b in range(3)},  # back, 3×3
                     {(14 + a, 5 * N_PHI // 16 + b) for a in range(3) for b in range(5)}]  # under-arm, +X
    removed = hem | neck | set().union(*hole_sets) if hole_sets else hem | neck
    Fs = np.array([f for i in range(N_RINGS - 1) for j in range(N_PHI)
                   if (i, j) not in removed for f in _cell_faces(i, j)])
    truth_idx = {"hem": _cell_boundary_vertices(hem), "neckline": _cell_boundary_vertices(neck),
                 "sleeve_left": ring(0), "sleeve_right": ring(N_RINGS - 1)}
    hole_idx = [_cell_boundary_vertices(h) for h in hole_sets]
    # keep referenced shirt vertices only (the cut-away cap vertices are not part of the scan)
    used = np.zeros(len(Vs), bool)
    used[Fs.ravel()] = True
    new = np.cumsum(used) - 1
    Vs, Fs = Vs[used], new[Fs]
    remap = lambda s: Vs[sorted(new[list(s)])]  # noqa: E731

    body = trimesh.creation.capsule(height=1.5, radius=0.1, count=[24, 24])
    Vb = np.asarray(body.vertices)[:, [0, 2, 1]] * [1, 1, -1] + [0, 0.85, 0]   # axis Z → Y
    Fb = np.asarray(body.faces)[:, [0, 2, 1]]                                    # keep outward winding
    V = np.concatenate([Vb, Vs])
    F = np.concatenate([Fb, Fs + len(Vb)])
    labels = np.concatenate([np.zeros(len(Vb), np.int64), np.ones(len(Vs), np.int64)])
    n_main, n_main_faces = len(V), len(F)
    if fragments:
        ico = trimesh.creation.icosphere(subdivisions=1, radius=0.01)
        for centre_, lab in (((0.5, 1.3, 0.1), 1), ((-0.4, 0.3, 0.0), 0), ((0.0, 1.9, 0.05), 5)):
            F = np.concatenate([F, np.asarray(ico.faces) + len(V)])
            V = np.concatenate([V, np.asarray(ico.vertices) + centre_])
            labels = np.concatenate([labels, np.full(len(ico.vertices), lab)])
    mask = np.zeros(n_main, bool)
    mask[len(Vb):] = True
    return SyntheticScan(V, F, labels, n_main, n_main_faces, mask,
                         {k: remap(v) for k, v in truth_idx.items()}, [remap(h) for h in hole_idx])


def core_to_scan(V, units: str, up: str) -> np.ndarray:
    """Core frame (m, Y up) → a scan frame, written out independently of the code under test:
    Z up means (x, y, z)_core = (x, z, -y)_scan."""
    scale = {"m": 1.0, "cm": 100.0, "mm": 1000.0}[units]
    P = np.asarray(V, dtype=np.float64)
    if up == "z":
        P = np.column_stack([P[:, 0], -P[:, 2], P[:, 1]])
    return P * scale


def write_ply(path, V, F, labels=None, binary: bool = False, label_type: str = "uchar") -> None:
    """PLY with double x, y, z and an optional per-vertex `label` (ascii uses repr: exact)."""
    head = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0",
            f"element vertex {len(V)}", "property double x", "property double y", "property double z"]
    if labels is not None:
        head.append(f"property {label_type} label")
    head += [f"element face {len(F)}", "property list uchar int vertex_indices", "end_header"]
    with open(path, "wb") as fh:
        fh.write(("\n".join(head) + "\n").encode())
        lab_fmt = {"uchar": "B", "int": "i", "ushort": "H"}[label_type]
        if binary:
            for k, p in enumerate(V):
                fh.write(struct.pack("<3d", *p))
                if labels is not None:
                    fh.write(struct.pack("<" + lab_fmt, int(labels[k])))
            for f in F:
                fh.write(struct.pack("<B3i", 3, *map(int, f)))
        else:
            lines = [" ".join(repr(float(c)) for c in p) + (f" {int(labels[k])}" if labels is not None else "")
                     for k, p in enumerate(V)]
            lines += [f"3 {int(f[0])} {int(f[1])} {int(f[2])}" for f in F]
            fh.write(("\n".join(lines) + "\n").encode())


# Fixtures (import them into a test module to use them)
@pytest.fixture(scope="session")
def synthetic():
    return make_synthetic_scan()


@pytest.fixture(scope="session")
def synthetic_ply(tmp_path_factory, synthetic):
    """{'ascii': path, 'binary': path} of the synthetic scan in cm, Z up."""
    d = tmp_path_factory.mktemp("scan")
    out = {}
    for enc in ("ascii", "binary"):
        p = d / f"scan_{enc}.ply"
        write_ply(p, core_to_scan(synthetic.V, "cm", "z"), synthetic.F, synthetic.labels, binary=enc == "binary")
        out[enc] = p
    return out
