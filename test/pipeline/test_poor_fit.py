"""A garment type that does not match a garment-only scan (the bundled sample's skirt recovered as
a t-shirt: its waist taken for the neckline, a hole for a sleeve) ran to the end with only an
'opening not found' warning and a result 6–9 cm from the scan; now the result says it misfits
(recovery.POOR_FIT_CM) and asks about the garment type. The right type gets no such warning."""
import pathlib

import numpy as np
import pytest
import trimesh

from diffavatar_core.pipeline import recover
from diffavatar_core.pipeline.recovery import POOR_FIT_CM

SAMPLE = pathlib.Path(__file__).resolve().parents[2] / "diffavatar_core" / "data" / "sample_scan.ply"
QUICK = dict(units="cm", iterations=0, measurement_fit_iterations=0, measurement_fit_bending=[],
             template_sizing=False, bending_range_offsets=[], bending_candidates=[], fresh_every=0)


@pytest.fixture(scope="module")
def skirt_only():
    """The sample's skirt region alone (cm, no labels): a garment-only scan."""
    m = trimesh.load(SAMPLE, process=False)
    L = np.asarray(m.metadata["_ply_raw"]["vertex"]["data"]["label"]).astype(np.int64)
    V, F = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    Fg = F[(L[F] == L.max()).all(axis=1)]
    used = np.unique(Fg)
    remap = -np.ones(len(V), np.int64)
    remap[used] = np.arange(len(used))
    return V[used], remap[Fg]


def _misfit(r):
    return [w for w in r.warnings if "does not describe this scan" in w]


def test_a_skirt_recovered_as_a_tshirt_is_said_to_misfit_and_as_a_skirt_is_not(skirt_only):
    wrong = recover(skirt_only, {**QUICK, "garment_type": "tshirt"})
    assert wrong.metrics["chamfer_final_cm"] > POOR_FIT_CM
    (w,) = _misfit(wrong)
    assert "garment type 'tshirt'" in w and "template 'tshirt'" in w and f"{wrong.metrics['chamfer_final_cm']:.1f} cm" in w
    right = recover(skirt_only, {**QUICK, "garment_type": "skirt"})
    assert right.metrics["chamfer_final_cm"] < 1.0   # a fit: well below the threshold
    assert not _misfit(right)
