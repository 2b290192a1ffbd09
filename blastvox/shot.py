"""Shot builds: run voxelize -> simulate -> export as a scene file says, like make.

A stage runs only when its output is missing or older than one of its inputs
(voxelize: the scene, its meshes and materials file; simulate: the model and
the scene; export: the cache and the scene), or when forced. Each stage writes
its output atomically, so an error or Ctrl-C never leaves a half-written file
and a rerun picks up where it stopped.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from blastvox.errors import SceneError

if TYPE_CHECKING:
    from blastvox.scene import Scene


def _stale(output: Path, inputs: list[Path]) -> bool:
    if not output.exists():
        return True
    newest = max((p.stat().st_mtime_ns for p in inputs if p.exists()), default=0)
    return output.stat().st_mtime_ns < newest


def _side_missing(export: Path) -> bool:
    """Is the file an export writes beside ``export`` (a .gltf's .bin) missing?"""
    from blastvox.export.api import side_outputs

    buffer, _ = side_outputs(export)
    return buffer is not None and not buffer.exists()


def _check_outputs(model: Path, cache: Path, exports: list[Path], inputs: list[Path],
                   layout: str = "xforms") -> None:
    """The output policy (blastvox.io.outputs) for every file the shot writes, before any
    stage runs: none is a device or an input, and no two are the same file."""
    from blastvox.export.api import GLTF_SUFFIXES, USD_SUFFIXES, side_folders, side_outputs
    from blastvox.io.outputs import (
        check_distinct,
        check_npz_output,
        check_output,
        check_side_directory,
    )

    outputs = [("output.model", model), ("output.cache", cache)]
    folders = []
    for i, path in enumerate(exports):
        label = "output.export" if len(exports) == 1 else f"output.export.{i}"
        outputs.append((label, path))
        buffer, _ = side_outputs(path)
        if buffer is not None:  # a .gltf's buffer is written beside it
            outputs.append((f"{label} (its .bin)", buffer))
        folders += [(f"{label} (its {f.name.rsplit('_', 1)[-1]})", f)
                    for f in side_folders(path)]
    for label, path in outputs:
        check_output(path, inputs, label=label, make_dirs=True)
    check_npz_output(model, "output.model", "VoxelModel")
    check_npz_output(cache, "output.cache", "SimCache")
    check_distinct(outputs)
    for label, folder in folders:  # the shot's own model and cache are inputs of export
        check_side_directory(folder, [*inputs, model, cache], label=label)
    for label, path in outputs:  # a file one output needs as the directory of another
        for other_label, other in outputs:
            if os.path.realpath(other).startswith(os.path.realpath(path) + os.sep):
                raise SceneError(f"{other}: {other_label}: its directory {path} is "
                                 f"{label}, a file")
    for label, path in outputs[2:]:  # refused here, not after voxelize and simulate ran
        suffix = Path(path).suffix.lower()
        if label.endswith("(its .bin)"):
            continue
        if suffix not in USD_SUFFIXES + GLTF_SUFFIXES:
            raise SceneError(f"{path}: {label}: unknown export format "
                             f"{suffix or '(no suffix)'!r}; use "
                             f"{', '.join(USD_SUFFIXES + GLTF_SUFFIXES)}")
        wrong = {"skinned": USD_SUFFIXES, "instancer": GLTF_SUFFIXES}.get(layout, ())
        if suffix in wrong:
            raise SceneError(f"{path}: {label}: output.layout {layout} is "
                             f"{'glTF' if layout == 'skinned' else 'USD'} only; this export "
                             f"takes xforms")


def run_scene(scene_path: Path, force: bool = False, log: Callable[[str], None] = print,
              warn: Callable[[str], None] | None = None,
              references_anywhere: bool = False,
              max_memory_gib: float | None = None) -> list[str]:
    """Bring the scene's outputs up to date; returns the stages that ran.

    Stage modules are imported only when their stage runs, so an up-to-date
    shot costs a few stat calls. ``references_anywhere``: a mesh's side files may lie
    outside its folder (:mod:`blastvox.io.references`); ``max_memory_gib``: the
    simulation's memory budget (``--max-memory``).
    """
    from blastvox.scene import load_scene

    scene_path = Path(scene_path)
    return build_shot(load_scene(scene_path), scene_path, force=force, log=log, warn=warn,
                      references_anywhere=references_anywhere,
                      max_memory_gib=max_memory_gib)


def check_simulation(scene: Scene, source: str, max_memory_gib: float | None = None) -> Any:
    """The scene's simulation settings (``SimSettings``), refused (one line naming
    ``source``) if a run of them would exceed its budgets: cheap, so a shot can be
    refused before voxelize. ``max_memory_gib``: the run's memory budget (default
    :class:`~blastvox.simulate.settings.Budget`'s)."""
    from blastvox.simulate.settings import Budget, check_settings
    from blastvox.simulate.settings import settings_from_scene as sim_settings

    budget = None if max_memory_gib is None else Budget(max_memory_gib=max_memory_gib)
    sim = sim_settings(scene, source, budget)
    if sim.charges:
        check_settings(sim)
    return sim


def voxelize_scene(scene: Scene, scene_path: Path, max_voxels: int | None = None,
                   references_anywhere: bool = False,
                   warn: Callable[[str], None] | None = None) -> Any:
    """The scene's VoxelModel, as ``blastvox voxelize SCENE`` makes it (the same
    settings recorded: :func:`~blastvox.voxelize.provenance.recorded_settings`).
    ``max_voxels``: the budget (None: voxelize's default)."""
    from blastvox.voxelize.pipeline import voxelize
    from blastvox.voxelize.provenance import recorded_settings
    from blastvox.voxelize.requests import requests_from_scene, settings_from_scene

    settings = settings_from_scene(scene, max_voxels)
    requests = requests_from_scene(scene)
    settings.recorded = recorded_settings(requests, settings, scene_path)
    settings.references_anywhere = references_anywhere
    return voxelize(requests, settings, warn=warn)


def build_shot(scene: Scene, scene_path: Path, force: bool = False,
               log: Callable[[str], None] = print, warn: Callable[[str], None] | None = None,
               seconds: dict[str, float] | None = None,
               references_anywhere: bool = False,
               max_memory_gib: float | None = None,
               max_voxels: int | None = None) -> list[str]:
    """Bring the outputs of ``scene`` (read from ``scene_path``, whose name the model
    records) up to date, as :func:`run_scene`; returns the stages that ran.

    ``seconds``, if given, receives the wall time of each stage that ran (s), keyed
    by stage name ("voxelize", "simulate", "export"). ``max_voxels``: voxelize's budget
    (``--max-voxels``; default its own, whose refusal says to voxelize the scene first).
    """
    seconds = {} if seconds is None else seconds
    out = scene.output
    if out.model is None or out.cache is None:
        raise SceneError(f"{scene_path}: output.model and output.cache must be set for "
                         f"`blastvox run`")
    exports = out.export if isinstance(out.export, list) else (
        [out.export] if out.export is not None else [])
    ran: list[str] = []
    from blastvox.io.references import ReferencePolicy
    from blastvox.io.resources import mesh_resources

    policy = ReferencePolicy(anywhere=references_anywhere)
    voxel_inputs = [scene_path] + [path for o in scene.objects
                                   for path in mesh_resources(Path(o.mesh), policy)]
    if scene.materials_file is not None:
        voxel_inputs.append(Path(scene.materials_file))
    _check_outputs(out.model, out.cache, exports, voxel_inputs, out.layout)
    sim = check_simulation(scene, str(scene_path), max_memory_gib)
    model = None
    if force or _stale(out.model, voxel_inputs):
        log(f"voxelize -> {out.model}")
        started = time.perf_counter()
        model = voxelize_scene(scene, scene_path, max_voxels, references_anywhere, warn)
        model.save(out.model)
        seconds["voxelize"] = time.perf_counter() - started
        ran.append("voxelize")
    cache = None
    if ran or _stale(out.cache, [out.model, scene_path]):
        from blastvox.model import VoxelModel
        from blastvox.simulate.engine import Progress, simulate

        if not sim.charges:
            raise SceneError(f"{scene_path}: charges: the scene has no [[charges]] to simulate")
        started = time.perf_counter()
        model = model or VoxelModel.load(out.model)
        log(f"simulate -> {out.cache}")
        cache = simulate(model, sim, progress=Progress(notes=log), warn=warn)
        cache.save(out.cache)
        seconds["simulate"] = time.perf_counter() - started
        ran.append("simulate")
    for path in exports:
        if "simulate" in ran or _stale(path, [out.cache, scene_path]) or _side_missing(path):
            from blastvox.cache import SimCache
            from blastvox.export.api import ExportOptions, export

            started = time.perf_counter()
            cache = cache or SimCache.load(out.cache)
            log(f"export -> {path}")
            export(cache, path, ExportOptions(up_axis=out.up_axis, layout=out.layout,
                                              shock=out.shock,
                                              damage_textures=out.damage_textures,
                                              fracture_faces=out.fracture_faces,
                                              particles=out.particles,
                                              volume_voxel_m=out.volume_voxel_m,
                                              key_tolerance_m=out.key_tolerance_m,
                                              key_tolerance_deg=out.key_tolerance_deg,
                                              damage_samples=out.damage_samples,
                                              velocity_primvars=out.velocity_primvars))
            seconds["export"] = seconds.get("export", 0.0) + time.perf_counter() - started
            ran.append("export")
    if not ran:
        log("up to date")
    return ran
