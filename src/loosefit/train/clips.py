"""The clips the motion stage and the baselines train on: each on the rollout timeline
(rest frames, blend, motion), with its motion features, root frames and simulated
garment in the root frame (and, given a generative model, that garment's codes).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import torch

from loosefit.data.format import DatasetReader
from loosefit.errors import LoosefitInputError
from loosefit.eval.rollouts import evaluate_rollouts
from loosefit.inference.rollout import latent_codes, timeline
from loosefit.inference.timeline import RolloutConfig
from loosefit.model.generative import GarmentGenerativeModel
from loosefit.model.motion_features import (
    feature_joints,
    motion_features,
    num_features,
    root_frames,
    to_root_frame,
)
from loosefit.train.frames import avatar_for, clip_versions, root_frame_contacts
from loosefit.types import Motion


@dataclass
class Clip:
    """One clip on the rollout timeline (P frames before the motion, then T).

    Attributes:
        name: the clip.
        motion: the body motion (T frames).
        features: (P + T, F) motion features.
        heading: (P + T, 3, 3) and ``origin`` (P + T, 3): the root frames.
        target: (T, V, 3) simulated garment, root frame.
        latent: (T, latent) the generative encoder's code of ``target`` (Z*), or None
            when prepared without a generative model (the baselines').
        preroll: P.
        contacts: the body's closest point to each simulated vertex and its outward normal
            there, (T, V, 3) each, root frame (a zero normal: no body within reach), or
            None when prepared without them (the collision term's).
    """

    name: str
    motion: Motion
    features: torch.Tensor
    heading: torch.Tensor
    origin: torch.Tensor
    target: torch.Tensor
    latent: torch.Tensor | None
    preroll: int
    contacts: tuple[torch.Tensor, torch.Tensor] | None = None

    @property
    def length(self) -> int:
        return int(self.features.shape[0])


@torch.no_grad()
def prepare_clips(
    reader: DatasetReader,
    split: str,
    generative: GarmentGenerativeModel | None,
    floor_height: float,
    config: RolloutConfig,
    *,
    max_frames: int | None = None,
    mirror: bool = False,
    joints: str = "all",
    contacts: bool = False,
) -> list[Clip]:
    """Every clip of a split on the rollout timeline, with its targets (and, given a
    generative model, their latent codes).

    ``mirror`` adds each clip mirrored left-right (:func:`clip_versions`).
    ``joints`` names the joint set of the features (``MotionEncoderConfig.joints``).
    ``contacts``: also each simulated vertex's closest point on the whole body, posed by
    the clip's motion on the data set's avatar, and the normal there (the collision term's;
    :func:`~loosefit.train.frames.body_contacts`).
    """
    avatar = avatar_for(reader) if contacts else None
    faces = avatar.collider_faces(arms=True).cpu().numpy() if contacts else None
    clips = []
    for label, m, v in clip_versions(reader, split, max_frames, mirror):
        rot, root, P = timeline(m, floor_height, config)
        H, p = (a.float() for a in root_frames(rot.double(), root.double()))
        target = to_root_frame(torch.from_numpy(np.ascontiguousarray(v, np.float32)), H[P:], p[P:])
        feats = motion_features(
            rot, root, m.fps, floor_height, feature_joints(m.joint_names, joints)
        )
        latent = None if generative is None else latent_codes(generative, target)  # (T, Z)
        touch = None
        if contacts:
            body = avatar.pose_motion(m).vertices  # (T, Vb, 3)
            touch = root_frame_contacts(np.asarray(v, np.float32), body, faces, H[P:], p[P:])
        clips.append(Clip(label, m, feats, H, p, target, latent, P, touch))
    return clips


def pad_frames(x: torch.Tensor, n: int) -> torch.Tensor:
    """Frames (T, ...) padded to ``n`` by repeating the last (clips stacked side by side)."""
    return torch.cat([x, x[-1:].expand(n - len(x), *x.shape[1:])]) if len(x) < n else x


class FeatureStatistics(NamedTuple):
    """The motion features of a stage's training clips, as its encoder normalises them."""

    count: int  # F: motion features per frame
    mean: torch.Tensor  # (F,) over every timeline frame of the clips
    std: torch.Tensor  # (F,) likewise


def feature_statistics(reader: DatasetReader, clips: list[Clip], joints: str) -> FeatureStatistics:
    """The number F of motion features of the clips, and their mean and std (F,) each.

    Raises:
        LoosefitInputError: F is not the number that the joint set ``joints`` gives.
    """
    feats = torch.cat([c.features for c in clips])  # (N, F) every timeline frame
    F = feats.shape[1]
    expected = num_features(len(feature_joints(clips[0].motion.joint_names, joints)) + 1)
    if F != expected:
        raise LoosefitInputError(reader.root, "features", expected, F)
    return FeatureStatistics(F, feats.mean(0), feats.std(0))


def feature_range(clips: list[Clip]) -> tuple[torch.Tensor, torch.Tensor]:
    """The least and the greatest value (F,) of each motion feature over the clips' motion
    frames (the preroll left out: the frames a loss sees)."""
    feats = torch.cat([c.features[c.preroll : c.length] for c in clips])  # (N, F)
    return feats.min(0).values, feats.max(0).values


def stack_clips(
    clips: list[Clip], longest: list[Clip] | None = None, extra: list[torch.Tensor] | None = None
) -> dict[str, torch.Tensor]:
    """Clips side by side, padded by repeating their last frame to the longest of
    ``longest`` (the whole batch, when ``clips`` is one process's part of it; default
    ``clips``). ``extra``: a per-motion-frame tensor of each clip (T, ...), stacked too."""
    longest = clips if longest is None else longest
    L = max(c.length for c in longest)
    T = max(c.target.shape[0] for c in longest)
    batch = {
        "features": torch.stack([pad_frames(c.features, L) for c in clips]),  # (B, L, F)
        "heading": torch.stack([pad_frames(c.heading, L) for c in clips]),  # (B, L, 3, 3)
        "origin": torch.stack([pad_frames(c.origin, L) for c in clips]),  # (B, L, 3)
        "target": torch.stack([pad_frames(c.target, T) for c in clips]),  # (B, T, V, 3)
        "preroll": torch.tensor([c.preroll for c in clips]),  # (B,)
        "length": torch.tensor([c.length for c in clips]),  # (B,)
    }
    if clips[0].latent is not None:
        batch["latent"] = torch.stack([pad_frames(c.latent, T) for c in clips])  # (B, T, Z)
    if clips[0].contacts is not None:  # (B, T, V, 3) each
        batch["contact_points"] = torch.stack([pad_frames(c.contacts[0], T) for c in clips])
        batch["contact_normals"] = torch.stack([pad_frames(c.contacts[1], T) for c in clips])
    if extra is not None:
        batch["extra"] = torch.stack([pad_frames(x, T) for x in extra])  # (B, T, ...)
    return batch


def rollout_evaluation(
    model, reader: DatasetReader, stages, epoch: int, record: dict, write
) -> dict[str, float]:
    """The held-out clips rolled out by ``model`` (the network being trained, through
    ``stages``) and scored against the simulation, as the motion stage and the baselines
    check themselves during training: the RMSE noted in the epoch's history ``record``,
    written under the progress bar (``write``), and returned as a TensorBoard scalar."""
    err = evaluate_rollouts(model, reader, "test", surface=False, stages=stages)
    record["test_rollout_rmse_cm"] = err["rmse_cm"]
    write(f"epoch {epoch}: held-out rollout RMSE {err['rmse_cm']:.2f} cm")
    return {"test/rollout_rmse_cm": err["rmse_cm"]}
