"""glTF files written from a BVH clip, as Blender or a game engine would export them.

:func:`write_gltf` writes a clip's skeleton as glTF nodes under an ``Armature`` node
(turned and scaled by 0.01, as a Mixamo rig imported into Blender is, so the joints'
numbers are centimetres), each joint with its own bone frame (a fixed rotation, as
Blender's bones point along their local +Y), a skin with inverse bind matrices at the
clip's rest pose, End Sites as leaf ``_end`` nodes, and an animation with a rotation
sampler per joint and a translation sampler on the root (and on any joint that moves
in its parent, such as hips below a still root joint). The world the file shows is
the clip's, so reading it back must give the clip's motion again.
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from loosefit.motion.skeleton_clip import BvhClip, forward_kinematics, rest_positions


class _Buffer:
    """A binary buffer with its bufferViews and accessors."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, kind: str, ctype: int = 5126, normalized=False) -> int:
        dtype = {5126: np.float32, 5122: np.int16, 5123: np.uint16, 5125: np.uint32}[ctype]
        a = np.ascontiguousarray(array, dtype=dtype)
        while len(self.data) % 4:
            self.data.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": a.nbytes})
        self.data += a.tobytes()
        acc = {
            "bufferView": len(self.views) - 1,
            "componentType": ctype,
            "count": len(a),
            "type": kind,
        }
        if normalized:
            acc["normalized"] = True
        if kind == "SCALAR":
            acc["min"], acc["max"] = [float(a.min())], [float(a.max())]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 4) quaternions (x, y, z, w), glTF's order."""
    return Rotation.from_matrix(m.reshape(-1, 3, 3)).as_quat().reshape(*m.shape[:-2], 4)


def write_gltf(
    path: Path,
    clip: BvhClip,
    *,
    bone_frames: bool = True,
    armature_scale: float = 0.01,
    node_rest: str = "bind",
    inverse_bind: bool = True,
    quantize: bool = False,
    idle_first: bool = False,
    prop_skin: bool = False,
    seed: int = 0,
    mesh: dict | None = None,
) -> Path:
    """Write ``clip`` as a glTF (``.gltf``, buffer embedded) or GLB (``.glb``) file.

    Args:
        path: the file; its suffix picks the container.
        clip: the skeleton and motion (Y up, facing +Z, metres).
        bone_frames: give each joint a random fixed bone frame (else world-aligned).
        armature_scale: the Armature node's scale (joint numbers divided by it).
        node_rest: the nodes' own transforms: ``"bind"`` (the rest pose) or
            ``"frame0"`` (the first frame: only the inverse bind matrices give the rest).
        inverse_bind: write the skin's inverseBindMatrices.
        quantize: rotations as normalized int16 (glTF allows it) instead of floats.
        idle_first: put a short second animation, "idle", before "dance".
        prop_skin: add a first skin with a single static prop joint.
        seed: seeds the bone frames.
        mesh: a skinned mesh on the skin: ``positions`` (V, 3) in the bind pose (glTF's
            world at the clip's rest, metres), ``faces`` (F, 3), ``joints`` (V, 4) indices
            into the clip's joints, ``weights`` (V, 4); a node with it and the skin.
    """
    rng = np.random.default_rng(seed)
    T, J = clip.num_frames, clip.num_joints
    P, G = (a.astype(np.float64) for a in forward_kinematics(clip))  # (T, J, 3), (T, J, 3, 3)
    rest = rest_positions(clip).astype(np.float64)  # (J, 3)
    # The joints: the clip's, then one leaf per End Site (world rotation its parent's).
    names = list(clip.joint_names)
    parents = list(clip.parents)
    for j, off in clip.end_offsets.items():
        names.append(f"{clip.joint_names[j]}_end")
        parents.append(j)
        G = np.concatenate([G, G[:, j : j + 1]], 1)
        P = np.concatenate([P, (P[:, j] + (G[:, j] @ off))[:, None]], 1)
        rest = np.vstack([rest, rest[j] + off])
    Jn = len(names)
    K = np.tile(np.eye(3), (Jn, 1, 1))  # (Jn, 3, 3) each joint's bone frame at rest
    if bone_frames:
        K = Rotation.random(Jn, random_state=rng).as_matrix()
    A = Rotation.from_euler("x", 90, degrees=True).as_matrix()  # the Armature's turn
    s = armature_scale
    W = G @ K[None]  # (T, Jn, 3, 3) glTF world rotations

    def locals_(Wt: np.ndarray, Pt: np.ndarray):
        """World rotations (Jn, 3, 3), positions (Jn, 3) -> local rotations, translations."""
        rot, tr = np.empty_like(Wt), np.empty_like(Pt)
        for j, p in enumerate(parents):
            pw, pp = (A, np.zeros(3)) if p < 0 else (Wt[p], Pt[p])
            rot[j] = pw.T @ Wt[j]
            tr[j] = pw.T @ (Pt[j] - pp) / s
        return rot, tr

    frames = [locals_(W[t], P[t]) for t in range(T)]
    rot_t = np.stack([f[0] for f in frames])  # (T, Jn, 3, 3)
    tr_t = np.stack([f[1] for f in frames])  # (T, Jn, 3)
    bind_rot, bind_tr = locals_(K, rest)
    node_rot, node_tr = (bind_rot, bind_tr) if node_rest == "bind" else (rot_t[0], tr_t[0])

    buf = _Buffer()
    nodes = []
    for j in range(Jn):
        kids = [c for c in range(Jn) if parents[c] == j]
        node = {
            "name": names[j],
            "translation": node_tr[j].tolist(),
            "rotation": _quat(node_rot[j]).tolist(),
        }
        if kids:
            node["children"] = kids
        nodes.append(node)
    roots = [j for j in range(Jn) if parents[j] < 0]
    armature = len(nodes)
    nodes.append(
        {"name": "Armature", "children": roots, "rotation": _quat(A).tolist(), "scale": [s, s, s]}
    )
    scene_nodes = [armature]
    skin = {"name": "body", "joints": list(range(Jn)), "skeleton": roots[0]}
    if inverse_bind:
        bind = np.zeros((Jn, 4, 4))
        bind[:, :3, :3] = s * K
        bind[:, :3, 3] = rest
        bind[:, 3, 3] = 1
        ibm = np.linalg.inv(bind)
        skin["inverseBindMatrices"] = buf.add(np.swapaxes(ibm, -1, -2).reshape(Jn, 16), "MAT4")
    skins = [skin]
    meshes = []
    if mesh is not None:
        attributes = {
            "POSITION": buf.add(mesh["positions"], "VEC3"),
            "JOINTS_0": buf.add(mesh["joints"], "VEC4", 5123),
            "WEIGHTS_0": buf.add(mesh["weights"], "VEC4"),
        }
        lo, hi = np.min(mesh["positions"], 0), np.max(mesh["positions"], 0)
        buf.accessors[attributes["POSITION"]].update(min=lo.tolist(), max=hi.tolist())
        indices = buf.add(np.asarray(mesh["faces"]).ravel(), "SCALAR", 5125)
        meshes.append(
            {
                "name": "character",
                "primitives": [{"attributes": attributes, "indices": indices, "mode": 4}],
            }
        )
        nodes.append({"name": "character", "mesh": 0, "skin": 0})
        scene_nodes.append(len(nodes) - 1)
    if prop_skin:
        nodes.append({"name": "Prop", "translation": [0.5, 0, 0]})
        scene_nodes.append(len(nodes) - 1)
        skins.insert(0, {"name": "prop", "joints": [len(nodes) - 1]})

    times = buf.add((np.arange(T) / clip.fps).astype(np.float32), "SCALAR")
    samplers, channels = [], []
    for j in range(Jn):
        if j >= J:
            continue  # End Site leaves: still
        q = _quat(rot_t[:, j])
        q *= np.where(q[:, 3:] < 0, -1, 1)  # a continuous sign: slerp takes the short way
        out = (
            buf.add(np.round(q * 32767), "VEC4", 5122, normalized=True)
            if quantize
            else buf.add(q, "VEC4")
        )
        samplers.append({"input": times, "output": out, "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "rotation"}})
        if parents[j] < 0 or np.ptp(tr_t[:, j], axis=0).max() > 1e-9:  # a root, or moving
            samplers.append({"input": times, "output": buf.add(tr_t[:, j], "VEC3")})
            channels.append(
                {"sampler": len(samplers) - 1, "target": {"node": j, "path": "translation"}}
            )
    animations = [{"name": "dance", "channels": channels, "samplers": samplers}]
    if idle_first:
        two = buf.add(np.array([0.0, 1.0], np.float32), "SCALAR")
        still = buf.add(np.stack([_quat(bind_rot[0])] * 2), "VEC4")
        channel = {"sampler": 0, "target": {"node": 0, "path": "rotation"}}
        animations.insert(
            0,
            {"name": "idle", "samplers": [{"input": two, "output": still}], "channels": [channel]},
        )
    doc = {
        "asset": {"version": "2.0", "generator": "loosefit tests"},
        "scene": 0,
        "scenes": [{"nodes": scene_nodes}],
        "nodes": nodes,
        "skins": skins,
        "animations": animations,
        **({"meshes": meshes} if meshes else {}),
        "accessors": buf.accessors,
        "bufferViews": buf.views,
        "buffers": [{"byteLength": len(buf.data)}],
    }
    return write_document(path, doc, bytes(buf.data))


def write_document(path: Path, doc: dict, data: bytes) -> Path:
    """Write a glTF JSON document and its one buffer as ``.glb`` or ``.gltf`` (embedded)."""
    path = Path(path)
    if path.suffix.lower() == ".glb":
        text = json.dumps(doc).encode()
        text += b" " * (-len(text) % 4)
        data += b"\0" * (-len(data) % 4)
        chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
        chunks += struct.pack("<II", len(data), 0x004E4942) + data
        path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)
    else:
        doc = dict(doc)
        uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
        doc["buffers"] = [{"byteLength": len(data), "uri": uri}]
        path.write_text(json.dumps(doc))
    return path
