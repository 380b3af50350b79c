"""Record in an engine-tier checkpoint the range of its features over its training frames.

A tier trained by ``loosefit train engine`` records it; this adds it to one saved before
(the shipped ``engine.pt`` of the ``dance`` set, its weights unchanged)::

    python scripts/engine_feature_range.py --data datasets/dance \\
        src/loosefit/pretrained/dance/engine.pt checkpoints/dance/engine.pt
"""

from __future__ import annotations

import argparse

from loosefit.train.engine import record_feature_range


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("engines", nargs="+", help="engine.pt files, rewritten in place")
    p.add_argument("--data", required=True, help="the data set the tiers were trained on")
    args = p.parse_args()
    for path in args.engines:
        low, high = record_feature_range(path, args.data)
        print(f"{path}: the range of {len(low)} features recorded")


if __name__ == "__main__":
    main()
