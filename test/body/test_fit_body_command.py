"""`diffavatar fit-body`: a point-cloud PLY scan (cm, Z up) in, body.obj + body.json out."""
import json

import numpy as np
import trimesh

from diffavatar_core.body import BodyModel, BodyParams
from diffavatar_core.cli import main
from diffavatar_core.io import load_mesh
from diffavatar_core.metrics import sample_surface


def test_fit_body_command(tmp_path, capsys):
    model = BodyModel.default()
    truth = model.zero_params()
    truth.shape[0] = 0.8
    truth.pose[model.joint_index("elbow_left")] = [-0.5, 0.0, 0.0]
    X = model.pose(truth)
    pts, _ = sample_surface(X, model.faces, 8000, seed=4)
    zup = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    scan = tmp_path / "scan.ply"
    trimesh.PointCloud(100 * pts @ zup.T).export(str(scan))
    rc = main(["fit-body", str(scan), "--out", str(tmp_path / "out"), "--units", "cm", "--up", "z",
               "--iterations", "20", "--quiet"])
    assert rc == 0
    V, F = load_mesh(tmp_path / "out" / "body.obj")
    assert len(V) == model.num_vertices and len(F) == len(model.faces)
    doc = json.loads((tmp_path / "out" / "body.json").read_text())
    p = BodyParams.from_dict(doc["params"])
    np.testing.assert_allclose(model.pose(p), V, atol=1e-5)
    assert np.linalg.norm(V - X, axis=1).mean() < 0.01
    assert abs(doc["landmarks"]["height"] - model.landmarks(truth).height) < 0.01
    assert json.loads(capsys.readouterr().out)["body_obj"].endswith("body.obj")


def test_fit_body_command_rejects_missing_scan(tmp_path, capsys):
    assert main(["fit-body", str(tmp_path / "nope.ply"), "--out", str(tmp_path)]) == 2
    assert "no such file" in capsys.readouterr().err
