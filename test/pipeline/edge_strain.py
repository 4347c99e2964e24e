"""Mean edge strain of a drape against its pattern, shared by the pipeline tests."""
import numpy as np


def mean_edge_strain(x, rest, faces) -> float:
    """Mean of |e|/|ē| − 1 over the triangles' edges: draped (x, m) against rest (pattern, m)."""
    E = np.vstack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return float((np.linalg.norm(x[E[:, 0]] - x[E[:, 1]], axis=1)
                  / np.linalg.norm(rest[E[:, 0]] - rest[E[:, 1]], axis=1) - 1).mean())
