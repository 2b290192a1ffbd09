"""Shared fixtures: paths to the real test meshes, and a warm numba cache.

The first use of the simulator compiles its numba kernels (about a minute on
two cores) and caches them beside the sources. Tests that start many
``blastvox`` subprocesses at once would otherwise all compile the same kernels
concurrently, so the session starts by compiling them once, in-process.
"""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

import blastvox  # noqa: F401  before numpy: the same numpy loops on every CPU (its docstring)

DATA = Path(__file__).parent / "data"

# Tests start blastvox subprocesses from threads (test_cli_voxelize's and
# test_cli_simulate's pools) in a worker whose numba kernels keep OpenMP threads. With
# CPython 3.11's vfork (the GIL held across it, gh-104372) two CI runs failed a spawn
# with "OSError: [Errno 14] Bad address" on the interpreter's path, one test each; fork
# is the fallback CPython itself documents for vfork trouble.
if hasattr(subprocess, "_USE_VFORK"):
    subprocess._USE_VFORK = False


@pytest.fixture(scope="session")
def data_dir() -> Path:
    return DATA


def _warm_kernels(tmp: Path) -> None:
    """Run a tiny voxelize -> simulate (every effect on) in ``tmp``: every kernel compiled
    into (or loaded from) the on-disk cache."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    trimesh.creation.box(extents=(1.0, 0.5, 1.0)).export(tmp / "wall.stl")
    for shape, fracture in (("cube", "yield"), ("conform", "damage")):
        model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                        material="wood", shape=shape)],
                         VoxelizeSettings(up_axis="Z"))
        simulate(model, SimSettings(duration=0.3, fracture=fracture,
                                    camera=((0.0, -10.0, 1.0), (0.0, 0.0, 0.5), 35.0),
                                    charges=(ChargeSpec((0.0, -1.5, 0.5), 2.0),)))


def pytest_configure(config: pytest.Config) -> None:
    """Give SIGINT back its default handler if this run started with it ignored: a
    non-interactive shell starts a background job (``make test &``) so, and the
    signal tests would then see their Ctrl-C ignored, as the CLI rightly leaves an
    inherited ignore alone (``nohup``). Runs in the xdist controller and in each
    worker."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_sessionstart(session: pytest.Session) -> None:
    """With pytest-xdist (``-n``), fill the kernel cache once in the controller before the
    workers start (xdist starts them in a trylast hook), so that they load the kernels
    instead of each compiling all of them at once on a cold cache."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        _warm_kernels(Path(tmp))


@pytest.fixture(scope="session", autouse=True)
def warm_numba_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Warm the kernels once per test session (per xdist worker: loads from the cache)."""
    _warm_kernels(tmp_path_factory.mktemp("warmup"))


#: Modules whose tests bake whole shots in subprocesses, render or run Blender: the
#: full suite (CI, ``make test``) runs them; ``make test-fast`` (-m "not slow") skips them.
SLOW_MODULES = {"test_cli_simulate", "test_cli_voxelize", "test_golden", "test_blender_import",
                "test_extremes", "test_tradeoff"}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if item.module is not None and item.module.__name__.rsplit(".", 1)[-1] in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def shattered_slab(tmp_path_factory: pytest.TempPathFactory):
    """A 2 x 2 x 0.5 m concrete slab (0.25 m voxels) that a 40 kg charge 1.5 m away
    breaks into many pieces, with a scene camera close enough to see their fracture
    faces at frame 3: for the damage-texture tests."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("slab")
    trimesh.creation.box(extents=(2, 2, 0.5)).apply_translation((0, 0, 0.25)).export(
        tmp / "slab.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "slab.stl", voxel_size=(0.25,) * 3,
                                    material="concrete")], VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.25, fps=24.0, dust=False, fire=False,
                                        fireball=False,
                                        charges=(ChargeSpec((0, -1.5, 0.3), 40.0),),
                                        camera=((0.3, -2.0, 1.4), (0.0, 0.0, 0.4), 35.0)))
    assert cache.piece_count > 20
    return cache


@pytest.fixture(autouse=True)
def signal_handlers_restored(request: pytest.FixtureRequest) -> Iterator[None]:
    """Every test leaves SIGINT's and SIGTERM's handlers as it found them, in Python and
    in the kernel (a C library can ignore a signal behind Python's back): a test that
    leaves SIGINT ignored makes every later signal test of its xdist worker fail (a
    subprocess inherits the ignored signal), far from the cause. This names the cause."""
    watched = (signal.SIGINT, signal.SIGTERM)
    before = {s: signal.getsignal(s) for s in watched}
    ignored = _kernel_ignored()
    yield
    changed = {s: signal.getsignal(s) for s in watched if signal.getsignal(s) is not before[s]}
    for signum in changed:
        signal.signal(signum, before[signum])
    assert not changed, f"{request.node.nodeid} left the handlers {changed}, was {before}"
    assert _kernel_ignored() == ignored, (
        f"{request.node.nodeid} left the kernel's ignored signals {_kernel_ignored()}, "
        f"was {ignored}")


def _kernel_ignored() -> set[int]:
    """SIGINT and SIGTERM if the kernel ignores them for this process (Linux), else {}."""
    try:
        line = next(x for x in Path("/proc/self/status").read_text().splitlines()
                    if x.startswith("SigIgn:"))
    except (OSError, StopIteration):
        return set()
    mask = int(line.split()[1], 16)
    return {s for s in (signal.SIGINT, signal.SIGTERM) if mask >> (s - 1) & 1}
