"""`diffavatar send` as a second OS process against the node (real DDS between processes):
a batch directory with a labelled PLY scan, a garment-only OBJ scan and a bad file; results
written as the CLI's files, the bad file reported before sending; a job cancelled mid-optimization
written with what it produced."""
import contextlib
import json
import os
import pathlib
import subprocess
import sys
import threading
import time

import numpy as np
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter

from diffavatar_core.io import load_mesh, save_mesh
from diffavatar_ros.node import DiffAvatarNode, shutdown_executor
from service_helpers import SphereFitRunner, small_scan


def _write_labelled_ply(path, V, F, labels):
    with open(path, "w") as fh:
        fh.write(f"ply\nformat ascii 1.0\nelement vertex {len(V)}\nproperty float x\nproperty float y\n"
                 f"property float z\nproperty uchar label\nelement face {len(F)}\n"
                 "property list uchar int vertex_indices\nend_header\n")
        for (x, y, z), lab in zip(V, labels):
            fh.write(f"{float(x)!r} {float(y)!r} {float(z)!r} {int(lab)}\n")
        for a, b, c in F:
            fh.write(f"3 {a} {b} {c}\n")


@contextlib.contextmanager
def _node(ros_context, runner, output_dir):
    """The node with `runner`, spun in a thread, writing to output_dir; stopped afterwards."""
    node = DiffAvatarNode(runner=runner, context=ros_context,
                          parameter_overrides=[Parameter("output_dir", value=str(output_dir))])
    ex = MultiThreadedExecutor(num_threads=4, context=ros_context)
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    try:
        yield node
    finally:
        node.stop_jobs()
        shutdown_executor(ex, spin)
        node.destroy_node()


def _send(domain, *args):
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
    return subprocess.run([sys.executable, "-m", "diffavatar_core", "send", *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=120)


def test_send_batch_directory_and_action(ros_domain, ros_context, tmp_path):
    V, F, L, _ = small_scan()
    batch = tmp_path / "batch"
    batch.mkdir()
    _write_labelled_ply(batch / "a_person.ply", V, F, L)
    save_mesh(batch / "b_bad.obj", V * 1000, F)  # millimetres sent as metres
    runner = SphereFitRunner()
    with _node(ros_context, runner, tmp_path / "node_out"):
        out = tmp_path / "client_out"
        proc = _send(ros_domain, batch, "--label-names", "body,tshirt", "--iterations", 3, "--out", out)
        assert proc.returncode == 1, proc.stdout + proc.stderr  # one bad file
        dirs = {d.name.rsplit("-", 1)[0]: d for d in out.iterdir()}
        assert set(dirs) == {"a_person", "b_bad"}
        err = json.loads((dirs["b_bad"] / "error.json").read_text())
        assert err["error"] == "IMPLAUSIBLE_SIZE" and "not sent" in proc.stdout
        assert len(runner.scans) == 1 and runner.scans[0].garment_type == "tshirt", proc.stdout + proc.stderr
        np.testing.assert_array_equal(runner.scans[0].garment_mask, L == 1)  # labels travelled
        assert "optimize 3/3" in proc.stderr  # progress shown

        # the client's files match the node's own record of the same job
        job_id = dirs["a_person"].name
        mine, theirs = dirs["a_person"], tmp_path / "node_out" / job_id
        a, b = json.loads((mine / "result.json").read_text()), json.loads((theirs / "result.json").read_text())
        assert [h["value"] for h in a["loss_history"]] == [h["value"] for h in b["loss_history"]]
        assert a["iterations"] == b["iterations"] == 3 and a["pattern"] == b["pattern"]
        for name in ("garment_draped.obj", "garment_rest.obj"):
            Va, Fa = load_mesh(mine / name)
            Vb, Fb = load_mesh(theirs / name)
            np.testing.assert_allclose(Va, Vb, rtol=1e-6, atol=1e-7)
            np.testing.assert_array_equal(Fa, Fb)
        assert (mine / "loss.png").stat().st_size > 0

        # the action path, garment-only OBJ in cm with Z up
        Vz = np.column_stack([V[:, 0], -V[:, 2], V[:, 1]]) * 100
        save_mesh(tmp_path / "garment.obj", Vz, F)
        proc = _send(ros_domain, tmp_path / "garment.obj", "--garment", "dress", "--units", "cm", "--up", "z",
                     "--iterations", 2, "--action", "--quiet", "--out", out)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "garment-" in proc.stdout and ": ok" in proc.stdout and proc.stderr.count("optimize") == 0
        np.testing.assert_allclose(runner.scans[-1].vertices, V, atol=1e-6)  # converted to m, Y up


def test_send_without_a_node_says_so(ros_domain, tmp_path):
    V, F, _, _ = small_scan()
    save_mesh(tmp_path / "s.obj", V, F)
    proc = _send(ros_domain, tmp_path / "s.obj", "--garment", "dress", "--wait", 1, "--out", tmp_path / "o")
    assert proc.returncode == 1 and "no /diffavatar_node found" in proc.stdout


def test_send_keeps_a_job_cancelled_in_its_optimization(ros_domain, ros_context, tmp_path):
    """A job cancelled on the node once its optimization has begun answers with what it produced
    (the runner raises RecoveryCancelled, as the recovery does): `diffavatar send` writes those
    assets as the node wrote them (the sphere of the iterations done, not of the 1000 asked),
    reports the job CANCELLED and exits 1."""
    V, F, L, _ = small_scan()
    _write_labelled_ply(tmp_path / "s.ply", V, F, L)
    runner = SphereFitRunner(repeat=400, keep_on_cancel=True)   # ~0.1-0.5 s per iteration
    out = tmp_path / "client_out"
    with _node(ros_context, runner, tmp_path / "node_out") as node:
        proc = subprocess.Popen([sys.executable, "-m", "diffavatar_core", "send", str(tmp_path / "s.ply"),
                                 "--label-names", "body,tshirt", "--iterations", "1000", "--quiet", "--out", str(out)],
                                env={**os.environ, "ROS_DOMAIN_ID": str(ros_domain)}, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 90
            while runner.done < 2:
                assert time.monotonic() < deadline and proc.poll() is None, proc.poll()
                time.sleep(0.02)
            job_id = node.queue.current.job_id
            assert node.queue.cancel(job_id)
            stdout, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    assert proc.returncode == 1, stdout + stderr
    assert f"{job_id}: CANCELLED: cancelled while running (cancelled during optimize): the assets are" in stdout
    mine, theirs = out / job_id, tmp_path / "node_out" / job_id
    a, b = json.loads((mine / "result.json").read_text()), json.loads((theirs / "result.json").read_text())
    assert a["metrics"]["stopped"] == "cancelled" and not (mine / "error.json").exists()
    assert 2 <= a["iterations"] == b["iterations"] < 1000 and a["pattern"] == b["pattern"]
    Va, Fa = load_mesh(mine / "garment_draped.obj")
    Vb, Fb = load_mesh(theirs / "garment_draped.obj")
    np.testing.assert_allclose(Va, Vb, rtol=1e-6, atol=1e-7)
    np.testing.assert_array_equal(Fa, Fb)
