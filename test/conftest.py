"""Shared test fixtures; reference-data helpers are in shared_data.py."""
import faulthandler
import os
import sys

# `make test` runs one pytest-xdist worker per core, each with the core's 2 OpenMP threads: threads
# that wait for work sleep instead of spinning on a core the other worker needs (read by libgomp
# when diffavatar_core._core first loads, below this line).
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import pytest  # noqa: E402

from shared_data import REPO, SHARED_DATA, shared_file  # noqa: F401 (re-exported for fixtures)


@pytest.fixture(autouse=True, scope="session")
def _two_threads():
    """Tests run with the core's thread count fixed at CI's 2 cores, in every xdist worker."""
    import diffavatar_core
    diffavatar_core.set_num_threads(2)


# A test that has not finished after this long is hung (the slowest test takes about two
# minutes on 2 cores): every thread's stack goes to stderr and the run exits with status 1,
# instead of a CI run that only stops at its time limit with nothing said. faulthandler's
# timer is a C thread, so it fires even when the hang holds the GIL (a DDS teardown, say).
TEST_TIMEOUT_S = float(os.environ.get("DIFFAVATAR_TEST_TIMEOUT_S", "900"))


_REAL_STDERR = None


def pytest_addoption(parser):
    parser.addoption("--roundoff-seed", type=int, default=None, metavar="N",
                     help="perturb every built-in template's pattern by 1e-13 m of seeded noise "
                          "(test/roundoff.py): do the tests hold in the fold states round-off gives?")


def pytest_configure(config):
    seed = config.getoption("--roundoff-seed")
    if seed is not None:
        import roundoff
        roundoff.install(seed)
    # a copy of the terminal's stderr, taken while pytest's capture is suspended: during a
    # test, fd 2 is pytest's capture file, which a process exiting from the timer never shows
    global _REAL_STDERR
    _REAL_STDERR = os.fdopen(os.dup(sys.__stderr__.fileno()), "w")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    out = _REAL_STDERR or sys.__stderr__
    faulthandler.dump_traceback_later(TEST_TIMEOUT_S, exit=True, file=out)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
