"""The source look: the inputs' textured surface, kept in the VoxelModel for export.

Voxels lose the input's surface: a jittered cell has its own faces and a conform
cell keeps pieces of the input triangles but not their texture coordinates. So
voxelize keeps, for every input that has a textured part, the input surface
itself (triangles in the model frame, the UVs of their corners and which texture
each uses) and the textures as PNG bytes. Export projects each exterior face of
a piece onto that surface to give it UVs and its texture
(:mod:`blastvox.export.uv`). Inputs without a texture add nothing, so untextured
models stay as small as before.

Arrays (S surface triangles, K textures, B bytes), all present or all absent:

=================  =============  ===================================================
surface_triangles  (S, 3, 3) f8   m, model frame: the input triangles
surface_uv         (S, 3, 2) f4   texture coordinates of their corners (v up, OpenGL)
surface_texture    (S,) i4        texture index, or -1 where the part has none
texture_data       (B,) u1        the textures' PNG files, one after another
texture_offsets    (K+1,) i8      byte ranges of the textures in texture_data
=================  =============  ===================================================

``meta["textures"]`` names them: ``[{"name": "<object>_<k>", "mime_type": "image/png"}]``.
"""

from __future__ import annotations

import numpy as np

from blastvox.voxelize.mesh_io import Part


class LookBuilder:
    """Collects the textured inputs' surfaces, one object at a time, textures shared
    by content (the same image in two parts is stored once)."""

    def __init__(self) -> None:
        self.triangles: list[np.ndarray] = []
        self.uv: list[np.ndarray] = []
        self.texture: list[np.ndarray] = []
        self.images: list[bytes] = []
        self.names: list[str] = []

    def add_object(self, name: str, parts: list[Part]) -> None:
        """Keep ``parts``' surfaces (all of them, so that a face near an untextured
        part is not given a texture from further away) if any part is textured."""
        if not any(p.texture is not None for p in parts):
            return
        for part in parts:
            faces = np.asarray(part.mesh.faces, dtype=np.int64)
            self.triangles.append(np.asarray(part.mesh.vertices, dtype=np.float64)[faces])
            if part.texture is None:
                self.uv.append(np.zeros((len(faces), 3, 2), dtype=np.float32))
                self.texture.append(np.full(len(faces), -1, dtype=np.int32))
                continue
            if part.texture not in self.images:
                self.images.append(part.texture)
                self.names.append(f"{name}_{len(self.names)}")
            self.uv.append(part.uv[faces].astype(np.float32))
            self.texture.append(np.full(len(faces), self.images.index(part.texture),
                                        dtype=np.int32))

    def arrays(self) -> tuple[dict[str, np.ndarray], list[dict]]:
        """The VoxelModel arrays and ``meta["textures"]`` (empty when nothing is textured)."""
        if not self.images:
            return {}, []
        sizes = np.array([len(b) for b in self.images], dtype=np.int64)
        arrays = {
            "surface_triangles": np.concatenate(self.triangles),
            "surface_uv": np.concatenate(self.uv),
            "surface_texture": np.concatenate(self.texture),
            "texture_data": np.frombuffer(b"".join(self.images), dtype=np.uint8).copy(),
            "texture_offsets": np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
        }
        meta = [{"name": n, "mime_type": "image/png"} for n in self.names]
        return arrays, meta

