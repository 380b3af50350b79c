"""Print the SMPL template skeleton of ``loosefit.motion.smpl`` (``SMPL_OFFSETS`` and
``SMPL_END_OFFSETS``) as derived from the project's default avatar (anny) in a T-pose
(:func:`loosefit.motion.smpl.template_from_skeleton`), as Python to paste there.

    .venv/bin/python scripts/smpl_template.py
"""

from __future__ import annotations

import numpy as np

from loosefit.body.avatar import Avatar
from loosefit.motion.smpl import SMPL_JOINTS, template_from_skeleton


def main() -> None:
    offsets, ends = template_from_skeleton(Avatar().skeleton)

    def row(v: np.ndarray) -> str:
        return "[" + ", ".join(f"{x:.4f}" for x in np.round(v, 4) + 0.0) + "]"

    print("SMPL_OFFSETS = np.array([")
    for name, o in zip(SMPL_JOINTS, offsets, strict=True):
        print(f"    {row(o) + ',':<30}# {name}")
    print("])  # fmt: skip")
    print("SMPL_END_OFFSETS = {")
    for j, e in ends.items():
        tip = {20: "the left hand's", 21: "the right hand's", 10: "the left toes'",
               11: "the right toes'"}[j]  # fmt: skip
        print(f"    {j}: np.array({row(e)}),  # {tip} tip")
    print("}")


if __name__ == "__main__":
    main()
