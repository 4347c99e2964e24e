"""Pattern recovery through the differentiable drape, ground-truth round trip: a skirt whose
panels are 10% longer than the template is draped and sampled as the 'scan'; fitting the
template's panel maps through the equilibrium adjoint must recover the length."""
import numpy as np

from diffavatar_core.loss import garment_samples
from diffavatar_core.pipeline.garment_fit import fit_garment
from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import mannequin, two_panel_skirt


def _ordered(x, idx):
    """A loop's vertex chain ordered by angle around the body axis (Y)."""
    return idx[np.argsort(np.arctan2(x[idx, 0], x[idx, 2]))]


def test_fit_recovers_panel_length_from_a_draped_ground_truth():
    V, Fb = mannequin(48, 40)
    sk = two_panel_skirt(edge=0.04)
    n = len(sk["rest"]) // 2
    panel = np.repeat([0, 1], n)

    def make(rest):
        return Cloth(rest, sk["faces"], sk["x0"], seams=sk["seams"], groups=sk["groups"],
                     materials=[ClothMaterial()] * 2, body=(V, Fb))

    rest0 = sk["rest"]
    centre = np.array([rest0[panel == p].mean(0) for p in (0, 1)])
    truth = centre[panel] + (rest0 - centre[panel]) * [1.0, 1.10]
    gt = make(truth)
    assert gt.drape(max_steps=3000, refine_iterations=200).converged
    xs = np.array(gt.x)
    scan_points = garment_samples(xs, sk["faces"], 3000, seed=7).points(xs, sk["faces"])
    scan_loops = {k: xs[_ordered(xs, v)] for k, v in sk["boundaries"].items()}

    tmpl = make(rest0)
    assert tmpl.drape(max_steps=1500).converged
    x0 = np.array(tmpl.x)
    loops = {k: _ordered(x0, v) for k, v in sk["boundaries"].items()}
    res = fit_garment(tmpl, sk["faces"], panel, loops, scan_points, scan_loops, max_iterations=15,
                      fit_bending=False)
    assert res.loss_final < 0.25 * res.loss_initial, (res.loss_initial, res.loss_final)
    lengths = res.panel_maps[:, 1, 1]
    assert np.all(np.abs(lengths - 1.10) < 0.03), lengths
    values = [h["value"] for h in res.history]
    assert min(values) == res.loss_final
