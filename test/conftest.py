"""Shared test fixtures. Reference data lives outside the repo in ../shared/data (never copied
in); tests that read it skip with a reason when it is absent."""
import os
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
SHARED_DATA = pathlib.Path(os.environ.get("DIFFAVATAR_SHARED_DATA", REPO.parent / "shared" / "data"))


def shared_file(*parts: str) -> pathlib.Path:
    """Path of a reference file in shared/data, or skip the calling test with the reason."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.skip(f"reference data not present: {p}")
    return p


@pytest.fixture(autouse=True, scope="session")
def _two_threads():
    """Tests run with the core's thread count fixed (determinism), as CI's 2 cores."""
    import diffavatar_core
    diffavatar_core.set_num_threads(2)
