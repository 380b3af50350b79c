"""Cameras: view / projection matrices, named views, framing a sequence and following it.

Matrices are (4, 4) float32 numpy arrays acting on column vectors
(``p_clip = proj @ view @ p_world``), in OpenGL conventions: the camera looks
down its -z axis and clip space depth runs from -1 (near) to +1 (far). Upload
them to GLSL as ``M.T`` (column-major).

Named views (the avatar faces -Y, its left hand points to +X). The azimuth is
measured from -Y, counter-clockwise seen from above, so the camera direction
(from the target to the eye) is ``(sin az cos el, -cos az cos el, sin el)``:

=============  =======  ==========================================================
name           azimuth  where the camera is
=============  =======  ==========================================================
front          0        at -Y looking +Y: sees the avatar's face, its left on the image right
side           90       at +X looking -X: sees the avatar's left side, facing image left
back           180      at +Y looking -Y
three_quarter  40       front-left, between "front" and "side"
top            0        straight above (elevation 90), the avatar's front at the image bottom
=============  =======  ==========================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from loosefit.errors import LoosefitInputError

Vec3 = Sequence[float] | np.ndarray


def _unit(v: np.ndarray, source: str, field: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n < 1e-12:
        raise LoosefitInputError(source, field, "a finite non-zero vector", f"{np.asarray(v)}")
    return v / n


def look_at(eye: Vec3, target: Vec3, up: Vec3 = (0.0, 0.0, 1.0)) -> np.ndarray:
    """World-to-camera matrix of a camera at ``eye`` looking at ``target``.

    Args:
        eye: (3,) camera position.
        target: (3,) point the camera looks at (maps to the image centre).
        up: (3,) world direction that appears upwards in the image; must not be
            parallel to ``target - eye``.

    Returns:
        (4, 4) float32 view matrix.
    """
    eye = np.asarray(eye, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    forward = _unit(target - eye, "look_at", "target - eye")
    right = np.cross(forward, np.asarray(up, dtype=np.float64))
    if np.linalg.norm(right) < 1e-9:
        raise LoosefitInputError(
            "look_at", "up", "a vector not parallel to the viewing direction", f"{np.asarray(up)}"
        )
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = right, true_up, -forward
    m[:3, 3] = -m[:3, :3] @ eye
    return m.astype(np.float32)


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """OpenGL perspective projection.

    Args:
        fov_y_deg: vertical field of view, degrees.
        aspect: width / height of the image.
        near: distance of the near clipping plane (> 0).
        far: distance of the far clipping plane (> near).

    Returns:
        (4, 4) float32 projection matrix.
    """
    if not (0.0 < fov_y_deg < 180.0 and aspect > 0.0 and 0.0 < near < far):
        raise LoosefitInputError(
            "perspective",
            "fov_y_deg, aspect, near, far",
            "0 < fov < 180, aspect > 0, 0 < near < far",
            f"{fov_y_deg}, {aspect}, {near}, {far}",
        )
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m.astype(np.float32)


def orthographic(
    left: float, right: float, bottom: float, top: float, near: float, far: float
) -> np.ndarray:
    """OpenGL orthographic projection (``glOrtho``) of the camera-space box given.

    ``near`` and ``far`` are distances along the viewing direction and may be negative.

    Returns:
        (4, 4) float32 projection matrix.
    """
    if not (right > left and top > bottom and far > near):
        raise LoosefitInputError(
            "orthographic",
            "left, right, bottom, top, near, far",
            "right > left, top > bottom, far > near",
            f"{left}, {right}, {bottom}, {top}, {near}, {far}",
        )
    m = np.eye(4)
    m[0, 0] = 2.0 / (right - left)
    m[1, 1] = 2.0 / (top - bottom)
    m[2, 2] = -2.0 / (far - near)
    m[0, 3] = -(right + left) / (right - left)
    m[1, 3] = -(top + bottom) / (top - bottom)
    m[2, 3] = -(far + near) / (far - near)
    return m.astype(np.float32)


@dataclass(frozen=True)
class CameraView:
    """A camera placed on a sphere around the framed target."""

    name: str  # label drawn on the image
    azimuth_deg: float  # from -Y (the avatar's front), counter-clockwise seen from above
    elevation_deg: float  # above the horizon; 90 looks straight down
    distance: float | None = None  # metres from the target; None fits the bounds
    fov_y_deg: float = 30.0  # vertical field of view, degrees
    margin: float = 1.08  # fitted framing leaves this factor of room around the bounds

    def direction(self) -> np.ndarray:
        """(3,) unit vector from the target to the eye."""
        az, el = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        return np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])

    def up(self) -> np.ndarray:
        """(3,) world direction shown upwards: +Z, or for (near) vertical views the far side."""
        if abs(self.elevation_deg) < 89.0:
            return np.array([0.0, 0.0, 1.0])
        az = math.radians(self.azimuth_deg)
        sign = 1.0 if self.elevation_deg > 0 else -1.0
        return sign * np.array([-math.sin(az), math.cos(az), 0.0])


_NAMED_VIEWS = (
    CameraView("front", 0.0, 8.0),
    CameraView("side", 90.0, 8.0),
    CameraView("back", 180.0, 8.0),
    CameraView("three_quarter", 40.0, 15.0),
    CameraView("top", 0.0, 90.0),
)
VIEW_NAMES = tuple(v.name for v in _NAMED_VIEWS)


def named_view(view: str | CameraView) -> CameraView:
    """The :class:`CameraView` named ``view`` (one of ``VIEW_NAMES``); CameraViews pass through."""
    if isinstance(view, CameraView):
        return view
    for v in _NAMED_VIEWS:
        if v.name == view:
            return v
    raise LoosefitInputError("views", "view name", f"one of {list(VIEW_NAMES)}", repr(view))


def _basis(view: CameraView) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(direction, right, up) unit vectors of the camera, in world space."""
    d = view.direction()
    right = np.cross(-d, view.up())
    right /= np.linalg.norm(right)
    return d, right, np.cross(right, -d)


def fit_distance(view: CameraView, bounds_min: Vec3, bounds_max: Vec3, aspect: float) -> float:
    """Smallest distance from the box centre at which the whole box is in the picture.

    Exact for the 8 box corners under perspective (not a bounding-sphere bound),
    scaled by ``view.margin``.

    Args:
        view: camera direction and field of view.
        bounds_min, bounds_max: (3,) corners of the axis-aligned box to frame.
        aspect: image width / height.
    """
    lo, hi = np.asarray(bounds_min, float), np.asarray(bounds_max, float)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = signs * (hi - lo) / 2  # (8, 3) relative to the box centre
    d, right, up = _basis(view)
    tan_v = math.tan(math.radians(view.fov_y_deg) / 2) / view.margin
    tan_h = tan_v * aspect
    towards = corners @ d  # (8,) how far each corner sticks out towards the camera
    need = towards + np.maximum(np.abs(corners @ right) / tan_h, np.abs(corners @ up) / tan_v)
    return float(max(need.max(), 1e-3))


def view_matrices(
    view: CameraView,
    bounds_min: Vec3,
    bounds_max: Vec3,
    aspect: float,
    distance: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """View and projection matrices that frame the box ``[bounds_min, bounds_max]``.

    Args:
        view: where the camera is; ``view.distance`` (or ``distance``) overrides the fit.
        bounds_min, bounds_max: (3,) corners of the box; its centre is the look-at target.
        aspect: image width / height.
        distance: camera distance to use instead of fitting (e.g. one fitted elsewhere).

    Returns:
        view (4, 4) and projection (4, 4) float32 matrices.
    """
    lo, hi = np.asarray(bounds_min, float), np.asarray(bounds_max, float)
    target = (lo + hi) / 2
    if distance is None:
        distance = view.distance or fit_distance(view, lo, hi, aspect)
    radius = float(np.linalg.norm(hi - lo)) / 2
    eye = target + distance * view.direction()
    near = max(0.02, 0.5 * (distance - radius))
    far = 3.0 * (distance + radius) + 10.0
    return look_at(eye, target, view.up()), perspective(view.fov_y_deg, aspect, near, far)


def frame_views(
    views: Sequence[str | CameraView],
    bounds_min: Vec3,
    bounds_max: Vec3,
    aspect: float = 1.0,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Cameras at the given views that each fit the box ``[bounds_min, bounds_max]``.

    Pass the bounds of a whole sequence (all frames) so the camera never jumps.

    Args:
        views: names from ``VIEW_NAMES`` or :class:`CameraView` objects.
        bounds_min, bounds_max: (3,) corners of the box to frame.
        aspect: image width / height.

    Returns:
        one ``(view (4, 4), proj (4, 4))`` pair per view.
    """
    return [view_matrices(named_view(v), bounds_min, bounds_max, aspect) for v in views]


def smooth_track(points: np.ndarray, sigma_frames: float) -> np.ndarray:
    """Zero-lag Gaussian smoothing of a per-frame track.

    The ends are padded by point reflection, so a track moving at constant velocity
    is returned unchanged (no drift or lag at the first and last frames).

    Args:
        points: (T, D) float track.
        sigma_frames: standard deviation of the Gaussian in frames; 0 returns a copy.

    Returns:
        (T, D) float64 smoothed track.
    """
    points = np.asarray(points, dtype=np.float64)
    if sigma_frames <= 0 or len(points) < 2:
        return points.copy()
    radius = int(math.ceil(3 * sigma_frames))
    k = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma_frames) ** 2)
    k /= k.sum()  # (2r+1,)
    padded = np.pad(points, ((radius, radius), (0, 0)), mode="reflect", reflect_type="odd")
    return np.stack(
        [np.convolve(padded[:, j], k, mode="valid") for j in range(points.shape[1])], axis=-1
    )


@dataclass
class CameraTrack:
    """Cameras for every frame of a sequence and every view.

    Attributes:
        names: N view labels.
        view: (T, N, 4, 4) float32 view matrices.
        proj: (N, 4, 4) float32 projection matrices.
        eye: (T, N, 3) float32 camera positions.
        target: (T, 3) float32 look-at points (shared by all views).
    """

    names: list[str]
    view: np.ndarray
    proj: np.ndarray
    eye: np.ndarray
    target: np.ndarray


def camera_track(
    views: Sequence[str | CameraView],
    frame_min: np.ndarray,
    frame_max: np.ndarray,
    aspect: float = 1.0,
    *,
    follow_centres: np.ndarray | None = None,
    follow_sigma_frames: float = 8.0,
) -> CameraTrack:
    """Cameras for a sequence, fixed or following the character horizontally.

    Without ``follow_centres`` every frame uses one camera per view fitted to the
    bounds of all frames. With them, the look-at target moves with the smoothed
    XY of the centres (its height stays fixed) and the distance is fitted once to
    the largest box seen relative to the moving centre, so the picture neither
    jumps nor zooms.

    Args:
        views: names from ``VIEW_NAMES`` or :class:`CameraView` objects (N of them).
        frame_min, frame_max: (T, 3) per-frame bounds of everything to keep in view.
        aspect: image width / height.
        follow_centres: (T, 3) per-frame point to follow (e.g. the body's mean vertex), or None.
        follow_sigma_frames: Gaussian smoothing of the followed XY, in frames.

    Returns:
        a :class:`CameraTrack`.
    """
    frame_min = np.asarray(frame_min, dtype=np.float64)
    frame_max = np.asarray(frame_max, dtype=np.float64)
    T = len(frame_min)
    offset = np.zeros((T, 3))  # per-frame shift of the framed box
    if follow_centres is not None:
        c = np.asarray(follow_centres, dtype=np.float64)
        if c.shape != (T, 3):
            raise LoosefitInputError(
                "camera_track", "follow_centres", f"shape ({T}, 3)", str(c.shape)
            )
        offset[:, :2] = smooth_track(c[:, :2], follow_sigma_frames)
    box_min = (frame_min - offset).min(axis=0)  # (3,) in the moving frame
    box_max = (frame_max - offset).max(axis=0)
    cams = [named_view(v) for v in views]
    N = len(cams)
    view = np.empty((T, N, 4, 4), np.float32)
    proj = np.empty((N, 4, 4), np.float32)
    eye = np.empty((T, N, 3), np.float32)
    centre = (box_min + box_max) / 2
    for i, cam in enumerate(cams):
        dist = cam.distance or fit_distance(cam, box_min, box_max, aspect)
        _, proj[i] = view_matrices(cam, box_min, box_max, aspect, distance=dist)
        for t in range(T):
            if t > 0 and follow_centres is None:
                view[t, i], eye[t, i] = view[0, i], eye[0, i]
                continue
            target = centre + offset[t]
            eye[t, i] = target + dist * cam.direction()
            view[t, i] = look_at(eye[t, i], target, cam.up())
    return CameraTrack(
        [c.name for c in cams], view, proj, eye, (centre + offset).astype(np.float32)
    )


def light_track(
    light_dir: Vec3, frame_min: np.ndarray, frame_max: np.ndarray, map_size: int
) -> tuple[np.ndarray, np.ndarray]:
    """Orthographic shadow cameras of a directional light, one per frame.

    Each frame's light box is centred on that frame's bounds but has the size
    of the largest frame, and its centre is snapped to whole shadow-map texels,
    so shadow edges do not shimmer as the scene moves.

    Args:
        light_dir: (3,) direction from the scene towards the light.
        frame_min, frame_max: (T, 3) per-frame bounds of the shadow casters.
        map_size: shadow map resolution in texels.

    Returns:
        view (T, 4, 4) and proj (T, 4, 4) float32 matrices.
    """
    L = _unit(np.asarray(light_dir, float), "light_track", "light_dir")
    up = (0.0, 1.0, 0.0) if abs(L[2]) > 0.99 else (0.0, 0.0, 1.0)
    view = look_at(L, (0.0, 0.0, 0.0), up).astype(np.float64)  # fixed orientation
    frame_min = np.asarray(frame_min, float)
    frame_max = np.asarray(frame_max, float)
    signs = np.array([[sx, sy, sz] for sx in (0, 1) for sy in (0, 1) for sz in (0, 1)])  # (8, 3)
    corners = frame_min[:, None] + signs[None] * (frame_max - frame_min)[:, None]  # (T, 8, 3)
    # Include where the highest corners' shadows land on the floor, so receivers fit in depth.
    drop = corners.copy()
    drop[..., :2] -= corners[..., 2:3] * L[:2] / max(L[2], 0.1)
    drop[..., 2] = 0.0
    pts = np.concatenate([corners, drop], axis=1)  # (T, 16, 3)
    ls = pts @ view[:3, :3].T + view[:3, 3]  # (T, 16, 3) in light space
    lo, hi = ls.min(axis=1), ls.max(axis=1)  # (T, 3)
    half = ((hi - lo) / 2).max(axis=0) * 1.05 + 0.05  # (3,) constant over frames
    half[:2] = half[:2].max()  # square map
    texel = 2 * half[0] / map_size
    centre = (lo + hi) / 2  # (T, 3)
    centre[:, :2] = np.round(centre[:, :2] / texel) * texel
    T = len(frame_min)
    proj = np.empty((T, 4, 4), np.float32)
    for t in range(T):
        cx, cy, cz = centre[t]
        # Camera space looks down -z, so the distance along the view is -z.
        proj[t] = orthographic(
            cx - half[0], cx + half[0], cy - half[1], cy + half[1], -cz - half[2], -cz + half[2]
        )
    return np.repeat(view[None].astype(np.float32), T, axis=0), proj
