"""Issue 37's scale moonshot: a city block of ~10 M voxels through the CLI, and as a wedge.

    python benchmarks/city.py                       # ~10 M voxels: voxelize + a 5 s shot
    python benchmarks/city.py --quick               # ~1 M voxels (the same scene, coarser)
    python benchmarks/city.py --voxels 3e6          # any size: the voxel edge follows
    python benchmarks/city.py --quick --wedge 2     # and the same scene as a 2-shot Dask wedge
    python benchmarks/city.py --scene-only DIR      # write the scene and its meshes, run nothing

The scene (``city_block``, deterministic): six hollow buildings, two rows of three
either side of a 14 m street, of different footprints (12 x 10 m to 22 x 16 m) and
heights (3 to 8 storeys of 3.2 m), each a 0.3 m shell with 0.25 m floor slabs and
window openings on every storey (manifold3d, exact CSG, so every mesh is closed),
brick or plain concrete with reinforced-concrete slabs (``[[objects.rules]]``), founded
on the ground. A 450 kg TNT vehicle bomb (an ATF "sedan") stands 0.8 m up in the middle
of the street, 7 m from the facades either side. The voxel edge is chosen from the
meshes' solid volume so that the block has about ``--voxels`` cube voxels.

Each CLI stage runs in a process of its own under ``/usr/bin/time -v``: ``blastvox
voxelize --scene`` and ``blastvox simulate --scene`` (the scene's 5 s at the default
dt, 1/240 s; ``--max-voxels`` and ``--max-memory`` raised to fit the block), and with
``--export`` ``blastvox export`` to .usdc. Wall time and peak RSS come from GNU time; a
sampler in this process adds the peak of the whole process tree's summed RSS (for the
wedge, the scheduler's and workers' processes together). The machine line and the NumPy
copy bandwidth of this machine (``performance.stream_gbs``, measured in this run) head
the table. ``--wedge N`` runs ``blastvox wedge`` of the same scene over N charge masses
(450 kg and up) on a local cluster of ``--wedge-workers`` processes.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from _machine import machine, revision  # benchmarks/ is on sys.path when run as a script
from performance import stream_gbs

STOREY = 3.2  # m, floor to floor
WALL = 0.3  # m, outer walls
SLAB = 0.25  # m, floor slabs and roof
STREET = 14.0  # m between the two rows' facades
CHARGE_KG = 450.0  # TNT: a sedan's load (ATF vehicle bomb table)
DURATION = 5.0  # s
#: (width along the street, depth, storeys, material) of the south row then the north row.
BUILDINGS = (
    (18.0, 14.0, 6, "brick"), (14.0, 12.0, 4, "concrete"), (22.0, 16.0, 8, "concrete"),
    (16.0, 12.0, 5, "brick"), (20.0, 14.0, 7, "concrete"), (12.0, 10.0, 3, "brick"),
)
GAP = 2.0  # m between neighbours in a row (alleys)
TIME = "/usr/bin/time"


# --------------------------------------------------------------------------- the scene


def building(width: float, depth: float, storeys: int):
    """A manifold3d solid, Z-up, corner at the origin: the shell, the slabs, windows."""
    import manifold3d as m3d

    def box(size, corner):
        return m3d.Manifold.cube(tuple(float(s) for s in size)).translate(
            tuple(float(c) for c in corner))

    height = storeys * STOREY + SLAB
    shell = box((width, depth, height), (0, 0, 0)) - box(
        (width - 2 * WALL, depth - 2 * WALL, height + 1.0), (WALL, WALL, -0.5))
    slabs = [box((width, depth, SLAB), (0, 0, k * STOREY)) for k in range(1, storeys + 1)]
    solid = m3d.Manifold.batch_boolean([shell, *slabs], m3d.OpType.Add)
    holes = []
    for k in range(storeys):
        sill = k * STOREY + SLAB + 0.9
        for span, along_x in ((width, True), (depth, False)):
            bays = max(1, int(span // 3.5))
            pitch = span / bays
            for i in range(bays):
                lo = i * pitch + (pitch - 1.6) / 2
                for side in (-0.5, (depth if along_x else width) - 0.5):
                    if along_x:
                        holes.append(box((1.6, 1.0, 1.5), (lo, side, sill)))
                    else:
                        holes.append(box((1.0, 1.6, 1.5), (side, lo, sill)))
    return solid - m3d.Manifold.batch_boolean(holes, m3d.OpType.Add)


def layout() -> list[tuple[float, float, float, float, int, str]]:
    """(x, y, width, depth, storeys, material) of each building: the south row's street
    facades on y = -STREET/2, the north row's on +STREET/2, each row centred on x = 0."""
    out = []
    for row, sign in ((BUILDINGS[:3], -1.0), (BUILDINGS[3:], 1.0)):
        total = sum(b[0] for b in row) + GAP * (len(row) - 1)
        x = -total / 2
        for width, depth, storeys, material in row:
            y = -STREET / 2 - depth if sign < 0 else STREET / 2
            out.append((x, y, width, depth, storeys, material))
            x += width + GAP
    return out


@dataclass
class Scene:
    """A written city-block scene: its file, voxel edge and expected voxel count."""

    path: Path
    voxel_size: float
    solid_m3: float
    expected: int
    buildings: int = 6
    files: list[Path] = field(default_factory=list)


def city_block(directory: Path, voxels: float, charge_kg: float = CHARGE_KG) -> Scene:
    """Write ``directory/scene.toml`` and one .ply per building; the voxel edge gives
    about ``voxels`` cube voxels (solid volume / edge^3, to 1 mm)."""
    import trimesh

    directory.mkdir(parents=True, exist_ok=True)
    solids, files = [], []
    for i, (x, y, width, depth, storeys, _) in enumerate(layout()):
        solid = building(width, depth, storeys).translate((x, y, 0.0))
        mesh = solid.to_mesh()
        tri = trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3],
                              np.asarray(mesh.tri_verts), process=True)
        path = directory / f"building{i}.ply"
        tri.export(path)
        solids.append(solid.volume())
        files.append(path)
    volume = float(sum(solids))
    edge = round((volume / voxels) ** (1 / 3), 3)
    lines = ["# Issue 37's city block (benchmarks/city.py): six hollow buildings either side",
             "# of a 14 m street, a vehicle bomb in the middle of it. Generated: do not edit.",
             "seed = 37", 'up_axis = "Z"', 'ground = "auto"', ""]
    for i, (x, y, width, depth, storeys, material) in enumerate(layout()):
        lines += ["[[objects]]", f'name = "building{i}"', f'mesh = "building{i}.ply"',
                  f"voxel_size = {edge}", f'material = "{material}"', ""]
        for k in range(1, storeys + 1):  # the slabs (and roof) are reinforced concrete
            z = k * STOREY
            lines += ["[[objects.rules]]",
                      f"box = {{ min = [{x - 1:.2f}, {y - 1:.2f}, {z - 0.01:.2f}], "
                      f"max = [{x + width + 1:.2f}, {y + depth + 1:.2f}, {z + SLAB + 0.01:.2f}] }}",
                      'material = "reinforced_concrete"', ""]
    lines += ["[[charges]]", "position = [0.0, 0.0, 0.8]", f"mass_kg = {charge_kg}", "",
              "[simulation]", f"duration = {DURATION}", "dt = 0.004166666666666667  # 1/240 s",
              "", "[camera]", "position = [-45.0, -5.0, 25.0]", "look_at = [0.0, 0.0, 8.0]", "",
              "[output]", 'model = "out/model.npz"', 'cache = "out/sim.npz"', ""]
    path = directory / "scene.toml"
    path.write_text("\n".join(lines), encoding="utf-8")
    return Scene(path, edge, volume, round(volume / edge**3), files=files)


# --------------------------------------------------------------------------- measuring


class TreeRss:
    """Samples, every ``period`` s, the summed RSS of a process and its descendants."""

    def __init__(self, pid: int, period: float = 0.5) -> None:
        self.pid, self.period, self.peak, self.peak_processes = pid, period, 0, 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _tree(self) -> list[int]:
        children: dict[int, list[int]] = {}
        for entry in os.listdir("/proc"):
            if entry.isdigit():
                try:
                    with open(f"/proc/{entry}/stat", encoding="ascii", errors="replace") as fh:
                        ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
                except (OSError, IndexError, ValueError):
                    continue
                children.setdefault(ppid, []).append(int(entry))
        out, todo = [], [self.pid]
        while todo:
            pid = todo.pop()
            out.append(pid)
            todo += children.get(pid, [])
        return out

    def _run(self) -> None:
        page = os.sysconf("SC_PAGE_SIZE")
        while not self._stop.is_set():
            total, count = 0, 0
            for pid in self._tree():
                try:
                    with open(f"/proc/{pid}/statm", encoding="ascii") as fh:
                        total += int(fh.read().split()[1]) * page
                    count += 1
                except (OSError, IndexError, ValueError):
                    pass
            if total > self.peak:
                self.peak, self.peak_processes = total, count
            self._stop.wait(self.period)

    def stop(self) -> float:
        """Stop sampling; the peak summed RSS in MiB."""
        self._stop.set()
        self._thread.join()
        return self.peak / 2**20


@dataclass
class Stage:
    """One CLI stage's wall time (s), peak RSS of its largest process (GNU time, MiB)
    and peak summed RSS of its process tree (sampled, MiB)."""

    name: str
    wall_s: float
    peak_mib: float
    tree_mib: float
    user_s: float


def run_stage(name: str, args: list[str], cwd: Path, log: Path) -> Stage:
    """``blastvox ARGS`` under ``/usr/bin/time -v`` in ``cwd``; its output into ``log``."""
    cmd = [TIME, "-v", sys.executable, "-m", "blastvox", *args]
    print(f"  {name}: blastvox {' '.join(args)}", file=sys.stderr, flush=True)
    with open(log, "w", encoding="utf-8") as out:
        proc = subprocess.Popen(cmd, cwd=cwd, stdout=out, stderr=subprocess.STDOUT)
        sampler = TreeRss(proc.pid)
        rc = proc.wait()
        tree = sampler.stop()
    text = log.read_text(encoding="utf-8", errors="replace")
    if rc != 0:
        tail = "\n".join(text.splitlines()[-30:])
        raise SystemExit(f"{name} failed (exit {rc}), see {log}:\n{tail}")
    return read_stage(name, log, tree)


def read_stage(name: str, log: Path, tree: float = float("nan")) -> Stage:
    """A stage's figures from its ``/usr/bin/time -v`` log."""
    text = log.read_text(encoding="utf-8", errors="replace")
    wall = re.search(r"Elapsed \(wall clock\) time.*: (.+)", text).group(1).strip()
    parts = [float(p) for p in wall.split(":")]
    seconds = sum(p * 60**i for i, p in enumerate(reversed(parts)))
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", text).group(1))
    user = float(re.search(r"User time \(seconds\): ([\d.]+)", text).group(1))
    return Stage(name, seconds, rss / 1024, tree, user)


def info(path: Path) -> dict:
    """``blastvox info --json`` of a model or cache."""
    out = subprocess.run([sys.executable, "-m", "blastvox", "info", str(path), "--json"],
                         check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


# --------------------------------------------------------------------------- main


def shot(scene: Scene, args: argparse.Namespace) -> tuple[list[Stage], dict, dict]:
    """Voxelize, simulate (and export) the scene through the CLI, one process each."""
    cwd, logs = scene.path.parent, scene.path.parent / "logs"
    logs.mkdir(exist_ok=True)
    max_voxels = str(max(4_000_000, int(2 * scene.expected)))
    voxelize = ["voxelize", "--scene", "scene.toml", "--max-voxels", max_voxels, "-q"]
    earlier = logs / "voxelize.txt"
    if args.reuse_model and (cwd / "out" / "model.npz").is_file() and earlier.is_file():
        stages = [read_stage("voxelize", earlier)]  # the model and timing of an earlier run
    else:
        stages = [run_stage("voxelize", voxelize, cwd, logs / "voxelize.txt")]
    model = info(cwd / "out" / "model.npz")
    sim = ["simulate", "out/model.npz", "--scene", "scene.toml", "--max-memory",
           str(args.max_memory)]
    if args.duration is not None:
        sim += ["--duration", str(args.duration)]
    stages.append(run_stage("simulate", sim, cwd, logs / "simulate.txt"))
    cache = info(cwd / "out" / "sim.npz")
    if args.export:
        stages.append(run_stage("export", ["export", "out/sim.npz", "-o", "out/shot.usdc",
                                           "-q"], cwd, logs / "export.txt"))
    return stages, model, cache


def wedge(scene: Scene, args: argparse.Namespace) -> tuple[Stage, list[dict]]:
    """``blastvox wedge`` of the scene over ``args.wedge`` charge masses."""
    masses = ",".join(f"{CHARGE_KG * (1 + 0.5 * i):g}" for i in range(args.wedge))
    cmd = ["wedge", "scene.toml", "--vary", f"charges.0.mass_kg={masses}", "--workers",
           str(args.wedge_workers), "--no-preview", "-o", "wedge", "--max-voxels",
           str(max(4_000_000, int(2 * scene.expected))), "--max-memory", str(args.max_memory)]
    if args.duration is not None:
        cmd += ["--vary", f"simulation.duration={args.duration}"]
    (scene.path.parent / "logs").mkdir(exist_ok=True)
    stage = run_stage("wedge", cmd, scene.path.parent, scene.path.parent / "logs" / "wedge.txt")
    summary = json.loads((scene.path.parent / "wedge" / "summary.json").read_text())
    return stage, summary if isinstance(summary, list) else summary.get("shots", [])


def table(scene: Scene, args: argparse.Namespace, gbs: float) -> None:
    """The shot's stages through the CLI and their table."""
    stages, model, cache = shot(scene, args)
    steps = round(cache["duration_s"] / cache["dt_s"])
    print("| stage | voxels | links | steps | pieces at end | wall s | user s | "
          "peak RSS MiB | GB/s copy |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|--:|")
    for s in stages:
        pieces = f"{cache['piece_count']:,}" if s.name != "voxelize" else ""
        step_cell = f"{steps:,}" if s.name == "simulate" else ""
        print(f"| {s.name} | {model['voxel_count']:,} | {model['link_count']:,} | "
              f"{step_cell} | {pieces} | {s.wall_s:,.1f} | {s.user_s:,.1f} | "
              f"{s.peak_mib:,.0f} | {gbs:.1f} |")
    print(f"\nChunks {model['chunk_count']:,}, foundations "
          f"{model['foundation_voxel_count']:,}; at the end: {cache['piece_count']:,} "
          f"pieces ({cache['moving_piece_count']:,} moving), "
          f"{cache['broken_link_count']:,} links broken, "
          f"{cache['destroyed_voxel_count']:,} voxels to dust; simulate "
          f"{model['voxel_count'] * steps / stages[1].wall_s / 1e6:.2f} M voxel-steps/s.")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--voxels", type=float, default=None,
                        help="voxels of the block (default 10e6, 1e6 with --quick)")
    parser.add_argument("--quick", action="store_true", help="~1 M voxels")
    parser.add_argument("--duration", type=float, default=None,
                        help=f"simulated seconds instead of the scene's {DURATION:g} "
                             f"(a shorter shot, labelled as such)")
    parser.add_argument("--export", action="store_true", help="also time export to .usdc")
    parser.add_argument("--wedge", type=int, default=0, metavar="N",
                        help="also run the scene as an N-shot wedge over the charge mass")
    parser.add_argument("--wedge-workers", type=int, default=1)
    parser.add_argument("--wedge-only", action="store_true",
                        help="run the wedge alone, not the stages one by one")
    parser.add_argument("--max-memory", type=float, default=20.0, metavar="GIB",
                        help="simulate's --max-memory (its default 4 GiB refuses ~5 M voxels)")
    parser.add_argument("--reuse-model", action="store_true",
                        help="with --out: keep an earlier run's model.npz (and its voxelize "
                             "figures) instead of voxelizing again")
    parser.add_argument("--out", type=Path, default=None,
                        help="working directory, kept (default: a temporary one, removed)")
    parser.add_argument("--scene-only", type=Path, default=None, metavar="DIR",
                        help="write the scene to DIR and stop")
    args = parser.parse_args(argv)
    voxels = args.voxels or (1e6 if args.quick else 10e6)
    if args.scene_only is not None:
        scene = city_block(args.scene_only, voxels)
        print(f"{scene.path}: voxel edge {scene.voxel_size} m, ~{scene.expected:,} voxels "
              f"({scene.solid_m3:,.0f} m^3 of wall and slab)")
        return 0
    print(machine(("blastvox", "numpy", "numba", "distributed")))
    print(f"Commit: {revision()}; date {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    gbs = stream_gbs()
    print(f"NumPy copy bandwidth of this machine (256 MiB, read + write): {gbs:.1f} GB/s")
    work = args.out or Path(tempfile.mkdtemp(prefix="blastvox-city-"))
    try:
        scene = city_block(work, voxels)
        duration = args.duration or DURATION
        print(f"\nCity block: {len(BUILDINGS)} buildings, {scene.solid_m3:,.0f} m^3 of wall and "
              f"slab, voxel edge {scene.voxel_size} m; {CHARGE_KG:g} kg TNT in the street; "
              f"{duration:g} s at 1/240 s{'' if args.duration is None else ' (SHORTENED)'}.\n")
        if not args.wedge_only:
            table(scene, args, gbs)
        if args.wedge:
            stage, shots = wedge(scene, args)
            print(f"\nWedge: {args.wedge} shots (charge mass), {args.wedge_workers} worker(s): "
                  f"wall {stage.wall_s:,.1f} s, user {stage.user_s:,.1f} s, largest process "
                  f"{stage.peak_mib:,.0f} MiB, all processes together {stage.tree_mib:,.0f} MiB")
            print("\n| shot | status | voxelize s | simulate s | total s | pieces |")
            print("|---|---|--:|--:|--:|--:|")
            for r in shots:
                sec, stats = r.get("seconds") or {}, r.get("stats") or {}
                print(f"| {r.get('params')} | {r.get('status')} | "
                      f"{sec.get('voxelize', float('nan')):,.1f} | "
                      f"{sec.get('simulate', float('nan')):,.1f} | "
                      f"{r.get('total_s', float('nan')):,.1f} | {stats.get('pieces', '?')} |")
        print(f"\nLoad average after: {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    finally:
        if args.out is None:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
