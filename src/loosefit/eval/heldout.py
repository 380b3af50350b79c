"""Which clips of a simulated data set a model can be judged on.

:func:`validation_clips`: the clips the data set simulated but its split leaves out (no
model trained on them), without those whose simulation tore.
"""

from __future__ import annotations

from loosefit.data.format import DatasetReader

EXPLODED_STRAIN_P99 = 1.0  # a flagged clip whose simulation tore: no ground truth


def validation_clips(reader: DatasetReader) -> list[str]:
    """The clips a data set simulated but its split leaves out, but for those that tore."""
    split = set(reader.split("all"))
    out = []
    for name, entry in sorted(reader.manifest.get("sequences", {}).items()):
        strain = entry.get("quality", {}).get("strain_p99", 0.0)
        if name in split or not reader.sequence_path(name).is_file():
            continue
        if strain > EXPLODED_STRAIN_P99:
            print(f"[compare_sets] {name}: left out (its simulation tore: strain p99 {strain:.1f})")
            continue
        out.append(name)
    return out
