"""Helpers of the node tests: scans, a runner doing real core work, and a node spun in a thread.

The runner stands in for diffavatar_core.pipeline.recover (written in parallel): it fits a
sphere (centre fixed at the garment's centroid, radius by gradient descent) to the received
scan's garment vertices, measuring point-to-surface distances with the core's BVH
(diffavatar_core.surface_distances, GIL released, cancel token polled) each iteration,
reporting progress each iteration, and returns a real RecoveryResult. It is deterministic, so a
test can run it directly on the same input and compare with what the node answered.
"""
from __future__ import annotations

import threading
import time

import numpy as np
import trimesh

import diffavatar_core as dc
from diffavatar_core.pipeline.result import BodyAssets, MaterialAssets, PatternAssets, RecoveryResult

SPHERE = trimesh.creation.icosphere(subdivisions=3)  # 642 vertices, 1280 faces, radius 1


def grid_sphere(n_lat: int, n_lon: int, radius: float = 0.4, noise: float = 0.0, seed: int = 0):
    """A UV-sphere scan: n_lat * n_lon vertices (poles excluded), quads split in two; metres."""
    th = np.linspace(0.05, np.pi - 0.05, n_lat)
    ph = np.linspace(0.0, 2 * np.pi, n_lon, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    V = radius * np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    if noise:
        V = V + np.random.default_rng(seed).normal(scale=noise, size=V.shape)
    i, j = np.meshgrid(np.arange(n_lat - 1), np.arange(n_lon), indexing="ij")
    a = (i * n_lon + j).ravel()
    b = (i * n_lon + (j + 1) % n_lon).ravel()
    c = a + n_lon
    d = b + n_lon
    F = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])
    return V.astype(np.float32), F.astype(np.uint32)


def small_scan(radius=0.4, seed=0):
    """A 20x24 sphere with the lower half labelled body, the upper half tshirt."""
    V, F = grid_sphere(20, 24, radius, noise=0.002, seed=seed)
    labels = (V[:, 1] > 0).astype(np.uint8)
    return V, F, labels, ["body", "tshirt"]


class SphereFitRunner:
    """runner(scan, options, run_control) -> RecoveryResult. `repeat` tiles the query points to
    make each iteration's core call longer (responsiveness and cancel tests). Records the scans
    it received (`scans`) and the iterations it started (`started` event)."""

    def __init__(self, repeat: int = 1, lr: float = 0.5, keep_on_cancel: bool = False):
        self.repeat, self.lr, self.keep_on_cancel = repeat, lr, keep_on_cancel
        self.scans = []
        self.started = threading.Event()
        self.done = 0   # iterations finished by the current job

    def __call__(self, scan, options, rc):
        self.scans.append(scan)
        self.started.set()
        n = int(options["iterations"])
        pts = scan.vertices[scan.garment_mask]
        c = pts.mean(axis=0)
        query = np.tile(pts, (self.repeat, 1)) if self.repeat > 1 else pts
        r, history = 0.2, []
        t0 = time.monotonic()
        self.done = 0
        for it in range(1, n + 1):
            try:
                rc.check("optimize")
                d = dc.surface_distances(query, c + r * SPHERE.vertices, SPHERE.faces, cancel=rc.cancel)[: len(pts)]
            except dc.Cancelled:
                if not (self.keep_on_cancel and history):
                    raise
                # as the recovery does once its optimization has begun: what it produced goes along
                from diffavatar_core.pipeline import RecoveryCancelled
                raise RecoveryCancelled("cancelled during optimize", self._result(scan, c, r, history, t0)) from None
            signed = np.linalg.norm(pts - c, axis=1) - r  # >0 outside: growing r reduces it
            loss = float(np.mean(d ** 2))
            r += self.lr * float(np.mean(np.sign(signed) * d))
            history.append({"iteration": it, "value": loss, "terms": {"feature": loss}})
            self.done = it
            rc.report("optimize", it, n, loss, {"feature": loss})
        return self._result(scan, c, r, history, t0)

    @staticmethod
    def _result(scan, c, r, history, t0) -> RecoveryResult:
        """The sphere of radius r (m) about c as a RecoveryResult after len(history) iterations."""
        n = len(history)
        V = c + r * SPHERE.vertices
        F = SPHERE.faces.astype(np.int64)
        uv = SPHERE.vertices[:, [0, 2]] * r
        q = dc.mesh_quality(V, F)
        d0 = history[0]["value"] if history else float("nan")
        return RecoveryResult(
            garment_type=scan.garment_type, template_name=scan.template_name or scan.garment_type,
            pattern=PatternAssets(rest_xy=uv, triangles=F, panel_vertex_start=np.array([0, len(uv)]),
                                  panel_names=["sphere"], panel_grain_rad=np.zeros(1),
                                  seam_pairs=np.zeros((0, 2), np.int64), handles=np.arange(0, len(uv), 64)),
            material=MaterialAssets(bending_stiffness=1e-6, panel_bending_stiffness=np.zeros(0),
                                    compliance_warp=1e-3, compliance_weft=1e-3, compliance_shear=2e-3,
                                    density=0.2, thickness=0.002),
            body=BodyAssets(model_id="none", shape=np.zeros(0), joint_names=[], pose=np.zeros((0, 3)),
                            bone_scales=np.zeros(0), global_transform=np.zeros(6)),
            garment_vertices=V, garment_faces=F, garment_uv=uv,
            body_vertices=scan.vertices[~scan.garment_mask] if (~scan.garment_mask).any() else np.zeros((0, 3)),
            body_faces=np.zeros((0, 3), np.int64),
            metrics={"chamfer_initial_cm": 100 * np.sqrt(d0), "chamfer_final_cm": 100 * np.sqrt(history[-1]["value"]) if history else float("nan"),
                     "mesh_quality_min": q.min, "mesh_quality_avg": q.mean, "seam_length_mismatch_max_pct": 0.0,
                     "radius_m": r},
            iterations=n, wall_s=time.monotonic() - t0, loss_history=history)
