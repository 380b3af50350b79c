"""A user's character built in code: anny of another phenotype, re-skinned to a Mixamo
skeleton (its names, centimetres, Y up), written as a glTF with its mesh, skin and
animation, as a Mixamo or Blender export would be."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loosefit.motion.bvh import read_bvh
from loosefit.motion.retarget import axis_change
from loosefit.motion.skeleton_clip import forward_kinematics, rest_positions
from tests.motion.bvh_conventions import MIXAMO, write_convention_bvh
from tests.motion.gltf_writer import write_gltf

SHAPE = {
    "gender": 0.6,
    "age": 0.5,
    "muscle": 0.5,
    "weight": 0.75,
    "height": 0.7,
    "proportions": 0.6,
}


def clip_joint_of(avatar, conv, clip) -> list[int]:
    """For each avatar joint, the index in ``clip`` of the joint that carries it: its own,
    or its nearest ancestor's the convention has."""
    names, parents = avatar.skeleton.names, avatar.skeleton.parents
    out = []
    for j, _ in enumerate(names):
        a = j
        while names[a] not in conv.joints:
            a = parents[a]
        out.append(clip.joint_names.index(conv.joints[names[a]]))
    return out


def write_character(
    path: Path, shape: dict = SHAPE, move: str = "dance:2", frames: int = 16, seed: int = 3
):
    """Write the character; returns (path, its avatar, its motion on that avatar)."""
    from loosefit.body.avatar import Avatar, AvatarConfig
    from loosefit.motion.motions import load_motion

    body = Avatar(AvatarConfig(shape=shape))
    motion = load_motion(move, body, seed=seed).slice(0, frames)
    bvh = write_convention_bvh(
        path.with_suffix(".bvh"), MIXAMO, body.skeleton, motion, body.floor_height
    )
    clip = read_bvh(bvh)
    P, G = (a.astype(np.float64) for a in forward_kinematics(clip))
    rest = rest_positions(clip).astype(np.float64)
    C = axis_change(MIXAMO.up, MIXAMO.forward)  # the file's axes to anny's
    x0 = body.pose_motion(motion.slice(0, 1)).vertices[0].double().cpu().numpy() @ C
    # anny's weights on the clip's joints, the four largest
    to_clip = np.asarray(clip_joint_of(body, MIXAMO, clip))
    w = body.model.vertex_bone_weights.double().cpu().numpy()
    j = to_clip[body.model.vertex_bone_indices.long().cpu().numpy()]
    dense = np.zeros((len(w), clip.num_joints))
    np.add.at(dense, (np.arange(len(w))[:, None], j), w)
    joints = np.argsort(-dense, 1)[:, :4]
    weights = np.take_along_axis(dense, joints, 1)
    weights /= weights.sum(1, keepdims=True)
    # the frame-0 skin undone by the rig: the bind pose (the clip's rest)
    R = G[0]  # (J, 3, 3) joint j moves rest -> frame 0 by R_j, P_j - R_j rest_j
    t = P[0] - np.einsum("jab,jb->ja", R, rest)
    A = np.einsum("vk,vkab->vab", weights, R[joints])
    b = np.einsum("vk,vka->va", weights, t[joints])
    bind = np.linalg.solve(A, (x0 - b)[..., None])[..., 0]
    mesh = {
        "positions": bind,
        "faces": body.faces.cpu().numpy(),
        "joints": joints,
        "weights": weights,
    }
    return write_gltf(path, clip, mesh=mesh), body, motion
