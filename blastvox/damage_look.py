"""The look of fracture faces: one generated, tileable damage texture per material.

Faces that were inside an object (fracture surfaces) get box UVs in rest space
(:mod:`blastvox.export.uv`, 1 UV unit per metre) and, on export, a texture drawn
by one of the :data:`PATTERNS`, tinted so that its mean linear colour is the
material's ``damage_color``. A tile is :data:`TILE_M` = 1 m wide at
:data:`TEXTURE_SIZE` pixels (about 4 mm per pixel).

A material chooses its pattern with ``damage_pattern`` in the materials file
(``blastvox/data/materials.toml``); an empty value picks the pattern named like
the material (or its first word, ``reinforced_concrete`` -> ``concrete``), then
:data:`DEFAULT_PATTERN`.

Every texture is a pure function of (pattern, colour): the noise is seeded from
the pattern's name, the image is periodic in both directions (value noise on a
wrapped lattice, Voronoi cells with wrapped distances), and Pillow's PNG encoder
gives the same bytes for the same pixels. Output is sRGB, as glTF's
``baseColorTexture`` and UsdUVTexture (``sourceColorSpace = "sRGB"``) read it.
"""

from __future__ import annotations

import io
import zlib
from collections.abc import Callable
from functools import lru_cache

import numpy as np

TEXTURE_SIZE = 256  # px per tile side
TILE_M = 1.0  # m per tile side (box UVs are in metres)
DEFAULT_PATTERN = "rubble"
#: pattern -> what it draws
PATTERNS: dict[str, str] = {
    "concrete": "grey paste with aggregate flecks and hairline cracks",
    "brick": "fired clay grain with darker burnt spots and cracks",
    "stone": "crystalline grains in irregular cells",
    "wood": "splintered fibres along one direction",
    "glass": "clean shards split by bright fracture lines",
    "metal": "torn, brushed streaks",
    "plaster": "fine powdery grain with soft cracks",
    "fibre": "loose straw strands",
    "rubble": "mixed grit with cracks",
}
_ALIASES = {"drywall": "plaster", "thatch": "fibre", "steel": "metal"}


def pattern_for(material: str, chosen: str = "") -> str:
    """The damage pattern of a material: ``chosen`` if given, else the pattern named like
    the material, its alias, or its first word, else :data:`DEFAULT_PATTERN`."""
    if chosen:
        return chosen
    name = material.strip().lower()
    for key in (name, *name.replace("-", "_").split("_")):
        key = _ALIASES.get(key, key)
        if key in PATTERNS:
            return key
    return DEFAULT_PATTERN


def damage_png(pattern: str, color: tuple[float, float, float]) -> bytes:
    """The damage texture of ``pattern`` tinted to linear RGB ``color`` (0..1), as PNG."""
    return _png(pattern, tuple(round(float(c), 6) for c in color))


@lru_cache(maxsize=64)
def _png(pattern: str, color: tuple[float, ...]) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(damage_image(pattern, color)).save(buffer, format="PNG", optimize=False)
    return buffer.getvalue()


def damage_image(pattern: str, color, size: int = TEXTURE_SIZE) -> np.ndarray:
    """(size, size, 3) uint8 sRGB image of ``pattern`` whose mean linear colour is
    ``color`` (linear RGB, 0..1, up to the clipping of the brightest pixels)."""
    if pattern not in PATTERNS:
        raise ValueError(f"unknown damage pattern {pattern!r} (known: {', '.join(PATTERNS)})")
    rng = np.random.default_rng(zlib.crc32(pattern.encode()))
    shade, tint = _DRAW[pattern](rng, size)          # (size, size) factors, mean ~1
    shade = shade / shade.mean()
    linear = np.asarray(color, dtype=np.float64)[None, None, :] * shade[..., None]
    linear = linear * (1.0 + tint[..., None] * np.array([0.06, 0.0, -0.06]))
    return _to_srgb8(linear)


def _to_srgb8(linear: np.ndarray) -> np.ndarray:
    """8-bit sRGB of linear values (..., 3) in [0, 1]; the power is libm's, as every
    transcendental of the texture (:mod:`blastvox.geometry.fixed`): numpy's rounds as
    the CPU it dispatched to, and one ulp moves a pixel across a rounding step."""
    from blastvox.geometry import fixed

    c = np.clip(linear, 0.0, 1.0)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * fixed.power(c, 1 / 2.4) - 0.055)
    return np.rint(srgb * 255.0).astype(np.uint8)


# ----------------------------------------------------------------------------- fields

def _noise(rng: np.random.Generator, size: int, cells: tuple[int, int]) -> np.ndarray:
    """Periodic value noise (size, size) in [0, 1]: a random (cy, cx) lattice on a torus,
    smoothstep-interpolated."""
    cy, cx = cells
    lattice = rng.random((cy, cx))
    y = np.arange(size) * cy / size
    x = np.arange(size) * cx / size
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    ty, tx = y - y0, x - x0
    ty, tx = ty * ty * (3 - 2 * ty), tx * tx * (3 - 2 * tx)
    y1, x1 = (y0 + 1) % cy, (x0 + 1) % cx
    a = lattice[np.ix_(y0, x0)] * (1 - tx) + lattice[np.ix_(y0, x1)] * tx
    b = lattice[np.ix_(y1, x0)] * (1 - tx) + lattice[np.ix_(y1, x1)] * tx
    return a * (1 - ty)[:, None] + b * ty[:, None]


def _fractal(rng: np.random.Generator, size: int, base: int, octaves: int,
             stretch: tuple[int, int] = (1, 1)) -> np.ndarray:
    """Sum of octaves of periodic value noise (size, size), zero mean, unit-ish range;
    ``stretch`` multiplies the lattice density per axis (y, x) for fibres and streaks."""
    total = np.zeros((size, size))
    for o in range(octaves):
        n = base * 2 ** o
        total += _noise(rng, size, (n * stretch[0], n * stretch[1])) * 0.5 ** o
    return (total - total.mean()) / max(np.ptp(total), 1e-12)


def _voronoi(rng: np.random.Generator, size: int, cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Periodic Voronoi of about ``cells`` random sites: the distance to the nearest cell edge
    (size, size, in tile units) and each pixel's cell index."""
    from blastvox.geometry import fixed  # libm's hypot, whatever numpy dispatched to

    n = max(1, round(np.sqrt(cells)))  # sites jittered on an n x n grid: no sliver cells
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    sites = (grid + 0.15 + 0.7 * rng.random((n * n, 2))) / n
    shifts = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)], dtype=float)
    images = (sites[:, None, :] + shifts[None]).reshape(-1, 2)  # the sites' 9 periodic images
    g = (np.arange(size) + 0.5) / size
    py, px = np.meshgrid(g, g, indexing="ij")
    first = np.full((size, size), np.inf)
    second = np.full((size, size), np.inf)
    index = np.zeros((size, size), dtype=np.int64)
    for k, (sy, sx) in enumerate(images):
        d = fixed.hypot(py - sy, px - sx)
        closer = d < first
        second = np.where(closer, first, np.minimum(second, d))
        index = np.where(closer, k // 9, index)  # image k of site k // 9
        first = np.minimum(first, d)
    return (second - first) * 0.5, index


def _cracks(rng: np.random.Generator, size: int, cells: int, width: float,
            depth: float) -> np.ndarray:
    """A darkening factor (size, size) along the edges of a periodic Voronoi: 1 - depth on
    a crack, 1 away from it; edges wobble with noise."""
    edge, _ = _voronoi(rng, size, cells)
    from blastvox.geometry import fixed

    edge = edge + 0.004 * _fractal(rng, size, 8, 3)
    return 1.0 - depth * fixed.exp(-(np.maximum(edge, 0.0) / width) ** 2)


def _cell_shades(rng: np.random.Generator, size: int, cells: int, spread: float) -> np.ndarray:
    """A brightness per Voronoi cell (size, size): 1 +- spread."""
    _, index = _voronoi(rng, size, cells)
    return 1.0 + spread * (rng.random(int(index.max()) + 1) * 2 - 1)[index]


# ----------------------------------------------------------------------------- patterns
# Each returns (shade, tint): a brightness factor and a warm(+)/cool(-) shift, (size, size).

def _concrete(rng, size):
    paste = 1.0 + 0.25 * _fractal(rng, size, 8, 5)
    flecks = _noise(rng, size, (size // 4, size // 4))
    aggregate = np.where(flecks > 0.8, 1.35, np.where(flecks < 0.12, 0.7, 1.0))
    return paste * aggregate * _cracks(rng, size, 7, 0.004, 0.6), _fractal(rng, size, 4, 2)


def _brick(rng, size):
    grain = 1.0 + 0.3 * _fractal(rng, size, 16, 4)
    burnt = 1.0 - 0.35 * (_noise(rng, size, (24, 24)) > 0.78)
    return grain * burnt * _cracks(rng, size, 6, 0.005, 0.55), 2 * _fractal(rng, size, 4, 2)


def _stone(rng, size):
    cells = _cell_shades(rng, size, 40, 0.22)
    grain = 1.0 + 0.2 * _fractal(rng, size, 32, 3)
    return cells * grain * _cracks(rng, size, 5, 0.003, 0.5), _fractal(rng, size, 4, 2)


def _wood(rng, size):
    fibres = 1.0 + 0.45 * _fractal(rng, size, 2, 5, stretch=(1, 24))
    splinters = 1.0 - 0.5 * (_noise(rng, size, (6, 96)) > 0.82)
    return fibres * splinters, 1.5 * _fractal(rng, size, 2, 3, stretch=(1, 8))


def _glass(rng, size):
    from blastvox.geometry import fixed

    edge, index = _voronoi(rng, size, 12)
    facets = 1.0 + 0.12 * (rng.random(int(index.max()) + 1) * 2 - 1)[index]
    lines = 1.0 + 1.2 * fixed.exp(-(edge / 0.003) ** 2)
    return facets * lines, np.zeros((size, size))


def _metal(rng, size):
    brushed = 1.0 + 0.3 * _fractal(rng, size, 2, 5, stretch=(32, 1))
    torn = 1.0 - 0.4 * (_noise(rng, size, (64, 4)) > 0.85)
    return brushed * torn, -0.5 * np.ones((size, size))


def _plaster(rng, size):
    powder = 1.0 + 0.15 * _fractal(rng, size, 16, 5)
    return powder * _cracks(rng, size, 5, 0.006, 0.3), 0.5 * _fractal(rng, size, 4, 2)


def _fibre(rng, size):
    strands = 1.0 + 0.6 * _fractal(rng, size, 3, 4, stretch=(1, 12))
    gaps = 1.0 - 0.6 * (_noise(rng, size, (8, 64)) > 0.8)
    return strands * gaps, 2 * _fractal(rng, size, 3, 2)


def _rubble(rng, size):
    grit = 1.0 + 0.3 * _fractal(rng, size, 12, 5)
    cells = _cell_shades(rng, size, 24, 0.15)
    return grit * cells * _cracks(rng, size, 8, 0.004, 0.5), _fractal(rng, size, 4, 2)


_DRAW: dict[str, Callable[[np.random.Generator, int], tuple[np.ndarray, np.ndarray]]] = {
    "concrete": _concrete, "brick": _brick, "stone": _stone, "wood": _wood,
    "glass": _glass, "metal": _metal, "plaster": _plaster, "fibre": _fibre,
    "rubble": _rubble,
}
