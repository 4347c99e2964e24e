"""A test scene shared by the Newton tests: a sheet hung over a sphere, draped, then rumpled."""
import numpy as np

from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet, sphere


def sheet_on_sphere(n: int = 11, subdivisions: int = 1, noise: float = 0.003):
    """A 20 cm sheet of n×n vertices pinned along its top edge, hung over an icosphere (radius
    8 cm; 80 faces at subdivisions=1, whose face contact planes jump where a vertex's closest face
    changes), draped to equilibrium, then every free vertex moved by `noise` m of seeded noise (an
    optimizer's warm start)."""
    rest, F = grid_sheet(0.2, 0.2, n, n)
    x0 = np.column_stack([rest[:, 0], 0.2 - rest[:, 1], np.zeros(len(rest))])
    body = sphere(0.08, center=np.array([0.1, 0.1, -0.06]), subdivisions=subdivisions)
    cloth = Cloth(rest, F, x0, pinned=np.flatnonzero(np.isclose(rest[:, 1], 0.0)), body=body,
                  materials=ClothMaterial(bend_stiffness=1e-5))
    assert cloth.drape(max_steps=400, residual_tol=1e-8, refine_iterations=200).converged
    x = np.array(cloth.x)
    free = np.asarray(cloth.model.inv_mass) > 0
    x[free] += np.random.default_rng(0).normal(scale=noise, size=x[free].shape)
    cloth.reset(x)
    return cloth
