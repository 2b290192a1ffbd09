"""Render one frame of a :class:`~blastvox.preview.geometry.PreviewScene` to 8-bit sRGB.

Layers, back to front: a sky gradient, the ground plane (a grid every 1, 10,
100 ... m to suit the shot, fading into haze), the pieces (flat-shaded
triangles, z-buffered), the particles (soft splats, far to near) and the shock
fronts (translucent spheres, brightest at their silhouette). Shading is
Lambert with ambient light in linear RGB: ``albedo * (AMBIENT + SKY * (1 +
n.up) / 2 + KEY * max(0, n.L))``, the key light ``L`` fixed above, behind and
to the left of the camera (it does not shake with it), so the faces the
camera sees are lit. The image is rendered ``supersample`` times larger in
each direction, box-filtered down and encoded to sRGB.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blastvox.preview import raster
from blastvox.preview.camera import Camera
from blastvox.preview.geometry import PreviewScene
from blastvox.preview.options import LAYERS

NEAR_M = 0.05                                   #: near clipping plane, m
AMBIENT, SKY, KEY = 0.22, 0.18, 0.8             #: light weights (albedo 1 faces)
SKY_TOP = np.array([0.22, 0.34, 0.55])          #: linear RGB, top of the frame
SKY_HORIZON = np.array([0.62, 0.66, 0.70])      #: linear RGB, bottom of the frame; haze
GROUND_ALBEDO = np.array([0.13, 0.13, 0.12])
SHOCK_TINT = np.array([0.85, 0.92, 1.0])
MAX_SPLAT_FRACTION = 20.0  #: a particle's radius on screen is at most 1/20 of the height


@dataclass(frozen=True)
class RenderSettings:
    """width, height: output pixels; supersample: samples per pixel along each axis;
    layers: which of :data:`LAYERS` to draw."""

    width: int = 960
    height: int = 540
    supersample: int = 2
    layers: frozenset[str] = frozenset(LAYERS)


def key_light(camera: Camera, up: np.ndarray) -> np.ndarray:
    """Unit (3,) direction towards the key light: above, behind and left of ``camera``."""
    right, forward = camera.rotation[0], camera.rotation[2]
    light = 0.8 * up - 0.5 * forward - 0.45 * right
    return light / np.linalg.norm(light)


def shade(normals: np.ndarray, up: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Lighting factor (T,) of unit world normals (T, 3) (see the module doc)."""
    return AMBIENT + SKY * 0.5 * (1.0 + normals @ up) + KEY * np.maximum(normals @ light, 0.0)


def grid_step(size_m: float) -> float:
    """Ground grid spacing (m): a power of ten, about a quarter of ``size_m`` or less."""
    return float(10.0 ** np.floor(np.log10(max(size_m, 1e-3) / 4.0)))


class Renderer:
    """Renders frames of ``scene``; buffers are allocated once and reused."""

    def __init__(self, scene: PreviewScene, settings: RenderSettings, light: np.ndarray,
                 grid_m: float, fog_m: float) -> None:
        """light: unit (3,) towards the key light; grid_m: ground grid step (m);
        fog_m: the ground's haze distance (m)."""
        self.scene = scene
        self.settings = settings
        self.light = np.asarray(light, dtype=np.float64)
        self.grid_m = float(grid_m)
        self.fog_m = float(fog_m)
        ss = settings.supersample
        self.big = (settings.height * ss, settings.width * ss)
        self.color = np.empty((*self.big, 3), dtype=np.float32)
        self.depth = np.empty(self.big, dtype=np.float32)
        self.target = raster.Target(self.color, self.depth)
        self.lut = raster.srgb_lut()
        up = scene.up
        self.axis_u = np.roll(up, 1)
        self.axis_v = np.cross(up, self.axis_u)
        self.view = np.empty((len(scene.tri_local), 3, 3))            # scratch, view space
        self.shaded = np.empty((len(scene.tri_local), 3), np.float32)   # scratch, colours
        self._backdrop_key: tuple | None = None
        self._backdrop_color = self._backdrop_depth = None

    def _backdrop(self, camera: Camera, pinhole: raster.Pinhole) -> None:
        """Sky and ground into the buffers; kept and copied while the camera stands still
        (they depend on nothing else)."""
        key = (camera.eye.tobytes(), camera.rotation.tobytes(), pinhole.fpx)
        if self._backdrop_key == key:
            np.copyto(self.color, self._backdrop_color)
            np.copyto(self.depth, self._backdrop_depth)
            return
        scene = self.scene
        raster.fill_background(self.target, SKY_TOP, SKY_HORIZON)
        if "ground" in self.settings.layers and scene.ground_height is not None:
            ground_shade = float(shade(scene.up[None, :], scene.up, self.light)[0])
            ground = raster.Ground(
                up=scene.up, height=scene.ground_height, axis_u=self.axis_u, axis_v=self.axis_v,
                grid_step=self.grid_m, albedo=GROUND_ALBEDO, shade=ground_shade,
                fog_distance=self.fog_m, fog_color=SKY_HORIZON)
            raster.draw_ground(self.target, pinhole, ground)
        self._backdrop_key = key
        self._backdrop_color = self.color.copy()
        self._backdrop_depth = self.depth.copy()

    def render(self, frame: int, camera: Camera) -> np.ndarray:
        """(height, width, 3) uint8 sRGB image of ``frame`` seen through ``camera``."""
        s, scene = self.settings, self.scene
        hb, wb = self.big
        pinhole = raster.Pinhole(rotation=camera.rotation, eye=camera.eye,
                                 fpx=camera.focal_px(wb), cx=wb / 2.0, cy=hb / 2.0, near=NEAR_M)
        self._backdrop(camera, pinhole)
        if "pieces" in s.layers and len(scene.tri_local):
            p = scene.pieces_at(frame)
            # view = Rc (Rp x + t - eye): one matrix and one offset per piece
            matrix = np.ascontiguousarray(camera.rotation[None] @ p.rotation)   # (P, 3, 3)
            offset = (p.position - camera.eye) @ camera.rotation.T              # (P, 3)
            count = raster.transform_triangles(
                raster.Triangles(p.local, p.normals, p.piece, p.albedo),
                raster.Poses(p.rotation, matrix, offset, p.alive),
                raster.Lighting(scene.up, self.light, AMBIENT, SKY, KEY), self.view, self.shaded)
            raster.draw_triangles(self.target, pinhole, self.view[:count], self.shaded[:count])
        if "particles" in s.layers and len(scene.particle_birth):
            q = scene.particles_at(frame)
            if len(q.position):
                view = camera.to_view(q.position)
                order = np.argsort(-view[:, 2], kind="stable")  # far to near
                ss = s.supersample
                splats = raster.Splats(view[order], q.radius[order],
                                       q.color[order].astype(np.float32),
                                       q.alpha[order].astype(np.float32))
                raster.draw_splats(self.target, pinhole, splats, 0.75 * ss,
                                   hb / MAX_SPLAT_FRACTION)
        if "shock" in s.layers:
            centres, radius, opacity = scene.shock_at(frame)
            live = (radius > 0) & (opacity > 0)
            if live.any():
                raster.draw_spheres(self.target, pinhole, camera.to_view(centres[live]),
                                    radius[live], opacity[live], SHOCK_TINT)
        out = np.empty((s.height, s.width, 3), dtype=np.uint8)
        raster.resolve(self.color, s.supersample, self.lut, out)
        return out
