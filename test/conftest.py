"""Shared test fixtures; reference-data helpers are in shared_data.py."""
import pytest

from shared_data import REPO, SHARED_DATA, shared_file  # noqa: F401 (re-exported for fixtures)


@pytest.fixture(autouse=True, scope="session")
def _two_threads():
    """Tests run with the core's thread count fixed (determinism), as CI's 2 cores."""
    import diffavatar_core
    diffavatar_core.set_num_threads(2)
