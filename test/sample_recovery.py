"""The bundled sample's recovery with the configured options (cm, `iterations` given), made once
per test session and shared: test_recover checks it against the sample's ground truth, and
test_node checks that the node's real job gives the same assets (each used to recover it
itself, about 80 s apiece on a 2-core machine). Callers must not modify what it returns."""
import functools

import pytest

from diffavatar_core.demo import SAMPLE

# Tests that use recovered_sample run on one pytest-xdist worker (`make test` runs one per core), so the
# recovery is made once, not once per worker.
SAMPLE_GROUP = pytest.mark.xdist_group("sample_recovery")


@functools.lru_cache(maxsize=None)
def recovered_sample(iterations: int):
    """(RecoveryResult, the stages its progress callback reported, in order)."""
    from diffavatar_core.pipeline import recover
    stages = []
    r = recover(SAMPLE, {"units": "cm", "iterations": iterations}, progress=lambda s, *_: stages.append(s))
    return r, tuple(stages)
