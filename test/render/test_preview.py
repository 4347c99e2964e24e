"""Preview PNGs (scan vs result from 4 views, contact sheets) and the render-based SSIM metric."""
import numpy as np
import pytest
import trimesh
from PIL import Image

from diffavatar_core.render import contact_sheet, orbit_cameras, preview_side_by_side, render, ssim_metric


def body_and_garment():
    """A capsule 'body' and a cylinder-shell 'garment' around its middle (m)."""
    body = trimesh.creation.capsule(height=1.2, radius=0.18, count=[24, 24])
    Vb = np.asarray(body.vertices)[:, [0, 2, 1]] + [0, 0.9, 0]  # Y up
    skirt = trimesh.creation.cylinder(radius=0.24, height=0.5, sections=48)
    Vg = np.asarray(skirt.vertices)[:, [0, 2, 1]] + [0, 0.8, 0]
    return (Vg, np.asarray(skirt.faces)), (Vb, np.asarray(body.faces), )


def scan_of(garment, body):
    Vg, Fg = garment
    Vb, Fb = body[:2]
    return np.concatenate([Vg, Vb]), np.concatenate([Fg, Fb + len(Vg)])


def test_preview_png_is_produced_and_not_blank(tmp_path):
    garment, body = body_and_garment()
    scan = scan_of(garment, body)
    path = tmp_path / "preview.png"
    img = preview_side_by_side(scan, [garment, body], path, size=96)
    assert path.exists()
    png = np.asarray(Image.open(path).convert("RGB"))
    assert png.shape == img.shape == (2 * 96 + 3 * 4, 4 * 96 + 5 * 4, 3)
    # each of the 8 cells shows the subject: many non-background pixels, real contrast
    for r in range(2):
        for c in range(4):
            cell = png[4 + r * 100:4 + r * 100 + 96, 4 + c * 100:4 + c * 100 + 96]
            fg = (cell < 250).any(axis=2)
            assert 0.05 < fg.mean() < 0.9
            assert cell.std() > 10
    # the result row is coloured (garment blue, body skin), the scan row is grey
    res = png[104:200].reshape(-1, 3).astype(int)
    assert (res[:, 2] - res[:, 0] > 30).any() and (res[:, 0] - res[:, 2] > 30).any()


def test_contact_sheet(tmp_path):
    garment, body = body_and_garment()
    cams = orbit_cameras([garment, body])
    frames = []
    for k in range(5):
        ang = 0.3 * k
        R = np.array([[np.cos(ang), 0, np.sin(ang)], [0, 1, 0], [-np.sin(ang), 0, np.cos(ang)]])
        frames.append(render([(garment[0] @ R.T, garment[1]), body], cams["front"], 64))
    path = tmp_path / "sheet.png"
    sheet = contact_sheet(frames, path, columns=3, labels=[f"{k}" for k in range(5)])
    png = np.asarray(Image.open(path).convert("RGB"))
    assert png.shape == sheet.shape == (2 * 64 + 3 * 4, 3 * 64 + 4 * 4, 3)
    assert png.std() > 10
    with pytest.raises(ValueError, match=r"frames\[1\]"):
        contact_sheet([frames[0], frames[1][:10]], tmp_path / "bad.png")


def test_ssim_metric_self_is_one_and_perturbation_lowers_it():
    garment, body = body_and_garment()
    scan = scan_of(garment, body)
    assert ssim_metric(scan, garment, body, size=96) == pytest.approx(1.0, abs=1e-12)
    rng = np.random.default_rng(0)
    z = rng.standard_normal(garment[0].shape)
    values = [ssim_metric(scan, (garment[0] + s * z, garment[1]), body, size=96) for s in (0.005, 0.02, 0.05)]
    assert values[0] < 1.0
    assert values[0] > values[1] > values[2], values
    # a garment that is missing entirely scores lower still than a slightly perturbed one
    assert ssim_metric(scan, body, None, size=96) < values[0]


def test_preview_command(tmp_path, capsys):
    import json

    from diffavatar_core.cli import main
    from diffavatar_core.io import save_mesh
    garment, body = body_and_garment()
    save_mesh(tmp_path / "scan.obj", *scan_of(garment, body))
    save_mesh(tmp_path / "garment.obj", *garment)
    save_mesh(tmp_path / "body.obj", *body)
    out = tmp_path / "p.png"
    rc = main(["preview", str(tmp_path / "scan.obj"), "--garment", str(tmp_path / "garment.obj"),
               "--body", str(tmp_path / "body.obj"), "--out", str(out), "--size", "64"])
    assert rc == 0 and out.exists()
    res = json.loads(capsys.readouterr().out)
    assert res["ssim"] == pytest.approx(1.0, abs=1e-9)


def test_write_result_with_scan_writes_preview_and_ssim(tmp_path):
    import json

    from diffavatar_core.pipeline.output import write_result
    from diffavatar_core.pipeline.result import BodyAssets, MaterialAssets, PatternAssets, RecoveryResult
    garment, body = body_and_garment()
    Vg, Fg = garment
    uv = Vg[:, :2].copy()
    pattern = PatternAssets(uv, Fg, np.array([0, len(Vg)]), ["tube"], np.zeros(1), np.zeros((0, 2), int),
                            np.zeros(0, int))
    material = MaterialAssets(2e-6, np.zeros(0), 1e-3, 1e-3, 5e-3, 0.15, 0.004)
    body_assets = BodyAssets("capsule", np.zeros(0), ["root"], np.zeros((1, 3)), np.ones(1), np.zeros(6))
    r = RecoveryResult("skirt", "tube", pattern, material, body_assets, Vg, Fg, uv, body[0], body[1],
                       {"chamfer_final_cm": 0.0}, iterations=1, wall_s=0.1)
    scan = scan_of(garment, body)
    out = write_result(r, tmp_path / "job", scan=scan)
    summary = json.loads((out / "result.json").read_text())
    assert summary["metrics"]["ssim"] == pytest.approx(1.0, abs=1e-9)
    png = np.asarray(Image.open(out / "preview.png").convert("RGB"))
    assert png.std() > 10 and (png < 250).any(axis=2).mean() > 0.05
