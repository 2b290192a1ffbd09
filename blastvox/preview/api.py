"""``preview(cache, path, options)``: the preview's one entry point.

The output's suffix picks what is made: ``.png`` a contact sheet of the chosen
frames (one frame: just that frame), each labelled with its frame number and
time; ``.gif`` / ``.mp4`` an animation of the chosen frames, each labelled in
its corner, at the shot's rate divided by the frame step (``--fps`` overrides).

The camera is the scene's (``meta["camera"]``, moved by the cache's
``camera_offset`` shake at each frame) when the cache has one, else an
automatic camera that frames the intact model and the 3rd-97th percentile of
the pieces' positions over the chosen frames, looking from the charge's side;
``--camera`` picks either or gives one explicitly. The automatic and explicit
cameras do not shake.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from blastvox.cache import SimCache
from blastvox.errors import BlastvoxError
from blastvox.preview import camera as cameras
from blastvox.preview.geometry import PreviewScene
from blastvox.preview.options import (
    FPS,
    CameraSpec,
    PreviewOptions,
    check_output_pixels,
    output_format,
    select_frames,
)
from blastvox.preview.render import Renderer, RenderSettings, grid_step, key_light

HAZE_FACTOR = 6.0  #: the ground fades to haze over this many camera-to-target distances


class _Progress:
    """The progress sink :func:`preview` reports to (no-ops here)."""

    def start(self, description: str, total: int) -> None: ...
    def advance(self, amount: int = 1) -> None: ...


@dataclass(frozen=True)
class PreviewResult:
    """What was written: kind ("sheet" or "animation"), frames drawn, pixel size of the
    file's image(s) (W, H), fps of an animation, and seconds spent rendering."""

    path: Path
    kind: str
    frames: list[int]
    size: tuple[int, int]
    fps: float | None
    render_seconds: float


@dataclass(frozen=True)
class Shot:
    """A prepared preview: the scene, the renderer, the base camera and whether it
    shakes with the cache's camera_offset."""

    scene: PreviewScene
    renderer: Renderer
    camera: cameras.Camera
    shake: bool

    def camera_at(self, frame: int) -> cameras.Camera:
        """The camera of ``frame`` (with the scene camera's shake)."""
        return self.camera.shifted(self.scene.camera_offset(frame)) if self.shake else self.camera

    def render(self, frame: int) -> np.ndarray:
        """(H, W, 3) uint8 image of ``frame``."""
        return self.renderer.render(frame, self.camera_at(frame))


def choose_camera(scene: PreviewScene, spec: CameraSpec | None, frames: list[int],
                  aspect: float, source: str = "SimCache") -> tuple[cameras.Camera, bool]:
    """(camera, shakes) for ``spec`` (None: the scene's camera if any, else auto)."""
    meta_camera = scene.cache.meta.get("camera")
    kind = spec.kind if spec is not None else ("scene" if meta_camera else "auto")
    if kind == "scene":
        if not meta_camera:
            raise BlastvoxError(f"--camera scene: {source} has no scene camera (the scene "
                                f"file had no [camera]); use --camera auto or "
                                f"PX,PY,PZ:LX,LY,LZ")
        return cameras.scene_camera(meta_camera, scene.up), True
    if kind == "explicit":
        assert spec is not None
        return cameras.look_at(np.asarray(spec.position), np.asarray(spec.look_at), scene.up,
                               spec.focal_mm), False
    lo, hi = scene.action_box(frames)
    return cameras.auto_camera(lo, hi, scene.up, aspect, scene.charge_direction(lo, hi)), False


def prepare(cache: SimCache, frames: list[int], options: PreviewOptions,
            source: str = "SimCache", camera_frames: list[int] | None = None) -> Shot:
    """Scene, camera and renderer for ``frames`` of ``cache``; an automatic camera frames
    ``camera_frames`` (default ``frames``: ``[0]`` frames the intact model, the same
    camera for every variant of a wedge)."""
    scene = PreviewScene(cache)
    width, height = options.size
    camera, shake = choose_camera(scene, options.camera, camera_frames or frames,
                                  width / height, source)
    lo, hi = scene.action_box(frames)
    distance = float(np.linalg.norm(camera.eye - 0.5 * (lo + hi)))
    settings = RenderSettings(width=width, height=height, supersample=options.supersample,
                              layers=frozenset(RenderSettings().layers - options.hide))
    renderer = Renderer(scene, settings, key_light(camera, scene.up),
                        grid_step(float(np.linalg.norm(hi - lo))),
                        HAZE_FACTOR * max(distance, 1e-3))
    return Shot(scene=scene, renderer=renderer, camera=camera, shake=shake)


def preview(cache: SimCache, path: str | Path, options: PreviewOptions | None = None,
            progress: _Progress | None = None, source: str = "SimCache") -> PreviewResult:
    """Render ``cache`` to ``path`` (.png contact sheet, .gif or .mp4 animation).

    ``source`` names the cache in error messages (the CLI passes its path).
    Raises :class:`BlastvoxError` for a bad format, frame range or camera, or a
    :class:`~blastvox.errors.BudgetError` for a sheet or GIF over the options'
    ``max_output_pixels``, before anything is allocated or written; the output is
    written atomically. Without ``options.fps`` an animation runs at the shot's rate
    divided by the frame step, held within :data:`~blastvox.preview.options.FPS`.
    """
    from blastvox.preview.sheet import contact_sheet, draw_label, frame_label
    from blastvox.preview.writers import write_gif, write_mp4, write_png

    options = options or PreviewOptions()
    progress = progress or _Progress()
    path = Path(path)
    suffix = output_format(path)
    width, height = options.size
    if suffix == ".mp4" and (width % 2 or height % 2):
        raise BlastvoxError(f"--size: {width}x{height}: MP4 (H.264, yuv420p) needs an even "
                            f"width and height")
    frames = select_frames(options.frames, cache.frame_count, suffix)
    check_output_pixels(options.size, len(frames), suffix, options.max_output_pixels)
    shot = prepare(cache, frames, options, source)
    times = shot.scene.times
    step = frames[1] - frames[0] if len(frames) > 1 else 1
    fps = options.fps or min(max(shot.scene.fps / step, FPS.lo), FPS.hi)
    spent = [0.0]

    def labelled() -> Iterator[np.ndarray]:
        progress.start("rendering", len(frames))
        for f in frames:
            started = time.perf_counter()
            image = shot.render(f)
            spent[0] += time.perf_counter() - started
            yield draw_label(image, frame_label(f, float(times[f])))
            progress.advance()

    if suffix == ".png":
        write_png(contact_sheet(list(labelled())), path)
        kind, rate = "sheet", None
    elif suffix == ".gif":
        write_gif(labelled(), path, fps)
        kind, rate = "animation", fps
    else:
        write_mp4(labelled(), path, (width, height), fps)
        kind, rate = "animation", fps
    return PreviewResult(path=path, kind=kind, frames=frames, size=(width, height), fps=rate,
                         render_seconds=spent[0])
