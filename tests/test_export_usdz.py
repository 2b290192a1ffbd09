"""The .usdz package: OpenUSD's own packager over the .usdc export and its textures.

Read back with the real library (``Sdf.ZipFile``, ``Usd.Stage``), checked by every
UsdValidation validator, compared with the .usdc export by ``blastvox diff``, and
byte-identical from run to run (its zip headers carry no time of export). Rendering
it in Blender is in tests/test_blender_render.py.
"""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from blastvox.cache import SimCache
from blastvox.export.api import ExportOptions, export
from blastvox.export.usd_validate import validate_usd

GOLDEN = Path(__file__).resolve().parents[1] / "examples" / "golden"


@pytest.fixture(scope="module")
def house() -> SimCache:
    return SimCache.load(GOLDEN / "house.sim.npz")


def test_the_package_holds_the_layer_first_then_its_textures(house: SimCache,
                                                             tmp_path: Path) -> None:
    from pxr import Sdf, Usd

    path = tmp_path / "shot.usdz"
    export(house, path, ExportOptions())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["shot.usdz"]  # nothing beside it
    names = Sdf.ZipFile.Open(str(path)).GetFileNames()
    assert names[0] == "shot.usdc"
    assert sorted(names[1:]) == ["shot_textures/damage_brick.png",
                                 "shot_textures/damage_roof_tiles.png"]  # the house's
    with zipfile.ZipFile(path) as archive:  # stored, not compressed, and dated 1980
        assert {i.compress_type for i in archive.infolist()} == {zipfile.ZIP_STORED}
        assert {i.date_time for i in archive.infolist()} == {(1980, 1, 1, 0, 0, 0)}
    stage = Usd.Stage.Open(str(path))
    xforms = [p for p in stage.Traverse() if p.GetTypeName() == "Xform"
              and p.GetName().startswith("piece_")]  # each holds its Mesh of the same name
    assert len(xforms) == house.piece_count
    assert validate_usd(path) == []


def test_the_package_is_the_usdc_export_and_the_same_every_time(house: SimCache,
                                                                tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    export(house, tmp_path / "a" / "shot.usdz", ExportOptions())
    export(house, tmp_path / "b" / "shot.usdz", ExportOptions())
    # the .usdc as a .usdz holds it: particles as spheres (a .usdz cannot carry .vdb files)
    export(house, tmp_path / "a" / "shot.usdc", ExportOptions(particles="spheres"))
    assert (tmp_path / "a" / "shot.usdz").read_bytes() == \
        (tmp_path / "b" / "shot.usdz").read_bytes()
    diff = subprocess.run([sys.executable, "-m", "blastvox", "diff",
                           str(tmp_path / "a" / "shot.usdc"), str(tmp_path / "a" / "shot.usdz")],
                          capture_output=True, text=True, timeout=300)
    assert diff.returncode == 0, diff.stdout + diff.stderr
