"""The voxel budget (``--max-voxels``), checked in floating point before allocating.

A lattice's cell counts are computed as floats (or from logarithms), never as
fixed-width integers, so a tiny voxel size or a huge resolution cannot overflow
them into a small or negative number that slips under the budget. Three checks,
in order:

1. before the inside test: the voxels the mesh's volume would give, if clearly
   (2x, the accuracy of the estimate) over the budget left;
2. before the inside test: the lattice searched, at most
   :data:`GRID_CELLS_PER_BUDGET_VOXEL` cells per voxel of budget (at least
   :data:`MIN_GRID_CELLS`), which bounds what is allocated;
3. after it: the voxels actually made.

Every refusal is one :class:`~blastvox.errors.BudgetError` line that names the
setting that made the size (the flag or the scene key), the budget and how to
raise it.

Two more budgets are checked before the work they bound (issue 36): the triangles
one voxelize reads (``--max-triangles``, all objects together: first what each file
says it holds, before it is parsed, then what it held) and the objects it takes
(``--max-objects``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from blastvox.bounds import (
    MAX_OBJECTS_LIMIT,
    MAX_TRIANGLES_LIMIT,
    MAX_VOXELS_LIMIT,
    MIN_VOXEL_SIZE_M,
    printable,
)
from blastvox.errors import BudgetError, InputError

#: Grid cells searched per voxel of budget, so huge sparse grids fail early.
GRID_CELLS_PER_BUDGET_VOXEL = 16
#: A lattice this small is always allowed, whatever the budget.
MIN_GRID_CELLS = 1_000_000
#: The volume estimate refuses only when this many times over the budget.
ESTIMATE_MARGIN = 2.0
#: What to do about a refusal, for the CLI's ``voxelize``.
HINT = (f"raise it with --max-voxels, up to {MAX_VOXELS_LIMIT:,}, or use a larger "
        f"voxel size")


def lattice_log10_counts(bounds: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """log10 of the cells per axis of a lattice of ``spacing`` over ``bounds`` (never overflows)."""
    extent = np.asarray(bounds, dtype=np.float64)[1] - np.asarray(bounds, dtype=np.float64)[0]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = np.log10(np.maximum(extent, 0.0)) - np.log10(spacing)
        counts = np.maximum(1.0, np.ceil(extent / spacing - 1e-6))
    # the float count where it is exact enough, its logarithm where it overflowed
    return np.where(np.isfinite(counts) & (counts < 1e15), np.log10(counts),
                    np.maximum(ratio, 0.0))


def about(log10_count: float) -> str:
    """A count given by its log10, in words: ``12,345`` or ``2.7e+901``."""
    if not math.isfinite(log10_count):
        return "infinitely many"
    if log10_count < 15:
        return f"{round(10.0 ** log10_count):,}"
    exponent = math.floor(log10_count)
    return f"{10.0 ** (log10_count - exponent):.1f}e+{exponent}"


def _over(budget_left: int, max_voxels: int) -> str:
    if budget_left < max_voxels:
        return f"over the {budget_left:,} voxels left of the budget of {max_voxels:,}"
    return f"over the budget of {max_voxels:,}"


def check_lattice(label: str, bounds: np.ndarray, spacing: np.ndarray, volume: float,
                  budget_left: int, max_voxels: int, hint: str = HINT) -> None:
    """Checks 1 and 2 (see the module), then the smallest voxel size.

    label: the setting that made ``spacing``, e.g. ``"wall.obj: --voxel-size 1e-300 m"``;
    volume: the solid's volume in m^3 (0 if unknown).
    """
    log_cells = lattice_log10_counts(bounds, spacing)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_voxels = math.log10(volume) - float(np.sum(np.log10(spacing))) if volume > 0 \
            else -math.inf
    total = float(np.sum(log_cells))
    log_voxels = min(log_voxels, total)
    if log_voxels > math.log10(ESTIMATE_MARGIN * max(budget_left, 1)):
        raise BudgetError(f"{label} gives about {about(log_voxels)} voxels, "
                          f"{_over(budget_left, max_voxels)} ({hint})")
    limit = max(GRID_CELLS_PER_BUDGET_VOXEL * max_voxels, MIN_GRID_CELLS)
    if total > math.log10(limit):
        shape = " x ".join(about(c) for c in log_cells)
        raise BudgetError(f"{label} gives a lattice of about {about(total)} cells ({shape}) "
                          f"to search, more than the {limit:,} that the budget of "
                          f"{max_voxels:,} voxels allows ({hint})")
    smallest = float(np.min(spacing))
    if smallest < MIN_VOXEL_SIZE_M:
        raise InputError(f"{label} gives voxels of {smallest:.3g} m, below the smallest "
                         f"voxel size of {MIN_VOXEL_SIZE_M:g} m (scale the mesh up)")


def check_count(label: str, count: int, budget_left: int, max_voxels: int,
                hint: str = HINT) -> None:
    """Check 3: the voxels the inside test chose."""
    if count > budget_left:
        raise BudgetError(f"{label} gives {count:,} voxels, {_over(budget_left, max_voxels)} "
                          f"({hint})")


def raise_hint(settings: Any, flag: str, limit: int) -> str:
    """How a refusal of the budget ``--flag`` says to raise it: the flag (voxelize), or
    voxelizing the scene first (``run``, which has no budget flags)."""
    if settings.budget_scene is not None:
        return (f"voxelize it first with `blastvox voxelize --scene {settings.budget_scene} "
                f"--{flag} N`, which `blastvox run` then finds up to date")
    return f"raise it with --{flag}, up to {limit:,}"


def check_objects(requests: Sequence[Any], settings: Any) -> None:
    """Refuse more objects than ``settings.max_objects`` before reading any."""
    if len(requests) <= settings.max_objects:
        return
    where = (requests[0].origin or "").split(": objects[")[0] or printable(requests[0].mesh)
    raise BudgetError(f"{where}: {len(requests):,} objects, more than the "
                      f"{settings.max_objects:,} one voxelize takes; "
                      f"{raise_hint(settings, 'max-objects', MAX_OBJECTS_LIMIT)}")


def triangle_budget(request: Any, settings: Any, left: list[int]
                    ) -> Callable[[int, bool], None]:
    """The check :func:`~blastvox.voxelize.mesh_io.load_parts` calls with a mesh's
    triangles (``said``: what the file says before it is parsed, at least that many;
    else what it held): over what the budget has ``left``, one BudgetError line; else,
    once held, taken from it."""
    def check(count: int, said: bool) -> None:
        if count > left[0]:
            used = settings.max_triangles - left[0]
            budget = (f"{left[0]:,} left of the {settings.max_triangles:,} one voxelize reads "
                      f"(the objects before it hold {used:,})" if used else
                      f"{settings.max_triangles:,} one voxelize reads")
            what = "says it holds" if said else "holds"
            raise BudgetError(
                f"{printable(request.mesh)}: {what} {count:,} triangles, more than the "
                f"{budget}; decimate the mesh, or "
                f"{raise_hint(settings, 'max-triangles', MAX_TRIANGLES_LIMIT)}")
        if not said:
            left[0] -= count

    return check
