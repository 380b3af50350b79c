"""Why the learned skirt's edge strain is high: compressed or rough?

On the held-out salsa chain, against its simulation: the signed strain
``length / rest - 1`` of every edge (negative: shorter than at rest), the mean
magnitude of the uniform Laplacian (how much the surface bends between
neighbours), and the strain after 1, 3 and 10 steps of Laplacian smoothing of the
motion stage's garment (every 50th of the first 600 frames)::

    python bench/quality/strain_sign.py --data datasets/salsa
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import torch

import loosefit
from loosefit.data.format import DatasetReader
from loosefit.geometry.edges import unique_edges
from loosefit.geometry.laplacian import laplacian_matrix
from loosefit.inference.stages import MOTION_ONLY
from loosefit.train.common import machine


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", default="checkpoints/salsa/motion.pt")
    p.add_argument("--data", default="datasets/salsa")
    p.add_argument("--frames", type=int, default=600)
    args = p.parse_args()
    torch.set_num_threads(1)
    reader = DatasetReader(args.data)
    seq = reader.read(next(n for n in reader.split("test") if n.startswith("chain_")))
    model = loosefit.load(args.checkpoint, detail=None).model
    t = model.template
    edges, _ = unique_edges(t.faces)
    rest = np.linalg.norm(t.vertices[edges[:, 0]] - t.vertices[edges[:, 1]], axis=-1)

    def signed(v: np.ndarray) -> np.ndarray:
        return np.linalg.norm(v[:, edges[:, 0]] - v[:, edges[:, 1]], axis=-1) / rest - 1

    L = laplacian_matrix(t.faces, t.num_vertices, "uniform")
    learned = model.animate(seq.motion.slice(0, args.frames), stages=MOTION_ONLY).vertices
    garments = {"simulation": seq.garment_vertices[: args.frames], "motion stage": learned}
    out: dict = {"machine": machine("cpu")}
    for name, v in garments.items():
        s = signed(v)
        lap = torch.stack([L @ torch.from_numpy(x).float() for x in v[::50]])
        out[name] = {
            "signed_strain_p10": float(np.percentile(s, 10)),
            "signed_strain_p50": float(np.median(s)),
            "signed_strain_p90": float(np.percentile(s, 90)),
            "laplacian_mm": 1e3 * float(lap.norm(dim=-1).mean()),
        }
    x = torch.from_numpy(learned[::50]).float()
    out["smoothed"] = {}
    y, done = x.clone(), 0
    for steps in (1, 3, 10):
        for _ in range(steps - done):
            y = y - 0.5 * torch.stack([L @ a for a in y])
        done = steps
        s = np.abs(signed(y.numpy()))
        out["smoothed"][steps] = {
            "strain_p50": float(np.median(s)),
            "strain_p99": float(np.percentile(s, 99)),
        }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
