"""Make the example meshes.

    python examples/make_assets.py

house/house.obj: a small house (Martins 2001 Fig. 9): a 5 x 4 m cottage of 0.25 m
brick walls with a door and four windows, gables and a pitched roof with a chimney,
1,546 conform voxels at 0.25 m.
building/building.glb: a three-storey building (Martins 2001 Fig. 10), a shell of
0.3 m walls and floor slabs on a 20 x 11.5 m footprint with windows, a door and
three inner columns, about 4,300 conform voxels at 0.5 m. glTF is Y-up: plan x is
X, plan y is Z, heights are Y.
sealed_room/room.obj: a closed room, 4 x 4 x 3 m inside, 0.5 m walls, floor and
ceiling all round (a sealed cavity: the voxels stay a hollow shell), 416 voxels
at 0.5 m.
logo/digit_<i>.obj: the four digits of "2001" (Martins 2001 Fig. 11), each a
separate object, 0.5 m pixels of a 3x5 bitmap font.
Meshes are built with manifold3d (exact CSG), so they are closed and manifold, and
the files are the same on every run.
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
    """Z-up, metres: a 5 x 4 m cottage, 0.25 m brick walls 2.5 m high, a door and two
    windows in the front wall (y = 0, facing -y), a window in each other wall, brick
    gables on the side walls and a 0.25 m pitched roof (ridge along x at 4 m, 0.25 m
    eaves all round) with a chimney. Every edge is on the 0.25 m lattice but the roof's."""
    t = 0.25
    walls = box((5.0, 4.0, 2.5), (0, 0, 0)) - box((5.0 - 2 * t, 4.0 - 2 * t, 2.5), (t, t, 0))
    holes = [box((1.0, 0.5, 2.0), (2.0, -0.1, 0.0)),                          # door
             box((1.0, 0.5, 1.0), (0.5, -0.1, 1.0)), box((1.0, 0.5, 1.0), (3.5, -0.1, 1.0)),
             box((1.0, 0.5, 1.0), (2.0, 3.6, 1.0)),                          # back window
             box((0.5, 1.0, 1.0), (-0.1, 1.5, 1.0)), box((0.5, 1.0, 1.0), (4.6, 1.5, 1.0))]
    walls = walls - m3d.Manifold.batch_boolean(holes, m3d.OpType.Add)
    # gables: the side walls' triangles from the wall top to the ridge
    gable = m3d.CrossSection([[(0.0, 0.0), (4.0, 0.0), (2.0, 1.5)]])
    gable = m3d.Manifold.extrude(gable, t).rotate((90.0, 0.0, 90.0)).translate((0, 0, 2.5))
    gables = gable + gable.translate((5.0 - t, 0.0, 0.0))
    # the roof: two slabs 0.25 m thick (0.3125 m plumb) on the gables' slopes, 0.25 m
    # eaves front, back and at both ends; a chimney through its back slope
    thick = t / 0.8  # plumb thickness: cos(36.87 deg) = 0.8
    profile = m3d.CrossSection([[(-0.25, 2.3125), (2.0, 4.0), (4.25, 2.3125),
                                 (4.25, 2.3125 + thick), (2.0, 4.0 + thick),
                                 (-0.25, 2.3125 + thick)]])
    roof = m3d.Manifold.extrude(profile, 5.5).rotate((90.0, 0.0, 90.0)).translate(
        (-0.25, 0, 0))
    chimney = box((0.5, 0.5, 1.5), (3.75, 2.75, 3.25))
    return to_trimesh(walls + gables + roof + chimney)


def plan_box(size, corner) -> m3d.Manifold:
    """A box given in plan coordinates (x, y, height), built Y-up (x, height, y)."""
    (sx, sy, sz), (cx, cy, cz) = size, corner
    return box((sx, sz, sy), (cx, cz, cy))


def building() -> trimesh.Trimesh:
    """Y-up, metres: 20 x 11.5 m footprint (plan x along X, plan y along Z), three 3 m
    storeys. 0.3 m outer walls from the ground to the roof, 0.3 m floor slabs on top
    of each storey (their top at 3.4, 6.4 and 9.4 m), 0.4 m columns at x = 5, 10 and
    15 m on the middle line, y = 5.75 m. Every face lies inside a 0.5 m lattice cell, none on a
    cell face, so at voxel_size = 0.5 each wall and slab is one layer of voxels.
    Windows 2.6 x 1.7 m, one per 5 m bay on the long sides and per 5.75 m bay on the
    short ones, on every storey; a 1.6 x 2.2 m door in the front's third bay."""
    width, depth, storey, wall = 20.0, 11.5, 3.0, 0.3
    top = 3 * storey + 0.4
    shell = plan_box((width, depth, top), (0, 0, 0)) - plan_box(
        (width - 2 * wall, depth - 2 * wall, top + 1.0), (wall, wall, -0.5))
    parts = [shell]
    parts += [plan_box((width, depth, 0.3), (0, 0, k * storey + 0.1)) for k in (1, 2, 3)]
    parts += [plan_box((0.4, 0.4, top), (x + 0.05, 5.55, 0)) for x in (5.0, 10.0, 15.0)]
    solid = m3d.Manifold.batch_boolean(parts, m3d.OpType.Add)
    holes = []
    for k in range(3):
        sill = k * storey + 0.9
        for i in range(4):
            for y in (-0.5, depth - 0.5):
                if k == 0 and i == 2 and y < 0:
                    holes.append(plan_box((1.6, 1.0, 2.3), (5 * i + 1.7, y, -0.1)))  # door
                else:
                    holes.append(plan_box((2.6, 1.0, 1.7), (5 * i + 1.2, y, sill)))
        for j in range(2):
            for x in (-0.5, width - 0.5):
                holes.append(plan_box((1.0, 2.6, 1.7), (x, 5.75 * j + 1.6, sill)))
    return to_trimesh(solid - m3d.Manifold.batch_boolean(holes, m3d.OpType.Add))


def sealed_room(wall: float = 0.5) -> trimesh.Trimesh:
    """Z-up, metres: a closed box room, 4 x 4 x 3 m inside, ``wall`` thick all round."""
    outer = (4.0 + 2 * wall, 4.0 + 2 * wall, 3.0 + 2 * wall)
    return to_trimesh(box(outer, (0, 0, 0)) - box((4.0, 4.0, 3.0), (wall, wall, wall)))


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
    building().export(HERE / "building" / "building.glb")
    (HERE / "sealed_room").mkdir(exist_ok=True)
    sealed_room().export(HERE / "sealed_room" / "room.obj")
    for i, char in enumerate("2001"):
        digit(char, x0=i * 2.0).export(HERE / "logo" / f"digit_{i}.obj")
    print("wrote house/house.obj, building/building.glb, sealed_room/room.obj and "
          "logo/digit_[0-3].obj")


if __name__ == "__main__":
    main()
