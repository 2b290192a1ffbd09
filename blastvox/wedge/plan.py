"""A wedge's plan: the varied keys, the grid of their values (or a sample) and its shots.

Each shot is the scene file with one combination of values set, its outputs in
``<out>/shots/<key>/`` (``model.npz``, ``sim.npz``, the scene's exports by their
file names), keyed by :func:`blastvox.wedge.digest.shot_key`. Every shot's scene
is validated before anything runs, so a value the schema refuses is one line
naming the shot and the key, not a failed shot half-way through a farm run.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from blastvox.bounds import printable
from blastvox.errors import SceneError, WedgeError
from blastvox.io.resources import mesh_resources
from blastvox.wedge.digest import keyed_scene, shot_key
from blastvox.wedge.keys import check_key, valid_keys, with_values
from blastvox.wedge.values import format_value, parse_values

#: Most shots one wedge runs (after sampling); the grid itself may be larger when sampled.
MAX_SHOTS = 10_000
#: Largest grid a sample is drawn from.
MAX_GRID = 10**12
SHOTS_DIR = "shots"


@dataclass(frozen=True)
class Axis:
    """One varied key (dotted) and its values, in the order given."""

    key: str
    values: list[Any]


@dataclass(frozen=True)
class ShotSpec:
    """What a worker needs to run one shot (plain data: it travels to Dask workers).

    index: the shot's position in the full grid (the first key varies slowest);
    key: its content key; params: varied key -> value; scene: the parsed scene file
    with the values set and the outputs in ``directory``; scene_path: the scene
    file (absolute: relative paths in ``scene`` are relative to its directory);
    preview: render a preview strip; max_voxels, max_memory_gib: voxelize's and
    simulate's budgets (``--max-voxels``, ``--max-memory``; None: their defaults). The
    budgets only refuse a shot, they never change its files, so they are not in its key.
    """

    index: int
    key: str
    params: dict[str, Any]
    scene: dict[str, Any]
    scene_path: str
    directory: str
    preview: bool
    max_voxels: int | None = None
    max_memory_gib: float | None = None

    def label(self) -> str:
        """``"shot 3: charges.0.mass_kg=50, seed=1"``."""
        return shot_label(self.index, self.params)


def shot_label(index: int, params: dict[str, Any]) -> str:
    """``"shot 3: charges.0.mass_kg=50, seed=1"``: a shot's grid index and values."""
    values = ", ".join(f"{k}={format_value(v)}" for k, v in params.items())
    return f"shot {index}: {values}"


@dataclass(frozen=True)
class WedgePlan:
    """The axes, the size of their full grid, the shots to run and where they go."""

    scene_path: Path
    out: Path
    axes: list[Axis]
    grid_size: int
    shots: list[ShotSpec]
    preview: bool


def parse_vary(option: str) -> tuple[str, str]:
    """``"KEY=VALUES"`` -> (KEY, VALUES)."""
    key, sep, values = option.partition("=")
    if not sep or not key.strip() or not values.strip():
        raise WedgeError(f"--vary {option!r}: expected KEY=VALUES, e.g. "
                         f"charges.0.mass_kg=10,50,100 or seed=0:3:4")
    return key.strip(), values


def plan_wedge(scene_path: Path, vary: Sequence[str] = (), sample: int | None = None,
               sample_seed: int | None = None, out: Path | None = None,
               preview: bool | None = None, max_voxels: int | None = None,
               max_memory_gib: float | None = None) -> WedgePlan:
    """The plan of a wedge of the scene file at ``scene_path``.

    ``vary``: ``KEY=VALUES`` options, added to the scene's ``[wedge.vary]`` table (a
    key given in both takes the option's values). ``sample``, ``sample_seed``, ``out``
    and ``preview`` override the ``[wedge]`` table's. ``max_voxels``, ``max_memory_gib``:
    every shot's voxelize and simulate budgets (None: their defaults). Raises
    :class:`~blastvox.errors.WedgeError` or :class:`~blastvox.errors.SceneError`: one
    line naming the key, option or shot.
    """
    from blastvox.materials import field_names, read_toml
    from blastvox.scene import Scene, scene_from_dict

    scene_path = Path(scene_path)
    source = printable(scene_path)
    raw = read_toml(scene_path, SceneError)
    scene = scene_from_dict(raw, source, scene_path.parent)
    table = scene.wedge
    valid = valid_keys(Scene, raw, scene.material_library().names(), field_names() + ["base"])
    axes = _axes(table.vary if table else {}, vary, valid, source)
    sample = sample if sample is not None else (table.sample if table else None)
    sample_seed = sample_seed if sample_seed is not None else (table.sample_seed if table else 0)
    preview = preview if preview is not None else (table.preview if table else True)
    out = Path(out) if out is not None else _default_out(scene, scene_path)
    grid_size = math.prod(len(a.values) for a in axes)
    indices = _chosen(grid_size, sample, sample_seed)
    base = {k: v for k, v in raw.items() if k != "wedge"}
    exports = _export_names(raw)
    memo: dict[Path, str] = {}
    limits = (max_voxels, max_memory_gib)
    shots = [_shot(i, axes, base, exports, scene_path, out, preview, memo, limits)
             for i in indices]
    return WedgePlan(scene_path=scene_path, out=out, axes=axes, grid_size=grid_size,
                     shots=shots, preview=preview)


def _axes(table: dict[str, Any], options: Sequence[str], valid: list[str],
          source: str) -> list[Axis]:
    axes: dict[str, Axis] = {}
    for key, values in table.items():
        dotted = check_key(key, valid, f"{source}: wedge.vary")
        axes[dotted] = Axis(dotted, parse_values(values, f"{source}: wedge.vary.{key}"))
    given: set[str] = set()
    for option in options:
        key, text = parse_vary(option)
        dotted = check_key(key, valid, "--vary")
        if dotted in given:
            raise WedgeError(f"--vary {key}: given twice")
        given.add(dotted)
        axes[dotted] = Axis(dotted, parse_values(text, f"--vary {key}"))
    if not axes:
        raise WedgeError(f"{source}: nothing to vary: give --vary KEY=VALUES or a "
                         f"[wedge.vary] table")
    for axis in axes.values():
        seen: dict[object, object] = {}
        for v in axis.values:  # 1 and 1.0 are one shot, twice
            key = float(v) if isinstance(v, int | float) and not isinstance(v, bool) else repr(v)
            if key in seen:
                raise WedgeError(f"{axis.key}: value {v!r} listed twice"
                                 + (f" (as {seen[key]!r})" if repr(seen[key]) != repr(v) else ""))
            seen[key] = v
    return list(axes.values())


def _chosen(grid_size: int, sample: int | None, seed: int) -> list[int]:
    """Grid indices to run: all, or a seeded sample of ``sample`` (in grid order)."""
    if sample is None or sample >= grid_size:
        if grid_size > MAX_SHOTS:
            raise WedgeError(f"the grid has {grid_size:,} shots; at most {MAX_SHOTS:,} "
                             f"(use --sample N for a random sample of it)")
        return list(range(grid_size))
    if sample > MAX_SHOTS:
        raise WedgeError(f"--sample {sample:,}: at most {MAX_SHOTS:,} shots")
    if grid_size > MAX_GRID:
        raise WedgeError(f"the grid has {grid_size:.3g} shots; a sample is drawn from at "
                         f"most {MAX_GRID:.0e}")
    rng = np.random.default_rng(seed)
    return sorted(int(i) for i in rng.choice(grid_size, size=sample, replace=False))


def _default_out(scene: Any, scene_path: Path) -> Path:
    if scene.wedge is not None and scene.wedge.out is not None:
        return Path(scene.wedge.out)
    if scene.output.cache is not None:
        return Path(scene.output.cache).parent / "wedge"
    return scene_path.parent / f"{scene_path.stem}_wedge"


def _export_names(raw: dict[str, Any]) -> list[str]:
    export = (raw.get("output") or {}).get("export")
    exports = export if isinstance(export, list) else ([export] if export else [])
    return [Path(str(e)).name for e in exports]


def _shot(index: int, axes: list[Axis], base: dict[str, Any], exports: list[str],
          scene_path: Path, out: Path, preview: bool, memo: dict[Path, str],
          limits: tuple[int | None, float | None] = (None, None)) -> ShotSpec:
    from blastvox.scene import scene_from_dict
    from blastvox.shot import check_simulation

    combo = np.unravel_index(index, [len(a.values) for a in axes])
    params = {a.key: a.values[int(i)] for a, i in zip(axes, combo, strict=True)}
    data = with_values(base, params)
    source = f"{printable(scene_path)} ({shot_label(index, params)})"
    scene = scene_from_dict(_with_outputs(data, out / "_", exports), source, scene_path.parent)
    if not scene.charges:
        raise SceneError(f"{source}: charges: the shot has no [[charges]] to simulate")
    max_voxels, max_memory_gib = limits
    check_simulation(scene, source, max_memory_gib)  # over its budgets: refused before any runs
    inputs = list(itertools.chain.from_iterable(mesh_resources(Path(o.mesh))
                                                for o in scene.objects))
    if scene.materials_file is not None:
        inputs.append(Path(scene.materials_file))
    key = shot_key(keyed_scene(data), scene_path.name, inputs, memo)
    directory = out / SHOTS_DIR / key
    return ShotSpec(index=index, key=key, params=params,
                    scene=_with_outputs(data, directory, exports),
                    scene_path=str(scene_path.absolute()), directory=str(directory),
                    preview=preview, max_voxels=max_voxels, max_memory_gib=max_memory_gib)


def _with_outputs(data: dict[str, Any], directory: Path, exports: list[str]) -> dict[str, Any]:
    output = dict(data.get("output") or {})
    output["model"] = str((directory / "model.npz").absolute())
    output["cache"] = str((directory / "sim.npz").absolute())
    if exports:
        output["export"] = [str((directory / name).absolute()) for name in exports]
    return {**data, "output": output}
