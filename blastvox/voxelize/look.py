"""The source look: the inputs' surface, kept in the VoxelModel for export.

Voxels lose the input's surface: a jittered cell has its own faces and a conform
cell keeps pieces of the input triangles but not their texture coordinates or
normals. So voxelize keeps, for every input that has a textured or a smooth part,
the input surface itself (triangles in the model frame, the UVs and normals of
their corners and which texture each uses) and the textures as PNG bytes.
Export projects each exterior face of a piece onto that surface to give it UVs,
its texture and smooth normals (:mod:`blastvox.export.uv`). An input with neither
(flat faces meeting at creases, no texture) adds nothing, so such models stay as
small as before.

Arrays (S surface triangles, K textures, B bytes), all present or all absent
(``surface_normals`` may be absent in models written before it):

=================  =============  ===================================================
surface_triangles  (S, 3, 3) f8   m, model frame: the input triangles
surface_uv         (S, 3, 2) f4   texture coordinates of their corners (v up, OpenGL)
surface_normals    (S, 3, 3) f4   unit normals of their corners, model frame: smooth
                                  within a part, sharp across creases
                                  (:func:`blastvox.geometry.normals.corner_normals`)
surface_texture    (S,) i4        texture index, or -1 where the part has none
surface_part       (S,) i4        the part (``meta["parts"]``, source node) each is of:
                                  a piece's face takes the look of its voxel's part only
texture_data       (B,) u1        the textures' PNG files, one after another
texture_offsets    (K+1,) i8      byte ranges of the textures in texture_data
=================  =============  ===================================================

``meta["textures"]`` names them after the source material that uses each first
(``<object>_<k>`` where the part has no material name): ``[{"name": ..., "mime_type":
"image/png"}]`` (an empty list when only smooth normals are kept).
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry.normals import corner_normals
from blastvox.voxelize.mesh_io import Part

#: A corner normal this far (cosine) from its face's normal makes a part smooth.
_SMOOTH_COSINE = math.cos(math.radians(0.5))


class LookBuilder:
    """Collects the textured or smooth inputs' surfaces, one object at a time, textures
    shared by content (the same image in two parts is stored once)."""

    def __init__(self) -> None:
        self.triangles: list[np.ndarray] = []
        self.uv: list[np.ndarray] = []
        self.normals: list[np.ndarray] = []
        self.texture: list[np.ndarray] = []
        self.part: list[np.ndarray] = []
        self.images: list[bytes] = []
        self.names: list[str] = []

    def add_object(self, name: str, parts: list[Part], first_part: int) -> None:
        """Keep ``parts``' surfaces (all of them, so that a face near a plain part is
        not given a texture or a normal from further away) if any part is textured or
        smooth somewhere; ``first_part`` is the index of ``parts[0]`` in the model's
        ``meta["parts"]``."""
        normals = [corner_normals(p.mesh.vertices, p.mesh.faces) for p in parts]
        if not any(p.texture is not None or _is_smooth(p, n) for p, n in zip(parts, normals,
                                                                             strict=True)):
            return
        for index, (part, normal) in enumerate(zip(parts, normals, strict=True)):
            faces = np.asarray(part.mesh.faces, dtype=np.int64)
            self.part.append(np.full(len(faces), first_part + index, dtype=np.int32))
            self.triangles.append(np.asarray(part.mesh.vertices, dtype=np.float64)[faces])
            self.normals.append(normal.astype(np.float32))
            if part.texture is None:
                self.uv.append(np.zeros((len(faces), 3, 2), dtype=np.float32))
                self.texture.append(np.full(len(faces), -1, dtype=np.int32))
                continue
            if part.texture not in self.images:
                self.images.append(part.texture)
                self.names.append(part.material or f"{name}_{len(self.names)}")
            self.uv.append(part.uv[faces].astype(np.float32))
            self.texture.append(np.full(len(faces), self.images.index(part.texture),
                                        dtype=np.int32))

    def arrays(self) -> tuple[dict[str, np.ndarray], list[dict]]:
        """The VoxelModel arrays (none when no input was textured or smooth) and
        ``meta["textures"]``."""
        if not self.triangles:
            return {}, []
        sizes = np.array([len(b) for b in self.images], dtype=np.int64)
        arrays = {
            "surface_triangles": np.concatenate(self.triangles),
            "surface_uv": np.concatenate(self.uv),
            "surface_normals": np.concatenate(self.normals),
            "surface_texture": np.concatenate(self.texture),
            "surface_part": np.concatenate(self.part),
            "texture_data": np.frombuffer(b"".join(self.images), dtype=np.uint8).copy(),
            "texture_offsets": np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        }
        meta = [{"name": n, "mime_type": "image/png"} for n in self.names]
        return arrays, meta



def _is_smooth(part: Part, normals: np.ndarray) -> bool:
    """Does any corner of ``part`` have a normal (``normals`` (F, 3, 3)) off its face's?
    (Degenerate triangles, without a normal, do not count.)"""
    flat = np.asarray(part.mesh.face_normals, dtype=np.float64)
    solid = (np.linalg.norm(flat, axis=1)[:, None] > 0.5) & (
        np.linalg.norm(normals, axis=2) > 0.5)
    return bool((solid & (np.einsum("fcj,fj->fc", normals, flat) < _SMOOTH_COSINE)).any())
