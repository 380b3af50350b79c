"""A character's skinned mesh and animation from its glTF (``.gltf``, ``.glb``).

The mesh is every triangle primitive of the nodes skinned by one skin (the skin the
animation drives most, as :func:`loosefit.motion.gltf.read_gltf` picks it), joined; each
frame is posed by the glTF's own linear blend skinning (the joints' world transforms
times their inverse bind matrices, blended by ``JOINTS_n``/``WEIGHTS_n``), sampled at
the times :func:`~loosefit.motion.gltf.read_gltf` samples the animation at, so frame t of
the character is frame t of the motion read from the same file. Positions are in the
glTF's world: metres, +Y up.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.motion.gltf import _node_parents, _skin_joints, _world_transforms
from loosefit.motion.gltf_animation import animation_channels, frame_times
from loosefit.motion.gltf_file import (
    GltfDocument,
    doc_item,
    doc_list,
    gltf_error,
    read_accessor,
    read_document,
)

TRIANGLES = 4  # a primitive's mode


@dataclass
class Character:
    """A skinned, animated mesh.

    Attributes:
        path: the file.
        faces: (F, 3) int64 triangles.
        bind: (V, 3) float64 vertices in the bind pose (the skin's space), metres.
        joints: (V, K) int64 each vertex's joints (indices into the skin's joints).
        weights: (V, K) float64 their weights, each row summing to 1.
        skin_matrices: (T, J, 4, 4) each joint's world transform times its inverse bind
            matrix, at each frame: what carries a bind-pose vertex to the frame.
        times: (T,) seconds of the file's timeline, the frames'.
        joint_names: J names of the skin's joints.
        inverse_bind: (J, 4, 4) the skin's inverse bind matrices.
        skin: the skin's index; ``animation`` the animation's; ``meshes`` the mesh
            indices joined.
    """

    path: Path
    faces: np.ndarray
    bind: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    skin_matrices: np.ndarray
    times: np.ndarray
    joint_names: tuple[str, ...]
    inverse_bind: np.ndarray
    skin: int
    animation: int
    meshes: tuple[int, ...]

    @property
    def num_frames(self) -> int:
        return int(self.skin_matrices.shape[0])

    @property
    def num_vertices(self) -> int:
        return int(self.bind.shape[0])

    def posed(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """(n, V, 3) float64 vertices of frames ``start`` to ``stop`` (glTF world, Y up)."""
        M = self.skin_matrices[start:stop]  # (n, J, 4, 4)
        out = np.zeros((len(M), self.num_vertices, 3))
        for k in range(self.joints.shape[1]):
            w = self.weights[:, k]
            used = w > 0
            if not used.any():
                continue
            Mk = M[:, self.joints[used, k]]  # (n, U, 4, 4)
            p = np.einsum("nuij,uj->nui", Mk[..., :3, :3], self.bind[used]) + Mk[..., :3, 3]
            out[:, used] += w[used, None] * p
        return out

    def joint_world(self, name: str) -> np.ndarray:
        """(T, 3) the world position of the skin joint ``name`` (its bind position moved)."""
        j = self.joint_names.index(name)
        bind = np.linalg.inv(self.inverse_bind[j])
        return self.skin_matrices[:, j, :3, :3] @ bind[:3, 3] + self.skin_matrices[:, j, :3, 3]


def has_skinned_mesh(path: str | Path) -> bool:
    """Whether a ``.gltf``/``.glb`` file holds a mesh on a skin (a character), not only a
    skeleton's animation. False for other files."""
    path = Path(path)
    if path.suffix.lower() not in (".gltf", ".glb") or not path.is_file():
        return False
    doc = read_document(path)
    return any(
        isinstance(n, dict) and n.get("mesh") is not None and n.get("skin") is not None
        for n in doc.gltf.get("nodes", [])
    )


def read_character(path: str | Path, fps: float, animation: str | int | None = None) -> Character:
    """The character of a glTF file: its skinned mesh and its animation at ``fps``.

    Args:
        path: the ``.gltf`` or ``.glb`` file.
        fps: the rate its animation is sampled at (the model's).
        animation: the animation's name or index (default: the first).

    Raises:
        LoosefitInputError: naming the file and the field: no mesh, no mesh on a skin, no
            animation, a primitive that is not triangles or has no skin weights.
    """
    path = Path(path)
    doc = read_document(path)
    nodes = doc_list(doc, "nodes")
    if not doc_list(doc, "meshes"):
        raise gltf_error(
            doc,
            "meshes",
            "a mesh (the character's body)",
            "none in the file",
            hint="a file of a skeleton alone is a motion: loosefit animate reads it on anny",
        )
    skinned = [
        (i, n) for i, n in enumerate(nodes) if isinstance(n, dict) and n.get("mesh") is not None
    ]
    skinned = [(i, n) for i, n in skinned if n.get("skin") is not None]
    if not skinned:
        raise gltf_error(
            doc,
            "nodes[*].skin",
            "a mesh node with a skin (the character's body bound to its skeleton)",
            "meshes, none of them skinned",
            hint="export the mesh with its armature (Blender: glTF export > Skinning)",
        )
    a, _, channels = animation_channels(doc, animation, len(nodes))
    driven = {n for n, _ in channels}
    skins = sorted({int(n["skin"]) for _, n in skinned})
    k = max(skins, key=lambda s: (len(driven & set(_skin_joints(doc, s, nodes))), -s))
    joint_nodes = _skin_joints(doc, k, nodes)
    meshes = tuple(sorted({int(n["mesh"]) for _, n in skinned if int(n["skin"]) == k}))
    faces, bind, joints, weights = _join_primitives(doc, meshes)
    frames = frame_times(doc, a, channels, fps)
    parent = _node_parents(doc, nodes)
    world, _ = _world_transforms(doc, nodes, parent, joint_nodes, channels, frames.at)
    skin_def = doc.gltf["skins"][k]
    if skin_def.get("inverseBindMatrices") is not None:
        ibm = read_accessor(doc, skin_def["inverseBindMatrices"], f"skins[{k}].inverseBindMatrices")
        inverse_bind = np.swapaxes(ibm.reshape(-1, 4, 4), -1, -2).astype(np.float64)
    else:
        inverse_bind = np.tile(np.eye(4), (len(joint_nodes), 1, 1))
    if inverse_bind.shape[0] != len(joint_nodes):
        raise gltf_error(
            doc,
            f"skins[{k}].inverseBindMatrices",
            f"{len(joint_nodes)} MAT4 (one per joint)",
            inverse_bind.shape[0],
        )
    if joints.max() >= len(joint_nodes):
        raise gltf_error(
            doc,
            f"meshes[{meshes[0]}].primitives[*].attributes.JOINTS_0",
            f"joint indices below {len(joint_nodes)} (skin {k}'s joints)",
            int(joints.max()),
        )
    M = np.stack([world[n] for n in joint_nodes], 1) @ inverse_bind[None]  # (T, J, 4, 4)
    names = tuple(str(nodes[n].get("name", f"node{n}")) for n in joint_nodes)
    return Character(
        path, faces, bind, joints, weights, M, frames.at, names, inverse_bind, k, a, meshes
    )


def _join_primitives(doc: GltfDocument, meshes: tuple[int, ...]):
    """Faces, bind positions, joints and weights of every triangle primitive of ``meshes``."""
    faces, positions, joints, weights = [], [], [], []
    count = 0
    for m in meshes:
        mesh = doc_item(doc, "meshes", m, f"meshes[{m}]")
        for p, prim in enumerate(mesh.get("primitives", [])):
            where = f"meshes[{m}].primitives[{p}]"
            if prim.get("mode", TRIANGLES) != TRIANGLES:
                raise gltf_error(doc, f"{where}.mode", "4 (triangles)", prim.get("mode"))
            att = prim.get("attributes", {})
            for need in ("POSITION", "JOINTS_0", "WEIGHTS_0"):
                if att.get(need) is None:
                    raise gltf_error(doc, f"{where}.attributes.{need}", "an accessor", "none")
            pos = read_accessor(doc, att["POSITION"], f"{where}.attributes.POSITION")
            sets = [s for s in range(8) if att.get(f"JOINTS_{s}") is not None]
            j = np.concatenate(
                [read_accessor(doc, att[f"JOINTS_{s}"], f"{where}.JOINTS_{s}") for s in sets], 1
            )
            w = np.concatenate(
                [
                    read_accessor(doc, att[f"WEIGHTS_{s}"], f"{where}.WEIGHTS_{s}")
                    for s in sets
                    if att.get(f"WEIGHTS_{s}") is not None
                ],
                1,
            )
            if prim.get("indices") is not None:
                idx = read_accessor(doc, prim["indices"], f"{where}.indices").astype(np.int64)
            else:
                idx = np.arange(len(pos), dtype=np.int64)
            if len(idx) % 3 or (len(idx) and (idx.min() < 0 or idx.max() >= len(pos))):
                raise gltf_error(
                    doc, f"{where}.indices", f"triangles of vertices below {len(pos)}", len(idx)
                )
            if w.shape != j.shape or len(w) != len(pos):
                raise gltf_error(
                    doc, f"{where}.attributes.WEIGHTS_0", f"{j.shape} weights", w.shape
                )
            faces.append(idx.reshape(-1, 3) + count)
            positions.append(pos.astype(np.float64))
            joints.append(j.astype(np.int64))
            weights.append(w.astype(np.float64))
            count += len(pos)
    width = max(j.shape[1] for j in joints)
    joints = [np.pad(j, ((0, 0), (0, width - j.shape[1]))) for j in joints]
    weights = [np.pad(w, ((0, 0), (0, width - w.shape[1]))) for w in weights]
    w = np.concatenate(weights)
    total = w.sum(1, keepdims=True)
    if (total <= 0).any():
        raise gltf_error(
            doc, f"meshes[{meshes[0]}].attributes.WEIGHTS_0", "weights summing to 1", "zeros"
        )
    return np.concatenate(faces), np.concatenate(positions), np.concatenate(joints), w / total
