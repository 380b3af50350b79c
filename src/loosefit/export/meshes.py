"""What the exporters write: animated meshes, a body's rig, and the export's options."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from loosefit.errors import LoosefitInputError

# loosefit's Z up to Y up (x, y, z) -> (x, z, -y): glTF's axes, and Alembic's by default.
Z_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass
class ExportConfig:
    """How animated meshes are written (every field has a default for every format). The
    format's own up axis: Z for USD; Y for Alembic, PC2 and OBJ; glTF is always Y."""

    up_axis: str | None = None  # "Z" or "Y"; None: the format's own (USD Z; the others Y)
    skinned_body: bool = True  # a body with a rig as a skinned mesh (USD, glTF), else points
    skin_tolerance: float = 1e-5  # metres: a rig farther than this from the body -> points

    def __post_init__(self) -> None:
        if self.up_axis is not None and self.up_axis.upper() not in ("Y", "Z"):
            raise LoosefitInputError("ExportConfig", "up_axis", "'Y', 'Z' or None", self.up_axis)
        self.up_axis = None if self.up_axis is None else self.up_axis.upper()


def in_up_axis(vertices: np.ndarray, up_axis: str) -> np.ndarray:
    """(..., 3) positions in loosefit's axes (Z up) written in ``up_axis``: "Z", as they
    are; "Y", turned by :data:`Z_TO_Y_UP`, (x, y, z) -> (x, z, -y), exactly (no rounding)."""
    if up_axis == "Z":
        return vertices
    return np.stack([vertices[..., 0], vertices[..., 2], -vertices[..., 1]], axis=-1)


@dataclass
class Skin:
    """A linear-blend-skinned mesh's rig: the mesh at rest, its joints and their motion.

    ``vertices[t] = sum_k weights[:, k] * S[t, indices[:, k]] @ rest_vertices`` with the
    skinning transforms ``S[t, j] = joint_poses[t, j] @ inv(bind_poses[j])``.

    Attributes:
        joint_names: J joint names, every parent before its children.
        parents: (J,) int parent index, -1 for the root.
        rest_vertices: (Vb, 3) the mesh at the bind pose, metres.
        bind_poses: (J, 4, 4) each joint's world pose at the bind pose (rigid).
        weights: (Vb, K) float skinning weights, rows summing to 1, and
            ``indices`` (Vb, K) int their joints.
        joint_poses: (T, J, 4, 4) each joint's world pose in every frame (rigid).
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    rest_vertices: np.ndarray
    bind_poses: np.ndarray
    weights: np.ndarray
    indices: np.ndarray
    joint_poses: np.ndarray

    def __post_init__(self) -> None:
        J, Vb = len(self.joint_names), len(self.rest_vertices)
        self.parents = np.asarray(self.parents, np.int64)
        self.rest_vertices = np.asarray(self.rest_vertices, np.float64)
        self.bind_poses = np.asarray(self.bind_poses, np.float64)
        self.weights = np.asarray(self.weights, np.float64)
        self.indices = np.asarray(self.indices, np.int64)
        self.joint_poses = np.asarray(self.joint_poses, np.float64)
        shapes = {
            "parents": (self.parents, (J,)),
            "bind_poses": (self.bind_poses, (J, 4, 4)),
            "weights": (self.weights, (Vb, self.weights.shape[-1])),
            "indices": (self.indices, self.weights.shape),
            "joint_poses": (self.joint_poses, (len(self.joint_poses), J, 4, 4)),
        }
        for name, (a, want) in shapes.items():
            if a.shape != want:
                raise LoosefitInputError("Skin", name, f"shape {want}", f"{a.shape}")
        if any(p >= j for j, p in enumerate(self.parents)):
            raise LoosefitInputError("Skin", "parents", "every parent before its child", "not")

    @property
    def num_frames(self) -> int:
        return int(self.joint_poses.shape[0])

    def transformed(self, rotation: np.ndarray) -> Skin:
        """The same rig with the world rotated by ``rotation`` (3, 3) (an axis change)."""
        A = np.eye(4)
        A[:3, :3] = rotation
        return Skin(
            self.joint_names,
            self.parents,
            self.rest_vertices @ np.asarray(rotation).T,
            A @ self.bind_poses,
            self.weights,
            self.indices,
            A @ self.joint_poses,
        )

    def local_poses(self) -> np.ndarray:
        """(T, J, 4, 4) each joint's pose in its parent's frame (the root's in the world)."""
        P = self.joint_poses
        parent = np.where(self.parents[None, :, None, None] >= 0, P[:, self.parents], np.eye(4))
        return np.linalg.inv(parent) @ P

    def local_bind_poses(self) -> np.ndarray:
        """(J, 4, 4) each joint's bind pose in its parent's frame."""
        B = self.bind_poses
        parent = np.where(self.parents[:, None, None] >= 0, B[self.parents], np.eye(4))
        return np.linalg.inv(parent) @ B

    def skinned(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """(T', Vb, 3) float64 the skinned mesh for frames ``start:stop`` (linear blend)."""
        S = self.joint_poses[start:stop, :, :3] @ np.linalg.inv(self.bind_poses)  # (T', J, 3, 4)
        dense = np.zeros((len(self.rest_vertices), len(self.joint_names)))  # (Vb, J)
        np.add.at(dense, (np.arange(len(dense))[:, None], self.indices), self.weights)
        n = len(S)
        blended = dense @ S.reshape(n, -1, 12).transpose(1, 0, 2).reshape(-1, n * 12)  # (Vb, T'12)
        blended = blended.reshape(-1, n, 3, 4).transpose(1, 0, 2, 3)  # (T', Vb, 3, 4)
        r = self.rest_vertices
        return sum(blended[..., i] * r[:, i, None] for i in range(3)) + blended[..., 3]

    def error(self, vertices: np.ndarray, chunk: int = 32) -> float:
        """The largest distance (metres) between the skinned mesh and ``vertices`` (T, Vb, 3)."""
        worst = 0.0
        for s in range(0, len(vertices), chunk):
            d = np.linalg.norm(self.skinned(s, s + chunk) - vertices[s : s + chunk], axis=-1)
            worst = max(worst, float(d.max()))
        return worst


@dataclass
class AnimatedMesh:
    """A triangle mesh whose vertices move.

    Attributes:
        name: a label (a USD prim name and a file-name part: letters, digits, ``_``).
        faces: (F, 3) int vertex indices, counter-clockwise seen from outside.
        vertices: (T, V, 3) float32 positions, metres, Z up.
        uvs: (U, 2) UV coordinates and ``face_uvs`` (F, 3) indices into them, or None.
        normals: write per-vertex normals (Alembic) where the format has them.
        skin: the rig that moves it (a body), or None: a point cache in every format.
    """

    name: str
    faces: np.ndarray
    vertices: np.ndarray
    uvs: np.ndarray | None = None
    face_uvs: np.ndarray | None = None
    normals: bool = False
    skin: Skin | None = None

    def __post_init__(self) -> None:
        src = f"mesh '{self.name}'"
        if not self.name.replace("_", "").isalnum() or self.name[0].isdigit():
            raise LoosefitInputError(
                src, "name", "letters, digits and _ (not first a digit)", repr(self.name)
            )
        v = np.asarray(self.vertices, np.float32)
        if v.ndim != 3 or v.shape[-1] != 3 or len(v) == 0:
            raise LoosefitInputError(src, "vertices", "shape (T >= 1, V, 3)", f"{v.shape}")
        if not np.isfinite(v).all():
            t = int(np.argwhere(~np.isfinite(v))[0][0])
            raise LoosefitInputError(src, "vertices", "finite values", f"NaN/inf in frame {t}")
        f = np.asarray(self.faces, np.int64)
        if f.ndim != 2 or f.shape[1] != 3 or (len(f) and (f.min() < 0 or f.max() >= v.shape[1])):
            raise LoosefitInputError(
                src, "faces", f"(F, 3) indices in [0, {v.shape[1]})", f"shape {f.shape}"
            )
        if (self.uvs is None) != (self.face_uvs is None):
            raise LoosefitInputError(src, "uvs, face_uvs", "both or neither", "only one")
        if self.uvs is not None:
            self.uvs = np.asarray(self.uvs, np.float32)
            self.face_uvs = np.asarray(self.face_uvs, np.int64)
            if self.face_uvs.shape != f.shape or self.face_uvs.max() >= len(self.uvs):
                want = f"shape {f.shape}, indices < {len(self.uvs)}"
                raise LoosefitInputError(src, "face_uvs", want, f"shape {self.face_uvs.shape}")
        if self.skin is not None:
            want = (v.shape[0], v.shape[1])
            found = (self.skin.num_frames, len(self.skin.rest_vertices))
            if found != want:
                raise LoosefitInputError(src, "skin", f"(frames, vertices) {want}", f"{found}")
        self.vertices, self.faces = v, f

    @property
    def num_frames(self) -> int:
        return int(self.vertices.shape[0])


def skin_to_write(mesh: AnimatedMesh, config: ExportConfig, where) -> Skin | None:
    """``mesh``'s rig if it is to be written skinned, else None (a point cache), saying why
    when a mesh that should have been skinned is not."""
    if not config.skinned_body:
        return None
    if mesh.skin is None:
        if mesh.name == "body":
            warnings.warn(
                f"{where}: the body has no rig (a mesh sequence without joints and "
                "skinning weights): written as a point cache",
                stacklevel=3,
            )
        return None
    err = mesh.skin.error(mesh.vertices)
    if err > config.skin_tolerance:
        warnings.warn(
            f"{where}: the rig of '{mesh.name}' reproduces it to {err * 1e3:.3f} mm, more than "
            f"the {config.skin_tolerance * 1e3:g} mm allowed: written as a point cache",
            stacklevel=3,
        )
        return None
    return mesh.skin


def check_meshes(meshes: list[AnimatedMesh], fps: float, where) -> int:
    """The frame count shared by ``meshes``; raises on none, unequal lengths, a bad fps."""
    if not meshes:
        raise LoosefitInputError(where, "meshes", "at least one animated mesh", "none")
    T = meshes[0].num_frames
    if any(m.num_frames != T for m in meshes):
        raise LoosefitInputError(
            where, "meshes", f"{T} frames each", str([m.num_frames for m in meshes])
        )
    if len({m.name for m in meshes}) != len(meshes):
        raise LoosefitInputError(where, "meshes", "distinct names", [m.name for m in meshes])
    if not (np.isfinite(fps) and fps > 0):
        raise LoosefitInputError(where, "fps", "a positive frame rate", fps)
    return T


def vertex_normals_np(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) float32 unit area-weighted vertex normals of one frame (V, 3)."""
    v = vertices.astype(np.float64)
    fn = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])  # (F, 3)
    out = np.zeros_like(v)
    for i in range(3):
        np.add.at(out, faces[:, i], fn)
    return (out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)).astype(np.float32)
