"""RecoverOptions: a dict of overrides of the configured defaults may name some fields of the
nested groups (weights, step_sizes) — merged over the configured group as a YAML --config is —
and unknown nested keys or wrong types are refused by name; a valid options object stays valid
through with_() (guided_stiffness 0 is stored as (), and the valley-contact fallback's
with_(contact_normals="valley") used to refuse it)."""
import copy
import dataclasses

import pytest

from diffavatar_core.config import load_config
from diffavatar_core.demo import SAMPLE
from diffavatar_core.pipeline import RecoverOptions, recover
from diffavatar_core.pipeline.options import StepSizes, Weights

FAST = {"units": "cm", "iterations": 0, "measurement_fit_iterations": 0, "measurement_fit_bending": [],
        "template_sizing": False, "bending_range_offsets": [], "bending_candidates": [], "fresh_every": 0}


def test_nested_overrides_merge_over_the_configured_groups():
    d = RecoverOptions.from_config()
    o = RecoverOptions.coerce({"weights": {"interior": 10.0}, "step_sizes": {"handles": 0.002}})
    assert o.weights == dataclasses.replace(d.weights, interior=10.0)
    assert o.step_sizes == dataclasses.replace(d.step_sizes, handles=0.002)
    # over the *configured* values, not the dataclass defaults
    cfg = load_config()
    cfg = copy.deepcopy(cfg)
    cfg["recover"]["weights"]["seam"] = 77.0
    o = RecoverOptions.from_config(cfg, weights={"interior": 10.0})
    assert (o.weights.seam, o.weights.interior, o.weights.curvature) == (77.0, 10.0, d.weights.curvature)
    # a whole group still replaces it; with_ merges a mapping over the object's own group
    w = Weights(interior=3.0)
    assert RecoverOptions.from_config(weights=w).weights is w
    o2 = o.with_(weights={"curvature": 0.5}, step_sizes=StepSizes(pose=0.01))
    assert (o2.weights.seam, o2.weights.interior, o2.weights.curvature) == (77.0, 10.0, 0.5)
    assert o2.step_sizes == StepSizes(pose=0.01)


@pytest.mark.parametrize("overrides,message", [
    ({"weights": {"interiour": 10.0}}, r"unknown key\(s\) weights\.interiour \(known: boundary, .*interior"),
    ({"step_sizes": {"handle": 0.1}}, r"unknown key\(s\) step_sizes\.handle"),
    ({"weights": {"interior": "10"}}, r"weights\.interior must be a non-negative number, got '10'"),
    ({"weights": {"seam": -1.0}}, r"weights\.seam must be a non-negative number"),
    ({"step_sizes": {"pose": float("nan")}}, r"step_sizes\.pose must be a non-negative number"),
    ({"step_sizes": {"measurements": 0.0}}, r"step_sizes\.measurements must be positive"),
    ({"weights": 3.0}, r"weights must be a mapping of boundary, .* got float"),
    ({"step_sizes": [0.1]}, r"step_sizes must be a mapping of handles, .* got list"),
    ({"config": {}}, r"unknown option\(s\) config"),
])
def test_bad_nested_overrides_are_refused_by_name(overrides, message):
    with pytest.raises(ValueError, match=message):
        RecoverOptions.coerce(overrides)
    if "config" not in overrides:   # with_ may swap the loaded config, not the groups' fields
        with pytest.raises(ValueError, match=message):
            RecoverOptions.from_config().with_(**overrides)


def test_a_config_with_an_unknown_group_key_is_refused_by_name():
    cfg = copy.deepcopy(load_config())
    cfg["recover"]["step_sizes"]["bend"] = 0.1
    with pytest.raises(ValueError, match=r"config: unknown key\(s\) recover\.step_sizes\.bend"):
        RecoverOptions.from_config(cfg)
    cfg["recover"]["step_sizes"] = 0.1
    with pytest.raises(ValueError, match=r"config: recover\.step_sizes must be a mapping"):
        RecoverOptions.from_config(cfg)


def test_a_group_of_the_wrong_type_built_directly_is_refused_by_name():
    with pytest.raises(ValueError, match="weights must be a Weights"):
        RecoverOptions(weights={"interior": 1.0})
    with pytest.raises(ValueError, match=r"unknown option\(s\) wieghts"):
        RecoverOptions.from_config().with_(wieghts={})


@pytest.mark.parametrize("overrides", [
    {"guided_stiffness": 0}, {"guided_stiffness": 0.0}, {"guided_stiffness": 5e4}, {"guided_stiffness": [1e4, 1e6]},
    {"bending_candidates": []}, {"bending_candidates": 0.5}, {"bending_range_offsets": []},
    {"measurement_fit_bending": 1}, {"weights": {"interior": 10}}, {"template": "skirt"},
    {"template": str(SAMPLE)}, {"contact_normals": "smooth"},
])
def test_a_valid_options_object_stays_valid_through_with_(overrides):
    o = RecoverOptions.from_config(**overrides)
    assert o.with_() == o                                          # re-validating changes nothing
    v = o.with_(contact_normals="valley")                          # the initial drape's fallback
    assert v.contact_normals == "valley" and v == dataclasses.replace(o, contact_normals="valley")
    assert v.with_(iterations=2).iterations == 2


def test_guided_stiffness_zero_means_off_and_the_documented_refusals_hold():
    assert RecoverOptions.from_config(guided_stiffness=0).guided_stiffness == ()
    assert RecoverOptions.from_config(guided_stiffness=[1e4, 1e6]).guided_stiffness == (1e4, 1e6)
    for bad in ([], [0, 1e4], -1.0, float("inf"), True, "1e4"):
        with pytest.raises(ValueError, match="guided_stiffness"):
            RecoverOptions.from_config(guided_stiffness=bad)


def test_a_recovery_with_nested_overrides_and_no_guided_drapes_falls_back_to_valley_contacts(monkeypatch):
    """End to end, options made from overrides: weights and step sizes merged (the run sees them), guided
    drapes off (guided_stiffness 0), and the initial drape's face planes made to fail (fault
    injected, as benchmark skirt 103's did) so the recovery continues with valley contacts —
    the with_() that aborted it before. It completes and records the valley plane."""
    from diffavatar_core.pipeline import recovery as rec
    real, seen, valley = rec._initial_drape, [], []

    def face_fails(cloth, opts, cancel):
        seen.append(opts)
        valley.append(bool(cloth.model.valley_contact))
        r, steps = real(cloth, opts, cancel)
        if not cloth.model.valley_contact:
            r = dataclasses.replace(r, converged=False, message="injected")
        return r, steps
    monkeypatch.setattr(rec, "_initial_drape", face_fails)
    opts = RecoverOptions.from_config(**FAST, guided_stiffness=0, weights={"interior": 10.0},
                                      step_sizes={"handles": 0.002})
    r = recover(SAMPLE, opts)
    assert valley[:2] == [False, True], valley
    assert all(o.guided_stiffness == () and o.weights.interior == 10.0 and o.step_sizes.handles == 0.002
               and o.weights.seam == RecoverOptions.from_config().weights.seam for o in seen)
    assert r.material.contact_normals == "valley"
    assert any("did not converge with face contact planes (injected" in w for w in r.warnings), r.warnings
