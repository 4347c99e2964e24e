"""RecoverOptions refuses, when the options are made and by the option's own name, every value a
stage would only refuse minutes later under another name (after the body fit and the drape): a
count of 0 (samples, drape_iterations), the step size of a group the co-optimization moves at 0,
a Sobolev length or a bending stiffness far past any garment's, a robust boundary scale that
underflows, a residual tolerance below Newton's round-off floor, a number past the C++ core's int,
an option of the wrong type (a list for garment_type: once a bare TypeError) — and the loaded
config's `metrics:` / `scan:` groups the recovery reads (metrics.chamfer_samples 0 once failed
late as 'n: expected a positive integer'). The good values next to each bound are still accepted,
through recover() and the command line the refusal comes before any stage starts."""
import copy

import pytest

from diffavatar_core.config import load_config
from diffavatar_core.demo import SAMPLE
from diffavatar_core.pipeline import RecoverOptions, recover
from diffavatar_core.pipeline import options as options_module

ZERO_STEPS = {"handles": 0.0, "log10_bending": 0.0, "log10_stretch": 0.0, "shape": 0.0, "pose": 0.0,
              "measurements": 0.0}


@pytest.mark.parametrize("overrides,message", [
    ({"samples": 0}, r"samples must be a positive integer, got 0"),
    ({"samples": 10**8}, r"samples must be at most 10000000"),
    ({"drape_iterations": 0}, r"drape_iterations must be a positive integer, got 0"),
    ({"drape_iterations": 2**31}, r"drape_iterations must be at most 2147483647"),
    ({"drape_iterations": 2**30, "edge_length": 0.01}, r"drape_iterations times \(0\.04 m / edge_length\)²"),
    ({"iterations": 2**40}, r"iterations must be at most 2147483647"),
    ({"step_sizes": ZERO_STEPS}, r"step_sizes\.measurements must be positive"),
    ({"step_sizes": {**ZERO_STEPS, "measurements": 0.01}}, r"step_sizes\.handles must be positive"),
    ({"step_sizes": {"log10_bending": 0.0}}, r"step_sizes\.log10_bending must be positive when bending is garment"),
    ({"step_sizes": {"log10_stretch": 0.0}, "stretch": "garment"},
     r"step_sizes\.log10_stretch must be positive when stretch is garment"),
    ({"step_sizes": {"shape": 0.0}}, r"step_sizes\.shape must be positive when optimize_body is true"),
    ({"step_sizes": {"pose": 0.0}}, r"step_sizes\.pose must be positive when optimize_body is true"),
    ({"sobolev_length": 1e12}, r"sobolev_length must lie in \[0, 10\] m"),
    ({"output_drape_damping": 60.0}, r"output_drape_damping must lie in \[0, 20\] 1/s"),
    ({"sobolev_length": 10.5}, r"sobolev_length must lie in \[0, 10\] m"),
    ({"boundary_scale": 1e-300}, r"boundary_scale must be 0 \(off\) or at least 0\.0001 m"),
    ({"bend_stiffness": 1000.0}, r"bend_stiffness must be at most 0\.01 N·m"),
    ({"residual_tol": 1e-300}, r"residual_tol must lie in \[1e-08, 1\)"),
    ({"residual_tol": 3e-9}, r"residual_tol must lie in \[1e-08, 1\)"),
    ({"residual_tol": 1.0}, r"residual_tol must lie in \[1e-08, 1\)"),
    ({"garment_type": ["skirt"]}, r"garment_type must be a garment type name .*got \['skirt'\]"),
    ({"garment_type": 5}, r"garment_type must be a garment type name"),
    ({"label": [1]}, r"label must be a label name or an integer label value, got \[1\]"),
    ({"label": True}, r"label must be a label name or an integer label value"),
    ({"job_id": 5}, r"job_id must be a string, got 5"),
    ({"units": ["cm"]}, r"units must be m, cm or mm, got \['cm'\]"),
    ({"up": ["y"]}, r"up must be one of"),
    ({"contact_normals": ["face"]}, r"contact_normals must be one of"),
    ({"newton_solver": 1}, r"newton_solver must be one of"),
    ({"newton_hinge_blocks": "exact"}, r"newton_hinge_blocks must be one of"),
    ({"interior_to": {"points": 1}}, r"interior_to must be one of"),
    ({"length_measure": ["raw"]}, r"length_measure must be raw or resampled"),
])
def test_a_bad_option_is_refused_by_name_when_the_options_are_made(overrides, message):
    with pytest.raises(ValueError, match=message):
        RecoverOptions.coerce(overrides)
    with pytest.raises(ValueError, match=message):   # with_ re-validates the same way
        RecoverOptions.from_config().with_(**overrides)


@pytest.mark.parametrize("overrides", [
    {"samples": 1}, {"samples": options_module.MAX_SAMPLES}, {"drape_iterations": 1},
    {"drape_iterations": 40, "edge_length": 0.005}, {"iterations": 0, "step_sizes": {**ZERO_STEPS, "measurements": 0.01}},
    {"step_sizes": {"log10_bending": 0.0}, "bending": "fixed"},
    {"step_sizes": {"log10_bending": 0.0, "log10_stretch": 0.0}, "bending_after": 30},   # held throughout
    {"step_sizes": {"shape": 0.0, "pose": 0.0}, "optimize_body": False},
    {"step_sizes": {"shape": 0.0, "pose": 0.0}, "body_after": 30},
    {"step_sizes": {"log10_stretch": 0.0}},                   # stretch fixed: not moved
    {"measurement_fit_iterations": 0, "step_sizes": {"measurements": 0.0}},
    {"sobolev_length": 0.0}, {"sobolev_length": 10.0}, {"sobolev_length": 3},
    {"output_drape_damping": 0.0}, {"output_drape_damping": 20.0},
    {"boundary_scale": 0.0}, {"boundary_scale": 1e-4}, {"boundary_scale": 0.01},
    {"bend_stiffness": 1e-2}, {"bend_stiffness": 1e-30}, {"residual_tol": 1e-8}, {"residual_tol": 0.5},
    {"garment_type": "skirt"}, {"label": "skirt"}, {"label": 3}, {"job_id": "j1"},
    {"units": "cm"}, {"up": "-y"}, {"contact_normals": "valley"},
])
def test_the_good_values_at_the_bounds_are_accepted(overrides):
    o = RecoverOptions.from_config(**overrides)   # (coerce reads iterations 0 as "the configured")
    assert o.with_() == o
    for k, v in overrides.items():
        if k not in ("step_sizes",):
            assert getattr(o, k) == v


def test_the_defaults_are_unchanged_and_valid():
    """The documented benchmarks depend on them: the bounds hold every configured default."""
    o = RecoverOptions.from_config()
    assert (o.samples, o.drape_iterations, o.sobolev_length, o.boundary_scale, o.bend_stiffness, o.residual_tol) == \
        (2000, 40, 0.3, 0.0, 5e-6, 1e-7)
    assert o == RecoverOptions(config=o.config)


def _cfg(**groups):
    cfg = copy.deepcopy(load_config())
    for group, values in groups.items():
        cfg[group].update(values)
    return cfg


@pytest.mark.parametrize("groups,message", [
    ({"metrics": {"chamfer_samples": 0}}, r"config: metrics\.chamfer_samples must be a positive integer .*got 0"),
    ({"metrics": {"chamfer_samples": -5}}, r"metrics\.chamfer_samples must be a positive integer .*got -5"),
    ({"metrics": {"chamfer_samples": "abc"}}, r"metrics\.chamfer_samples must be a positive integer .*got 'abc'"),
    ({"metrics": {"chamfer_samples": 2.5}}, r"metrics\.chamfer_samples"),
    ({"metrics": {"chamfer_samples": 10**12}}, r"metrics\.chamfer_samples .*at most 10000000"),
    ({"metrics": {"seed": -1}}, r"metrics\.seed must be an integer in \[0, 2\*\*64\)"),
    ({"metrics": {"seed": "x"}}, r"metrics\.seed"),
    ({"scan": {"interior_samples": 0}}, r"scan\.interior_samples must lie in \[10, 10000000\] for a recovery, got 0"),
    ({"scan": {"interior_samples": 10**12}}, r"scan\.interior_samples must lie in \[10, 10000000\]"),
    ({"scan": {"interior_samples": "1e12"}}, r"interior_samples must be a non-negative integer"),
    ({"scan": {"max_height": float("inf")}}, r"max_height must be a non-negative number"),
    ({"scan": {"min_height": 3.0}}, r"min_height < max_height"),
])
def test_the_metrics_and_scan_groups_the_recovery_reads_are_checked_with_the_options(groups, message):
    with pytest.raises(ValueError, match=message):
        RecoverOptions.from_config(_cfg(**groups))


def test_good_metrics_and_scan_groups_are_accepted():
    for groups in ({"metrics": {"chamfer_samples": 1, "seed": 2**64 - 1}}, {"scan": {"interior_samples": 10}},
                   {"metrics": {"chamfer_samples": 10**7}, "scan": {"interior_samples": 10**7}}):
        RecoverOptions.from_config(_cfg(**groups))


def test_recover_refuses_a_bad_option_before_any_stage(monkeypatch):
    """recover(scan, {...}) refuses before the preprocess stage: the scan is never read."""
    from diffavatar_core.pipeline import recovery
    reached = []

    def stand_in(*a, **k):
        reached.append("scan_for_recovery")
        raise AssertionError("the scan was read")
    monkeypatch.setattr(recovery, "scan_for_recovery", stand_in)
    stages = []
    for overrides, name in (({"garment_type": ["skirt"]}, "garment_type"), ({"samples": 0}, "samples"),
                            ({"drape_iterations": 0}, "drape_iterations"), ({"sobolev_length": 1e12}, "sobolev_length"),
                            ({"step_sizes": ZERO_STEPS}, "step_sizes.")):
        with pytest.raises(ValueError, match=rf"recover options: {name}"):
            recover(SAMPLE, {"units": "cm", **overrides}, progress=lambda stage, *a: stages.append(stage))
    assert reached == [] and stages == []


CS0 = "metrics:\n  chamfer_samples: {n}\n"


@pytest.fixture
def stand_ins(monkeypatch):
    """The recovery and the body fit replaced by stand-ins that record they were reached."""
    import diffavatar_core.body.fitting as fitting
    import diffavatar_core.pipeline as pipeline
    started = []

    def stage(name):
        def run(*a, **k):
            started.append(name)
            raise ValueError(f"stand-in {name} reached")
        return run
    monkeypatch.setattr(pipeline, "recover", stage("recover"))
    monkeypatch.setattr(fitting, "fit_body", stage("fit_body"))
    return started


@pytest.mark.parametrize("n", ["0", "-5", "abc"])
def test_the_command_line_refuses_a_bad_chamfer_samples_before_the_recovery(tmp_path, capsys, stand_ins, n):
    from diffavatar_core.cli import main
    cfg = tmp_path / "cs.yaml"
    cfg.write_text(CS0.format(n=n))
    rc = main(["recover", str(SAMPLE), "--units", "cm", "--out", str(tmp_path / "out"), "--config", str(cfg)])
    err = capsys.readouterr().err
    assert rc == 2 and stand_ins == [], err
    assert err.startswith("diffavatar: error: config: metrics.chamfer_samples must be a positive integer") and \
        "Traceback" not in err, err
    # a good value goes on to the recovery (here its stand-in)
    cfg.write_text(CS0.format(n=1000))
    rc = main(["recover", str(SAMPLE), "--units", "cm", "--out", str(tmp_path / "out"), "--config", str(cfg)])
    assert stand_ins == ["recover"] and "stand-in recover reached" in capsys.readouterr().err
