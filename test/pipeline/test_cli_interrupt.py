"""Ctrl-C (SIGINT) ends any `diffavatar` command with one line, `diffavatar: cancelled`, and exit
status 130 (128 + SIGINT), never a KeyboardInterrupt traceback (a recovery interrupted used to
print one and die by the signal). A recovery interrupted mid-run also cancels its token, so work
in other threads stops with it."""
import pytest

from interrupted_recovery import interrupt_recovery


@pytest.mark.parametrize("stage", ["body", "drape"])   # the body fit (~0.3 s in), the initial drape (~6 s in)
def test_sigint_during_a_recovery_ends_it_with_one_line_and_status_130(tmp_path, stage):
    out = tmp_path / "out"
    r = interrupt_recovery(out, 1, lambda line: f"] {stage}" in line, settle_s=0.5)
    assert r.rc == 130, r.stderr
    assert "Traceback" not in r.stderr and "KeyboardInterrupt" not in r.stderr, r.stderr
    assert r.messages == ["diffavatar: cancelled"], r.stderr
    assert r.stdout == "" and r.waited < 5, (r.stdout, r.waited)
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
