"""One wedge shot, as a Dask worker runs it: voxelize, simulate, export, preview strip.

:func:`run_shot` builds the shot's scene exactly as ``blastvox run`` builds a
scene file (:func:`blastvox.shot.build_shot`), so its files are byte-identical
to running the same scene by itself. It never raises for a failed shot: the
result says ``"failed"`` with the one-line error, and the shot's ``log.txt``
holds its messages (and the traceback of an unexpected error). Only a finished
shot writes ``result.json``, last and atomically: a shot without one (failed,
interrupted, its worker lost) runs again on the next wedge, reusing the stage
files it had finished.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import time
import traceback
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from blastvox.errors import BlastvoxError
from blastvox.wedge.plan import ShotSpec

RESULT = "result.json"
LOG = "log.txt"
PREVIEW = "preview.png"
#: Pixel size and number of the frames of a shot's preview strip (first to last).
PREVIEW_SIZE = (320, 180)
PREVIEW_FRAMES = 4
#: Voxels of a piece that reads as a chunk of rubble rather than a loose voxel.
CHUNKY_VOXELS = 8


def run_shot(spec: ShotSpec) -> dict[str, Any]:
    """Run ``spec``'s shot (missing stages only); its result record (see :func:`record`)."""
    from blastvox.io.atomic import clean_stale
    from blastvox.scene import scene_from_dict
    from blastvox.shot import build_shot

    directory = Path(spec.directory)
    clean_stale(directory)  # writes cut short when their worker was killed; never a live one's
    earlier = _earlier_result(spec)
    for owner in corrupted(spec, earlier) if earlier is not None else []:
        owner.unlink(missing_ok=True)  # its stage (and those after it) runs again
    lines: list[str] = []
    seconds: dict[str, float] = {}
    started = time.perf_counter()
    status, error, stats = "ran", None, {}
    try:
        scene_path = Path(spec.scene_path)
        scene = scene_from_dict(spec.scene, f"{scene_path} ({spec.label()})", scene_path.parent)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            build_shot(scene, scene_path, log=lines.append,
                       warn=lambda m: lines.append(f"warning: {m}"), seconds=seconds,
                       max_memory_gib=spec.max_memory_gib, max_voxels=spec.max_voxels)
        lines += [f"warning: {w.message}" for w in caught]
        cache = _load_cache(Path(scene.output.cache))
        stats = cache_stats(cache)
        if spec.preview:
            begun = time.perf_counter()
            write_preview_strip(cache, directory / PREVIEW)
            seconds["preview"] = time.perf_counter() - begun
    except BlastvoxError as exc:
        status, error = "failed", str(exc)
    except MemoryError:
        status, error = "failed", "out of memory"
    except Exception as exc:  # a bug must not stop the other shots: its traceback is logged
        status, error = "failed", f"{type(exc).__name__}: {exc}"
        lines.append(traceback.format_exc())
    if error:
        lines.append(f"error: {error}")
    result = record(spec, status, error, stats, seconds, time.perf_counter() - started)
    try:
        _write_text(directory / LOG, "\n".join(lines) + "\n")
        if status == "ran":  # with its files' digests, checked before it is called done
            _write_text(directory / RESULT, json.dumps({**result, "files": file_digests(spec)},
                                                       indent=1, sort_keys=True) + "\n")
    except BlastvoxError as exc:  # a full disk, a read-only directory: the shot is not done
        result = record(spec, "failed", str(exc), stats, seconds, time.perf_counter() - started)
    return result


def record(spec: ShotSpec, status: str, error: str | None, stats: dict[str, Any],
           seconds: dict[str, float], total_s: float) -> dict[str, Any]:
    """A shot's result: ``shot`` (grid index), ``key``, ``params``, ``status`` ("ran",
    "cached", "failed"), ``error`` (one line or None), the cache's ``stats`` (see
    :func:`cache_stats`), stage ``seconds`` (voxelize, simulate, export, preview),
    ``total_s``, the ``worker`` host and process, and the shot's ``directory``."""
    return {"shot": spec.index, "key": spec.key, "params": spec.params, "status": status,
            "error": error, "stats": stats,
            "seconds": {k: round(v, 3) for k, v in seconds.items()},
            "total_s": round(total_s, 3), "worker": f"{socket.gethostname()}:{os.getpid()}",
            "directory": spec.directory}


def cached_result(spec: ShotSpec) -> dict[str, Any] | None:
    """The result of a shot that finished in an earlier wedge (status "cached"), or None
    if it has not (no readable ``result.json`` for this key, an output is missing, or
    one is not the file the shot finished with: its size and SHA-256 are recorded at
    completion and checked here, so a corrupted ``sim.npz`` runs its shot again)."""
    result = _earlier_result(spec)
    if result is None:
        return None
    output = spec.scene["output"]
    needed = [output["model"], output["cache"], *output.get("export", [])]
    if spec.preview:
        needed.append(str(Path(spec.directory) / PREVIEW))
    if not all(Path(p).is_file() for p in needed) or corrupted(spec, result):
        return None
    result.pop("files", None)
    return {**result, "status": "cached", "params": spec.params, "shot": spec.index,
            "directory": spec.directory}


def _earlier_result(spec: ShotSpec) -> dict[str, Any] | None:
    """The shot's ``result.json`` if it is one of this key, else None."""
    try:
        result = json.loads((Path(spec.directory) / RESULT).read_text())
    except (OSError, ValueError):
        return None
    return result if isinstance(result, dict) and result.get("key") == spec.key else None


def _shot_files(spec: ShotSpec) -> list[tuple[Path, Path]]:
    """(output, file) of every file a finished shot consists of: the model, the cache,
    each export with the files it writes beside it (a .gltf's .bin, a USD file's
    textures), the preview; ``output`` is the file whose stage makes ``file``."""
    from blastvox.export.api import side_folders, side_outputs

    output = spec.scene["output"]
    files = [(Path(output["model"]),) * 2, (Path(output["cache"]),) * 2]
    for export in map(Path, output.get("export", [])):
        files.append((export, export))
        buffer, _ = side_outputs(export)
        if buffer is not None:
            files.append((export, buffer))
        for folder in side_folders(export):  # textures, volumes
            if folder.is_dir():
                files += [(export, f) for f in sorted(folder.rglob("*")) if f.is_file()]
    if spec.preview:
        files.append((Path(spec.directory) / PREVIEW,) * 2)
    return files


def _digest(path: Path) -> dict[str, Any] | None:
    import hashlib

    try:
        with open(path, "rb") as fh:
            return {"bytes": os.fstat(fh.fileno()).st_size,
                    "sha256": hashlib.file_digest(fh, "sha256").hexdigest()}
    except OSError:
        return None


def _name(spec: ShotSpec, path: Path) -> str:
    """``path`` as recorded: relative to the shot's folder when inside it."""
    with contextlib.suppress(ValueError):
        return Path(path).relative_to(spec.directory).as_posix()
    return str(path)


def file_digests(spec: ShotSpec) -> dict[str, dict[str, Any]]:
    """The size and SHA-256 of each of the shot's files (and the output that makes it,
    ``of``), as its result records them at completion."""
    recorded = {}
    for owner, path in _shot_files(spec):
        digest = _digest(path)
        if digest is not None:
            recorded[_name(spec, path)] = {**digest, "of": _name(spec, owner)}
    return recorded


def corrupted(spec: ShotSpec, result: dict[str, Any]) -> list[Path]:
    """The outputs whose files are not those ``result`` recorded (missing, another size
    or digest); [] for a result that recorded none (written before files were)."""
    recorded = result.get("files")
    if not isinstance(recorded, dict):
        return []
    bad: list[Path] = []
    for name, was in recorded.items():
        if not isinstance(was, dict):
            continue
        path = Path(spec.directory) / name
        owner = Path(spec.directory) / str(was.get("of", name))
        if owner in bad:
            continue
        try:
            size = path.stat().st_size
        except OSError:
            size = None
        if size != was.get("bytes") or _digest(path) != {"bytes": was.get("bytes"),
                                                           "sha256": was.get("sha256")}:
            bad.append(owner)
    return bad


def cache_stats(cache: Any) -> dict[str, Any]:
    """What a wedge compares of a SimCache: pieces (all, moving), broken links, voxels
    turned to dust, the mass (kg) of the whole model and of what moved (voxels turned
    to dust, and voxels whose final piece travelled more than
    :data:`blastvox.cache.MOVED_M`) with the
    moved fraction, and how the moving pieces are made: the fraction of them that are a
    single voxel, and the fraction of their mass in pieces of :data:`CHUNKY_VOXELS` or
    more voxels (rubble, not voxel soup)."""
    from blastvox.cache import moved_pieces

    a, model = cache.arrays, cache.model.arrays
    moving = moved_pieces(a)
    dust = a["voxel_destroyed_frame"] >= 0
    voxel_moved = moving[a["voxel_piece"]] | dust
    voxel_mass = model["voxel_mass"]
    mass, moved = float(np.sum(voxel_mass)), float(np.sum(voxel_mass[voxel_moved]))
    whole = ~dust  # a piece's voxels at the end of the shot
    size = np.bincount(a["voxel_piece"][whole], minlength=len(moving))
    piece_mass = np.bincount(a["voxel_piece"][whole], weights=voxel_mass[whole],
                             minlength=len(moving))
    flying = moving & (size > 0)
    flying_mass = float(piece_mass[flying].sum())
    return {"pieces": int(len(a["piece_mass"])), "moving_pieces": int(moving.sum()),
            "broken_links": int(len(a["link_break_link"])),
            "dust_voxels": int(np.count_nonzero(dust)),
            "mass_kg": round(mass, 6), "moved_mass_kg": round(moved, 6),
            "moved_fraction": round(moved / mass, 6) if mass > 0 else 0.0,
            "single_voxel_fraction": round(float(np.mean(size[flying] == 1)), 6)
            if flying.any() else 0.0,
            "chunky_mass_fraction": round(float(piece_mass[flying & (size >= CHUNKY_VOXELS)]
                                                .sum()) / flying_mass, 6)
            if flying_mass > 0 else 0.0}


def write_preview_strip(cache: Any, path: Path) -> None:
    """A row of :data:`PREVIEW_FRAMES` frames of ``cache``, first to last, each
    :data:`PREVIEW_SIZE` and labelled with its frame and time, seen by the scene's
    camera or else an automatic camera framing the intact model (the same view for
    every variant of a wedge)."""
    from blastvox.preview.api import prepare
    from blastvox.preview.options import PreviewOptions
    from blastvox.preview.sheet import contact_sheet, draw_label, frame_label
    from blastvox.preview.writers import write_png

    count = cache.frame_count
    frames = sorted({int(round(f)) for f in np.linspace(0, count - 1, PREVIEW_FRAMES)})
    shot = prepare(cache, frames, PreviewOptions(size=PREVIEW_SIZE), camera_frames=[0])
    times = shot.scene.times
    images = [draw_label(shot.render(f), frame_label(f, float(times[f]))) for f in frames]
    write_png(contact_sheet(images, columns=len(images)), path)


def _load_cache(path: Path) -> Any:
    from blastvox.cache import SimCache

    return SimCache.load(path)


def _write_text(path: Path, text: str) -> None:
    from blastvox.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(text)
