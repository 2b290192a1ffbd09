"""Make the example meshes that are ours (the building comes from trimesh's test models).

    python examples/make_assets.py

house/house.obj: a small house (Martins 2001 Fig. 9): 0.5 m brick walls with a
door and a window, and a pitched roof, about 150 voxels at 0.5 m.
logo/digit_<i>.obj: the four digits of "2001" (Martins 2001 Fig. 11), each a
separate object, 0.5 m pixels of a 3x5 bitmap font.
Meshes are built with manifold3d (exact CSG), so they are closed and manifold.
"""

from __future__ import annotations

from pathlib import Path

import manifold3d as m3d
import numpy as np
import trimesh

HERE = Path(__file__).parent


def box(size, corner) -> m3d.Manifold:
    return m3d.Manifold.cube(tuple(float(s) for s in size)).translate(
        tuple(float(c) for c in corner))


def to_trimesh(solid: m3d.Manifold) -> trimesh.Trimesh:
    mesh = solid.to_mesh()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts),
                           process=True)


def house() -> trimesh.Trimesh:
    """Z-up, metres: 4 x 3 m footprint, 2.5 m walls, 0.5 m thick, roof to 4 m."""
    walls = box((4.0, 3.0, 2.5), (0, 0, 0)) - box((3.0, 2.0, 2.5), (0.5, 0.5, 0.0))
    walls = walls - box((1.0, 0.6, 2.0), (1.5, -0.05, 0.0))  # door
    walls = walls - box((0.6, 1.0, 1.0), (3.45, 1.0, 1.0))   # window
    # roof: a prism over the 4 m side, from the wall top to the ridge
    profile = m3d.CrossSection([[(0.0, 0.0), (3.0, 0.0), (1.5, 1.5)]])
    roof = m3d.Manifold.extrude(profile, 4.0).rotate((90.0, 0.0, 90.0)).translate((0, 0, 2.5))
    return to_trimesh(walls + roof)


FONT = {  # 3 x 5 pixels, top row first
    "2": ["###", "..#", "###", "#..", "###"],
    "0": ["###", "#.#", "#.#", "#.#", "###"],
    "1": [".#.", "##.", ".#.", ".#.", "###"],
}


def digit(char: str, x0: float, pixel: float = 0.5, depth: float = 0.5) -> trimesh.Trimesh:
    cubes = [box((pixel, depth, pixel), (x0 + c * pixel, 0.0, (4 - r) * pixel))
             for r, row in enumerate(FONT[char]) for c, on in enumerate(row) if on == "#"]
    return to_trimesh(m3d.Manifold.batch_boolean(cubes, m3d.OpType.Add))


def main() -> None:
    house().export(HERE / "house" / "house.obj")
    for i, char in enumerate("2001"):
        digit(char, x0=i * 2.0).export(HERE / "logo" / f"digit_{i}.obj")
    print("wrote house/house.obj and logo/digit_[0-3].obj")


if __name__ == "__main__":
    main()
