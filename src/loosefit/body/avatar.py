"""The avatar: NAVER's ``anny`` body model, posed by a :class:`~loosefit.types.Motion`.

anny (Apache-2.0 code, CC0 MakeHuman assets) is used with its ``cmu_mb`` rig, a
31-joint skeleton with the CMU MotionBuilder joint names, so motion capture can
drive it by name. Conventions (see :mod:`loosefit.types`): metres, Z up, the
avatar faces -Y at its reference pose (anny's A-pose); a root translation of
``(0, 0, avatar.floor_height)`` with identity rotations stands it on z = 0.

Pose parameterisation: a motion's local rotations are anny's ``local-ref``
deltas, which are exactly SMPL-style local rotations relative to the rest pose
(``G_j = G_parent @ R_j`` with ``G`` the world rotation from rest to posed).

The first construction of an anny model builds and caches its data (about two
minutes and 0.8 GB under ``~/.cache/anny``, or ``$ANNY_CACHE_DIR``); later ones
take well under a second.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch

from loosefit.errors import LoosefitInputError
from loosefit.geometry.cap import cut_and_cap
from loosefit.geometry.normals import vertex_normals
from loosefit.geometry.query import closest_points
from loosefit.geometry.skinning import rigid_point_frames
from loosefit.types import Motion

# Bones of the arms, shoulder joint down, on the cmu_mb rig (see Avatar.collider_faces).
ARM_BONES: tuple[str, ...] = tuple(
    f"{side}{bone}"
    for side in ("Left", "Right")
    for bone in ("Arm", "ForeArm", "Hand", "FingerBase", "HandFinger1")
) + ("LThumb", "RThumb")

# The arm from the elbow down: what a dress's collider leaves out (arms="upper").
FOREARM_BONES: tuple[str, ...] = tuple(
    f"{side}{bone}"
    for side in ("Left", "Right")
    for bone in ("ForeArm", "Hand", "FingerBase", "HandFinger1")
) + ("LThumb", "RThumb")
ARM_COLLISION = (False, True, "upper")  # what ClothConfig.arm_collision may say

# anny phenotype parameters, each in [0, 1]. In anny, gender 0 is male and 1 female.
DEFAULT_SHAPE: dict[str, float] = {
    "gender": 0.9,
    "age": 0.5,
    "muscle": 0.5,
    "weight": 0.5,
    "height": 0.5,
    "proportions": 0.5,
}

# Bones whose skin lies under a skirt: seed points for inverse skinning come from here.
LOWER_BODY_BONES: tuple[str, ...] = (
    "Hips",
    "LowerBack",
    "Spine",
    "LHipJoint",
    "RHipJoint",
    "LeftUpLeg",
    "RightUpLeg",
    "LeftLeg",
    "RightLeg",
)


@dataclass
class AvatarConfig:
    """How the avatar is built."""

    rig: str = "cmu_mb"  # anny rig; cmu_mb has CMU MotionBuilder joint names
    shape: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_SHAPE))  # phenotype
    proxy_topology: str = "notoes_collapse10pc"  # anny low-res topology for the collision proxy
    proxy_margin: float = 0.005  # metres the proxy stands outside the full body at rest
    dtype: str = "float32"  # compute dtype: float32 or float64


@dataclass
class Skeleton:
    """The avatar's skeleton at its rest pose (metres, Z up, root at the origin).

    Attributes:
        names: J joint names.
        parents: (J,) parent index, -1 for the root.
        heads: (J, 3) joint (bone head) positions.
        tails: (J, 3) bone tail positions (where the bone points).
    """

    names: tuple[str, ...]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray

    def index(self, name: str) -> int:
        return self.names.index(name)

    def children(self, j: int) -> list[int]:
        return [int(c) for c in np.nonzero(self.parents == j)[0]]


@dataclass
class BodySequence:
    """A posed body over time.

    Attributes:
        vertices: (T, Vb, 3) posed body vertices.
        joint_transforms: (T, J, 4, 4) skinning transforms (rest pose -> posed).
        joint_poses: (T, J, 4, 4) world poses of the bones (head position in [:3, 3]).
        faces: (F, 3) triangles.
    """

    vertices: torch.Tensor
    joint_transforms: torch.Tensor
    joint_poses: torch.Tensor
    faces: torch.Tensor


@dataclass
class SeedPoints:
    """Body-surface seed points for inverse skinning (paper 3.2).

    Attributes:
        vertex_indices: (m,) indices into the avatar's body vertices.
        rest: (m, 3) positions at the rest pose, root at the origin.
        weights: (m, K) skinning weights.
        joints: (m, K) joint indices.
    """

    vertex_indices: torch.Tensor
    rest: torch.Tensor
    weights: torch.Tensor
    joints: torch.Tensor


def _build_anny(rig: str, topology: str, shape: dict[str, float]):
    from loosefit.warp_log import import_warp

    import_warp()  # before anny: importing it initialises warp, whose banner goes to stderr
    import anny  # imported lazily

    model = anny.Anny(rig=rig, topology=topology)
    unknown = set(shape) - set(model.phenotype_labels)
    if unknown:
        raise LoosefitInputError(
            "AvatarConfig.shape",
            ", ".join(sorted(unknown)),
            f"phenotype names among {list(model.phenotype_labels)}",
            "unknown names",
        )
    for k, v in shape.items():
        if not (0.0 <= float(v) <= 1.0):
            raise LoosefitInputError("AvatarConfig.shape", k, "a value in [0, 1]", repr(v))
    return model


def farthest_point_sampling(points: torch.Tensor, count: int, start: int = 0) -> torch.Tensor:
    """Indices of ``count`` points spread regularly over ``points`` (greedy farthest point).

    Args:
        points: (N, 3).
        count: number of samples, at most N.

    Returns:
        (count,) int64 indices, deterministic for given input.
    """
    N = points.shape[0]
    count = min(count, N)
    chosen = torch.empty(count, dtype=torch.long)
    dist = torch.full((N,), float("inf"), dtype=points.dtype)
    idx = start
    for i in range(count):
        chosen[i] = idx
        dist = torch.minimum(dist, (points - points[idx]).square().sum(-1))
        idx = int(dist.argmax())
    return chosen


class Avatar(torch.nn.Module):
    """The anny body, batched posing, a collision proxy and seed points.

    Holds two anny models of one rig and shape: the full mesh (13,718
    vertices) and a decimated watertight proxy driven by the same pose.
    """

    def __init__(self, config: AvatarConfig | None = None, device: str | torch.device = "cpu"):
        super().__init__()
        self.config = config = config or AvatarConfig()
        dtype = {"float32": torch.float32, "float64": torch.float64}[config.dtype]
        shape = {**DEFAULT_SHAPE, **config.shape}
        self.model = _build_anny(config.rig, "anny", shape).to(device=device, dtype=dtype)
        self.proxy_model = _build_anny(config.rig, config.proxy_topology, shape).to(
            device=device, dtype=dtype
        )
        if list(self.proxy_model.bone_labels) != list(self.model.bone_labels):
            raise RuntimeError("anny proxy topology has a different skeleton")  # invariant
        self.shape = shape
        self._cut_faces: dict = {}  # arms (False or "upper") -> the collider's faces, and limbs
        self._phenotype = {k: float(v) for k, v in shape.items()}

        # Our rest pose: identity rotations with the root joint at the origin.
        J = len(self.model.bone_labels)
        identity = torch.eye(4, dtype=dtype, device=device).expand(1, J, 4, 4)
        rest = self.model(pose_parameters=identity, phenotype_kwargs=self._phenotype)
        self.register_buffer("faces", self.model.get_triangular_faces().long(), persistent=False)
        self.register_buffer("rest_vertices", rest["vertices"][0], persistent=False)
        self.register_buffer("rest_joint_poses", rest["bone_poses"][0], persistent=False)
        # anny's own rest has the root elsewhere: shift its bone ends to our rest.
        shift = (rest["bone_poses"][0, 0, :3, 3] - rest["rest_bone_heads"][0, 0]).double().cpu()
        self.skeleton = Skeleton(
            names=tuple(self.model.bone_labels),
            parents=np.asarray(self.model.bone_parents, dtype=np.int64),
            heads=(rest["rest_bone_heads"][0].double().cpu() + shift).numpy(),
            tails=(rest["rest_bone_tails"][0].double().cpu() + shift).numpy(),
        )
        # Height of the root above the soles at the rest pose.
        self.floor_height = float(-self.rest_vertices[:, 2].min())

        proxy_rest = self.proxy_model(pose_parameters=identity, phenotype_kwargs=self._phenotype)
        self.register_buffer(
            "proxy_faces", self.proxy_model.get_triangular_faces().long(), persistent=False
        )
        self.register_buffer(
            "proxy_offsets",
            self._proxy_offsets(proxy_rest["vertices"][0]).to(dtype),
            persistent=False,
        )

    # -- description -------------------------------------------------------

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.skeleton.names

    @property
    def num_joints(self) -> int:
        return len(self.skeleton.names)

    @property
    def device(self) -> torch.device:
        return self.rest_vertices.device

    @property
    def dtype(self) -> torch.dtype:
        return self.rest_vertices.dtype

    def _proxy_offsets(self, proxy_rest: torch.Tensor, rounds: int = 8) -> torch.Tensor:
        """Per-vertex distances along the normals that enclose the full body in the proxy.

        The decimated proxy's vertices lie on the body but its flat faces cut
        inside it (by up to ~2.5 cm). Each round finds the full-body vertices
        still outside the inflated proxy and pushes the vertices of the proxy
        face nearest to each by its distance; ``proxy_margin`` is added at the end.
        """
        faces = self.proxy_faces.cpu().numpy()
        body = self.rest_vertices.double().cpu().numpy()
        rest = proxy_rest.double().cpu()
        normals = vertex_normals(rest, self.proxy_faces.cpu())
        offsets = np.zeros(len(rest))
        for _ in range(rounds):
            proxy = (rest + torch.from_numpy(offsets)[:, None] * normals).numpy()
            hit = closest_points(proxy, faces, body)
            out = ~hit.inside & (hit.faces >= 0)
            if not out.any():
                break
            push = np.zeros(len(rest))
            np.maximum.at(push, faces[hit.faces[out]].ravel(), np.repeat(hit.distance[out], 3))
            offsets += push
        return torch.from_numpy(offsets + self.config.proxy_margin)

    # -- posing -----------------------------------------------------------

    def _pose_parameters(self, rotations: torch.Tensor, root: torch.Tensor) -> torch.Tensor:
        T, J = rotations.shape[:2]
        pose = torch.zeros(T, J, 4, 4, dtype=self.dtype, device=self.device)
        pose[:, :, :3, :3] = rotations
        pose[:, :, 3, 3] = 1.0
        pose[:, 0, :3, 3] = root
        return pose

    def check_motion(self, motion: Motion) -> None:
        """Raise unless the motion is on this avatar's skeleton."""
        if motion.joint_names != self.joint_names:
            missing = [n for n in self.joint_names if n not in motion.joint_names]
            extra = [n for n in motion.joint_names if n not in self.joint_names]
            raise LoosefitInputError(
                f"motion '{motion.name}'",
                "joint_names",
                f"the avatar's {self.num_joints} joints ({self.config.rig} rig) in its order",
                f"{motion.num_joints} joints; missing {missing[:5]}, unknown {extra[:5]}",
                hint="retarget the motion to the avatar first (loosefit.motion.retarget)",
            )

    def pose(
        self,
        rotations: torch.Tensor,
        root_translation: torch.Tensor,
        batch_size: int = 512,
        with_proxy: bool = False,
    ) -> BodySequence:
        """Pose the body for every frame.

        Args:
            rotations: (T, J, 3, 3) local rotations (see :class:`~loosefit.types.Motion`).
            root_translation: (T, 3) world position of the root joint.
            batch_size: frames per anny forward pass.
            with_proxy: pose the collision proxy instead of the full mesh.

        Returns:
            A :class:`BodySequence`; with ``with_proxy`` its vertices are the
            inflated proxy's (T, Vp, 3) and its faces the proxy's.
        """
        J = self.num_joints
        if rotations.ndim != 4 or rotations.shape[1:] != (J, 3, 3):
            raise LoosefitInputError(
                "Avatar.pose", "rotations", f"shape (T, {J}, 3, 3)", f"{tuple(rotations.shape)}"
            )
        if root_translation.shape != (rotations.shape[0], 3):
            raise LoosefitInputError(
                "Avatar.pose",
                "root_translation",
                f"shape ({rotations.shape[0]}, 3)",
                f"{tuple(root_translation.shape)}",
            )
        model = self.proxy_model if with_proxy else self.model
        rotations = rotations.to(self.device, self.dtype)
        root_translation = root_translation.to(self.device, self.dtype)
        verts, transforms, poses = [], [], []
        for s in range(0, rotations.shape[0], batch_size):
            pose = self._pose_parameters(
                rotations[s : s + batch_size], root_translation[s : s + batch_size]
            )
            out = model(pose_parameters=pose, phenotype_kwargs=self._phenotype)
            v = out["vertices"]
            if with_proxy:
                n = vertex_normals(v, self.proxy_faces)
                v = v + self.proxy_offsets[None, :, None] * n
            verts.append(v)
            poses.append(out["bone_poses"])
            # Skinning transforms from our rest pose: T = W W_rest^-1.
            transforms.append(out["bone_poses"] @ torch.linalg.inv(self.rest_joint_poses))
        return BodySequence(
            vertices=torch.cat(verts),
            joint_transforms=torch.cat(transforms),
            joint_poses=torch.cat(poses),
            faces=self.proxy_faces if with_proxy else self.faces,
        )

    def pose_motion(self, motion: Motion, **kwargs) -> BodySequence:
        """Pose the body for a motion on this avatar's skeleton (see :meth:`pose`)."""
        self.check_motion(motion)
        return self.pose(
            torch.from_numpy(motion.rotations), torch.from_numpy(motion.root_translation), **kwargs
        )

    def rest_motion(self, num_frames: int = 1, fps: float = 30.0) -> Motion:
        """The reference pose standing on the floor, for ``num_frames`` frames."""
        rot = np.broadcast_to(np.eye(3, dtype=np.float32), (num_frames, self.num_joints, 3, 3))
        root = np.tile(np.array([0.0, 0.0, self.floor_height], np.float32), (num_frames, 1))
        return Motion(self.joint_names, rot.copy(), root, fps, name="rest")

    # -- body regions and seed points ----------------------------------------

    def vertices_of_bones(self, bones: tuple[str, ...]) -> torch.Tensor:
        """(N,) indices of the body vertices skinned mostly (largest weight) to one of ``bones``."""
        unknown = [b for b in bones if b not in self.joint_names]
        if unknown:
            raise LoosefitInputError(
                "Avatar", "bones", f"joints of the {self.config.rig} rig", f"{unknown}"
            )
        weights = self.model.vertex_bone_weights
        indices = self.model.vertex_bone_indices.long()
        dominant = indices.gather(1, weights.argmax(1, keepdim=True))[:, 0]
        allowed = torch.tensor([self.joint_names.index(b) for b in bones], device=dominant.device)
        return torch.nonzero(torch.isin(dominant, allowed))[:, 0]

    def collider_faces(self, arms: bool | str = True) -> torch.Tensor:
        """(F', 3) faces of the closed mesh the cloth collides with, on the full body's vertices.

        With ``arms`` True it is the body's own faces; False cuts away the arms (the faces
        skinned mostly to :data:`ARM_BONES`) and closes the two holes at the shoulders;
        ``"upper"`` keeps the upper arms and cuts from the elbows down
        (:data:`FOREARM_BONES`), what a dress's bodice needs
        (see :func:`~loosefit.geometry.cap.cut_and_cap`).
        """
        if arms not in ARM_COLLISION:
            raise LoosefitInputError(
                "Avatar.collider_faces", "arms", f"one of {ARM_COLLISION}", repr(arms)
            )
        if arms is True:
            return self.faces
        if arms not in self._cut_faces:
            removed = np.zeros(self.rest_vertices.shape[0], bool)
            bones = ARM_BONES if arms is False else FOREARM_BONES
            removed[self.vertices_of_bones(bones).cpu().numpy()] = True
            faces = cut_and_cap(self.faces.cpu().numpy(), removed)
            self._cut_faces[arms] = torch.from_numpy(faces).to(self.faces.device)
        return self._cut_faces[arms]

    def cut_limb_faces(self, arms: bool | str = False) -> torch.Tensor:
        """(F', 3) faces of the closed mesh of what :meth:`collider_faces` cuts away.

        The arms from the shoulders (``arms`` False) or from the elbows (``"upper"``),
        each closed by a fan at its cut, on the full body's vertices: a collider of their
        own, which the cloth meets with a friction of its own
        (``ClothConfig.arm_friction``). Faces across the cut belong to both meshes.
        """
        if arms not in (False, "upper"):
            raise LoosefitInputError(
                "Avatar.cut_limb_faces", "arms", "false or 'upper'", repr(arms)
            )
        key = ("limbs", arms)
        if key not in self._cut_faces:
            bones = ARM_BONES if arms is False else FOREARM_BONES
            kept = np.zeros(self.rest_vertices.shape[0], bool)
            kept[self.vertices_of_bones(bones).cpu().numpy()] = True
            faces = cut_and_cap(self.faces.cpu().numpy(), ~kept)
            self._cut_faces[key] = torch.from_numpy(faces).to(self.faces.device)
        return self._cut_faces[key]

    def seed_points(
        self, count: int = 256, bones: tuple[str, ...] = LOWER_BODY_BONES
    ) -> SeedPoints:
        """Seed points spread regularly over the skin of the given bones (paper 3.2).

        Args:
            count: m, the number of seed points.
            bones: joints whose dominantly-weighted skin may hold seed points.

        Returns:
            :class:`SeedPoints`, deterministic for a given avatar.
        """
        weights = self.model.vertex_bone_weights
        indices = self.model.vertex_bone_indices.long()
        candidates = self.vertices_of_bones(bones)
        pts = self.rest_vertices[candidates].double().cpu()
        # Start from the point nearest the root so the sample does not depend on vertex order.
        start = int(pts.norm(dim=-1).argmin())
        chosen = candidates[farthest_point_sampling(pts, count, start).to(candidates.device)]
        return SeedPoints(
            vertex_indices=chosen,
            rest=self.rest_vertices[chosen],
            weights=weights[chosen].to(self.dtype),
            joints=indices[chosen],
        )

    def seed_frames(
        self, seeds: SeedPoints, body: BodySequence
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Per-frame rotation (T, m, 3, 3) and translation (T, m, 3) of the seed points.

        ``R @ rest + t`` reproduces each seed point's posed position exactly.
        """
        return rigid_point_frames(body.joint_transforms, seeds.weights, seeds.joints, seeds.rest)
