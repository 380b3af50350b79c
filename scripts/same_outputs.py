"""Compare two folders written by scripts/same_outputs.sh, array by array, bit for bit.

Every ``.npz`` and ``.npy`` array and every tensor of every ``.pt`` file (nested in dicts and lists)
of the first folder must be in the second with the same dtype, shape and bytes. Prints
each difference and exits 1 if there is one.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch


def arrays(obj, prefix: str = ""):
    """(name, numpy array) of every tensor or array inside ``obj``."""
    if isinstance(obj, torch.Tensor):
        yield prefix, obj.detach().cpu().numpy()
    elif isinstance(obj, np.ndarray):
        yield prefix, obj
    elif isinstance(obj, dict):
        for k, v in obj.items():
            yield from arrays(v, f"{prefix}/{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            yield from arrays(v, f"{prefix}[{i}]")


def read(path: Path) -> dict[str, np.ndarray]:
    if path.suffix == ".npy":
        return {"": np.load(path, allow_pickle=False)}
    if path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    return dict(arrays(torch.load(path, map_location="cpu", weights_only=False)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    args = ap.parse_args()
    files = sorted(p for p in args.before.rglob("*") if p.suffix in (".npz", ".npy", ".pt"))
    if not files:
        print(f"no .npz, .npy or .pt files under {args.before}")
        return 1
    bad = 0
    count = 0
    for p in files:
        rel = p.relative_to(args.before)
        q = args.after / rel
        if not q.is_file():
            print(f"{rel}: missing in {args.after}")
            bad += 1
            continue
        a, b = read(p), read(q)
        for name in sorted(set(a) | set(b)):
            if name not in a or name not in b:
                print(f"{rel}{name}: only in {'the first' if name in a else 'the second'}")
                bad += 1
                continue
            x, y = a[name], b[name]
            count += 1
            if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
                print(f"{rel}{name}: differs ({x.dtype}{x.shape} vs {y.dtype}{y.shape})")
                bad += 1
    print(f"{len(files)} files, {count} arrays compared; {bad} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
