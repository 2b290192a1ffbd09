"""Frame labels and contact sheets (Pillow, imported lazily by the callers of this module).

A label is a line of text in a dark box at the top-left corner of a frame; a
contact sheet lays labelled frames out in a grid of ``ceil(sqrt(n))`` columns
with ``GAP_PX`` gaps on a dark background. Both are deterministic (Pillow's
bundled default font, no antialiasing differences between runs).
"""

from __future__ import annotations

import math

import numpy as np

GAP_PX = 4
SHEET_BACKGROUND = (20, 20, 22)
LABEL_BOX = (0, 0, 0)
LABEL_TEXT = (245, 245, 240)


def frame_label(frame: int, time_s: float) -> str:
    """``"frame 12  0.50 s"``."""
    return f"frame {frame}  {time_s:.2f} s"


def draw_label(image: np.ndarray, text: str) -> np.ndarray:
    """A copy of ``image`` (H, W, 3) uint8 with ``text`` in a dark box at its top-left."""
    from PIL import Image, ImageDraw, ImageFont

    h = image.shape[0]
    size = max(9, min(28, h // 24))
    font = ImageFont.load_default(size=size)
    pil = Image.fromarray(image)
    draw = ImageDraw.Draw(pil)
    pad = max(2, size // 4)
    left, top, right, bottom = draw.textbbox((pad, pad), text, font=font)
    draw.rectangle((0, 0, right + pad, bottom + pad), fill=LABEL_BOX)
    draw.text((pad, pad), text, font=font, fill=LABEL_TEXT)
    return np.asarray(pil)


def sheet_columns(count: int) -> int:
    """Columns of a contact sheet of ``count`` frames: ceil(sqrt(count))."""
    return max(1, math.ceil(math.sqrt(count)))


def contact_sheet(frames: list[np.ndarray], columns: int | None = None) -> np.ndarray:
    """Frames (each (H, W, 3) uint8, all one size) in a grid, left to right, top to
    bottom: (rows H + (rows + 1) GAP, columns W + (columns + 1) GAP, 3) uint8. A single
    frame is returned as it is."""
    if len(frames) == 1:
        return frames[0]
    h, w = frames[0].shape[:2]
    cols = columns or sheet_columns(len(frames))
    rows = math.ceil(len(frames) / cols)
    sheet = np.empty((rows * h + (rows + 1) * GAP_PX, cols * w + (cols + 1) * GAP_PX, 3),
                     dtype=np.uint8)
    sheet[:] = SHEET_BACKGROUND
    for i, frame in enumerate(frames):
        r, c = divmod(i, cols)
        y = GAP_PX + r * (h + GAP_PX)
        x = GAP_PX + c * (w + GAP_PX)
        sheet[y:y + h, x:x + w] = frame
    return sheet
