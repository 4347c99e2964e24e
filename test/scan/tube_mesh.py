"""An open cylinder (a skirt's shape) for the scan tests, m: rings of n_phi vertices from y0 up to
y1 around the Y axis, radius r."""
import numpy as np


def tube_quads(n_phi: int, n_y: int, r: float, y0: float, y1: float):
    """(V (n_y·n_phi, 3), Q (Q, 4)): the vertices ring by ring and the quads (a, a + n_phi,
    b + n_phi, b), b the next vertex around the ring, band by band."""
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    y = np.repeat(np.linspace(y0, y1, n_y), n_phi)
    V = np.column_stack([r * np.cos(np.tile(phi, n_y)), y, r * np.sin(np.tile(phi, n_y))])
    i, j = np.meshgrid(np.arange(n_y - 1), np.arange(n_phi), indexing="ij")
    a, b = (i * n_phi + j).ravel(), (i * n_phi + (j + 1) % n_phi).ravel()
    return V, np.stack([a, a + n_phi, b + n_phi, b], 1)


def tube(n_phi: int = 24, n_y: int = 10, r: float = 0.2, y0: float = 0.5, y1: float = 1.0, interleaved: bool = False):
    """(V, F): tube_quads split into the triangles (a, a + n_phi, b) and (b, a + n_phi, b + n_phi) —
    all the first ones, then all the second ones; interleaved: quad by quad, as the triangle strip
    a0, a0 + n_phi, a1, a1 + n_phi, ... of each band gives them."""
    V, Q = tube_quads(n_phi, n_y, r, y0, y1)
    first, second = Q[:, [0, 1, 3]], Q[:, [3, 1, 2]]
    F = np.stack([first, second], 1).reshape(-1, 3) if interleaved else np.concatenate([first, second])
    return V, F
