"""A scan far from its file's origin (a rig whose origin is a room's corner): recovered centred on
the subject (scan/frame.py), its outputs placed back on the scan as given. Before, the bundled
sample moved 30 m failed its initial drape (the single-precision sweeps resolve 3.6 µm at 30 m)."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

import bundled_sample
from bundled_sample import QUICK
from diffavatar_core.metrics import surface_distances
from diffavatar_core.pipeline import recover


@pytest.fixture(scope="module")
def sample_arrays():
    return bundled_sample.sample_arrays()


def test_a_scan_30_m_from_its_origin_recovers_and_its_outputs_overlay_it(sample_arrays):
    V, F, L = sample_arrays
    offset_cm = np.array([3000.0, 3000.0, -3000.0])
    r = recover((V + offset_cm, F, L), QUICK)
    origin = np.asarray(r.metrics["scan_origin_m"])
    np.testing.assert_array_equal(origin, [30.0, 30.0, -30.0])   # the floor below the subject, whole metres
    given = 0.01 * (V + offset_cm)   # the scan as given, in m (cm, Y up: no rotation)
    # the cleaned scan the preview overlays: the given vertices, back in place (fragments dropped)
    assert cKDTree(given).query(r.scan_mesh[0])[0].max() < 1e-9
    garment = L[F].min(axis=1) == L.max()   # the sample: body 0, skirt its one garment label
    assert garment.any() and not garment.all()
    # the draped garment lies on the scan's garment as given: its vertices' mean distance to it is
    # the size of the recovery's own Chamfer distance (cm), not 30 m
    d_garment = 100 * surface_distances(np.asarray(r.garment_vertices), given, F[garment].astype(np.int32))
    assert np.mean(d_garment) < 3 * r.metrics["chamfer_final_cm"] + 0.2
    # the body stands in the scan: the scan's body vertices lie on the posed body as given (cm)
    body_v = np.unique(F[~garment])
    d_body = 100 * surface_distances(given[body_v], np.asarray(r.body_vertices), np.asarray(r.body_faces, np.int32))
    assert np.median(d_body) < 1.0
    # the body's global translation (m) is given in the scan's frame too: 30 m away, as the scan is
    np.testing.assert_allclose(r.body_params.translation, origin, atol=0.05)
