"""End-to-end preprocessing of a synthetic segmented scan with known ground truth
(synthetic_scan.py): frame/units conversion, fragment removal, garment region, named openings,
holes, interior samples; ascii/binary/array inputs agree; the DiffAvatar t-shirt template as a
garment-only scan."""
import json

import numpy as np
import pytest
from scipy.spatial import cKDTree

from diffavatar_core import metrics
from diffavatar_core.scan import OPENING_NAMES, ScanOptions, load_scan
from synthetic_scan import core_to_scan, shared_file, synthetic, synthetic_ply  # noqa: F401 (fixtures)


def _same_points(A, B, tol=1e-9):
    """A and B hold the same points (any order): a one-to-one match within tol (m)."""
    assert A.shape == B.shape, (A.shape, B.shape)
    d, j = cKDTree(B).query(A)
    assert d.max() <= tol, d.max()
    assert len(np.unique(j)) == len(B)


@pytest.fixture(scope="module")
def data(synthetic_ply):
    return load_scan(synthetic_ply["binary"], units="cm", up="z")


def test_units_and_axes_give_the_core_frame_geometry(data, synthetic):
    # fragments were appended last: the cleaned scan is exactly the main mesh, in order
    np.testing.assert_allclose(data.vertices, synthetic.V[:synthetic.n_main], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(data.faces, synthetic.F[:synthetic.n_main_faces])
    np.testing.assert_array_equal(data.labels, synthetic.labels[:synthetic.n_main])
    assert data.height_m == pytest.approx(1.7, abs=1e-9)           # the body capsule's height
    assert data.transform.scale == 0.01 and data.transform.up == "z"
    # mapping back gives the file's own coordinates
    np.testing.assert_allclose(data.transform.to_scan(data.vertices),
                               core_to_scan(synthetic.V[:synthetic.n_main], "cm", "z"), rtol=0, atol=1e-7)


def test_floating_fragments_are_dropped_with_a_warning(data, synthetic):
    assert len(data.vertices) == synthetic.n_main
    w = [m for m in data.warnings if "floating fragment" in m]
    assert len(w) == 1 and w[0].startswith("dropped 3 floating fragment(s)")
    assert "(0.500, 1.300, 0.100) m" in w[0]                       # where the garment-labelled one was


def test_a_body_piece_cut_off_near_the_scan_is_kept(synthetic):
    """fragment_keep_fraction 0.03: a body-labelled ball (1 cm radius) 3 cm outside the body
    capsule — a hand cut off where a cuff hides the wrist — is no floating fragment: it is kept
    with its label and named in its own warning, while the three far fragments are still
    dropped. By default (0) it is dropped with them."""
    import trimesh
    ico = trimesh.creation.icosphere(subdivisions=1, radius=0.01)
    centre = np.array([0.14, 0.85, 0.0])                       # capsule radius 0.1 → 3 cm gap
    V = np.concatenate([synthetic.V, np.asarray(ico.vertices) + centre])
    F = np.concatenate([synthetic.F, np.asarray(ico.faces) + len(synthetic.V)])
    L = np.concatenate([synthetic.labels, np.zeros(len(ico.vertices), np.int64)])
    d = load_scan((V, F, L), units="m", options=ScanOptions(fragment_keep_fraction=0.03))
    piece = np.linalg.norm(d.vertices - centre, axis=1) < 0.011
    assert piece.sum() == len(ico.vertices) and np.all(d.labels[piece] == 0)
    assert len(d.vertices) == synthetic.n_main + len(ico.vertices)
    kept = [m for m in d.warnings if m.startswith("kept 1 small part")]
    assert len(kept) == 1 and "11.7 cm² at (0.140, 0.850," in kept[0], d.warnings   # 80 faces of the ball
    assert any(m.startswith("dropped 3 floating fragment(s)") for m in d.warnings)
    d0 = load_scan((V, F, L), units="m")   # the default (off): dropped with the far ones
    assert len(d0.vertices) == synthetic.n_main
    assert any(m.startswith("dropped 4 floating fragment(s)") for m in d0.warnings)


def test_garment_region_is_the_shirt(data, synthetic):
    np.testing.assert_array_equal(data.garment_vertex_mask, synthetic.shirt_vertex_mask)
    assert data.garment_label == 1 and data.garment_class == "upper"
    Vg, Fg = data.garment_mesh()
    _same_points(Vg, synthetic.V[:synthetic.n_main][synthetic.shirt_vertex_mask])
    assert data.garment_face_mask.sum() == len(Fg)


def test_openings_are_found_and_named(data, synthetic):
    assert set(data.boundaries) == {"hem", "neckline", "sleeve_left", "sleeve_right"}
    assert set(data.boundaries) <= set(OPENING_NAMES)
    for name, truth in synthetic.openings.items():
        _same_points(data.boundaries[name], truth)
        np.testing.assert_array_equal(data.vertices[data.boundary_indices[name]], data.boundaries[name])
    cy = {k: P[:, 1].mean() for k, P in data.boundaries.items()}
    assert cy["hem"] == min(cy.values()) and cy["neckline"] == max(cy.values())
    assert data.boundaries["sleeve_left"][:, 0].min() > 0.3        # the body's left is +X
    assert data.boundaries["sleeve_right"][:, 0].max() < -0.3


def test_loops_are_ordered_closed_polylines(data):
    for P in list(data.boundaries.values()) + data.holes:
        seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
        assert seg.max() < 0.05                  # consecutive points are mesh neighbours
        assert len(np.unique(P, axis=0)) == len(P)
        assert P[0, 2] == P[:, 2].max()          # starts at the front-most point


def test_holes_are_reported_as_holes(data, synthetic):
    assert len(data.holes) == len(synthetic.holes) == 3
    for truth in synthetic.holes:
        same = [P for P in data.holes if P.shape == truth.shape and cKDTree(truth).query(P)[0].max() < 1e-9]
        assert len(same) == 1
        _same_points(same[0], truth)
    assert not any("openings not found" in w for w in data.warnings)


def test_interior_samples_lie_on_the_garment_away_from_every_boundary(data):
    P = data.interior_points
    assert P.shape == (ScanOptions.from_config().interior_samples, 3)
    Vg, Fg = data.garment_mesh()
    assert metrics.surface_distances(P, Vg, Fg).max() < 1e-9
    margin = ScanOptions.from_config().interior_margin
    dmin = np.full(len(P), np.inf)
    for L in list(data.boundaries.values()) + data.holes:      # exact point-segment distances
        A, B = L, np.roll(L, -1, axis=0)
        AB = B - A
        t = np.clip(((P[:, None, :] - A) * AB).sum(-1) / (AB * AB).sum(-1), 0, 1)
        d = np.linalg.norm(P[:, None, :] - (A + t[..., None] * AB), axis=-1).min(axis=1)
        dmin = np.minimum(dmin, d)
    assert dmin.min() >= margin


def test_ascii_and_binary_ply_give_identical_results(synthetic_ply, data):
    a = load_scan(synthetic_ply["ascii"], units="cm", up="z")
    np.testing.assert_array_equal(a.vertices, data.vertices)
    np.testing.assert_array_equal(a.faces, data.faces)
    np.testing.assert_array_equal(a.labels, data.labels)
    assert a.boundaries.keys() == data.boundaries.keys()
    for k in a.boundaries:
        np.testing.assert_array_equal(a.boundaries[k], data.boundaries[k])
    for h, g in zip(a.holes, data.holes):
        np.testing.assert_array_equal(h, g)
    np.testing.assert_array_equal(a.interior_points, data.interior_points)
    assert json.loads(a.to_json())["boundaries"] == json.loads(data.to_json())["boundaries"]


@pytest.mark.parametrize("units,up", [("m", "y"), ("mm", "y"), ("m", "z")])
def test_any_units_and_up_axis_give_the_same_scan(synthetic, data, units, up):
    s = load_scan((core_to_scan(synthetic.V, units, up), synthetic.F, synthetic.labels), units=units, up=up)
    np.testing.assert_allclose(s.vertices, data.vertices, rtol=0, atol=1e-12)
    for k in data.boundaries:
        np.testing.assert_allclose(s.boundaries[k], data.boundaries[k], rtol=0, atol=1e-12)


def test_message_arrays_flat_float32_with_own_label_names(synthetic):
    V = core_to_scan(synthetic.V, "cm", "z").astype(np.float32)
    msg = {"vertices": V.ravel(), "faces": synthetic.F.astype(np.uint32).ravel(),
           "labels": synthetic.labels.astype(np.uint8), "units": "cm", "up_axis": "z",
           "label_names": ["skin", "tshirt", "dress", "skirt", "pants", "hair"], "garment_type": ""}
    s = load_scan(msg)
    assert s.label_names[1] == "tshirt" and s.garment_class == "upper"
    np.testing.assert_allclose(s.vertices, synthetic.V[:synthetic.n_main], rtol=0, atol=1e-5)
    assert set(s.boundaries) == {"hem", "neckline", "sleeve_left", "sleeve_right"}


def test_garment_only_scan_with_its_type(synthetic):
    m = synthetic.shirt_vertex_mask
    Vs = synthetic.V[:synthetic.n_main]
    F = synthetic.F[:synthetic.n_main_faces]
    keep = m[F].all(axis=1)
    new = np.cumsum(m) - 1
    s = load_scan((Vs[m], new[F[keep]]), garment_type="tshirt")
    assert s.labels is None and s.garment_label is None and s.garment_type == "tshirt"
    assert s.garment_vertex_mask.all()
    for name, truth in synthetic.openings.items():
        _same_points(s.boundaries[name], truth)


def test_label_chosen_by_name_or_value_gives_the_same_region(synthetic_ply, data):
    for label in ("upper", 1, "1"):
        s = load_scan(synthetic_ply["binary"], units="cm", up="z", label=label)
        np.testing.assert_array_equal(s.garment_vertex_mask, data.garment_vertex_mask)


def test_tshirt_template_as_garment_only_scan():
    path = shared_file("diffavatar_templates", "tshirt.obj")
    s = load_scan(path, units="cm", up="y", garment_type="tshirt")
    assert set(s.boundaries) == {"hem", "neckline", "sleeve_left", "sleeve_right"}
    c = {k: P.mean(axis=0) for k, P in s.boundaries.items()}
    assert c["hem"][1] < min(c[k][1] for k in c if k != "hem")
    assert c["neckline"][1] > max(c[k][1] for k in c if k != "neckline")
    assert c["sleeve_left"][0] > 0.2 and c["sleeve_right"][0] < -0.2
    assert not any("dropped" in w for w in s.warnings)          # one piece, nothing thrown away
    assert not s.holes
    assert 0.5 < s.height_m < 0.8


def test_cli_scan_info_prints_the_summary(synthetic_ply, capsys):
    from diffavatar_core.cli import main
    assert main(["scan-info", str(synthetic_ply["ascii"]), "--units", "cm", "--up", "z", "--label", "upper"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["boundaries"]) == {"hem", "neckline", "sleeve_left", "sleeve_right"}
    assert out["garment"]["label_name"] == "upper" and len(out["holes"]) == 3
    assert out["transform"]["units"] == "cm" and out["height_m"] == pytest.approx(1.7)


def test_cli_reports_bad_input_as_an_error(synthetic_ply, capsys):
    from diffavatar_core.cli import main
    assert main(["scan-info", str(synthetic_ply["ascii"]), "--units", "m", "--up", "z"]) == 2
    err = capsys.readouterr().err
    assert "170 m tall" in err and "units=cm would make it 1.7 m tall" in err


def test_skirt_region_cut_out_of_one_connected_labelled_surface():
    """A full scan is usually one connected surface: the garment region ends where the labels
    change. A capsule 'body' with a skirt band labelled on it gives the waist (top) and the
    hem (bottom) exactly at the label borders."""
    import trimesh
    m = trimesh.creation.uv_sphere(radius=1.0, count=[48, 64])                 # rings of constant z
    V = np.asarray(m.vertices)[:, [0, 2, 1]] * [0.2, 0.85, -0.15] + [0, 0.85, 0]   # 1.7 m, axis Y
    F = np.asarray(m.faces)[:, [0, 2, 1]]
    band = (V[:, 1] > 0.55) & (V[:, 1] < 1.05)
    L = np.where(band, 3, 0)
    s = load_scan((V, F, L))
    assert s.garment_class == "skirt" and set(s.boundaries) == {"waist", "hem"}, s.warnings
    top, bottom = V[band, 1].max(), V[band, 1].min()
    np.testing.assert_allclose(s.boundaries["waist"][:, 1], top, atol=1e-12)
    np.testing.assert_allclose(s.boundaries["hem"][:, 1], bottom, atol=1e-12)
    assert len(s.boundaries["waist"]) == np.count_nonzero(np.isclose(V[:, 1], top))
    assert s.holes == []
    np.testing.assert_array_equal(s.label_vertex_mask("body"), L == 0)
    np.testing.assert_array_equal(s.garment_vertex_mask, band)


@pytest.mark.parametrize("seed", [0, 5])
def test_noisy_scan_with_label_noise_keeps_the_openings(synthetic, seed):
    """2 mm vertex noise and 2% of the shirt's vertices mislabelled as body (ragged borders,
    many small holes): the same four openings, each centroid within 2 cm of the clean one
    (a mislabelled vertex next to an opening notches it by one ring of cells, 1 × 2.6 cm)."""
    rng = np.random.default_rng(seed)
    V = synthetic.V + rng.normal(scale=0.002, size=synthetic.V.shape)
    L = synthetic.labels.copy()
    shirt = np.flatnonzero(L == 1)
    L[rng.choice(shirt, size=len(shirt) // 50, replace=False)] = 0
    s = load_scan((V, synthetic.F, L))
    assert set(s.boundaries) == set(synthetic.openings)
    for name, truth in synthetic.openings.items():
        assert np.linalg.norm(s.boundaries[name].mean(axis=0) - truth.mean(axis=0)) < 0.02, name
    assert len(s.holes) > 50                      # the mislabelled vertices' 1-rings


def test_segmented_scan_message_round_trip(synthetic, data):
    """The node's path: SegmentedScan message → msg_to_arrays → load_scan (float32 on the wire)."""
    pytest.importorskip("diffavatar_msgs", reason="ROS interfaces (diffavatar_msgs) not built")
    from diffavatar_ros.convert import msg_to_arrays, scan_to_msg
    V = core_to_scan(synthetic.V, "cm", "z").astype(np.float32)
    msg = scan_to_msg(V, synthetic.F.astype(np.uint32), synthetic.labels.astype(np.uint8),
                      ["body", "upper", "dress", "skirt", "pants", "hair"], units="cm", up_axis="z",
                      garment_type="tshirt")
    s = load_scan(msg_to_arrays(msg))
    assert s.garment_type == "tshirt" and s.garment_label == 1
    np.testing.assert_allclose(s.vertices, data.vertices, rtol=0, atol=2e-7)   # float32 of ≤ 180 cm
    assert set(s.boundaries) == set(data.boundaries)
    for k in data.boundaries:
        np.testing.assert_array_equal(s.boundary_indices[k], data.boundary_indices[k])


def test_a_turned_scan_names_its_openings_once_turned_back():
    """ScanData.turned(Q): the bundled sample skirt turned 90° about the vertical loses its waist
    (the openings' rules take +X as the body's left); turned back to face +Z and preprocessed
    again it names waist and hem as the scan at rest does, with the same loops, and its
    transform includes the turn (to_scan maps back into the file's frame)."""
    from diffavatar_core.demo import SAMPLE
    from diffavatar_core.pipeline.facing import yaw_rotation
    from diffavatar_core.scan import read_scan_file
    raw = read_scan_file(SAMPLE)
    Q = yaw_rotation(np.radians(90.0))
    rest = load_scan((raw.vertices, raw.faces, raw.labels), units="cm")
    turned = load_scan((raw.vertices @ Q.T, raw.faces, raw.labels), units="cm")
    assert set(rest.boundaries) == {"waist", "hem"} and "waist" not in turned.boundaries
    back = turned.turned(Q.T)
    assert set(back.boundaries) == {"waist", "hem"}
    for name, P in rest.boundaries.items():
        np.testing.assert_array_equal(back.boundary_indices[name], rest.boundary_indices[name])
        np.testing.assert_allclose(back.boundaries[name], P, atol=1e-12)
    np.testing.assert_allclose(back.transform.to_scan(back.vertices), turned.transform.to_scan(turned.vertices),
                               atol=1e-9)


def test_only_a_lying_scan_gets_the_lying_hint():
    """frame.lying_hint: the sample standing (1.67 m tall, 1.07 wide with its arms, 0.52 deep),
    turned to face +X, and its cleaned garment alone (a skirt, 0.50 m tall, as deep) stand; the sample
    lying (a Z-up file read as Y-up) gets the hint naming up=z and its height."""
    from diffavatar_core.demo import SAMPLE
    from diffavatar_core.pipeline.facing import yaw_rotation
    from diffavatar_core.scan import read_scan_file
    from diffavatar_core.scan.frame import ScanTransform, lying_hint
    raw = read_scan_file(SAMPLE)
    tf = ScanTransform.from_options("cm", "y")
    V = tf.to_core(raw.vertices[np.unique(raw.faces)])
    assert lying_hint(V, tf) == ""
    assert lying_hint(V @ yaw_rotation(np.pi / 2).T, tf) == ""
    assert lying_hint(load_scan(SAMPLE, units="cm").garment_mesh()[0], tf) == ""   # fragments dropped
    lying = np.column_stack([V[:, 0], -V[:, 2], V[:, 1]])
    assert "up=z would make it 1.67 m tall" in lying_hint(lying, tf)
