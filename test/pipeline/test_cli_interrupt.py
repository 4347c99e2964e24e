"""Ctrl-C (SIGINT) ends any `diffavatar` command with one line, `diffavatar: cancelled`, and exit
status 130 (128 + SIGINT), never a KeyboardInterrupt traceback (a recovery interrupted used to
print one and die by the signal). A recovery interrupted mid-run also cancels its token, so work
in other threads stops with it."""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

from diffavatar_core.demo import SAMPLE

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.parametrize("stage", ["body", "drape"])   # the body fit (~0.3 s in), the initial drape (~6 s in)
def test_sigint_during_a_recovery_ends_it_with_one_line_and_status_130(tmp_path, stage):
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "diffavatar_core", "recover", str(SAMPLE), "--units", "cm",
                          "--iterations", "1", "--out", str(out)], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True,
                         # SIGINT at its default whatever the runner's (a background job ignores it)
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines, started = [], threading.Event()

    def read():   # the progress lines (stderr is no tty: one line per report)
        for line in p.stderr:
            lines.append(line)
            if f"] {stage}" in line:
                started.set()
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert started.wait(20), "".join(lines)   # the recovery reached the stage
        time.sleep(0.5)
        assert p.poll() is None, "".join(lines)
        t0 = time.perf_counter()
        p.send_signal(signal.SIGINT)
        stdout = p.stdout.read()
        rc = p.wait(timeout=10)
        waited = time.perf_counter() - t0
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    reader.join(5)
    err = "".join(lines)
    assert rc == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    messages = [line for line in err.splitlines() if not line.startswith("[")]   # not the progress lines
    assert messages == ["diffavatar: cancelled"], err
    assert stdout == "" and waited < 5, (stdout, waited)
    assert not (out / "result.json").exists()


@pytest.mark.parametrize("how", ["KeyboardInterrupt", "Cancelled"])
def test_every_command_ends_an_interrupt_with_one_line_and_status_130(tmp_path, capsys, monkeypatch, how):
    """In process, through cli.main: a command interrupted (drape's job) or cancelled by the core."""
    from diffavatar_core import Cancelled
    from diffavatar_core.cli import main
    import diffavatar_core.sim.drape_job as drape_job

    def interrupted(*a, **k):
        raise KeyboardInterrupt if how == "KeyboardInterrupt" else Cancelled("cancelled during drape")
    monkeypatch.setattr(drape_job, "run", interrupted)
    rc = main(["drape", "--out", str(tmp_path / "drape")])
    err = capsys.readouterr().err
    assert rc == 130 and err == "diffavatar: cancelled\n", err
