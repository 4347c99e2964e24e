"""The bundled sample scan (diffavatar_core/data/sample_scan.ply: a skirt on a body, cm, Y up) as
arrays, and the quick recovery options the input-handling tests run it with (no iterations, none
of the optional stages: body fit, initial drape and the assets' drape only)."""
import functools
import pathlib

import numpy as np
import trimesh

SAMPLE = pathlib.Path(__file__).resolve().parents[2] / "diffavatar_core" / "data" / "sample_scan.ply"
QUICK = dict(units="cm", iterations=0, measurement_fit_iterations=0, measurement_fit_bending=[],
             template_sizing=False, bending_range_offsets=[], bending_candidates=[], fresh_every=0)
# The recovery without its bending search after the measurement fit and without the bending's
# range (about 35 of the sample's 60 s at iterations 2): for the tests whose property lies in
# another stage.
NO_BENDING_SEARCH = dict(measurement_fit_bending=[], bending_range_offsets=[])


@functools.lru_cache(maxsize=1)
def _read():
    m = trimesh.load(SAMPLE, process=False)
    labels = np.asarray(m.metadata["_ply_raw"]["vertex"]["data"]["label"]).astype(np.int64)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), labels


def sample_arrays():
    """(vertices (N, 3) cm, faces (M, 3), labels (N,): body 0, the skirt the largest value), copies."""
    return tuple(a.copy() for a in _read())
