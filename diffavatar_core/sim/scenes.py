"""Geometry the project generates for tests, benchmarks and the drape demo (metres, Y up,
facing +Z): regular sheets, a body-like mannequin (closed surface of revolution with elliptic
cross-sections) and a two-panel skirt sewn around it."""
from __future__ import annotations

import numpy as np


def grid_sheet(width: float, height: float, nx: int, ny: int):
    """A rectangular pattern width×height (m) with nx×ny vertices; returns rest (V,2), faces
    (F,3) counter-clockwise. Vertex (i, j) has index j*nx + i."""
    xs, ys = np.meshgrid(np.linspace(0.0, width, nx), np.linspace(0.0, height, ny))
    rest = np.column_stack([xs.ravel(), ys.ravel()])
    j, i = np.mgrid[0:ny - 1, 0:nx - 1]
    a = (j * nx + i).ravel()
    b, c, d = a + 1, a + nx, a + nx + 1
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])]).astype(np.int32)
    return rest, faces


# Mannequin radius profile: (height y in m, half-width in m); depth = 0.75 × width.
_PROFILE = np.array([[0.60, 0.000], [0.60, 0.150], [0.75, 0.165], [0.90, 0.180], [1.00, 0.150],
                     [1.06, 0.135], [1.18, 0.150], [1.30, 0.165], [1.40, 0.175], [1.45, 0.14],
                     [1.49, 0.070], [1.55, 0.060], [1.58, 0.000]])


def mannequin(n_around: int = 64, n_up: int = 60):
    """A closed, outward-oriented body-like torso (hips, waist, chest, shoulders, neck) from
    y = 0.60 m to 1.58 m; returns (V (N,3), F (M,3)). Waist girth ≈ 0.75 m, hips ≈ 0.99 m."""
    ys = np.linspace(_PROFILE[0, 0], _PROFILE[-1, 0], n_up)
    # Arc-length-free interpolation of the half-width; caps are single pole vertices.
    prof = np.interp(ys, _PROFILE[1:-1, 0], _PROFILE[1:-1, 1])
    t = np.linspace(0, 2 * np.pi, n_around, endpoint=False)
    rings = [np.column_stack([r * np.sin(t), np.full(n_around, y), 0.75 * r * np.cos(t)])
             for y, r in zip(ys[1:-1], prof[1:-1])]
    V = np.vstack([[[0.0, ys[0], 0.0]], *rings, [[0.0, ys[-1], 0.0]]])
    F = []
    nr = len(rings)
    for k in range(n_around):
        k1 = (k + 1) % n_around
        F.append([0, 1 + k1, 1 + k])  # bottom cap, normal −Y
        for r in range(nr - 1):
            a, b = 1 + r * n_around + k, 1 + r * n_around + k1
            c, d = a + n_around, b + n_around
            F += [[a, b, d], [a, d, c]]
        top = len(V) - 1
        base = 1 + (nr - 1) * n_around
        F.append([base + k, base + k1, top])
    F = np.array(F, dtype=np.int32)
    # Orient outward: the signed volume must be positive.
    v0, v1, v2 = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    if np.einsum("ij,ij->i", v0, np.cross(v1, v2)).sum() < 0:
        F = F[:, ::-1].copy()
    return V, F


def ellipse_perimeter(a: float, b: float) -> float:
    """Ramanujan's approximation (m)."""
    h = ((a - b) / (a + b)) ** 2
    return np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))


def two_panel_skirt(waist: float = 0.80, hem: float = 1.10, length: float = 0.40, y_waist: float = 1.06,
                    edge: float = 0.02):
    """A skirt of two trapezoid panels (front, back) sewn at both sides, placed as an elliptic
    cone around the mannequin with its waist at y_waist (m). Girths waist/hem in m, target edge
    length `edge` (m). Returns dict(rest, faces, x0, seams, groups, boundaries) — boundaries
    'waist' and 'hem' as ordered vertex chains."""
    nx = max(3, int(round(hem / 2 / edge)) + 1)
    ny = max(3, int(round(length / edge)) + 1)
    sq, faces = grid_sheet(1.0, 1.0, nx, ny)
    # Trapezoid: row j at fraction s = j/(ny-1) from the hem (s=0) to the waist (s=1).
    s = sq[:, 1]
    half = 0.5 * (hem / 2 * (1 - s) + waist / 2 * s)
    panel = np.column_stack([(sq[:, 0] - 0.5) * 2 * half, s * length])
    n = len(panel)
    rest = np.vstack([panel, panel + [hem / 2 + 0.1, 0.0]])  # back panel beside the front one
    F = np.vstack([faces, faces + n]).astype(np.int32)
    # 3D: each panel wraps half an ellipse (front z > 0, back z < 0) with a 3 cm clearance.
    u = sq[:, 0]  # 0..1 across the panel
    girth = hem * (1 - s) + waist * s
    a = girth / (2 * np.pi) * 1.05 + 0.03  # semi-axis x (m), slightly outside the body
    b = 0.75 * a
    ang_front = np.pi * (u - 0.5)          # −90°..90° across the front
    front = np.column_stack([a * np.sin(ang_front), y_waist - length + s * length, b * np.cos(ang_front)])
    ang_back = np.pi * (u - 0.5) + np.pi   # the back panel continues around
    back = np.column_stack([a * np.sin(ang_back), y_waist - length + s * length, b * np.cos(ang_back)])
    # Back panel's pattern orientation: its left edge (u = 0) is at the body's left side (+X)
    x0 = np.vstack([front, back])
    j = np.arange(ny)
    right_f, left_f = j * nx + (nx - 1), j * nx        # front: u=1 at +X side, u=0 at −X side
    right_b, left_b = n + j * nx, n + j * nx + (nx - 1)  # back: u=0 at +X, u=1 at −X
    seams = np.vstack([np.column_stack([right_f, right_b]), np.column_stack([left_f, left_b])]).astype(np.int32)
    groups = np.concatenate([np.zeros(len(faces)), np.ones(len(faces))]).astype(np.int32)
    top = (ny - 1) * nx + np.arange(nx)
    bottom = np.arange(nx)
    boundaries = {"waist": np.concatenate([top, n + top]), "hem": np.concatenate([bottom, n + bottom])}
    return dict(rest=rest, faces=F, x0=x0, seams=seams, groups=groups, boundaries=boundaries)


def hanging_sheet(width=0.1, length=0.3, nx=6, ny=19, material=None, vertical_axis=1, **kw):
    """A sheet width×length (m) hung in the XY plane from its pinned top row; pattern axis
    `vertical_axis` (0 = warp/x, 1 = weft/y) points down. Returns (Cloth, rest, pinned)."""
    from .cloth import Cloth
    from .material import ClothMaterial
    if vertical_axis == 1:
        rest, F = grid_sheet(width, length, nx, ny)
        x0 = np.column_stack([rest[:, 0], length - rest[:, 1], np.zeros(len(rest))])
        pinned = np.flatnonzero(np.isclose(rest[:, 1], 0.0))
    else:
        rest, F = grid_sheet(length, width, ny, nx)
        x0 = np.column_stack([rest[:, 1], length - rest[:, 0], np.zeros(len(rest))])
        pinned = np.flatnonzero(np.isclose(rest[:, 0], 0.0))
    cloth = Cloth(rest, F, x0, pinned=pinned, materials=material or ClothMaterial(), **kw)
    return cloth, rest, pinned


def sphere(radius=0.2, center=(0.0, 0.0, 0.0), subdivisions=3):
    """An outward-oriented icosphere (V, F) of `radius` (m) at `center`."""
    import trimesh
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices) + np.asarray(center, dtype=float), np.asarray(m.faces, dtype=np.int32)


def sheet_against_sphere(offset=(0.0, 0.0, 0.0), n=11, bend_stiffness=1e-5, **kw):
    """A 0.2 m square sheet hung from its pinned top row in the plane z = 0, with a sphere
    (radius 8 cm, centre 6 cm behind the sheet) bulging it forward: a stable contact scene
    (used by the translation and gradient tests). Everything shifted by `offset` (m)."""
    from .cloth import Cloth
    from .material import ClothMaterial
    off = np.asarray(offset, dtype=float)
    rest, F = grid_sheet(0.2, 0.2, n, n)
    x0 = np.column_stack([rest[:, 0], 0.2 - rest[:, 1], np.zeros(len(rest))]) + off
    pinned = np.flatnonzero(np.isclose(rest[:, 1], 0.0))
    V, Fb = sphere(0.08, center=off + [0.1, 0.1, -0.06], subdivisions=3)
    mat = kw.pop("materials", ClothMaterial(bend_stiffness=bend_stiffness))
    return Cloth(rest, F, x0, pinned=pinned, body=(V, Fb), materials=mat, **kw)
