"""What a motion capture's frames show, measured before retargeting: its up axis, the
frames its skeleton is matched on, the dancer's height.

All of it from forward kinematics (the joints' world positions frame by frame), never
from the zero pose alone: a rig's zero pose may lie in any direction (every bone along
its own X axis), while its frames show a person standing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loosefit.motion.joint_names import classify_joint_name

# Height from a standing frame: the head joint (the base of the skull) above the lower
# ankle is this fraction of the stature. Measured: the avatar 1.363 m of 1.580 m (0.863);
# the CMU salsa and ballet dancers 1.69-1.72 times their hip-to-ankle legs at their most
# extended frame, which at the avatar's legs-to-stature 0.485 is 0.82-0.83;
# anthropometric tables (base of the skull 0.87, ankle 0.04 of the stature) give 0.83.
HEAD_ANKLE_TO_HEIGHT = 0.85
# Height from the legs' hip-to-ankle length (anthropometric tables 0.47-0.49; the avatar
# 0.485): used when the dancer never stands straight in the clip.
LEG_TO_HEIGHT = 0.48
# The dancer "stands straight" in some frame when the frame's height reaches this
# fraction of the legs' (a clip danced crouching or on the floor throughout does not).
STRAIGHT = 0.85

# With up guessed, the way the skeleton faces (a right-handed frame whose left is the
# avatar's +X for the usual ones: Y up facing +Z, Z up facing -Y).
FORWARD_FOR_UP = {"+y": "+z", "-y": "-z", "+z": "-y", "-z": "+y", "+x": "+z", "-x": "-z"}


def guess_up(names: list[str] | tuple[str, ...], positions: np.ndarray) -> str | None:
    """The file's up axis from its frames: the signed axis from the feet to the head.

    Args:
        names: J joint names (a head and feet found by name, see
            :func:`~loosefit.motion.joint_names.classify_joint_name`).
        positions: (T, J, 3) world joint positions in the file's axes.

    Returns:
        "+y", "-z", ...; None when the names show no head or no foot, or no axis holds
        most (70 %) of the mean feet-to-head direction.
    """
    parts = [classify_joint_name(n).part for n in names]
    head = [j for j, p in enumerate(parts) if p == "head"]
    feet = [j for j, p in enumerate(parts) if p in ("foot", "toe")]
    if not head or not feet:
        return None
    d = (positions[:, head].mean(1) - positions[:, feet].mean(1)).mean(0)  # (3,)
    k = int(np.argmax(np.abs(d)))
    if abs(d[k]) < 0.7 * np.linalg.norm(d):
        return None
    return ("+" if d[k] > 0 else "-") + "xyz"[k]


def matching_frames(num_frames: int) -> list[int]:
    """The frames the joint matcher tries after the zero pose: the first, the middle,
    the quarters (a capture's first frame is usually its standing reference pose)."""
    picks = [0, num_frames // 2, num_frames // 4, (3 * num_frames) // 4]
    return list(dict.fromkeys(min(max(t, 0), num_frames - 1) for t in picks))


def face_forward(points: np.ndarray, forward: np.ndarray) -> np.ndarray:
    """(J, 3) points turned about +Z so that the horizontal ``forward`` points to -Y."""
    yaw = np.arctan2(forward[0], -forward[1])  # angle from -Y to forward, about +Z
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # turns forward onto -Y
    return points @ R.T


@dataclass(frozen=True)
class HeightMeasure:
    """The dancer's height and how it was measured.

    Attributes:
        height: metres, as the file was read (its unit).
        frame: the frame measured (None: bone lengths, or no frame).
        how: a few words for messages, e.g. "head 1.41 m above the ankles at frame 0,
            the most extended".
    """

    height: float
    frame: int | None
    how: str


def _leg(positions: np.ndarray, present: dict[str, int], side: str) -> float | None:
    ids = [present.get(f"{side}{b}") for b in ("UpLeg", "Leg", "Foot")]
    if None in ids:
        return None
    a, b, c = (positions[:, i] for i in ids)
    return float(np.median(np.linalg.norm(b - a, axis=-1) + np.linalg.norm(c - b, axis=-1)))


def measure_height(
    positions: np.ndarray, present: dict[str, int], extra: np.ndarray | None = None
) -> HeightMeasure:
    """The dancer's standing height from the capture's frames.

    With a head and the ankles mapped: the head above the lower ankle at the frame where
    that is largest (the most extended), over :data:`HEAD_ANKLE_TO_HEIGHT`; if the dancer
    never stands that straight (below :data:`STRAIGHT` of what the legs say), the legs'
    hip-to-ankle length over :data:`LEG_TO_HEIGHT`. Without them: the skeleton's vertical
    extent (joints and ``extra`` points) at the median frame.

    Args:
        positions: (T, Js, 3) world joint positions, avatar axes (Z up), metres.
        present: avatar joint -> source joint index (may be empty).
        extra: (T, E, 3) more points (End Sites) for the extent, or None.

    Returns:
        The measure.
    """
    z = positions[..., 2]  # (T, Js)
    feet = [present[a] for a in ("LeftFoot", "RightFoot") if a in present]
    legs = [x for x in (_leg(positions, present, s) for s in ("Left", "Right")) if x]
    by_legs = float(np.mean(legs)) / LEG_TO_HEIGHT if legs else None
    if "Head" in present and feet:
        h = z[:, present["Head"]] - z[:, feet].min(1)  # (T,)
        t = int(np.argmax(h))
        height = float(h[t]) / HEAD_ANKLE_TO_HEIGHT
        if by_legs is None or height >= STRAIGHT * by_legs:
            return HeightMeasure(
                height, t, f"head {h[t]:.3g} m above the ankles at frame {t}, the most extended"
            )
        return HeightMeasure(
            by_legs,
            None,
            f"legs {by_legs * LEG_TO_HEIGHT:.3g} m hip to "
            f"ankle; the head is {h[t]:.3g} m above the ankles at most "
            f"(frame {t}): the dancer never stands straight",
        )
    if by_legs is not None:
        return HeightMeasure(by_legs, None, f"legs {by_legs * LEG_TO_HEIGHT:.3g} m hip to ankle")
    if extra is not None and extra.shape[1]:
        z = np.concatenate([z, extra[..., 2]], axis=1)
    extent = z.max(1) - z.min(1)  # (T,)
    t = int(np.argsort(extent)[len(extent) // 2])
    return HeightMeasure(
        float(extent[t]),
        t,
        f"the skeleton's extent at frame {t}, the median frame; no head and feet found",
    )
