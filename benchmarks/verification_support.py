"""Verification, part two (issue 34): freed pieces fall, and a wall under the same peak
with a thousand times the impulse.

    python benchmarks/verification_support.py            # every row (~10 min on 2 cores)
    python benchmarks/verification_support.py --quick    # 0.25 and 0.125 m, dt 1/240 s
    python benchmarks/verification_support.py --docs     # also rewrite its tables in
                                                         # docs/physics.md

Scenes (through the library, as ``benchmarks/verification.py``'s):

6. **Freed pieces fall** (:func:`lintel`, :func:`balcony`; issue 34: "a 6 m stone lintel
   on piers (1.16 MPa against 0.15) cracks into three, and the freed half sleeps in
   place; a cracked brick balcony's detached 1 t piece hangs"). A stone lintel 6 x 0.5 x
   0.5 m laid on two founded stone piers 0.5 x 0.5 x 2 m whose centres are 5.5 m apart
   (beam theory at mid-span 3 rho g L^2 / (4 h) = 1.16 MPa against stone's 0.15 MPa,
   ``blastvox/data/materials.toml``), and a brick balcony slab 1.5 m out, 2 m wide,
   0.25 m thick, built into a founded brick wall 4 x 3.5 x 0.25 m (one mesh; root
   stress 3 rho g L^2 / t = 0.50 MPa against brick's 0.10 MPa). Nothing but gravity, 3 s.
   Figure: the mass fraction of the lintel's span at least 0.5 m from the piers' faces,
   and of the balcony's slab beyond 0.3 m from the wall, that came down more than 1 m.
   Reference: it falls (at least 95 %).
7. **Same peak, different impulse** (:func:`pi_wall`): a founded 3 x 3 m plain concrete
   wall 0.25 m thick, 1 kg TNT at 6 m and 1000 kg at 60 m (air bursts 1.5 m up; both
   Z = 6, the same peak overpressure, a thousand times the impulse's scale), 3 s.
   Figures: links broken, mass still founded, how far its top moved, the impulse per m^2
   of face (Pa s) its freed part left with (the largest horizontal momentum of the free
   pieces over their face area), and Housner's least impulse that topples that part
   (:func:`housner_impulse`). References (issue 34's done-when): 1 kg leaves it standing
   (99 % of its mass founded, its top within 1 cm); 1000 kg breaches it (at least half
   its mass off its foundation) and topples it (its top more than 1 m away).
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
import time

import numpy as np

try:  # run as a script (benchmarks/ on sys.path) or imported as benchmarks.verification_support
    import verification as base
    from _machine import machine
except ImportError:  # pragma: no cover
    from benchmarks import verification as base
    from benchmarks._machine import machine

from blastvox.simulate.settings import ChargeSpec

DOC = base.DOC
BEGIN, END = "<!-- verification-support:begin -->", "<!-- verification-support:end -->"

SECONDS = 3.0  # s of shot
FALLEN = 1.0  # m: a voxel that came down more than this has fallen
FALLS = 0.95  # fraction of the freed span that must fall
SUPPORT_SIZES = (0.25, 0.125, 0.1)  # m; 0.1 does not divide the balcony's 0.25 m
SUPPORT_STEPS = (240, 960)
WALL_SIZES = (0.25, 0.125, 0.0625)

#: the lintel: piers' centres SPAN apart, each PIER wide and PIER_HEIGHT high; the lintel
#: LINTEL = (length, width, depth) m lies on them
SPAN, PIER, PIER_HEIGHT = 5.5, 0.5, 2.0
LINTEL = (6.0, 0.5, 0.5)
#: the balcony: a wall (thickness, length, height) m and a slab (out, width, thickness) m
#: whose top is flush with SLAB_TOP m
WALL = (0.25, 4.0, 3.5)
SLAB = (1.5, 2.0, 0.25)
SLAB_TOP = 3.0

#: the same-peak wall: (thickness, width, height) m, charges (kg, m from its face)
PI_WALL = (0.25, 3.0, 3.0)
PI_CHARGES = ((1.0, 6.0), (1000.0, 60.0))
TOPPLED = 1.0  # m: the top moved this far
STANDS, STILL = 0.99, 0.01  # left standing: this much of its mass founded, its top within m


def lintel_theory() -> float:
    """Beam theory's mid-span stress (Pa) of the lintel simply supported over the piers'
    centres under its own weight: w L^2 / 8 over b h^2 / 6 = 3 rho g L^2 / (4 h)."""
    return 3.0 * base.LIBRARY["stone"].density * 9.81 * SPAN ** 2 / (4.0 * LINTEL[2])


def balcony_theory() -> float:
    """Root stress (Pa) of the balcony slab as a cantilever under its own weight:
    w L^2 / 2 over t^2 / 6 per metre of width = 3 rho g L^2 / t."""
    return 3.0 * base.BRICK.density * 9.81 * SLAB[0] ** 2 / SLAB[2]


def _fallen(run, model, part: np.ndarray) -> float:
    """Mass fraction of the voxels flagged in ``part`` that came down more than FALLEN m
    (or turned to dust)."""
    moved = base._voxel_moved(run, model)
    mass = model.arrays["voxel_mass"]
    return float(mass[part & (moved > FALLEN)].sum() / mass[part].sum())


def lintel(size: float, dt: float) -> dict:
    """Scene 6a: the stone lintel on two piers (one object each: it rests on them)."""
    trimesh = base.trimesh
    started = time.perf_counter()
    piers = trimesh.util.concatenate([
        trimesh.creation.box(extents=(PIER, PIER, PIER_HEIGHT)).apply_translation(
            (x, 0.0, PIER_HEIGHT / 2)) for x in (-SPAN / 2, SPAN / 2)])
    beam = trimesh.creation.box(extents=LINTEL).apply_translation(
        (0.0, 0.0, PIER_HEIGHT + LINTEL[2] / 2))
    model = base.voxelize_meshes([(piers, "stone"), (beam, "stone")], size)
    run = base._advance(model, base._settings(dt, base.FAR, duration=SECONDS), SECONDS)
    centre = model.arrays["voxel_centroid"]
    inner = SPAN / 2 - PIER / 2 - 0.5
    span = (centre[:, 2] > PIER_HEIGHT) & (np.abs(centre[:, 0]) < inner)
    return {"voxels": len(centre), "fallen": _fallen(run, model, span),
            "broken": int((~run.state.links.alive).sum()),
            "pieces": int(base._free_pieces(run).sum()), "theory": lintel_theory(),
            "strength": base.LIBRARY["stone"].tensile_strength,
            "seconds": time.perf_counter() - started}


def balcony(size: float, dt: float) -> dict:
    """Scene 6b: the brick balcony built into its wall (one mesh)."""
    boxes = [(WALL, (WALL[0] / 2, 0.0, WALL[2] / 2)),
             (SLAB, (WALL[0] + SLAB[0] / 2, 0.0, SLAB_TOP - SLAB[2] / 2))]
    started = time.perf_counter()
    model, _ = base._model(boxes, size, "brick")
    run = base._advance(model, base._settings(dt, base.FAR, duration=SECONDS), SECONDS)
    centre = model.arrays["voxel_centroid"]
    slab = centre[:, 0] > WALL[0] + 0.3
    return {"voxels": len(centre), "fallen": _fallen(run, model, slab),
            "broken": int((~run.state.links.alive).sum()),
            "pieces": int(base._free_pieces(run).sum()), "theory": balcony_theory(),
            "strength": base.BRICK.tensile_strength,
            "seconds": time.perf_counter() - started}


def housner_impulse(height: float, thickness: float, density: float,
                    gravity: float = 9.81) -> float:
    """The least impulse per m^2 (Pa s), uniform over its face, that topples a rigid block
    ``height`` x ``thickness`` m standing free on rigid ground (pivoting on its far toe,
    no sliding): the angular velocity omega_c^2 = 2 m g (R - h/2) / I_o that lifts its
    centre of mass over the toe (R = sqrt(h^2 + b^2) / 2; I_o = m (h^2 + b^2) / 3 per
    metre of length, about the toe; Housner 1963, "The behavior of inverted pendulum
    structures during earthquakes", BSSA 53(2)), given by the face's angular impulse
    i h^2 / 2 about the toe."""
    h, b = height, thickness
    mass = density * h * b  # kg per metre of length
    inertia = mass * (h * h + b * b) / 3.0
    rise = math.hypot(h, b) / 2.0 - h / 2.0
    omega = math.sqrt(2.0 * mass * gravity * rise / inertia)
    return inertia * omega / (h * h / 2.0)


def pi_wall(kg: float, distance: float, size: float, dt: float = 1.0 / 240.0) -> dict:
    """Scene 7: the founded concrete wall, ``kg`` TNT ``distance`` m from its face."""
    t, width, height = PI_WALL
    started = time.perf_counter()
    model, _ = base._model([(PI_WALL, (t / 2, 0.0, height / 2))], size, "concrete")
    peak = [0.0]

    def watch(run, _t: float) -> None:
        peak[0] = max(peak[0], base._free_momentum(run))

    charge = (ChargeSpec((-distance, 0.0, 1.5), kg, burst="air"),)
    run = base._advance(model, base._settings(dt, charge, duration=SECONDS), SECONDS, watch)
    debris = base._debris(run, model)
    centre = model.arrays["voxel_centroid"]
    moved = base._voxel_moved(run, model)
    density = base.CONCRETE.density
    freed_mass = (1.0 - debris["standing"] - debris["dust"]) * model.arrays["voxel_mass"].sum()
    freed_height = freed_mass / (density * t * width)
    return {"voxels": len(centre), "broken": debris["broken"], "standing": debris["standing"],
            "top": float(np.median(moved[centre[:, 2] > height - size])),
            "impulse": peak[0] / (freed_height * width) if freed_height > 0 else 0.0,
            "housner": housner_impulse(freed_height, t, density) if freed_height > 0 else math.nan,
            "seconds": time.perf_counter() - started}


def matrix(quick: bool) -> dict:
    """Every row: lists of dicts by scene."""
    sizes = SUPPORT_SIZES[:2] if quick else SUPPORT_SIZES
    steps = SUPPORT_STEPS[:1] if quick else SUPPORT_STEPS
    out: dict[str, list[dict]] = {"support": [], "pi": []}
    for name, scene in (("lintel", lintel), ("balcony", balcony)):
        for size in sizes:
            for per_s in steps:
                row = {"scene": name, "size": size, "steps": per_s, **scene(size, 1.0 / per_s)}
                out["support"].append(row)
                base.log(f"{name} {size:g} m 1/{per_s} s: fallen {row['fallen']:.3f} "
                         f"({row['seconds']:.1f} s)")
    for kg, distance in PI_CHARGES:
        for size in WALL_SIZES[:2] if quick else WALL_SIZES:
            row = {"kg": kg, "distance": distance, "size": size, **pi_wall(kg, distance, size)}
            out["pi"].append(row)
            base.log(f"wall {kg:g} kg at {distance:g} m, {size:g} m: broken {row['broken']:.3f}, "
                     f"standing {row['standing']:.2f}, top {row['top']:.2f} m")
    return out


def _support_verdict(row: dict) -> str:
    return "pass" if row["fallen"] >= FALLS else "FAIL: hangs"


def _pi_verdict(row: dict) -> str:
    if row["kg"] < 10.0:  # leaves it standing
        return "pass" if row["standing"] >= STANDS and row["top"] < STILL else "FAIL: moves"
    misses = [m for m, ok in (("breach", row["standing"] <= 0.5),
                              ("topple", row["top"] > TOPPLED)) if not ok]
    return "pass" if not misses else "FAIL: " + ", ".join(misses)


def tables(out: dict) -> list[str]:
    lines = [
        f"**6. Freed pieces fall** (issue 34): a stone lintel {LINTEL[0]:g} x {LINTEL[1]:g} x "
        f"{LINTEL[2]:g} m laid on two founded stone piers {PIER:g} m square and "
        f"{PIER_HEIGHT:g} m high, {SPAN:g} m apart centre to centre (beam theory at mid-span: "
        f"{lintel_theory() / 1e6:.2f} MPa against stone's "
        f"{base.LIBRARY['stone'].tensile_strength / 1e6:.2f} MPa), and a brick balcony slab "
        f"{SLAB[0]:g} m out, {SLAB[1]:g} m wide, {SLAB[2]:g} m thick built into a founded "
        f"brick wall (root stress {balcony_theory() / 1e6:.2f} MPa against brick's "
        f"{base.BRICK.tensile_strength / 1e6:.2f} MPa); gravity alone, {SECONDS:g} s. fallen: "
        f"mass fraction of the lintel's span at least 0.5 m from the piers' faces, or of the "
        f"slab beyond 0.3 m from the wall, that came down more than {FALLEN:g} m. Reference: "
        f"it falls (at least {FALLS:.0%}).", "",
        "| scene | voxel m | dt s | voxels | links broken | free pieces | fallen | run s "
        "| verdict |",
        "|---|--:|--:|--:|--:|--:|--:|--:|---|"]
    for r in out["support"]:
        lines.append(f"| {r['scene']} | {r['size']:g} | 1/{r['steps']} | {r['voxels']:,} | "
                     f"{r['broken']:,} | {r['pieces']:,} | {100 * r['fallen']:.1f} % | "
                     f"{r['seconds']:.1f} | {_support_verdict(r)} |")
    t, width, height = PI_WALL
    lines += [
        "", f"**7. Same peak, different impulse** (issue 34): a founded {width:g} x {height:g} m "
        f"plain concrete wall {t:g} m thick, air bursts 1.5 m up, {SECONDS:g} s, dt 1/240 s. "
        "standing: mass still founded; top: how far its top row moved (median); impulse: "
        "the largest horizontal momentum of its free pieces over their face area; Housner: "
        "the least impulse per m² that topples a rigid block of that freed height and "
        f"{t:g} m thickness on its toe (Housner 1963). References (issue 34): 1 kg at 6 m "
        f"leaves it standing (standing at least {STANDS:.0%}, top within {100 * STILL:g} "
        "cm); 1000 kg at 60 m breaches it (standing at most 50 %) and topples it (top "
        f"more than {TOPPLED:g} m away).", "",
        "| charge | voxel m | voxels | links broken | standing | top m | impulse Pa s "
        "| Housner Pa s | run s | verdict |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|---|"]
    for r in out["pi"]:
        lines.append(f"| {r['kg']:g} kg at {r['distance']:g} m | {r['size']:g} | "
                     f"{r['voxels']:,} | {100 * r['broken']:.1f} % | "
                     f"{100 * r['standing']:.1f} % | {r['top']:.2f} | {r['impulse']:.0f} | "
                     f"{base._fmt(r['housner'], '.0f')} | {r['seconds']:.1f} | "
                     f"{_pi_verdict(r)} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="0.25 and 0.125 m voxels, dt 1/240 s (about 2 minutes)")
    parser.add_argument("--docs", action="store_true",
                        help=f"rewrite this part's tables in {DOC.relative_to(base.ROOT)}")
    args = parser.parse_args(argv)
    command = "python benchmarks/verification_support.py" + (" --quick" if args.quick else "")
    header = (f"{machine(('blastvox', 'numpy', 'numba', 'scipy'))}; {base.revision()}; "
              f"{datetime.date.today().isoformat()}")
    print(header, flush=True)
    started = time.perf_counter()
    out = matrix(args.quick)
    report = [f"`{command}`", "", header, "",
              f"These rows took {time.perf_counter() - started:.0f} s.", "", *tables(out)]
    print("\n".join(report[4:]))
    if args.docs:
        base.write_docs(report, begin=BEGIN, end=END)
        print(f"wrote {DOC.relative_to(base.ROOT)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
