"""Minimal binary glTF 2.0 (.glb) writer for animated triangle meshes, numpy + struct only.

Each mesh is stored once with its frame-0 positions and one morph target per later frame
(POSITION displacement X_t − X_0, float32); a `weights` animation sampled at t/fps with LINEAR
interpolation sets weight 1 on target t−1 at frame t (all zero at frame 0), so a viewer plays
the positions of every frame exactly and blends linearly between frames. Units: m, s.
Spec: https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html (GLB container, accessors,
morph targets, animations)."""
from __future__ import annotations

import json
import pathlib
import struct
from dataclasses import dataclass

import numpy as np

_FLOAT, _UINT32 = 5126, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


@dataclass
class AnimatedMesh:
    """frames: T×#V×3 positions (m); faces: #F×3 vertex indices; colour: RGB in [0, 1];
    uv: optional #V×2 texture coordinates (OBJ convention, v up; flipped to glTF's v down)."""
    name: str
    frames: np.ndarray
    faces: np.ndarray
    colour: tuple = (0.8, 0.8, 0.8)
    uv: np.ndarray | None = None


class _Builder:
    def __init__(self):
        self.bin = bytearray()
        self.views, self.accessors = [], []

    def add(self, arr: np.ndarray, type_: str, component: int, target: int | None = None,
            minmax: bool = False) -> int:
        while len(self.bin) % 4:
            self.bin.append(0)
        data = np.ascontiguousarray(arr).tobytes()
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.bin += data
        self.views.append(view)
        ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[type_]
        acc = {"bufferView": len(self.views) - 1, "componentType": component,
               "count": int(arr.size // ncomp), "type": type_}
        if minmax:
            flat = np.asarray(arr).reshape(-1, ncomp)
            acc["min"] = [float(x) for x in flat.min(axis=0)]
            acc["max"] = [float(x) for x in flat.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def write_glb(path, meshes: list[AnimatedMesh], fps: float) -> pathlib.Path:
    """Writes the animated meshes (all with the same frame count T) to `path` (.glb); `fps`
    frames per second sets the keyframe times t/fps (s)."""
    if not meshes:
        raise ValueError("meshes: is empty")
    T = meshes[0].frames.shape[0]
    if T < 1:
        raise ValueError("frames: no frames")
    for m in meshes:
        if m.frames.ndim != 3 or m.frames.shape[0] != T or m.frames.shape[2] != 3:
            raise ValueError(f"{m.name}.frames: expected shape ({T}, V, 3), got {m.frames.shape}")
    if not fps > 0:
        raise ValueError(f"fps: expected > 0, got {fps}")
    b = _Builder()
    gl_meshes, nodes, materials, samplers, channels = [], [], [], [], []
    times_acc = b.add(np.arange(T, dtype=np.float32) / np.float32(fps), "SCALAR", _FLOAT, minmax=True) if T > 1 else None
    weights = np.zeros((T, T - 1), np.float32)
    weights[np.arange(1, T), np.arange(T - 1)] = 1.0
    for k, m in enumerate(meshes):
        X = np.asarray(m.frames, dtype=np.float64)
        X0 = X[0].astype(np.float32)
        attrs = {"POSITION": b.add(X0, "VEC3", _FLOAT, _ARRAY_BUFFER, minmax=True)}
        if m.uv is not None:
            uv = np.asarray(m.uv, dtype=np.float32).copy()
            uv[:, 1] = 1.0 - uv[:, 1]
            attrs["TEXCOORD_0"] = b.add(uv, "VEC2", _FLOAT, _ARRAY_BUFFER)
        idx = b.add(np.asarray(m.faces, dtype=np.uint32).reshape(-1), "SCALAR", _UINT32, _ELEMENT_ARRAY_BUFFER,
                    minmax=True)
        targets = [{"POSITION": b.add((X[t] - X[0]).astype(np.float32), "VEC3", _FLOAT, _ARRAY_BUFFER, minmax=True)}
                   for t in range(1, T)]
        materials.append({"name": f"{m.name}_material", "doubleSided": True,
                          "pbrMetallicRoughness": {"baseColorFactor": [*map(float, m.colour), 1.0],
                                                   "metallicFactor": 0.0, "roughnessFactor": 0.9}})
        prim = {"attributes": attrs, "indices": idx, "material": k, "mode": 4}
        mesh = {"name": m.name, "primitives": [prim]}
        if targets:
            prim["targets"] = targets
            mesh["weights"] = [0.0] * (T - 1)
            mesh["extras"] = {"targetNames": [f"frame_{t:04d}" for t in range(1, T)]}
            samplers.append({"input": times_acc, "interpolation": "LINEAR",
                             "output": b.add(weights, "SCALAR", _FLOAT)})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": k, "path": "weights"}})
        gl_meshes.append(mesh)
        nodes.append({"name": m.name, "mesh": k})
    while len(b.bin) % 4:
        b.bin.append(0)
    doc = {"asset": {"version": "2.0", "generator": "diffavatar_core.gltf"},
           "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes, "meshes": gl_meshes,
           "materials": materials, "accessors": b.accessors, "bufferViews": b.views,
           "buffers": [{"byteLength": len(b.bin)}]}
    if channels:
        doc["animations"] = [{"name": "simulation", "samplers": samplers, "channels": channels}]
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * ((-len(js)) % 4)
    total = 12 + 8 + len(js) + 8 + len(b.bin)
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        fh.write(struct.pack("<III", _GLB_MAGIC, 2, total))
        fh.write(struct.pack("<II", len(js), _JSON_CHUNK))
        fh.write(js)
        fh.write(struct.pack("<II", len(b.bin), _BIN_CHUNK))
        fh.write(bytes(b.bin))
    return path


def read_glb(path) -> tuple[dict, bytes]:
    """The (JSON document, BIN chunk) of a .glb file."""
    data = pathlib.Path(path).read_bytes()
    magic, version, total = struct.unpack_from("<III", data, 0)
    if magic != _GLB_MAGIC or version != 2 or total != len(data):
        raise ValueError(f"path: {path} is not a glTF 2.0 binary (magic/version/length mismatch)")
    jlen, jtype = struct.unpack_from("<II", data, 12)
    if jtype != _JSON_CHUNK:
        raise ValueError(f"path: first chunk of {path} is not JSON")
    doc = json.loads(data[20:20 + jlen])
    off = 20 + jlen
    blen, btype = struct.unpack_from("<II", data, off)
    if btype != _BIN_CHUNK:
        raise ValueError(f"path: second chunk of {path} is not BIN")
    return doc, data[off + 8:off + 8 + blen]


def accessor_array(doc: dict, bin_chunk: bytes, index: int) -> np.ndarray:
    """The data of accessor `index` (tightly packed float32/uint32 views) as a numpy array
    shaped (count,) or (count, components)."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    dtype = {_FLOAT: np.float32, _UINT32: np.uint32}[acc["componentType"]]
    ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    a = np.frombuffer(bin_chunk, dtype=dtype, count=acc["count"] * ncomp, offset=start)
    return a if ncomp == 1 else a.reshape(acc["count"], ncomp)
