"""Result files and ROS conversion of a RecoveryResult: round trips with known content."""
import json

import numpy as np
import pytest
import trimesh

from diffavatar_core.pipeline.output import write_result
from diffavatar_core.pipeline.result import BodyAssets, MaterialAssets, PatternAssets, RecoveryResult


def example_result(seed=0):
    rng = np.random.default_rng(seed)
    n, t = 30, 40
    pattern = PatternAssets(rest_xy=rng.random((n, 2)), triangles=rng.integers(0, n, (t, 3)),
                            panel_vertex_start=np.array([0, 12, 30]), panel_names=["front", "back"],
                            panel_grain_rad=np.array([0.0, 0.1]), seam_pairs=np.array([[0, 12], [1, 13]]),
                            handles=np.array([0, 3, 12, 20]))
    material = MaterialAssets(2e-6, np.array([1e-6, 3e-6]), 1e-3, 2e-3, 5e-3, 0.15, 0.004, "valley", (None, 6.3e-6))
    body = BodyAssets("test-model", rng.normal(size=6), ["root", "spine"], rng.normal(size=(2, 3)),
                      np.ones(2), np.zeros(6))
    gv = rng.random((n, 3))
    return RecoveryResult("tshirt", "tshirt", pattern, material, body, gv, pattern.triangles, pattern.rest_xy,
                          rng.random((8, 3)), np.array([[0, 1, 2], [2, 3, 4]]),
                          {"chamfer_initial_cm": 3.0, "chamfer_final_cm": 1.2, "mesh_quality_min": 0.2,
                           "mesh_quality_avg": 0.4, "seam_length_mismatch_max_pct": 0.5},
                          iterations=2, wall_s=1.5,
                          loss_history=[{"iteration": i, "value": 1.0 / (i + 1), "terms": {"interior": 0.5 / (i + 1)}}
                                        for i in range(3)])


def test_written_files_round_trip(tmp_path):
    r = example_result()
    out = write_result(r, tmp_path / "job")
    summary = json.loads((out / "result.json").read_text())
    assert summary["metrics"]["chamfer_final_cm"] == 1.2 and summary["iterations"] == 2
    assert summary["material"]["bending_stiffness_Nm"] == 2e-6
    assert summary["material"]["contact_normals"] == "valley"
    assert summary["material"]["bending_stiffness_range_Nm"] == [None, 6.3e-6]   # open below
    assert len(summary["loss_history"]) == 3
    draped = trimesh.load(out / "garment_draped.obj", process=False, maintain_order=True)
    np.testing.assert_allclose(draped.vertices, r.garment_vertices, atol=1e-8)
    np.testing.assert_allclose(draped.visual.uv, r.garment_uv, atol=1e-8)
    np.testing.assert_array_equal(draped.faces, r.garment_faces)
    rest = trimesh.load(out / "garment_rest.obj", process=False, maintain_order=True)
    np.testing.assert_allclose(rest.vertices[:, :2], r.pattern.rest_xy, atol=1e-8)
    assert (out / "loss.png").stat().st_size > 1000 and (out / "body.obj").exists()
    assert r.output_dir == str(out)


def test_ros_assets_round_trip():
    pytest.importorskip("rclpy")
    from diffavatar_ros.convert import assets_to_arrays, assets_to_result, result_to_assets
    r = example_result(1)
    r.warnings = ["openings not found for a 'skirt' garment: waist", "the subject faces 90° from +Z"]
    msg = result_to_assets("job-7", r)
    a = assets_to_arrays(msg)
    np.testing.assert_array_equal(a["rest_xy"], r.pattern.rest_xy)  # float64: exact
    np.testing.assert_array_equal(a["seam_pairs"], r.pattern.seam_pairs)
    np.testing.assert_allclose(a["garment_vertices"], r.garment_vertices, rtol=1e-7)
    np.testing.assert_array_equal(a["pose"], r.body.pose)
    assert msg.job_id == "job-7" and msg.error_code == 0 and msg.chamfer_final_cm == 1.2
    assert list(msg.pattern.panel_names) == ["front", "back"]
    assert msg.material.contact_normals == "valley"
    assert list(assets_to_result(msg).warnings) == r.warnings   # what the recovery warned of reaches a ROS client
    back = assets_to_result(msg).material
    assert (back.contact_normals, back.thickness, back.compliance_weft) == ("valley", 0.004, 2e-3)
    assert (msg.material.bending_stiffness_low, msg.material.bending_stiffness_high) == (0.0, 6.3e-6)
    assert back.bending_stiffness_range == (None, 6.3e-6)
