"""The tolerance of a test that compares two simulations of the same cloth.

Two simulations of one clip by different paths (settled elsewhere, batched, another
schedule) agree within a multiple of what drawing the 0.1 mm start jitter again moves the
cloth, measured in the same run: folds fall one way or another with the processor's
rounding (OpenBLAS's and MKL's kernels are picked for the processor) as with the seed, so no
fixed distance holds on every machine. The floor covers a run whose reseeded folds happen
to fall as before (the tiny spin's seeds move it 0.4, 0.8 or 5.4 mm): the factor times the
largest spread measured on any target, rounded up. Both numbers come from
bench/data/test_tolerances.py (docs/design/TEST_TOLERANCES.md: seeds, processors' rounding,
and what a broken feature gives, 22 mm and more).
"""

from __future__ import annotations

import numpy as np

SEED_FACTOR = 2.0  # x the mean gap of a reseeded run
SEED_FLOOR = 0.012  # m: 2 x 5.4 mm, rounded up


def mean_gap(a: np.ndarray, b: np.ndarray) -> float:
    """The mean distance (m) between two (..., V, 3) arrays of vertices."""
    return float(np.linalg.norm(a - b, axis=-1).mean())


def seed_bound(spread: float) -> float:
    """The mean gap (m) allowed between two simulations of a clip whose reseeded runs are
    ``spread`` (m, mean gap) from it."""
    return max(SEED_FACTOR * spread, SEED_FLOOR)
