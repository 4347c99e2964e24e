"""`diffavatar recover` on the bundled sample in a process of its own, sent SIGINT once a progress
line (stderr is no tty: one line per report) satisfies a predicate; what it answered."""
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass

from bundled_sample import SAMPLE

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@dataclass
class Interrupted:
    rc: int
    stdout: str
    stderr: str      # progress lines included
    waited: float    # s from the signal to the process's end

    @property
    def messages(self) -> list:
        """stderr's lines that are not progress lines ('[  t s] stage ...')."""
        return [line for line in self.stderr.splitlines() if not line.startswith("[")]


def interrupt_recovery(out, iterations: int, when, settle_s: float = 0.0, reach_s: float = 120.0,
                       end_s: float = 10.0) -> Interrupted:
    """Runs the recovery with `--out out`, sends SIGINT settle_s after the first progress line for
    which when(line) holds (within reach_s s of the start), and waits up to end_s s for its end.
    reach_s only bounds the wait for that line (the body fit before the drape takes ~10 s alone on
    a 2-core machine and over 20 s beside the other pytest-xdist worker); what is asserted about the
    interrupt is the caller's."""
    p = subprocess.Popen([sys.executable, "-m", "diffavatar_core", "recover", str(SAMPLE), "--units", "cm",
                          "--iterations", str(iterations), "--out", str(out)], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True,
                         # SIGINT at its default whatever the runner's (a background job ignores it)
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines, reached = [], threading.Event()

    def read():
        for line in p.stderr:
            lines.append(line)
            if when(line):
                reached.set()
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert reached.wait(reach_s), "".join(lines)
        time.sleep(settle_s)
        assert p.poll() is None, "".join(lines)
        t0 = time.perf_counter()
        p.send_signal(signal.SIGINT)
        stdout = p.stdout.read()
        rc = p.wait(timeout=end_s)
        waited = time.perf_counter() - t0
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    reader.join(5)
    return Interrupted(rc, stdout, "".join(lines), waited)
