"""Pinhole cameras for previews: the scene's camera (with its shake) or an automatic one.

Conventions match the exports (blastvox.export.usd/gltf): a 36 x 24 mm film
back and ``focal_length_mm``; the horizontal aperture fits the image width, so
the focal length in pixels is ``focal_mm / 36 * width``. The camera's up
vector is the model's up axis (no roll). Everything is in the model (world)
frame, metres.

View space (what :mod:`blastvox.preview.raster` draws) has the camera at the
origin, x right, y up and z forward along the line of sight:
``view = rotation @ (world - eye)``, with the rows of ``rotation`` the right,
up and forward vectors (a left-handed basis).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

APERTURE_MM = 36.0        #: horizontal film back, as the USD/glTF exports
AUTO_FOCAL_MM = 35.0      #: focal length of the automatic camera
AUTO_ELEVATION_DEG = 15.0  #: the automatic camera looks down at this angle
AUTO_AZIMUTH_DEG = 30.0   #: and this far round from the charge side (or the front)
AUTO_FILL = 0.85          #: the action fills this fraction of the frame's half-extent


@dataclass(frozen=True)
class Camera:
    """eye (3,) m; rotation (3, 3) world -> view (rows right, up, forward); focal_mm."""

    eye: np.ndarray
    rotation: np.ndarray
    focal_mm: float

    def focal_px(self, width: int) -> float:
        """Focal length in pixels for an image ``width`` pixels wide."""
        return self.focal_mm / APERTURE_MM * width

    def shifted(self, offset: np.ndarray) -> Camera:
        """The same camera moved by ``offset`` (3,) m (camera shake: no rotation)."""
        return replace(self, eye=self.eye + np.asarray(offset, dtype=np.float64))

    def to_view(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) m -> view space (..., 3) m."""
        return (np.asarray(points, dtype=np.float64) - self.eye) @ self.rotation.T

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """World points (..., 3) -> (..., 3): pixel x, pixel y (from the top-left corner
        of the image, pixel centres at +0.5) and view depth z (m)."""
        v = self.to_view(points)
        f = self.focal_px(width)
        z = v[..., 2]
        return np.stack([width / 2 + f * v[..., 0] / z, height / 2 - f * v[..., 1] / z, z],
                        axis=-1)


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray, focal_mm: float) -> Camera:
    """A camera at ``eye`` (3,) m looking at ``target`` (3,) m with ``up`` (3,) kept up.

    Looking straight along ``up`` (no horizon to keep level) picks another
    axis as up, as the exports do.
    """
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-9:
        right = np.cross(forward, np.roll(up, 1))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    return Camera(eye=eye, rotation=np.stack([right, true_up, forward]), focal_mm=float(focal_mm))


def scene_camera(camera: dict, up: np.ndarray) -> Camera:
    """The SimCache's ``meta["camera"]`` (position, look_at in m, focal_length_mm)."""
    return look_at(np.asarray(camera["position"], dtype=np.float64),
                   np.asarray(camera["look_at"], dtype=np.float64), up,
                   float(camera.get("focal_length_mm", 35.0)))


def _horizontal(vector: np.ndarray, up: np.ndarray) -> np.ndarray:
    return vector - np.dot(vector, up) * up


def auto_camera(box_min: np.ndarray, box_max: np.ndarray, up: np.ndarray,
                aspect: float, toward: np.ndarray | None = None,
                focal_mm: float = AUTO_FOCAL_MM) -> Camera:
    """A camera that frames the box ``box_min``..``box_max`` (3,) m.

    It looks at the box centre from ``AUTO_ELEVATION_DEG`` above the horizon,
    turned ``AUTO_AZIMUTH_DEG`` about ``up`` from the horizontal direction
    ``toward`` (3,) (the side of the charge; default: the model's front, -Y
    for Z-up and +Z for Y-up models), and backs off until all eight corners
    fall within ``AUTO_FILL`` of the half-width and half-height of an image of
    width/height ``aspect``.
    """
    lo, hi = np.asarray(box_min, dtype=np.float64), np.asarray(box_max, dtype=np.float64)
    centre = 0.5 * (lo + hi)
    if toward is None or np.linalg.norm(_horizontal(np.asarray(toward, float), up)) < 1e-9:
        toward = np.array([0.0, 0.0, 1.0]) if up[1] > 0.5 else np.array([0.0, -1.0, 0.0])
    side = _horizontal(np.asarray(toward, dtype=np.float64), up)
    side /= np.linalg.norm(side)
    turn = math.radians(AUTO_AZIMUTH_DEG)
    side = side * math.cos(turn) + np.cross(up, side) * math.sin(turn)
    elevation = math.radians(AUTO_ELEVATION_DEG)
    direction = side * math.cos(elevation) + up * math.sin(elevation)  # centre -> eye
    corners = np.array([[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 1e-3)
    tan_x = APERTURE_MM / 2.0 / focal_mm
    tan_y = tan_x / aspect

    def fits(distance: float) -> bool:
        cam = look_at(centre + direction * distance, centre, up, focal_mm)
        v = cam.to_view(corners)
        if np.any(v[:, 2] <= 1e-6):
            return False
        return bool(np.all(np.abs(v[:, 0] / v[:, 2]) <= AUTO_FILL * tan_x)
                    and np.all(np.abs(v[:, 1] / v[:, 2]) <= AUTO_FILL * tan_y))

    near, far = radius * 1e-3, radius / math.sin(math.atan(min(tan_x, tan_y) * AUTO_FILL)) * 2
    while not fits(far):  # cannot happen for a sane box, but never loop forever
        far *= 2.0
        if far > 1e12:
            break
    for _ in range(60):  # bisection: the closest distance at which the box fits
        mid = 0.5 * (near + far)
        if fits(mid):
            far = mid
        else:
            near = mid
    return look_at(centre + direction * far, centre, up, focal_mm)
