"""Vertex and face colours as a texture, so that they travel the source look's path.

A mesh coloured per vertex or per face (PLY ``red green blue``, OBJ's extended
``v x y z r g b``, glTF ``COLOR_0``: whatever trimesh reads as ``ColorVisuals``)
has no texture to carry its look. This bakes one: every triangle gets a cell of
:data:`CELL` x :data:`CELL` pixels in an atlas, its corners at three points of
the cell, and each pixel of the cell the barycentric blend of the corner colours
(clamped to the triangle, so the cell's margin repeats its edge and linear
filtering never reaches a neighbour's colours). The triangle's corners get UVs
at those points; the rest is the textured look (:mod:`blastvox.voxelize.look`,
:mod:`blastvox.export.uv`). Colours are blended as stored (sRGB), as a renderer
blends texels.
"""

from __future__ import annotations

import io
import math

import numpy as np
from PIL import Image

#: Pixels per triangle cell side (the corners sit MARGIN pixels in from its edges).
CELL = 8
MARGIN = 1.5
#: Largest atlas side in pixels; beyond it cells shrink (at least MIN_CELL).
MAX_SIDE = 4096
MIN_CELL = 4
#: Triangles whose texels are blended at once (bounds the float scratch to ~16 MB).
BLOCK = 1 << 14


def corner_colors(visual, faces: np.ndarray) -> np.ndarray | None:
    """The (F, 3, 4) uint8 RGBA colours of the corners of ``faces`` (F, 3) from a trimesh
    ``visual``, or None when it holds no colour or one colour for everything."""
    kind = getattr(visual, "kind", None)
    if kind == "vertex":
        colors = np.asarray(visual.vertex_colors, dtype=np.uint8)
        if colors.ndim != 2 or colors.shape[1] != 4 or len(colors) <= int(faces.max(initial=0)):
            return None
        corners = colors[faces]
    elif kind == "face":
        colors = np.asarray(visual.face_colors, dtype=np.uint8)
        if colors.ndim != 2 or colors.shape[1] != 4 or len(colors) != len(faces):
            return None
        corners = np.repeat(colors[:, None, :], 3, axis=1)
    else:
        return None
    flat = corners.reshape(-1, 4)
    if len(flat) == 0 or (flat == flat[0]).all():
        return None
    return corners


def bake(corners: np.ndarray) -> tuple[np.ndarray, bytes]:
    """An atlas of the triangles' colours: (corner UVs (F, 3, 2) float64, OpenGL
    convention (v up), PNG bytes (RGB, or RGBA when any alpha is below 255)).
    ``corners`` (F, 3, 4) uint8 RGBA."""
    count = len(corners)
    columns = max(1, math.ceil(math.sqrt(count)))
    rows = max(1, math.ceil(count / columns))
    cell = max(MIN_CELL, min(CELL, MAX_SIDE // max(columns, rows)))
    width, height = columns * cell, rows * cell
    margin = MARGIN * cell / CELL
    # the corners in a cell (image x right, y down) and every pixel's weights for them
    points = np.array([[margin, margin], [cell - margin, margin], [margin, cell - margin]])
    centre = np.arange(cell) + 0.5
    u = (centre[None, :] - margin) / (cell - 2 * margin)   # along x
    v = (centre[:, None] - margin) / (cell - 2 * margin)   # along y
    weights = np.stack(np.broadcast_arrays(1.0 - u - v, u, v), axis=-1)  # (cell, cell, 3)
    weights = np.maximum(weights, 0.0)
    weights /= weights.sum(axis=-1, keepdims=True)
    cells = np.zeros((rows * columns, cell, cell, 4), dtype=np.uint8)
    for start in range(0, count, BLOCK):  # in blocks: float texels of one block at a time
        block = corners[start:start + BLOCK].astype(np.float32)
        texels = np.einsum("yxk,fkc->fyxc", weights.astype(np.float32), block)
        cells[start:start + len(block)] = np.clip(np.rint(texels), 0, 255).astype(np.uint8)
    pixels = cells.reshape(rows, columns, cell, cell, 4).transpose(0, 2, 1, 3, 4).reshape(
        height, width, 4)
    index = np.arange(count)
    origin = np.stack([(index % columns) * cell, (index // columns) * cell], axis=1)
    xy = origin[:, None, :] + points[None, :, :]                          # (F, 3, 2) pixels
    uv = np.stack([xy[..., 0] / width, 1.0 - xy[..., 1] / height], axis=-1)
    opaque = bool((corners[..., 3] == 255).all())
    image = Image.fromarray(pixels[..., :3] if opaque else pixels, "RGB" if opaque else "RGBA")
    out = io.BytesIO()
    image.save(out, format="PNG")
    return uv, out.getvalue()
