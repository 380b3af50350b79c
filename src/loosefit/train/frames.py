"""The arrays the generative model trains on: a data set's frames in the root frame
(:mod:`loosefit.model.motion_features`), with their unposed targets; and the clips every
training stage reads, each with its mirror image if asked (:func:`clip_versions`).

**Unposed targets.** The unposed decoder is supervised by the inverse skinning
of each simulated frame (paper Eq. 4) with seed points on the body, computed
here once per dataset.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import torch

from loosefit.body.avatar import Avatar, AvatarConfig
from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.geometry.inverse_skinning import InverseSkinningConfig, seed_weights, unskin
from loosefit.model.motion_features import from_root_frame, heading_frames, to_root_frame
from loosefit.motion.mirror import mirror_garment, mirror_motion, vertex_twins
from loosefit.types import Motion


@dataclass
class PreparedFrames:
    """A split of a dataset, ready for training (all frames of all its clips).

    Attributes:
        names: the clips.
        clip: (N,) int64 index into ``names`` of each frame.
        frame: (N,) int64 frame index within its clip.
        posed: (N, V, 3) float32 simulated garment, root frame.
        unposed: (N, V, 3) float32 its inverse skinning, canonical frame.
        heading: (N, 3, 3) float32 and origin (N, 3) float32 of each root frame.
        fps: frames per second of the clips.
        contact_points, contact_normals: (N, V, 3) float32, root frame: each simulated
            vertex's closest point on the whole body and the body's outward normal there
            (0 beyond 10 cm), for the collision term; None unless asked for.
    """

    names: list[str]
    clip: torch.Tensor
    frame: torch.Tensor
    posed: torch.Tensor
    unposed: torch.Tensor
    heading: torch.Tensor
    origin: torch.Tensor
    fps: float
    contact_points: torch.Tensor | None = None
    contact_normals: torch.Tensor | None = None

    def __len__(self) -> int:
        return int(self.posed.shape[0])

    def world(self, index: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """Root-frame garments (B, V, 3) of frames ``index`` (B,) back into the world."""
        return from_root_frame(x, self.heading[index], self.origin[index])


def clip_versions(
    reader: DatasetReader, split: str, max_frames: int | None = None, mirror: bool = False
) -> Iterator[tuple[str, Motion, np.ndarray]]:
    """Every clip of a split as (name, motion, simulated garment (T, V, 3), world frame),
    each followed, with ``mirror``, by itself mirrored left-right (``NAME~mirror``): the
    motion by :func:`~loosefit.motion.mirror.mirror_motion`, the garment reflected about
    X = 0 onto its twin vertices (:func:`~loosefit.motion.mirror.vertex_twins`; the garment
    must be mirror-symmetric). Physics has no handedness, so that is the simulation of the
    mirrored motion, up to the body's own asymmetry (mm). ``max_frames``: the first frames
    of each clip only.

    Raises (on the call, before any clip is read): what
    :meth:`~loosefit.data.format.DatasetReader.training_clips` refuses (clips of another
    cloth configuration), and an asymmetric garment with ``mirror``.
    """
    names = reader.training_clips(split)
    twins = vertex_twins(reader.template.vertices) if mirror else None

    def versions() -> Iterator[tuple[str, Motion, np.ndarray]]:
        for name in names:
            seq = reader.read(name)
            motion = seq.motion if max_frames is None else seq.motion.slice(0, max_frames)
            garment = seq.garment_vertices[: motion.num_frames]
            yield name, motion, garment
            if mirror:
                yield f"{name}~mirror", mirror_motion(motion), mirror_garment(garment, twins)

    return versions()


def avatar_for(reader: DatasetReader, device: str = "cpu") -> Avatar:
    """The avatar a dataset was simulated on (its manifest's body shape)."""
    return Avatar(AvatarConfig(shape=dict(reader.body.get("shape", {}))), device=device)


def prepare_split(
    reader: DatasetReader,
    split: str,
    avatar: Avatar,
    skinning: InverseSkinningConfig | None = None,
    *,
    max_frames: int | None = None,
    contacts: bool = False,
    mirror: bool = False,
) -> PreparedFrames:
    """Root-frame garments and inverse-skinning targets for every frame of a split.

    Args:
        reader: the dataset.
        split: "train", "test" or "all".
        avatar: the body the dataset was made on (:func:`avatar_for`).
        skinning: seed count and softmax temperature of the inverse skinning.
        max_frames: keep at most this many frames of each clip (for quick runs).
        contacts: also find each simulated vertex's closest point on the whole body (arms
            and hands included) and the normal there (the collision term's contacts).

    Returns:
        :class:`PreparedFrames`.
    """
    versions = clip_versions(reader, split, max_frames, mirror)  # refuses before any work
    skinning = skinning or InverseSkinningConfig()
    names: list[str] = []
    template = torch.from_numpy(reader.template.vertices)
    seeds = avatar.seed_points(skinning.num_seeds)
    weights = seed_weights(template, seeds.rest.float().cpu(), skinning.temperature)[None]
    out: dict[str, list] = {
        k: [] for k in ("clip", "frame", "posed", "unposed", "H", "p", "cp", "cn")
    }
    faces = avatar.collider_faces(arms=True).cpu().numpy() if contacts else None
    fps = None
    for i, (name, motion, garment) in enumerate(versions):
        names.append(name)
        g = torch.from_numpy(np.ascontiguousarray(garment, np.float32))
        fps = motion.fps if fps is None else fps
        if motion.fps != fps:  # a mirror image has its clip's: only a clip can differ
            raise LoosefitInputError(
                reader.sequence_path(name), "fps", f"{fps} like the other clips", motion.fps
            )
        with torch.no_grad():
            body = avatar.pose_motion(motion)
            R, t = avatar.seed_frames(seeds, body)
            H, p = heading_frames(body.joint_transforms[:, 0].float().cpu())
            unposed = unskin(g, weights, R.float().cpu(), t.float().cpu())
        out["clip"].append(torch.full((len(g),), i, dtype=torch.long))
        out["frame"].append(torch.arange(len(g)))
        out["posed"].append(to_root_frame(g, H, p))
        out["unposed"].append(unposed)
        out["H"].append(H)
        out["p"].append(p)
        if contacts:
            cp, cn = root_frame_contacts(g.numpy(), body.vertices, faces, H, p)
            out["cp"].append(cp)
            out["cn"].append(cn)
    return PreparedFrames(
        names=names,
        clip=torch.cat(out["clip"]),
        frame=torch.cat(out["frame"]),
        posed=torch.cat(out["posed"]).contiguous(),
        unposed=torch.cat(out["unposed"]).contiguous(),
        heading=torch.cat(out["H"]),
        origin=torch.cat(out["p"]),
        fps=float(fps),
        contact_points=torch.cat(out["cp"]).contiguous() if contacts else None,
        contact_normals=torch.cat(out["cn"]).contiguous() if contacts else None,
    )


def root_frame_contacts(
    garment: np.ndarray, body: torch.Tensor, faces: np.ndarray, H: torch.Tensor, p: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`body_contacts` of garments (T, V, 3) on the posed body (T, Vb, 3), world
    frame, put in the root frames ``H`` (T, 3, 3), ``p`` (T, 3): the points moved, the
    normals turned only. (T, V, 3) each, float32."""
    cp, cn = body_contacts(garment, body.float().cpu().numpy(), faces)
    return (
        to_root_frame(torch.from_numpy(cp), H, p),
        to_root_frame(torch.from_numpy(cn), H, torch.zeros_like(p)),
    )


def body_contacts(
    garment: np.ndarray, body: np.ndarray, faces: np.ndarray, reach: float = 0.1
) -> tuple[np.ndarray, np.ndarray]:
    """Each garment vertex's closest body point and the body's outward normal there.

    Args:
        garment: (T, V, 3); body: (T, Vb, 3) the posed body; faces: (Fb, 3) its triangles.
        reach: m; vertices farther from the body get a zero normal (no contact).

    Returns:
        points (T, V, 3) and normals (T, V, 3), float32.
    """
    from loosefit.eval.depth import body_surfaces
    from loosefit.geometry.signed_distance import signed_distances

    points = np.zeros(garment.shape, np.float32)
    normals = np.zeros(garment.shape, np.float32)
    for t, surface in enumerate(body_surfaces(body[: len(garment)], faces)):
        n, ds = signed_distances(garment[t].astype(np.float64), surface, reach)
        near = np.isfinite(ds)
        normals[t] = n
        points[t] = garment[t] - np.where(near, ds, 0.0)[:, None] * n
    return points, normals
