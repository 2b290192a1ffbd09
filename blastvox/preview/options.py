"""The preview's arguments: output format, --frames, --size, --camera, --hide, --fps, and
its pixel budgets.

Each parser raises :class:`~blastvox.errors.BlastvoxError` with a one-line
message naming the argument and what is wrong, before any work is done.

Budgets (docs/user-guide.md, "Limits and exit codes"), checked before anything is
allocated: a frame is rendered at ``--supersample`` x the size along each axis into
buffers of about 32 bytes a pixel, so ``W x H x S^2`` is at most ``--max-pixels``
(:data:`MAX_PIXELS`, 2 GiB of buffers); a .png contact sheet and a .gif keep every
frame in memory (about 6 bytes a pixel), so ``frames x W x H`` is at most
``--max-output-pixels`` (:data:`MAX_OUTPUT_PIXELS`); an .mp4 streams its frames.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blastvox.bounds import (
    COORDINATE,
    FOCAL_LENGTH_MM,
    MAX_OUTPUT_PIXELS,
    MAX_PIXELS,
    Bound,
    fmt,
)
from blastvox.errors import BlastvoxError, BudgetError

FORMATS = (".png", ".gif", ".mp4")
LAYERS = ("pieces", "ground", "particles", "shock")  #: what a preview draws
SHEET_FRAMES = 6          #: frames on a PNG contact sheet when --frames is not given
MAX_SIDE_PX = 8192
MIN_SIDE_PX = 16
#: Animation rates: a GIF delay is 1/100 s to 655 s; ffmpeg wants a sane rate.
FPS = Bound(0.01, 1000.0, unit="frames/s")
#: Explicit cameras: within +-1000 km (bounds.COORDINATE, m); focal length 1 mm to 10 m (mm).
FOCAL_MM = FOCAL_LENGTH_MM
MIN_CAMERA_DISTANCE_M = 1e-6


@dataclass(frozen=True)
class CameraSpec:
    """kind: "scene" (the SimCache's camera and shake), "auto" (framed automatically)
    or "explicit" (position and look_at in m, model frame, focal_mm; no shake)."""

    kind: str
    position: tuple[float, float, float] | None = None
    look_at: tuple[float, float, float] | None = None
    focal_mm: float = 35.0


@dataclass(frozen=True)
class PreviewOptions:
    """Everything ``blastvox preview`` takes besides the SimCache and the output path.

    frames: the parsed --frames (None: the format's default); camera: None picks
    the scene camera if the cache has one, else auto; size: (width, height) px
    of each frame; supersample: samples per pixel along each axis (1-4); hide:
    layers not drawn; fps: animation rate (None: the shot's rate / frame step, within
    :data:`FPS`); max_pixels, max_output_pixels: the budgets (see the module doc).
    The size, supersampling, rate and per-frame budget are checked on construction.
    """

    frames: FrameSpec | None = None
    camera: CameraSpec | None = None
    size: tuple[int, int] = (960, 540)
    supersample: int = 2
    hide: frozenset[str] = field(default_factory=frozenset)
    fps: float | None = None
    max_pixels: int = MAX_PIXELS
    max_output_pixels: int = MAX_OUTPUT_PIXELS

    def __post_init__(self) -> None:
        from blastvox.bounds import check_count

        check_count(self.max_pixels, "--max-pixels")
        check_count(self.max_output_pixels, "--max-output-pixels")
        width, height = self.size
        parse_size(f"{width}x{height}")
        check_supersample(self.supersample)
        check_fps(self.fps)
        check_render_pixels(self.size, self.supersample, self.max_pixels)


def check_render_pixels(size: tuple[int, int], supersample: int, max_pixels: int) -> int:
    """Pixels rendered per frame, ``W x H x S^2``, if within ``max_pixels``, else a
    one-line BudgetError naming --size, --supersample and --max-pixels."""
    width, height = size
    pixels = width * height * supersample * supersample
    if pixels > max_pixels:
        raise BudgetError(f"--size {width}x{height} at --supersample {supersample} renders "
                          f"{pixels:,} pixels a frame (about {pixels * 32 / 2**30:.3g} GiB of "
                          f"buffers), over the limit of {max_pixels:,} (raise it with "
                          f"--max-pixels)")
    return pixels


def check_output_pixels(size: tuple[int, int], frames: int, suffix: str,
                        max_output_pixels: int) -> int:
    """Pixels a .png sheet or a .gif keeps in memory, ``frames x W x H``, if within
    ``max_output_pixels`` (an .mp4 streams: no limit), else a one-line BudgetError."""
    width, height = size
    pixels = frames * width * height
    if suffix != ".mp4" and pixels > max_output_pixels:
        what = "a contact sheet" if suffix == ".png" else "a GIF"
        raise BudgetError(f"--size {width}x{height} x {frames:,} frames (--frames) is "
                          f"{pixels:,} pixels for {what}, over the limit of "
                          f"{max_output_pixels:,} (raise it with --max-output-pixels, or "
                          f"pick fewer frames or a smaller size, or write an .mp4)")
    return pixels


def output_format(path: str | Path) -> str:
    """The output's suffix, lower case, if it is one of :data:`FORMATS`."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise BlastvoxError(f"{path}: unknown preview format {suffix or '(no suffix)'!r}; use "
                            f"{', '.join(FORMATS)} (a contact sheet or an animation)")
    return suffix


def parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` in pixels, each 16..8192."""
    match = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text or "")
    if not match:
        raise BlastvoxError(f"--size: {text!r} is not WIDTHxHEIGHT in pixels (e.g. 960x540)")
    sides = []
    for name, digits in (("width", match.group(1)), ("height", match.group(2))):
        value = int(digits.lstrip("0") or "0") if len(digits.lstrip("0")) <= 9 else None
        if value is None or not MIN_SIDE_PX <= value <= MAX_SIDE_PX:
            shown = digits if value is None and len(digits) <= 30 else (
                f"{digits[:12]}... ({len(digits)} digits)" if value is None else value)
            raise BlastvoxError(f"--size: {name} {shown} px is outside "
                                f"{MIN_SIDE_PX}..{MAX_SIDE_PX}")
        sides.append(value)
    return sides[0], sides[1]


def _int(text: str, what: str, spec: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise BlastvoxError(f"--frames: {what} {text!r} in {spec!r} is not a whole "
                            f"number") from None


@dataclass(frozen=True)
class FrameSpec:
    """A parsed --frames: start and end frame (None: first and last), step, and text."""

    start: int | None
    stop: int | None
    step: int
    text: str


def parse_frame_spec(text: str | None) -> FrameSpec | None:
    """``A``, ``A:B`` or ``A:B:STEP`` (frames A to B inclusive, every STEP frames);
    empty parts default to the first frame, the last frame and a step of 1 (``::10``
    is every tenth frame). None stays None (the format's default)."""
    if text is None:
        return None
    parts = text.strip().split(":")
    if len(parts) > 3 or not text.strip():
        raise BlastvoxError(f"--frames: {text!r} is not A, A:B or A:B:STEP")
    if len(parts) == 1:
        start = stop = _int(parts[0].strip(), "frame", text)
        step = 1
    else:
        start = _int(parts[0].strip(), "start", text) if parts[0].strip() else None
        stop = _int(parts[1].strip(), "end", text) if parts[1].strip() else None
        step = (_int(parts[2].strip(), "step", text)
                if len(parts) == 3 and parts[2].strip() else 1)
    if step < 1:
        raise BlastvoxError(f"--frames: step {step} in {text!r} must be 1 or more")
    for what, value in (("start", start), ("end", stop)):
        if value is not None and value < 0:
            raise BlastvoxError(f"--frames: {what} frame {value} in {text!r} is negative")
    if start is not None and stop is not None and stop < start:
        raise BlastvoxError(f"--frames: {text!r} ends (frame {stop}) before it starts "
                            f"(frame {start})")
    return FrameSpec(start=start, stop=stop, step=step, text=text)


def select_frames(spec: FrameSpec | str | None, frame_count: int, suffix: str) -> list[int]:
    """Frame indices (0..frame_count-1) of a --frames spec for an output of ``suffix``.

    Without one, a PNG shows :data:`SHEET_FRAMES` frames spread evenly over the
    shot and an animation every frame.
    """
    if isinstance(spec, str):
        spec = parse_frame_spec(spec)
    last = frame_count - 1
    if frame_count <= 0:
        raise BlastvoxError("--frames: the SimCache has no frames")
    if spec is None:
        if suffix == ".png":
            count = min(SHEET_FRAMES, frame_count)
            return sorted({int(round(x)) for x in np.linspace(0, last, count)})
        return list(range(frame_count))
    start = 0 if spec.start is None else spec.start
    stop = last if spec.stop is None else spec.stop
    for what, value in (("start", start), ("end", stop)):
        if value > last:
            raise BlastvoxError(f"--frames: {what} frame {value} in {spec.text!r} is out of "
                                f"range; the SimCache has frames 0..{last}")
    if stop < start:
        raise BlastvoxError(f"--frames: {spec.text!r} ends (frame {stop}) before it starts "
                            f"(frame {start})")
    return list(range(start, stop + 1, spec.step))


def _vector(text: str, what: str, spec: str) -> tuple[float, float, float]:
    parts = text.split(",")
    if len(parts) != 3:
        raise BlastvoxError(f"--camera: {what} {text!r} in {spec!r} is not X,Y,Z")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise BlastvoxError(f"--camera: {what} {text!r} in {spec!r} is not three "
                            f"numbers") from None
    for axis, value in zip("XYZ", values, strict=True):
        COORDINATE.named(value, f"--camera {spec!r}: {what} {axis}")
    return values  # type: ignore[return-value]


def parse_camera(text: str | None) -> CameraSpec | None:
    """``scene``, ``auto`` or ``PX,PY,PZ:LX,LY,LZ[:FOCAL_MM]`` (position and look-at
    point in m, the model's frame; focal length in mm, default 35)."""
    if text is None:
        return None
    spec = text.strip()
    if spec.lower() in ("scene", "auto"):
        return CameraSpec(kind=spec.lower())
    parts = spec.split(":")
    if len(parts) not in (2, 3):
        raise BlastvoxError(f"--camera: {text!r} is not 'scene', 'auto' or "
                            f"PX,PY,PZ:LX,LY,LZ[:FOCAL_MM]")
    position = _vector(parts[0], "position", text)
    target = _vector(parts[1], "look-at point", text)
    focal = 35.0
    if len(parts) == 3:
        try:
            focal = float(parts[2])
        except ValueError:
            raise BlastvoxError(f"--camera: focal length {parts[2]!r} in {text!r} is not a "
                                f"number (mm)") from None
        FOCAL_MM.named(focal, f"--camera {text!r}: focal length")
    if math.dist(position, target) < MIN_CAMERA_DISTANCE_M:
        raise BlastvoxError(f"--camera: position and look-at point in {text!r} are the same "
                            f"(less than {fmt(MIN_CAMERA_DISTANCE_M)} m apart)")
    return CameraSpec(kind="explicit", position=position, look_at=target, focal_mm=focal)


def parse_hide(text: str | None) -> frozenset[str]:
    """Comma-separated layers to leave out: pieces, ground, particles, shock."""
    if not text:
        return frozenset()
    names = [p.strip().lower() for p in text.split(",") if p.strip()]
    for name in names:
        if name not in LAYERS:
            raise BlastvoxError(f"--hide: unknown layer {name!r}; use {', '.join(LAYERS)}")
    return frozenset(names)


def check_supersample(value: int) -> int:
    """--supersample: 1 to 4."""
    if not 1 <= value <= 4:
        raise BlastvoxError(f"--supersample: {value} is outside 1..4")
    return value


def check_fps(value: float | None) -> float | None:
    """--fps: a rate within :data:`FPS` (or None)."""
    return None if value is None else FPS.named(value, "--fps")

