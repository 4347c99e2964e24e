"""Client of the asset service for capture rigs and batch jobs (`diffavatar send`).

Loads scan files, checks them with the same function as the node's front door
(diffavatar_core.scan.check_scan, so a bad file is reported before anything is sent), sends
them to a running diffavatar_node on its `~/scans` topic (or as `~/optimize` action goals),
shows progress, waits for every result and writes each into OUT/<job_id>/: the CLI's files
(diffavatar_core.pipeline.output.write_result) for a success, error.json for an error.
Ctrl-C cancels the jobs still pending. Exit status: 0 all succeeded, 1 otherwise.
"""
from __future__ import annotations

import json
import pathlib
import sys
import threading
import time

import numpy as np

from diffavatar_core.config import load_config

MESH_SUFFIXES = (".ply", ".obj", ".off", ".stl", ".glb", ".gltf")


def scan_files(paths) -> list[pathlib.Path]:
    """The scan files named, a directory standing for its mesh files (sorted by name)."""
    out = []
    for p in map(pathlib.Path, paths):
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in MESH_SUFFIXES and q.is_file())
            if not found:
                raise ValueError(f"{p}: no scan files ({', '.join(MESH_SUFFIXES)}) in this directory")
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise FileNotFoundError(f"{p}: no such file or directory")
    return out


def load_scan(path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(vertices (V, 3) as stored, faces (F, 3), per-vertex labels or None). Labels come from a
    PLY vertex property named `label` (any integer type); other formats are garment-only."""
    import trimesh
    from diffavatar_core.io import load_mesh
    V, F = load_mesh(path)
    labels = None
    if pathlib.Path(path).suffix.lower() == ".ply":
        m = trimesh.load(str(path), force="mesh", process=False)
        data = (m.metadata.get("_ply_raw") or {}).get("vertex", {}).get("data")
        if data is not None and "label" in (data.keys() if isinstance(data, dict) else data.dtype.names or ()):
            labels = np.asarray(data["label"]).ravel()
    return V, F, labels


def job_id_for(path: pathlib.Path, used: set) -> str:
    """<file stem>-<6 random hex digits>: unique per send, so a result latched on the node from
    an earlier run of the same file is never mistaken for this run's."""
    import uuid
    base = "".join(c if c.isalnum() or c in "-_" else "_" for c in path.stem) or "scan"
    job_id = f"{base}-{uuid.uuid4().hex[:6]}"
    while job_id in used:
        job_id = f"{base}-{uuid.uuid4().hex[:6]}"
    used.add(job_id)
    return job_id


class ServiceClient:
    """A node on its own rclpy context talking to one diffavatar_node; spins in a thread."""

    def __init__(self, node: str = "/diffavatar_node", use_action: bool = False, args=None):
        import rclpy
        from rclpy.action import ActionClient
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import String

        from diffavatar_msgs.action import OptimizeAvatar
        from diffavatar_msgs.msg import AvatarAssets, OptimizationProgress, SegmentedScan

        from .node import PROGRESS_QOS, SCAN_QOS, result_qos  # also selects the large-data transport

        self._rclpy, self._String, self._Goal = rclpy, String, OptimizeAvatar.Goal
        self.ns = node.rstrip("/")
        self.context = rclpy.context.Context()
        rclpy.init(args=args, context=self.context)
        self.node = rclpy.create_node("diffavatar_send", context=self.context)
        self.lock = threading.Condition()
        self.results: dict = {}
        self.submitted: set = set()
        self.progress: dict = {}
        self.on_progress = lambda msg: None
        self.use_action = use_action
        self._goals: dict = {}
        self.scan_pub = self.node.create_publisher(SegmentedScan, f"{self.ns}/scans", SCAN_QOS)
        self.cancel_pub = self.node.create_publisher(String, f"{self.ns}/cancel", SCAN_QOS)
        self.node.create_subscription(OptimizationProgress, f"{self.ns}/progress", self._progress, PROGRESS_QOS)
        self.node.create_subscription(AvatarAssets, f"{self.ns}/result", self._result, result_qos(1))
        self.action = ActionClient(self.node, OptimizeAvatar, f"{self.ns}/optimize")
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _progress(self, msg):
        with self.lock:
            self.progress.setdefault(msg.job_id, []).append(msg)
        self.on_progress(msg)

    def _result(self, msg):
        with self.lock:
            if msg.job_id not in self.submitted:  # another client's job
                return
            self.results.setdefault(msg.job_id, msg)
            self.lock.notify_all()

    def wait_for_service(self, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.use_action and self.action.server_is_ready() and self.node.count_publishers(f"{self.ns}/result"):
                return
            if not self.use_action and self.scan_pub.get_subscription_count() \
                    and self.node.count_publishers(f"{self.ns}/result"):
                return
            time.sleep(0.05)
        raise TimeoutError(f"no {self.ns} found within {timeout:.0f} s (is diffavatar-node running on this "
                           f"ROS_DOMAIN_ID?)")

    def submit(self, msg) -> None:
        with self.lock:
            self.submitted.add(msg.job_id)
        if not self.use_action:
            self.scan_pub.publish(msg)
            return
        fut = self.action.send_goal_async(self._Goal(scan=msg), feedback_callback=lambda f: self._progress(
            f.feedback.progress))
        job_id = msg.job_id

        def accepted(f):
            gh = f.result()
            self._goals[job_id] = gh
            gh.get_result_async().add_done_callback(lambda r: self._result(r.result().result.assets))
        fut.add_done_callback(accepted)

    def cancel(self, job_id: str) -> None:
        self.cancel_pub.publish(self._String(data=job_id))

    def wait(self, job_ids, timeout: float | None = None) -> dict:
        """Results of job_ids received so far once all arrived or the timeout passed."""
        deadline = None if not timeout else time.monotonic() + timeout
        with self.lock:
            while not all(j in self.results for j in job_ids):
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    break
                self.lock.wait(0.2 if left is None else min(0.2, left))
            return {j: self.results[j] for j in job_ids if j in self.results}

    def loss_history(self, job_id: str) -> list:
        """Per iteration {"iteration", "value", "terms"} from the job's progress messages."""
        by_it = {}
        with self.lock:
            for p in self.progress.get(job_id, []):
                if p.iteration > 0:
                    by_it[p.iteration] = {"iteration": int(p.iteration), "value": float(p.loss),
                                          "terms": dict(zip(p.loss_term_names, map(float, p.loss_terms)))}
        return [by_it[k] for k in sorted(by_it)]

    def close(self) -> None:
        self.executor.shutdown()
        self.action.destroy()
        self.node.destroy_node()
        self.thread.join(5.0)
        if self.context.ok():
            self._rclpy.shutdown(context=self.context, uninstall_handlers=True)


def _write_error(out: pathlib.Path, job_id: str, code: str, number: int, message: str) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "error.json").write_text(json.dumps({"job_id": job_id, "error": code, "error_code": number,
                                                "message": message}, indent=2))


def send(paths, out_dir, *, garment: str = "", units: str = "m", up_axis: str = "y", template: str = "",
         iterations: int = 0, label_names=(), use_action: bool = False, node: str = "/diffavatar_node",
         discovery_timeout: float = 30.0, timeout: float | None = None, quiet: bool = False,
         stream=sys.stdout) -> int:
    """Sends every scan, waits for the results, writes them under out_dir; returns the exit status."""
    from diffavatar_msgs.msg import AvatarAssets
    from diffavatar_core.pipeline.output import write_result
    from diffavatar_core.scan import check_scan, scan_from_arrays

    from . import convert

    out_dir = pathlib.Path(out_dir)
    max_vertices = int(load_config()["node"]["max_vertices"])
    used, msgs, failed = set(), [], 0
    for path in scan_files(paths):
        job_id = job_id_for(path, used)
        try:
            V, F, labels = load_scan(path)
            check_scan(scan_from_arrays(V, F, labels, list(label_names) or None, source=str(path)),
                       units or "m", up_axis or "y", garment_type=garment or None, template_name=template,
                       max_vertices=max_vertices)
        except (ValueError, OSError) as err:
            code = getattr(err, "code", "BAD_OPTION")
            _write_error(out_dir / job_id, job_id, code, convert.error_code(code), f"{path}: {err}")
            print(f"{job_id}: not sent, {code}: {err}", file=stream, flush=True)
            failed += 1
            continue
        msgs.append(convert.scan_to_msg(V, F, labels, label_names, units=units or "m", up_axis=up_axis or "y",
                                        job_id=job_id, garment_type=garment, template_name=template,
                                        iterations=iterations))
    if not msgs:
        return 1

    client = ServiceClient(node, use_action=use_action)
    last_line = {}

    def show(p):
        if quiet or p.stage == "queued" or p.iteration == last_line.get(p.job_id):
            return
        last_line[p.job_id] = p.iteration
        eta = f", ~{p.eta_s:.0f} s left" if p.eta_s >= 0 else ""
        print(f"{p.job_id}: {p.stage} {p.iteration}/{p.max_iterations} loss {p.loss:.4g}{eta}",
              file=sys.stderr, flush=True)

    client.on_progress = show
    ids = [m.job_id for m in msgs]
    try:
        try:
            client.wait_for_service(discovery_timeout)
        except TimeoutError as exc:
            print(f"diffavatar send: {exc}", file=stream, flush=True)
            client.close()
            return 1
        for m in msgs:
            client.submit(m)
        results = client.wait(ids, timeout)
    except KeyboardInterrupt:
        pending = [j for j in ids if j not in client.results]
        for j in pending:
            client.cancel(j)
        print(f"interrupted: cancelled {len(pending)} pending job(s)", file=stream, flush=True)
        results = client.wait(ids, 5.0)
    try:
        for job_id in ids:
            res = results.get(job_id)
            out = out_dir / job_id
            if res is None:
                print(f"{job_id}: no result received", file=stream, flush=True)
                failed += 1
            elif res.error_code == AvatarAssets.ERROR_NONE:
                write_result(convert.assets_to_result(res, client.loss_history(job_id)), out)
                print(f"{job_id}: ok, Chamfer {res.chamfer_initial_cm:.3g} -> {res.chamfer_final_cm:.3g} cm, "
                      f"{res.iterations} iterations, {res.wall_s:.1f} s -> {out}", file=stream, flush=True)
            elif res.error_code == AvatarAssets.ERROR_CANCELLED and len(res.garment_draped.faces):
                # cancelled once its optimization had begun: the assets are what it had produced
                kept = convert.assets_to_result(res, client.loss_history(job_id))
                kept.metrics["stopped"] = "cancelled"
                write_result(kept, out)
                print(f"{job_id}: CANCELLED: {res.error_msg}; Chamfer {res.chamfer_initial_cm:.3g} -> "
                      f"{res.chamfer_final_cm:.3g} cm -> {out}", file=stream, flush=True)
                failed += 1
            else:
                name = next((k[len("ERROR_"):] for k in dir(AvatarAssets)
                             if k.startswith("ERROR_") and getattr(AvatarAssets, k) == res.error_code), "UNKNOWN")
                _write_error(out, job_id, name, res.error_code, res.error_msg)
                print(f"{job_id}: {name}: {res.error_msg}", file=stream, flush=True)
                failed += 1
    finally:
        client.close()
    return 0 if failed == 0 else 1
