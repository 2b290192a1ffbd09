"""Debris speeds of a breached wall against the charge (issue 15's check of the loads).

A 3 x 3 m, 25 cm plain concrete wall founded on the ground, surface bursts at a
few scaled distances: links broken, and the median and 90th-percentile speed of
the pieces a few frames after the wave has passed (contacts off, so that only
the blast moves them). The momentum bound (Ir - Is) / (rho t) is printed beside.

    python benchmarks/debris_speeds.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import trimesh

from benchmarks._machine import machine
from blastvox.blast.kingery_bulmash import SURFACE, burst_parameters
from blastvox.simulate.engine import simulate
from blastvox.simulate.settings import ChargeSpec, SimSettings
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

CASES = ((1000.0, 60.0), (100.0, 10.0), (10.0, 3.0))
FPS, FRAME = 60.0, 32  # measured between frames 32 and 33 (0.53 s): every wave has passed


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "wall.stl"
        mesh = trimesh.creation.box(extents=(0.25, 3.0, 3.0))
        mesh.apply_translation((0.0, 0.0, 1.5))
        mesh.export(path)
        model = voxelize([ObjectRequest(mesh=path, voxel_size=(0.25,) * 3,
                                        material="concrete")],
                         VoxelizeSettings(up_axis="Z", ground="auto"))
    print(machine())
    print("\n| charge | Z (m/kg^(1/3)) | links broken | median speed (m/s) | 90th pct (m/s) "
          "| bound (Ir - Is)/(rho t) (m/s) |")
    print("|---|--:|--:|--:|--:|--:|")
    for kg, distance in CASES:
        cache = simulate(model, SimSettings(duration=0.6, fps=FPS, collisions=False,
                                            gravity=0.0, charges=(ChargeSpec(
                                                (-distance, 0.0, 1.5), kg, burst="surface"),)))
        pos = cache.piece_position.astype(np.float64)
        alive = cache.piece_end_frame > FRAME + 1
        speed = np.linalg.norm((pos[FRAME + 1] - pos[FRAME])[alive] * FPS, axis=1)
        z = distance / kg ** (1 / 3)
        _, _, _, i_s, _, i_r = burst_parameters(np.array([z]), SURFACE)
        bound = float(i_r[0] - i_s[0]) * kg ** (1 / 3) / (2400.0 * 0.25)
        print(f"| {kg:g} kg at {distance:g} m | {z:.1f} | {cache.meta['broken_links']} / "
              f"{model.link_count} | {np.median(speed):.2f} | {np.percentile(speed, 90):.2f} "
              f"| {bound:.2f} |")


if __name__ == "__main__":
    main()
