"""Read a glTF 2.0 skinned skeleton and one of its animations (``.gltf``, ``.glb``).

What Blender, Mixamo (through Blender), Unity and Unreal export: a skin (its joints
are nodes of the scene), an animation whose channels drive those nodes' rotation,
translation and scale. The result is a :class:`~loosefit.motion.skeleton_clip.BvhClip`, so the
retargeting and the joint matcher apply unchanged.

Quick start::

    clip = read_gltf("dance.glb", animation="Take 001")  # a BvhClip, glTF's axes
    motion = retarget_bvh(clip, avatar.skeleton, avatar.floor_height)

How a glTF becomes a clip:

* Joints: the skin's joints, ordered parents first; a joint's parent is its nearest
  ancestor node that is a joint. Skins whose joints hang from several roots get one
  more joint above them: their nearest common ancestor node, or ``"(scene root)"``.
* World transforms: every joint's, at each frame, through all its ancestor nodes
  (an ``Armature`` node's rotation and its scale of 0.01 included); the scene is
  glTF's: +Y up, facing +Z, metres.
* Rest pose: the skin's bind pose (the inverses of its ``inverseBindMatrices``),
  or the nodes' own transforms when the skin has none.
* The clip is a BVH-like skeleton whose frames are world-aligned at rest: a joint's
  rotation ``Q_j(t) = R_j(t) R_j(rest)^T`` (its world rotation from the rest pose; scale
  removed), local rotations ``Q_parent^T Q_j``, rest offsets from the rest positions,
  and local translations that put every joint where the glTF does.
* Frames: the animation is sampled at ``fps``, by default its keyframes' rate (the
  densest sampler's median spacing, rounded to a whole rate within 0.5 %) when that is
  at least :data:`~loosefit.motion.gltf_animation.MIN_KEY_FPS`, else
  :data:`~loosefit.motion.gltf_animation.DEFAULT_FPS`; from the first keyframe time
  to the last. ``LINEAR`` (rotations by slerp), ``STEP`` and ``CUBICSPLINE``
  interpolation; before the first key and after the last, the end values hold.
* A joint with a single child joint that is a leaf (Mixamo's ``HeadTop_End``, a
  ``_end`` tip) gets that child's offset as its End Site.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loosefit.errors import LoosefitInputError
from loosefit.geometry.rotations import _matrix_to_quat_f64, quat_to_matrix
from loosefit.motion.bvh import _UNIT_SCALES
from loosefit.motion.gltf_animation import Channel, animation_channels, frame_times, sample_channel
from loosefit.motion.gltf_file import (
    GltfDocument,
    doc_index,
    doc_item,
    doc_list,
    gltf_error,
    read_accessor,
    read_document,
)
from loosefit.motion.skeleton_clip import BvhClip

GLTF_SUFFIXES = (".gltf", ".glb")

# --------------------------------------------------------------------------- transforms


def _trs_matrix(t: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(T, 3) translations, (T, 4) quaternions (x, y, z, w), (T, 3) scales -> (T, 4, 4)."""
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = quat_to_matrix(np.roll(q, 1, -1)).astype(np.float64) * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def _orthonormal(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) matrices -> the nearest rotations (scale and shear removed)."""
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    flip = np.linalg.det(r) < 0  # a mirroring scale: keep a proper rotation
    u[flip, :, 2] *= -1
    return np.where(flip[..., None, None], u @ vt, r)


# --------------------------------------------------------------------------- reading


def read_gltf(
    path: str | Path,
    animation: str | int | None = None,
    skin: str | int | None = None,
    fps: float | None = None,
    units: str = "auto",
    scale: float | None = None,
) -> BvhClip:
    """Read a glTF/GLB skin and animation into a :class:`BvhClip` (see the module's notes).

    Args:
        path: the ``.gltf`` or ``.glb`` file.
        animation: the animation's name or index (default: the first).
        skin: the skin's name or index (default: the skin whose joints the animation
            drives most, the first on a tie).
        fps: the sampling rate (default: the keyframes' rate, see the module's notes).
        units: ``"auto"`` or ``"m"`` (glTF is in metres), ``"cm"``, ``"mm"``.
        scale: metres per file unit; overrides ``units``.

    Returns:
        The clip, in glTF's axes (+Y up, facing +Z); ``meta`` names the animation,
        the skin, the rest pose used and the sampling rate.

    Raises:
        LoosefitInputError: naming the file and the field: a malformed file, no skin,
            no animation, an animation that drives none of the skin's joints, a name
            or index that is not there.
    """
    path = Path(path)
    try:
        with np.errstate(all="ignore"):  # overflows end as non-finite values, refused
            return _read_gltf(read_document(path), animation, skin, fps, units, scale)
    except LoosefitInputError:
        raise
    except (TypeError, KeyError, AttributeError, ValueError, IndexError) as exc:
        raise gltf_error(
            path, "<json>", "a well-formed glTF 2.0 document", f"{type(exc).__name__}: {exc}"
        ) from exc


def _read_gltf(doc: GltfDocument, animation, skin, fps, units, scale) -> BvhClip:
    nodes = doc_list(doc, "nodes")

    # 1. The animation and its channels on nodes.
    anims = doc_list(doc, "animations")
    a, anim, channels = animation_channels(doc, animation, len(nodes))
    anim_name = str(anim.get("name", f"#{a}"))

    # 2. The skin and its joints, parents first.
    skins = doc_list(doc, "skins")
    if not skins:
        raise gltf_error(
            doc,
            "skins",
            "a skinned skeleton (a skin)",
            "none in the file",
            hint="export the armature with its mesh (Blender: glTF export > Skinning)",
        )
    driven = {n for n, _ in channels}
    best = max(
        range(len(skins)), key=lambda i: (len(driven & set(_skin_joints(doc, i, nodes))), -i)
    )
    k = doc_index(doc, "skins", skin, best, "skin")
    skin_def, skin_joints = skins[k], _skin_joints(doc, k, nodes)
    skin_name = str(skin_def.get("name", f"#{k}"))
    if not driven & set(skin_joints):
        raise gltf_error(
            doc,
            f"animations[{a}].channels",
            f"channels that drive the joints of skin '{skin_name}'",
            f"animation '{anim_name}' drives none of its {len(skin_joints)} joints"
            + (f" (it drives nodes {sorted(driven)[:8]})" if driven else ""),
            hint="pick another --animation or skin",
        )
    parent_node = _node_parents(doc, nodes)
    clip_nodes, parents, names = _joint_tree(doc, nodes, parent_node, skin_joints)

    # 3. Frame times.
    frames = frame_times(doc, a, channels, fps)

    # 4. World transforms of the joints and every node above them, at each frame and at rest.
    world, rest = _world_transforms(doc, nodes, parent_node, clip_nodes, channels, frames.at)
    ibm_how = "the nodes' own transforms (the skin has no inverseBindMatrices)"
    if skin_def.get("inverseBindMatrices") is not None:
        rest.update(_bind_pose(doc, skin_def, k, skin_joints))
        ibm_how = "the skin's bind pose (inverseBindMatrices)"

    # 5. The clip: world-aligned rest frames, rotations from the rest pose.
    units_scale = _units_scale(doc, units, scale)
    J = len(clip_nodes)
    local = _local_frames(doc, clip_nodes, parents, world, rest, units_scale)
    rot_channels = ("Xrotation", "Yrotation", "Zrotation")
    return BvhClip(
        path=doc.path,
        joint_names=tuple(names),
        parents=np.asarray(parents, np.int64),
        offsets=local.offsets.astype(np.float32),
        channels=[("Xposition", "Yposition", "Zposition", *rot_channels)]
        + [rot_channels] * (J - 1),
        end_offsets=_end_offsets(parents, local.offsets),
        rotations=local.rotations.astype(np.float32),
        local_translations=local.translations.astype(np.float32),
        frame_time=1.0 / frames.fps,
        units_scale=units_scale,
        meta={
            "format": "glTF",
            "report": {
                "animation": f"'{anim_name}' ({a + 1} of {len(anims)}: "
                + ", ".join(repr(str(x.get("name", f"#{i}"))) for i, x in enumerate(anims))
                + ")",
                "skin": f"'{skin_name}' ({k + 1} of {len(skins)}), {len(skin_joints)} joints",
                "rest pose": ibm_how,
                "sampled": f"{frames.fps:g} fps ({frames.how}), "
                f"keyframes {frames.t0:.3f} s to {frames.t1:.3f} s",
            },
        },
    )


def _skin_joints(doc: GltfDocument, i: int, nodes: list) -> list[int]:
    """Skin ``i``'s joints, node indices, checked."""
    js = doc_item(doc, "skins", i, f"skins[{i}]").get("joints", [])
    if not (
        isinstance(js, list)
        and js
        and all(isinstance(j, int) for j in js)
        and all(0 <= j < len(nodes) for j in js)
    ):
        raise gltf_error(
            doc, f"skins[{i}].joints", f"node indices below {len(nodes)}", repr(js)[:60]
        )
    return js


def _world_transforms(
    doc: GltfDocument,
    nodes: list,
    parent_node: dict[int, int],
    clip_nodes: list[int],
    channels: dict[tuple[int, str], Channel],
    at: np.ndarray,
) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """node -> (T, 4, 4) world transforms at times ``at``, and node -> (4, 4) at rest.

    For the clip's nodes and every node above them; ``-1`` (the scene) is the identity.
    """
    T = len(at)
    world: dict[int, np.ndarray] = {-1: np.broadcast_to(np.eye(4), (T, 4, 4))}
    rest: dict[int, np.ndarray] = {-1: np.eye(4)}
    for n in _with_ancestors(clip_nodes, parent_node):
        t, q, s = _node_trs(doc, nodes, n)  # (3,), (4,), (3,) the node's own transform
        rest[n] = rest[parent_node[n]] @ _trs_matrix(t[None], q[None], s[None])[0]
        sampled = []
        for prop, default in (("translation", t), ("rotation", q), ("scale", s)):
            if (n, prop) in channels:
                times, values, interp = channels[(n, prop)]
                sampled.append(sample_channel(times, values, interp, at, prop == "rotation"))
            else:
                sampled.append(np.broadcast_to(default, (T, len(default))))
        world[n] = world[parent_node[n]] @ _trs_matrix(*sampled)  # (T, 4, 4)
    return world, rest


def _bind_pose(
    doc: GltfDocument, skin_def: dict, k: int, skin_joints: list[int]
) -> dict[int, np.ndarray]:
    """joint node -> (4, 4) world transform at bind, from the skin's inverseBindMatrices."""
    ibm = read_accessor(doc, skin_def["inverseBindMatrices"], f"skins[{k}].inverseBindMatrices")
    if ibm.shape != (len(skin_joints), 16):
        raise gltf_error(
            doc,
            f"skins[{k}].inverseBindMatrices",
            f"{len(skin_joints)} MAT4 (one per joint)",
            f"{ibm.shape}",
        )
    bind = np.linalg.inv(np.swapaxes(ibm.reshape(-1, 4, 4), -1, -2))  # column-major
    return dict(zip(skin_joints, bind, strict=True))


def _units_scale(doc: GltfDocument, units: str, scale: float | None) -> float:
    """Metres per file unit: ``scale``, else ``units`` (glTF is in metres)."""
    if scale is not None:
        if not (np.isfinite(scale) and scale > 0):
            raise gltf_error(doc, "scale", "a positive factor", repr(scale))
        return float(scale)
    if units == "auto":
        return 1.0  # glTF is in metres
    if units in _UNIT_SCALES:
        return _UNIT_SCALES[units]
    raise gltf_error(doc, "units", "one of 'auto', 'm', 'cm', 'mm'", repr(units))


@dataclass(frozen=True)
class _LocalFrames:
    """The clip's joints relative to their parents, in world-aligned rest frames.

    Attributes:
        rotations: (T, J, 3, 3) local rotations from the rest pose.
        translations: (T, J, 3) local translations (the root's: its position).
        offsets: (J, 3) rest offsets from the parent (the root's: its rest position).
    """

    rotations: np.ndarray
    translations: np.ndarray
    offsets: np.ndarray


def _local_frames(
    doc: GltfDocument,
    clip_nodes: list[int],
    parents: list[int],
    world: dict[int, np.ndarray],
    rest: dict[int, np.ndarray],
    units_scale: float,
) -> _LocalFrames:
    """The clip's local rotations, translations and offsets from world and rest transforms."""
    J = len(clip_nodes)
    pos = np.stack([world[n][:, :3, 3] for n in clip_nodes], 1) * units_scale  # (T, J, 3)
    rot = _orthonormal(np.stack([world[n][:, :3, :3] for n in clip_nodes], 1))  # (T, J, 3, 3)
    rest_pos = np.stack([rest[n][:3, 3] for n in clip_nodes]) * units_scale  # (J, 3)
    rest_rot = _orthonormal(np.stack([rest[n][:3, :3] for n in clip_nodes]))  # (J, 3, 3)
    Q = rot @ np.swapaxes(rest_rot, -1, -2)[None]  # (T, J, 3, 3) world rotation from rest
    local = Q.copy()
    trans = pos.copy()
    offsets = rest_pos.copy()
    for j in range(1, J):
        p = parents[j]
        local[:, j] = np.swapaxes(Q[:, p], -1, -2) @ Q[:, j]
        trans[:, j] = (np.swapaxes(Q[:, p], -1, -2) @ (pos[:, j] - pos[:, p])[..., None])[..., 0]
        offsets[j] = rest_pos[j] - rest_pos[p]
    if not all(np.all(np.isfinite(x)) for x in (local, trans, offsets)):
        raise gltf_error(
            doc,
            "nodes",
            "finite joint transforms",
            "NaN or an overflow (a zero quaternion, a singular bind matrix or a huge "
            "translation or scale)",
        )
    return _LocalFrames(local, trans, offsets)


def _end_offsets(parents: list[int], offsets: np.ndarray) -> dict[int, np.ndarray]:
    """End Sites: a joint whose single child joint is a leaf gets that child's (3,) offset."""
    J = len(parents)
    children = [[c for c in range(J) if parents[c] == j] for j in range(J)]
    return {
        j: offsets[kids[0]].astype(np.float32)
        for j, kids in enumerate(children)
        if len(kids) == 1 and not children[kids[0]]
    }


def _node_parents(doc: GltfDocument, nodes: list) -> dict[int, int]:
    """node -> its parent node, -1 for the scene's roots."""
    parent = dict.fromkeys(range(len(nodes)), -1)
    for i, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise gltf_error(doc, f"nodes[{i}]", "an object", repr(node)[:40])
        for c in node.get("children", []):
            if not (isinstance(c, int) and 0 <= c < len(nodes)) or c == i or parent[c] >= 0:
                raise gltf_error(
                    doc, f"nodes[{i}].children", "indices of nodes with one parent each", repr(c)
                )
            parent[c] = i
    for i in range(len(nodes)):  # a cycle never reaches a root
        seen, n = set(), i
        while n >= 0:
            if n in seen:
                raise gltf_error(doc, f"nodes[{i}]", "a tree of nodes", "a cycle of children")
            seen.add(n)
            n = parent[n]
    return parent


def _with_ancestors(joints: list[int], parent: dict[int, int]) -> list[int]:
    """The nodes and all their ancestors, each after its parent (``-1`` left out)."""
    out: list[int] = []
    for n in joints:
        chain = []
        while n >= 0 and n not in out and n not in chain:
            chain.append(n)
            n = parent[n]
        out.extend(reversed(chain))
    return out


def _joint_tree(doc: GltfDocument, nodes: list, parent: dict[int, int], joints: list[int]):
    """The clip's joints (node indices, -1 for a synthetic root), parents, unique names."""
    inside = set(joints)

    def joint_parent(n: int) -> int:
        p = parent[n]
        while p >= 0 and p not in inside:
            p = parent[p]
        return p

    roots = [n for n in joints if joint_parent(n) < 0]
    top = None
    if len(roots) > 1:  # one root above them: their nearest common ancestor, or the scene
        chains = []
        for r in roots:
            chain, n = [], parent[r]
            while n >= 0:
                chain.append(n)
                n = parent[n]
            chains.append(chain)
        common = [n for n in chains[0] if all(n in c for c in chains[1:])]
        top = common[0] if common else -1
    kids: dict[int, list[int]] = {}
    for n in joints:
        kids.setdefault(joint_parent(n), []).append(n)
    order: list[int] = [] if top is None else [top]
    stack = list(reversed(roots[:1] if top is None else roots))
    while stack:  # depth first, children in the skin's order
        n = stack.pop()
        order.append(n)
        stack.extend(reversed(kids.get(n, [])))
    index = {n: i for i, n in enumerate(order)}
    parents = [-1 if i == 0 else index.get(joint_parent(n), 0) for i, n in enumerate(order)]
    names: list[str] = []
    for n in order:
        name = "(scene root)" if n < 0 else str(nodes[n].get("name") or f"node{n}")
        names.append(name if name not in names else f"{name}#{n}")
    return order, parents, names


def _node_trs(doc: GltfDocument, nodes: list, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's own translation (3,), rotation (4,) as (x, y, z, w) and scale (3,)."""
    node = nodes[n]
    if "matrix" in node:
        try:
            m = np.asarray(node["matrix"], np.float64)
        except (TypeError, ValueError):
            m = np.full(1, np.nan)
        if m.shape != (16,) or not np.all(np.isfinite(m)):
            raise gltf_error(
                doc, f"nodes[{n}].matrix", "16 finite numbers", repr(node["matrix"])[:60]
            )
        m = m.reshape(4, 4).T  # column-major
        s = np.linalg.norm(m[:3, :3], axis=0)
        r = _orthonormal(m[:3, :3] / np.where(s > 0, s, 1.0))
        w, x, y, z = _matrix_to_quat_f64(r)
        return m[:3, 3], np.array([x, y, z, w]), s
    out = []
    for key, default in (
        ("translation", [0, 0, 0]),
        ("rotation", [0, 0, 0, 1]),
        ("scale", [1, 1, 1]),
    ):
        try:
            v = np.asarray(node.get(key, default), np.float64)
        except (TypeError, ValueError):
            v = np.full(1, np.nan)
        if v.shape != (len(default),) or not np.all(np.isfinite(v)):
            raise gltf_error(
                doc, f"nodes[{n}].{key}", f"{len(default)} finite numbers", repr(node.get(key))[:60]
            )
        out.append(v)
    return out[0], out[1], out[2]
