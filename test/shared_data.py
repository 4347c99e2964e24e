"""Reference data of the tests (a module with a unique name: several test directories have a
`conftest.py`, so `from conftest import ...` inside a test resolves to whichever was loaded
last). Reference data lives outside the repo in ../shared/data (never copied in); tests that
read it skip with a reason when it is absent."""
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
