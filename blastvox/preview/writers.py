"""Image and animation writers: PNG and GIF (Pillow), MP4 (imageio-ffmpeg's bundled ffmpeg).

Every writer writes atomically (a temporary file beside the output, renamed
on success; see :mod:`blastvox.io.atomic`), so a failed or interrupted
preview never leaves a partial file. PNG and GIF bytes depend only on the
pixels (no timestamps); MP4 is encoded with ffmpeg's ``+bitexact`` flags.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from blastvox.errors import BlastvoxError
from blastvox.io.atomic import atomic_path

MP4_QUALITY = 7.0  #: imageio-ffmpeg quality 0..10 (7: libx264 crf 15)


def write_png(image: np.ndarray, path: str | Path) -> None:
    """Write ``image`` (H, W, 3) uint8 sRGB as PNG."""
    from PIL import Image

    with atomic_path(path) as tmp:
        Image.fromarray(image).save(tmp, format="PNG")


def gif_frame_ms(fps: float) -> int:
    """GIF frame delay (ms) for ``fps``: GIF counts in 1/100 s, at least 20 ms
    (browsers slow faster GIFs down to 100 ms)."""
    return int(max(2, round(100.0 / fps)) * 10)


def write_gif(frames: Iterable[np.ndarray], path: str | Path, fps: float) -> int:
    """Write frames (each (H, W, 3) uint8) as a looping GIF at ``fps``; returns the count.

    Each frame gets its own 256-colour median-cut palette with Floyd-Steinberg
    dithering. Pillow merges a frame identical to the one before into it, so
    callers label frames (each then differs) to keep one GIF frame per frame.
    """
    from PIL import Image

    images = [Image.fromarray(f).quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                                          dither=Image.Dither.FLOYDSTEINBERG)
              for f in frames]
    if not images:
        raise BlastvoxError(f"{path}: no frames to write")
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                       duration=gif_frame_ms(fps), loop=0, optimize=False)
    return len(images)


def write_mp4(frames: Iterable[np.ndarray], path: str | Path, size: tuple[int, int],
              fps: float) -> int:
    """Stream frames (each (H, W, 3) uint8, ``size`` = (W, H), both even) into an H.264
    MP4 (yuv420p) at ``fps``; returns the count."""
    import imageio_ffmpeg

    count = 0
    with atomic_path(path) as tmp:
        writer = imageio_ffmpeg.write_frames(
            str(tmp), size, fps=fps, codec="libx264", pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p", quality=MP4_QUALITY, macro_block_size=2,
            ffmpeg_log_level="error",
            output_params=["-f", "mp4", "-fflags", "+bitexact", "-flags:v", "+bitexact",
                           "-map_metadata", "-1"])
        writer.send(None)
        try:
            for frame in frames:
                writer.send(np.ascontiguousarray(frame))
                count += 1
        finally:
            writer.close()
        if count == 0:
            raise BlastvoxError(f"{path}: no frames to write")
    return count
