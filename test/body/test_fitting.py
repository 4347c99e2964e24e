"""Body fitting round trips (paper §4.1): a body with known random parameters, a noisy partial
scan of it (or a garment around it), fitted back."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from diffavatar_core.body import BodyModel, BodyParams
from diffavatar_core.body.synthetic import (OFFSET_GARMENTS, TORSO, offset_garment_case, random_body,
                                            region_garment, stature)
from diffavatar_core.body.fitting import (GARMENT_BONES, FitOptions, _Fitter, contact_points, fit_body,
                                          garment_faces, inside_fraction, scan_to_core)
from diffavatar_core.metrics import sample_surface


@pytest.fixture(scope="module")
def model():
    return BodyModel.default()


def partial_noisy_scan(X, F, rng, n=25000):
    """Scan of surface (X, F) in m: n samples, ~15% removed in 6 cm patches, 2 mm noise, four
    floating fragments of 60 points each."""
    pts, _ = sample_surface(X, F, n, seed=int(rng.integers(1 << 30)))
    keep = np.ones(len(pts), bool)
    while keep.mean() > 0.85:
        keep &= np.linalg.norm(pts - pts[rng.integers(len(pts))], axis=1) > 0.06
    pts = pts[keep] + rng.normal(scale=0.002, size=(int(keep.sum()), 3))
    frags = [pts.mean(0) + rng.normal(size=3) * 0.5 + rng.normal(scale=0.03, size=(60, 3)) for _ in range(4)]
    return np.concatenate([pts] + frags), float(1 - keep.mean())


ZUP = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])   # core (Y up) → Z-up scan frame


def test_scan_frame_conversion():
    P = np.array([[100.0, 20.0, 170.0]])
    Q, A = scan_to_core(P, units="cm", up="z")
    np.testing.assert_allclose(Q, [[1.0, 1.7, -0.2]])
    np.testing.assert_allclose(A @ ZUP, np.eye(3) * 0.01 @ np.eye(3), atol=1e-15)
    with pytest.raises(ValueError, match="units"):
        scan_to_core(P, units="inch")
    with pytest.raises(ValueError, match="up"):
        scan_to_core(P, up="x")


@pytest.mark.parametrize("seed", [7])
def test_full_scan_round_trip(model, seed):
    rng = np.random.default_rng(seed)
    truth = random_body(model, rng)
    X = model.pose(truth)
    scan, removed = partial_noisy_scan(X, model.faces, rng)
    assert 0.15 <= removed < 0.2
    R = Rotation.from_rotvec([0, rng.uniform(-np.pi, np.pi), 0]).as_matrix()
    t = rng.normal(scale=0.5, size=3)
    scan_cm = 100 * (scan @ R.T + t) @ ZUP.T             # random rigid motion, cm, Z up
    res = fit_body(scan_cm, model=model, units="cm", up="z")
    err = np.linalg.norm(model.pose(res.params) - (X @ R.T + t), axis=1)
    assert err.mean() <= 0.01, err.mean()
    assert np.all(res.params.pose >= model.limits_lo) and np.all(res.params.pose <= model.limits_hi)
    assert res.rms < 0.005


def test_full_scan_with_the_torso_and_arms_under_a_garment(model):
    """A full scan whose body points stop where a long-sleeved top covers the body (0.85–1.42 m:
    torso, arms, the wrists): without the garment's points the body → scan term pulls the
    hidden arms toward the visible hips and hands (measured: 11 cm mean vertex error, 46 cm
    max); with them as occluders (fit_body(occluders=...)) hidden vertices are left to the
    priors and the visible parts, and the body is recovered (measured 0.3 cm; bound 1 cm)."""
    from diffavatar_core.pipeline.synthetic import random_body as recovery_body   # the recovery benchmark's prior
    truth = recovery_body(model, np.random.default_rng(3))
    X = model.pose(truth)
    F = np.asarray(model.faces)
    n = np.zeros_like(X)
    fn = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    for k in range(3):
        np.add.at(n, F[:, k], fn)
    n /= np.linalg.norm(n, axis=1)[:, None]
    hidden = (X[:, 1] > 0.85) & (X[:, 1] < 1.42)
    sleeve = X[hidden] + 0.01 * n[hidden]                 # the garment 1 cm outside the hidden skin
    err = {}
    for name, occ in (("plain", None), ("occluders", sleeve)):
        res = fit_body(100 * X[~hidden], model=model, units="cm", occluders=None if occ is None else 100 * occ)
        err[name] = np.linalg.norm(model.pose(res.params) - X, axis=1).mean()
    assert err["occluders"] < 0.01 and err["plain"] > 0.05, err


def torso_garment(model, X, offset):
    """A top made by offsetting the posed body's torso surface (pelvis to clavicles) outward."""
    return region_garment(model, X, offset, TORSO)


garment_case = offset_garment_case


def _height(V):
    return V[:, 1].max() - V[:, 1].min()


# seed 4: a tall body (1.79 m) that came out 7.4 cm short with the earlier asymmetric clearance
# term and strong priors
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5])
def test_garment_only_fit_puts_the_body_inside(model, seed):
    truth, X, G, Fg = garment_case(model, seed)
    res = fit_body(100 * G @ ZUP.T, Fg, model=model, units="cm", up="z", garment_only=True)
    assert inside_fraction(model, res.params, G) <= 0.01
    assert abs(_height(model.pose(res.params)) - _height(X)) <= 0.03     # as posed
    assert abs(stature(model, res.params) - stature(model, truth)) <= 0.03
    shown = [model.joint_index(n) for n in GARMENT_BONES["upper"]]
    hidden = np.setdiff1d(np.arange(model.num_joints), shown)
    np.testing.assert_array_equal(res.params.bone_scales[hidden], 1.0)     # held: the top hides them


# the whole prior, bone lengths included. Trousers seeds 0 and 3-6 ended 14-22 cm short with 2-3%
# of the garment inside the body before the fit ignored the feet (caught in the trouser legs) and
# used the Euclidean distance (face-normal distances jump between the faces of an edge: LM stalled)
@pytest.mark.parametrize("kind", ["top", "trousers"])
@pytest.mark.parametrize("seed", range(8))
def test_garment_only_fit_with_bone_lengths_from_the_prior(model, kind, seed):
    joints, gtype = OFFSET_GARMENTS[kind]
    truth, X, G, Fg = garment_case(model, seed, joints=joints, bone_noise=True)
    res = fit_body(100 * G @ ZUP.T, Fg, model=model, units="cm", up="z", garment_only=True, garment_type=gtype)
    assert inside_fraction(model, res.params, G) <= 0.01
    # standing height: a top hides the legs' pose and a pair of trousers the spine's, not their lengths
    assert abs(stature(model, res.params) - stature(model, truth)) <= 0.03


def test_garment_faces_leave_out_head_hands_and_feet(model):
    F = garment_faces(model)
    dom = np.argmax(model.weights, axis=1)
    bare = [model.joint_index(n) for n in ("head", "wrist_left", "wrist_right", "ankle_left", "ankle_right")]
    assert not np.isin(dom[F], bare).any()
    kept = {tuple(f) for f in F}
    rest = [f for f in model.faces if not np.isin(dom[f], bare).any()]
    assert len(rest) == len(F) and all(tuple(f) in kept for f in rest)     # and nothing else


def test_garment_distance_jacobian_matches_central_differences(model):
    """The garment term's residual rows (c − d_i, d_i the Euclidean signed distance to the
    coverable surface) against central differences in shape, pose, bone scale, rotation and
    translation, on points whose closest body points lie on edges and vertices as well as faces."""
    rng = np.random.default_rng(3)
    p = random_body(model, rng, pose_sd=0.08)
    X = model.pose(p)
    G, _ = torso_garment(model, X, 0.01)
    pts = G[rng.choice(len(G), 60, replace=False)] + rng.normal(scale=0.01, size=(60, 3))
    f = _Fitter(model, pts, None, FitOptions(), garment=True)
    idx = np.arange(len(pts))
    res, _, rows, _, _ = f._terms(p, 0.03, idx, idx[:1], with_jac=True)
    sl = model.param_slices()
    cols = [sl["shape"].start, sl["shape"].start + 2, sl["pose"].start + 3 * model.joint_index("spine_2") + 1,
            sl["bone_scales"].start + model.joint_index("chest"), sl["rotation"].start + 1,
            sl["translation"].start]
    x0, h = p.to_vector(), 1e-6
    for c in cols:
        r = []
        for s in (1, -1):
            x = x0.copy()
            x[c] += s * h
            q = BodyParams.from_vector(x, model.num_shape, model.num_joints)
            r.append(f._terms(q, 0.03, idx, idx[:1], with_jac=False)[0][:len(pts)])
        fd = (r[0] - r[1]) / (2 * h)
        np.testing.assert_allclose(rows[:len(pts), c], fd, rtol=1e-5, atol=1e-7 * np.abs(fd).max() + 1e-12)


def test_garment_type_places_shorts_at_the_waist(model):
    """Shorts (pelvis and thighs) in the core frame (m, Y up): with garment_type the body's hips
    end up in them (placed as a top, they are 20-25 cm off)."""
    truth, X, G, Fg = garment_case(model, 0, joints=["pelvis", "spine_1", "hip_left", "hip_right"])
    res = fit_body(G, Fg, model=model, garment_type="shorts")
    assert inside_fraction(model, res.params, G) <= 0.01
    hips = [model.joint_index(n) for n in ("pelvis", "hip_left", "hip_right")]
    assert np.linalg.norm(model.joints(res.params)[hips] - model.joints(truth)[hips], axis=1).max() <= 0.02
    assert abs(stature(model, res.params) - stature(model, truth)) <= 0.03


def test_contact_points(model):
    """A garment 1 cm off the body touches it everywhere at a 1 cm clearance and nowhere at 4 cm."""
    p = model.zero_params()
    G, _ = torso_garment(model, model.pose(p), 0.01)
    assert contact_points(model, p, G, 0.01, 0.003).mean() > 0.98
    assert not contact_points(model, p, G, 0.04, 0.01).any()


def test_draped_tshirt_fits_by_its_contacts(model):
    """A t-shirt draped by the simulator hangs loose below the chest; attracting all of it grew
    this body (seed 1) 10.8 cm too tall with the shape at its ±3.5 bound. Fitted by its top band,
    then by the points that touch the body: the body is inside, the hips within 2.5 cm and the
    shoulders within 2 cm, the shape within 3 prior standard deviations and the stature within
    4 cm. Which folds the truth's drape settles into is round-off (a chaotic drape), and the fit
    follows them: over this drape and 24 whose patterns differ by 1e-13 m of noise (stop 33) the
    stature error was 0.09-3.46 cm (3.2-3.5 on 22), hips 0.68-1.18 cm, shoulders 1.18-1.49 cm,
    |ν| ≤ 1.89. A t-shirt hides the legs: the prior mean body is 2.86 cm off this stature
    (docs/body.md: draped t-shirts, 10 of 12 within 3 cm)."""
    from diffavatar_core.pipeline.synthetic import make_case
    c = make_case("tshirt", seed=1, model=model)
    V, F = c.garment_scan()
    res = fit_body(V, F, model=model, units=c.units, up=c.up, garment_type="tshirt")
    p, t = res.params, c.body_params
    assert inside_fraction(model, p, c.garment_x) <= 0.01
    assert abs(stature(model, p) - stature(model, t)) <= 0.04
    hips = [model.joint_index(n) for n in ("pelvis", "hip_left", "hip_right")]
    assert np.linalg.norm(model.joints(p)[hips] - model.joints(t)[hips], axis=1).max() <= 0.025
    shoulders = [model.joint_index(n) for n in ("clavicle_left", "clavicle_right", "shoulder_left", "shoulder_right")]
    assert np.linalg.norm(model.joints(p)[shoulders] - model.joints(t)[shoulders], axis=1).max() <= 0.02
    assert np.abs(p.shape).max() < 3.0                 # within 3 prior standard deviations


def test_draped_skirt_sits_at_the_waist(model):
    """A skirt draped by the simulator on a body from the prior (the synthetic case of the
    recovery benchmark: cm, Y up, noise, holes, fragments), fitted under: the body is inside,
    its waist and hip joints are where the skirt hangs from, and the hidden legs stay plausible.
    Standing height is not asserted: a skirt does not show it (bench/fit_body.py measures it).
    The first seed from 4 whose ground truth is a worn skirt: on some CPUs seed 4's skirt slides
    off the hips to the floor (round-off decides), and make_case refuses such a case."""
    from diffavatar_core.pipeline.synthetic import make_case
    c = None
    for seed in range(4, 10):
        try:
            c = make_case("skirt", seed=seed, model=model)
            break
        except RuntimeError as e:
            assert "slid off" in str(e) or "did not converge" in str(e)
    assert c is not None
    V, F = c.garment_scan()
    res = fit_body(V, F, model=model, units=c.units, up=c.up, garment_type="skirt")
    p, t = res.params, c.body_params
    assert inside_fraction(model, p, c.garment_x) <= 0.01
    waist = np.linalg.norm(np.asarray(model.landmarks(p).waist_center) - np.asarray(model.landmarks(t).waist_center))
    assert waist <= 0.025, waist
    hips = [model.joint_index(n) for n in ("pelvis", "hip_left", "hip_right")]
    assert np.linalg.norm(model.joints(p)[hips] - model.joints(t)[hips], axis=1).max() <= 0.025
    assert np.abs(p.shape).max() < 3.0                 # within 3 prior standard deviations


def test_garment_type_is_checked(model):
    G = np.random.default_rng(0).normal(size=(50, 3))
    with pytest.raises(ValueError, match="not a known garment type"):
        fit_body(G, model=model, garment_type="hat")
    with pytest.raises(ValueError, match="garment-only"):
        fit_body(G, model=model, garment_only=False, garment_type="skirt")


def test_self_penetration_depth(model):
    from diffavatar_core.body.fitting import self_penetration_depth
    assert self_penetration_depth(model, model.zero_params()) == 0.0
    # the same body with its joint limits opened: the left arm swung into the chest
    wide = BodyModel(model.v_template, model.shapedirs, model.j_template, model.j_shapedirs, model.parents,
                     model.weights, model.faces, model.joint_names, -np.pi * np.ones((22, 3)),
                     np.pi * np.ones((22, 3)))
    p = wide.zero_params()
    depths = []
    for a in (-0.8, -1.0, -1.2):
        p.pose[wide.joint_index("shoulder_left")] = [0, 0, a]
        depths.append(self_penetration_depth(wide, p))
    assert 0 < depths[0] < depths[1] < depths[2]


def test_a_ground_truth_skirt_that_slid_off_the_body_is_refused(model):
    """make_case never returns a garment that fell off the body (a fit would then be asked to put
    a body into a skirt lying at its feet): a skirt with 0.5 m of waist ease (its waist wider than
    the hips) slides down, and drape_truth refuses it by name (its top sinks more than
    MAX_TOP_DROP below its placement)."""
    from diffavatar_core.pipeline.synthetic import make_case
    with pytest.raises(RuntimeError, match="slid off the body"):
        make_case("skirt", seed=0, model=model, measurements={"waist_ease": 0.5})


@pytest.mark.parametrize("kind", ["token", "event"])
def test_a_fit_stops_within_an_iteration_of_its_cancel(model, kind):
    """A fit takes seconds: its Gauss–Newton loop checks `cancel` (a CancelToken or a
    threading.Event) every iteration, so a cancel set mid-fit ends it at once."""
    import threading
    import time
    import diffavatar_core as dc
    X = model.pose(random_body(model, np.random.default_rng(7)))
    cancel = dc.CancelToken() if kind == "token" else threading.Event()
    set_at = []
    timer = threading.Timer(0.3, lambda: (set_at.append(time.monotonic()),
                                          cancel.cancel() if kind == "token" else cancel.set()))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(dc.Cancelled, match="body fit"):
        fit_body(X, model=model, cancel=cancel)
    assert set_at, "the fit ended before its cancel was set (it no longer takes 0.3 s)"
    assert time.monotonic() - set_at[0] < 0.5, time.monotonic() - t0
