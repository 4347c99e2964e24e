"""The command line refuses bad inputs with `diffavatar: error: <message>` and exit status 2,
before any long work: an --out that cannot be a directory (an existing file, a path below a
file), a --config that is not a YAML mapping file (syntax error, tab indent, a python tag, a
directory, not text), a --template that is a directory. A write that fails after the work (disk
full) is named the same way, not a traceback; the good paths still run."""
import json
import os

import pytest

from diffavatar_core.cli import main
from diffavatar_core.commands import check_out_dir, check_out_file
from diffavatar_core.config import load_config
from diffavatar_core.demo import SAMPLE

FAST = """recover:
  iterations: 1
  measurement_fit_iterations: 0
  measurement_fit_bending: []
  template_sizing: false
  bending_range_offsets: []
  bending_candidates: []
  guided_stiffness: 0
  fresh_every: 0
"""


@pytest.fixture
def no_long_work(monkeypatch):
    """Every long stage the commands start replaced by one that records it was reached: a
    refusal 'before any work' must leave this empty."""
    import diffavatar_core.body.fitting as fitting
    import diffavatar_core.demo as demo
    import diffavatar_core.pipeline as pipeline
    import diffavatar_core.pipeline.synthetic as synthetic
    import diffavatar_core.sim.drape_job as drape_job
    started = []

    def stage(name):
        def run(*a, **k):
            started.append(name)
            raise AssertionError(f"{name} started")
        return run
    monkeypatch.setattr(pipeline, "recover", stage("recover"))
    monkeypatch.setattr(drape_job, "run", stage("drape"))
    monkeypatch.setattr(drape_job, "build", stage("animate's drape"))
    monkeypatch.setattr(fitting, "fit_body", stage("fit_body"))
    monkeypatch.setattr(synthetic, "make_case", stage("synthetic make_case"))
    monkeypatch.setattr(demo, "run", stage("demo"))
    return started


def _error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("diffavatar: error: ") and "Traceback" not in err, err
    return err.strip()


@pytest.fixture
def a_file(tmp_path):
    f = tmp_path / "afile"
    f.write_text("keep me\n")
    return f


@pytest.mark.parametrize("below", [False, True])
def test_recover_refuses_an_out_that_is_a_file_before_the_recovery(tmp_path, a_file, capsys, no_long_work, below):
    out = a_file / "sub" if below else a_file
    rc = main(["recover", str(SAMPLE), "--units", "cm", "--out", str(out)])
    err = _error(capsys)
    assert rc == 2 and no_long_work == []
    if below:
        assert f"--out {out}: cannot create it: {a_file} is not a directory" in err, err
    else:
        assert f"--out {out}: exists and is not a directory" in err, err
    assert a_file.read_text() == "keep me\n"          # the file named is left alone


@pytest.mark.parametrize("argv", [
    ["drape", "--out", "{f}"],
    ["animate", "--out", "{f}/x"],
    ["fit-body", str(SAMPLE), "--units", "cm", "--out", "{f}"],
    ["synthetic-scan", "--out", "{f}"],
    ["pattern", "skirt", "--out", "{f}/x"],
    ["send", "scan.ply", "--out", "{f}"],
    ["demo", "--out", "{f}"],
    ["preview", str(SAMPLE), "--garment", str(SAMPLE), "--out", "{f}/p.png"],
], ids=lambda a: a[0])
def test_every_command_with_out_refuses_a_file_before_its_work(a_file, capsys, no_long_work, argv):
    rc = main([a.replace("{f}", str(a_file)) for a in argv])
    err = _error(capsys)
    assert rc == 2 and no_long_work == [], (err, no_long_work)
    assert str(a_file) in err and "not a directory" in err, err
    assert a_file.read_text() == "keep me\n"


def test_preview_refuses_an_out_that_is_a_directory(tmp_path, capsys):
    assert main(["preview", str(SAMPLE), "--garment", str(SAMPLE), "--out", str(tmp_path)]) == 2
    assert f"--out {tmp_path}: is a directory, not a file" in _error(capsys)


def test_out_dir_check_accepts_existing_and_creatable_directories_without_creating(tmp_path, a_file):
    assert check_out_dir(tmp_path) == tmp_path
    nested = tmp_path / "a" / "b" / "c"
    assert check_out_dir(nested) == nested and not (tmp_path / "a").exists()   # nothing made by the check
    assert check_out_file(tmp_path / "new" / "p.png") == tmp_path / "new" / "p.png"
    for bad, why in ((a_file, "exists and is not a directory"), (a_file / "x" / "y", "is not a directory"),
                     ("", "empty path")):
        with pytest.raises(ValueError, match=why):
            check_out_dir(bad)
    link = tmp_path / "dangling"
    link.symlink_to(tmp_path / "gone")
    with pytest.raises(ValueError, match="broken symbolic link"):
        check_out_dir(link / "sub")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into any directory")
def test_out_dir_check_refuses_a_read_only_directory(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(ValueError, match="not writable"):
            check_out_dir(ro)
        with pytest.raises(ValueError, match=f"cannot create it: {ro} is not writable"):
            check_out_dir(ro / "sub")
    finally:
        ro.chmod(0o700)


def test_recover_writes_its_result_and_names_a_failed_write(tmp_path, capsys, monkeypatch):
    """The good path (a fast recovery into a directory that does not exist yet, two levels deep)
    writes the result; the same result written where a file cannot be written (result.json → /dev/full:
    'disk full') ends in a clean error naming the directory and the reason, not a traceback."""
    import diffavatar_core.pipeline as pipeline
    cfg = tmp_path / "fast.yaml"
    cfg.write_text(FAST)
    real, results = pipeline.recover, []

    def recover(*a, **k):
        results.append(real(*a, **k))
        return results[-1]
    monkeypatch.setattr(pipeline, "recover", recover)
    out = tmp_path / "new" / "out"
    rc = main(["recover", str(SAMPLE), "--units", "cm", "--out", str(out), "--config", str(cfg),
               "--iterations", "0", "--quiet"])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert json.loads(captured.out[:captured.out.rindex("}") + 1])["output_dir"] == str(out)
    assert json.loads((out / "result.json").read_text())["garment_type"] == "skirt"
    assert (out / "garment_draped.obj").stat().st_size > 0

    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full to fill")
    full = tmp_path / "full"
    full.mkdir()
    (full / "result.json").symlink_to("/dev/full")
    monkeypatch.setattr(pipeline, "recover", lambda *a, **k: results[0])   # the same result, again
    rc = main(["recover", str(SAMPLE), "--units", "cm", "--out", str(full), "--config", str(cfg), "--quiet"])
    err = _error(capsys)
    assert rc == 2 and f"writing the recovery's result to {full} failed" in err and "No space left" in err, err


@pytest.mark.parametrize("name,text,why", [
    ("syntax.yaml", "recover:\n  iterations: [1\n", r"is not valid YAML: .*expected ',' or '\]'.* at line 3"),
    ("tab.yaml", "recover:\n\titerations: 1\n", r"is not valid YAML: .*'\\t' that cannot start any token at line 2, column 1"),
    ("tag.yaml", "!!python/object/apply:os.system ['touch {marker}']\n", "holds a YAML tag that is not plain data"),
    ("list.yaml", "- 1\n- 2\n", "does not hold a mapping"),
    ("binary.yaml", None, "is not UTF-8 text"),
    ("dir.yaml", "DIR", "is a directory, not a YAML file"),
    ("missing.yaml", "MISSING", "no such file"),
    ("unknown.yaml", "recover:\n  weights:\n    interiour: 3\n", r"unknown key 'recover.weights.interiour'"),
])
def test_a_bad_config_file_is_refused_by_name(tmp_path, capsys, no_long_work, name, text, why):
    path = tmp_path / name
    marker = tmp_path / "ran"
    if text == "DIR":
        path.mkdir()
    elif text is None:
        path.write_bytes(b"\x7fELF\x02\x01\x01\x00\xff\xfe\x00")
    elif text != "MISSING":
        path.write_text(text.replace("{marker}", str(marker)))
    for argv in (["recover", str(SAMPLE), "--units", "cm", "--out", str(tmp_path / "out")],
                 ["scan-info", str(SAMPLE), "--units", "cm"]):
        rc = main(argv + ["--config", str(path)])
        err = _error(capsys)
        assert rc == 2 and str(path) in err, err
        assert __import__("re").search(why, err), err
    assert no_long_work == [] and not marker.exists() and not (tmp_path / "out").exists()


def test_a_good_config_file_still_loads_and_merges(tmp_path):
    path = tmp_path / "good.yaml"
    path.write_text("recover:\n  iterations: 3\n  weights:\n    interior: 12.5\n")
    cfg = load_config(path)
    assert cfg["recover"]["iterations"] == 3 and cfg["recover"]["weights"]["interior"] == 12.5
    assert cfg["recover"]["weights"]["seam"] == load_config()["recover"]["weights"]["seam"]   # the rest kept
    (tmp_path / "empty.yaml").write_text("")
    assert load_config(tmp_path / "empty.yaml") == load_config()


@pytest.mark.parametrize("kind", ["dir", "missing"])
def test_a_template_that_is_not_a_file_is_refused_before_the_recovery(tmp_path, capsys, no_long_work, kind):
    t = tmp_path / "tmpl.obj"
    if kind == "dir":
        t.mkdir()
    rc = main(["recover", str(SAMPLE), "--units", "cm", "--out", str(tmp_path / "out"), "--template", str(t)])
    err = _error(capsys)
    assert rc == 2 and no_long_work == [] and str(t) in err and "template" in err, err
    assert ("is a directory" if kind == "dir" else "nor an existing file") in err, err
