"""What a trained generative model (the garment VAE, paper 3.2) has learnt, through the API:
a data set's clip encoded and decoded frame by frame, and garments along a line between two
frames' latent codes.

::

    from loosefit.api.generative import open_generative, render_interpolation

    gen = open_generative("runs/gen/checkpoint.pt", "datasets/demo")
    clip = gen.read(gen.split("test")[0])
    rec = gen.reconstruct(clip.motion, clip.garment_vertices)
    rec.sequence.save("reconstruction.npz")      # world positions; rec.rmse in metres
    line = gen.interpolate((clip, 0), (clip, 40), steps=8)
    render_interpolation(line, "out", title="0 -> 40")

Each function imports what it needs when called.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class Reconstruction:
    """A clip's garment through the generative model.

    Attributes:
        sequence: the reconstruction, a :class:`~loosefit.sequence.GarmentSequence` of the
            clip's motion (world positions), as ``loosefit render --sequence`` reads.
        rmse: its root-mean-square distance to the clip's garment, metres.
    """

    sequence: object
    rmse: float


@dataclass
class Interpolation:
    """Garments decoded along the line between two latent codes.

    Attributes:
        vertices: (S, V, 3) the garments in the root frame (the root joint at the origin).
        faces: (F, 3) their triangles.
        alpha: (S,) each garment's place on the line, 0 (the first) to 1 (the second).
        floor_height: the root joint's height at rest above the floor, metres.
    """

    vertices: np.ndarray
    faces: np.ndarray
    alpha: np.ndarray
    floor_height: float

    def save(self, path: str | Path) -> None:
        """An ``.npz`` of ``vertices``, ``faces`` and ``alpha``."""
        np.savez(path, vertices=self.vertices, faces=self.faces, alpha=self.alpha)


class GenerativeOnData:
    """A generative checkpoint opened with the data set it is looked at on
    (:func:`open_generative`).

    Attributes:
        checkpoint: the checkpoint's path.
        template: the data set's garment (:class:`~loosefit.types.GarmentTemplate`).
        body: the data set's body record (``shape``, ``floor_height``, ...).
    """

    def __init__(self, checkpoint: Path, reader, model) -> None:
        self.checkpoint, self._reader, self._model = checkpoint, reader, model
        self.template = reader.template
        self.body = reader.body

    def split(self, name: str) -> list[str]:
        """The clips of a split (``train``, ``test``, ``all``)."""
        return self._reader.split(name)

    def read(self, name: str):
        """A clip: its :class:`~loosefit.sequence.GarmentSequence` as simulated."""
        return self._reader.read(name)

    def reconstruct(self, motion, garment: np.ndarray) -> Reconstruction:
        """A garment encoded and decoded frame by frame in its root frame, and put back in
        the world.

        Args:
            motion: the clip's :class:`~loosefit.types.Motion` (T frames).
            garment: (T, V, 3) its garment's world positions.
        """
        import torch

        from loosefit.eval.metrics import rmse
        from loosefit.model.motion_features import (
            from_root_frame,
            garment_in_root_frame,
            motion_root_frames_of,
        )
        from loosefit.sequence import GarmentSequence

        H, p = motion_root_frames_of(motion)
        with torch.no_grad():
            rec = self._model.reconstruct_all(garment_in_root_frame(motion, garment), 64)
            world = from_root_frame(rec, H, p).numpy()
        source = f"generative reconstruction {self.checkpoint.resolve()}"
        sequence = GarmentSequence(motion, self.template, world, self._reader.avatar, source)
        return Reconstruction(sequence, rmse(world, garment))

    def interpolate(self, a: tuple, b: tuple, *, steps: int) -> Interpolation:
        """``steps`` garments decoded along the line between the latent codes (the means)
        of two frames.

        Args:
            a: ``(clip, frame)``: a clip's :class:`~loosefit.sequence.GarmentSequence` (from
                :meth:`read`) and a frame of it.
            b: the second, likewise.
            steps: how many garments, the two ends included.
        """
        import torch

        from loosefit.model.motion_features import garment_in_root_frame

        posed = [
            garment_in_root_frame(seq.motion.slice(f, f + 1), seq.garment_vertices[f : f + 1])
            for seq, f in (a, b)
        ]
        with torch.no_grad():
            mu, _ = self._model.encode(torch.cat(posed))
            alpha = torch.linspace(0, 1, steps)[:, None]
            garments = self._model.decode((1 - alpha) * mu[0] + alpha * mu[1])["vertices"]
        floor = float(self.body.get("floor_height", 0.9))
        return Interpolation(garments.numpy(), self.template.faces, alpha[:, 0].numpy(), floor)


def open_generative(checkpoint: str | Path, data: str | Path) -> GenerativeOnData:
    """A generative run's checkpoint (its ``checkpoint.pt``) and the data set folder to
    look at it on, checked to be of the same garment.

    Raises:
        LoosefitInputError: an unreadable data set, not a generative checkpoint, or one of
            another garment.
    """
    from loosefit.data.format import DatasetReader
    from loosefit.inference.checkpoints import load_generative

    reader = DatasetReader(data)
    model, _ = load_generative(checkpoint, reader.template)
    return GenerativeOnData(Path(checkpoint), reader, model)


def render_interpolation(
    line: Interpolation, out: str | Path, *, title: str, size: int = 384, fps: float = 4.0
):
    """The garments of an :class:`Interpolation` standing where the body's root joint
    rests, one a frame, rendered into the folder ``out`` (front and side, a fixed camera,
    every frame a PNG; :func:`loosefit.api.render.render_garments`)."""
    from loosefit.api.render import render_garments

    lifted = line.vertices + np.array([0.0, 0.0, line.floor_height])
    return render_garments(out, faces=line.faces, vertices=lifted, title=title, fps=fps, size=size)
