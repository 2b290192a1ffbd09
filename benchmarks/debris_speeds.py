"""Debris speeds of a breached wall against the charge (issue 15's check of the loads).

1. A 3 x 3 m, 25 cm plain concrete wall founded on the ground, surface bursts at a
   few scaled distances: links broken, and the median and 90th-percentile speed of
   the pieces a few frames after the wave has passed (contacts off, so that only
   the blast moves them). The momentum bound (Ir - Is) / (rho t) is printed beside.
2. Contact charges on a 2 x 2 m, 25 cm reinforced concrete slab, against the
   fastest debris measured off the far face by high-speed video (Hupfauf & Gebbeken
   2022, "Secondary debris resulting from concrete slabs subjected to contact
   detonations", Adv. Struct. Eng. 25(7), 1373-1385; Hupfauf 2024, PhD thesis, UniBw
   Muenchen: v_max = 292 / T_W - 98 m/s, T_W = thickness cm / (TNT g)^(1/3); the
   speeds as read off the thesis's figures, to about 1 m/s, by the repository
   emmettl/bombcad, Fixtures/Hupfauf/slabs.json). The slab floats free (no ground,
   no gravity, no contacts), 0.05 m voxels; the charge is a TNT sphere (1600 kg/m^3)
   resting on its top face. Reported: whether it breached (a piece or dust left the
   slab's far face), the fastest piece and the 90th-percentile piece speed 10 ms
   after the detonation, and the fastest dust.

    python benchmarks/debris_speeds.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import trimesh
from _machine import machine  # benchmarks/ is on sys.path when run as a script

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


#: Hupfauf's 25 cm slabs: TNT equivalent kg -> (breached, fastest debris m/s, each test)
HUPFAUF_25CM = ((1.550, False, (35.0,)), (1.841, True, (46.0, 41.5)),
                (2.058, True, (55.5, 46.4)))
SLAB_FPS, SLAB_FRAME = 1000.0, 10  # speeds between frames 10 and 11 (10 ms)


def contact_table() -> None:
    """Part 2 of the module doc."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "slab.stl"
        trimesh.creation.box(extents=(2.0, 2.0, 0.25)).apply_translation(
            (0.0, 0.0, 1.0)).export(path)
        model = voxelize([ObjectRequest(mesh=path, voxel_size=(0.05,) * 3,
                                        material="reinforced_concrete")],
                         VoxelizeSettings(up_axis="Z", ground=None))
    print("\n| TNT kg | T_W | breached (published) | fastest piece m/s | 90th pct m/s "
          "| fastest dust m/s | published fastest m/s | fit 292/T_W - 98 |")
    print("|--:|--:|---|--:|--:|--:|--:|--:|")
    for kg, breached, measured in HUPFAUF_25CM:
        radius = (3.0 * kg / (4.0 * np.pi * 1600.0)) ** (1.0 / 3.0)
        cache = simulate(model, SimSettings(
            duration=SLAB_FRAME / SLAB_FPS + 0.002, fps=SLAB_FPS, dt=1.0 / 40000.0,
            collisions=False, gravity=0.0, ground=False,
            charges=(ChargeSpec((0.0, 0.0, 1.125 + radius), kg, burst="air"),)))
        pos = cache.piece_position.astype(np.float64)
        alive = cache.piece_end_frame > SLAB_FRAME + 1
        velocity = (pos[SLAB_FRAME + 1] - pos[SLAB_FRAME])[alive] * SLAB_FPS
        speed = np.linalg.norm(velocity, axis=1)
        down = velocity[:, 2] < -1.0
        below = (pos[SLAB_FRAME + 1][alive][:, 2] < 0.875).any()
        dust = cache.particle_velocity[cache.particle_system == 0]
        fastest_dust = float(np.linalg.norm(dust, axis=1).max()) if len(dust) else 0.0
        t_w = 25.0 / (kg * 1000.0) ** (1.0 / 3.0)
        print(f"| {kg:.3f} | {t_w:.3f} | {'yes' if below or down.any() else 'no'} "
              f"({'yes' if breached else 'no'}) | {speed.max():.1f} | "
              f"{np.percentile(speed, 90):.1f} | {fastest_dust:.1f} | "
              f"{' and '.join(f'{v:g}' for v in measured)} | {292.0 / t_w - 98.0:.1f} |")


if __name__ == "__main__":
    main()
    contact_table()
