"""Open parts voxelized as sheets (blastvox.voxelize.sheets): a pane beside a solid.

A glTF of a closed box and an open 1 x 1 m pane (two triangles, material "pane")
standing on it: the pane becomes voxels of its own material, one voxel deep, every
cell it passes through; its mass is area x sheet_thickness x density whatever the
voxel size; a link touching it carries the pane's section (thickness x face side).
A lone open sheet is still refused. The Cesium Milk Truck keeps its glass.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from blastvox.errors import MeshError
from blastvox.model import VoxelModel
from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

DATA = Path(__file__).parent / "data"
THICKNESS = 0.006  # m
PANE_AREA = 1.0  # m², the pane is 1 x 1 m
GLASS_DENSITY = 2500.0  # kg/m³, the library's glass


def _glb(path: Path, parts: dict[str, tuple[trimesh.Trimesh, str]]) -> Path:
    """Write ``parts`` (node name -> (mesh, glTF material name)) as one glTF file."""
    scene = trimesh.Scene()
    for name, (mesh, material) in parts.items():
        mesh.visual = trimesh.visual.TextureVisuals(
            material=trimesh.visual.material.PBRMaterial(name=material))
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    scene.export(path)
    return path


def _box_and_pane(path: Path, y: float = 0.03) -> Path:
    """A 2 x 1 x 0.5 m box on z = 0 and, standing on its top, a 1 x 1 m pane in the
    plane y (0.03: inside a cell of a 0.1 or 0.05 m lattice; 0: on a cell face)."""
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    box.apply_translation((0.0, 0.0, 0.25))
    pane = trimesh.Trimesh(vertices=[[-0.5, y, 0.5], [0.5, y, 0.5], [0.5, y, 1.5],
                                     [-0.5, y, 1.5]], faces=[[0, 1, 2], [0, 2, 3]])
    return _glb(path, {"box": (box, "body"), "pane": (pane, "pane")})


@pytest.fixture(scope="module")
def mesh(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _box_and_pane(tmp_path_factory.mktemp("sheets") / "box_pane.glb")


def _model(path: Path, size: float, shape: str = "cube", said: list | None = None
           ) -> VoxelModel:
    return voxelize([ObjectRequest(mesh=path, voxel_size=(size,) * 3, material="concrete",
                                   material_map={"pane": "glass"}, chunk_size=0.0,
                                   shape=shape, sheet_thickness=THICKNESS)],
                    VoxelizeSettings(up_axis="Z", ground=0.0),
                    warn=(said if said is not None else []).append)


def _pane_voxels(model: VoxelModel) -> np.ndarray:
    a = model.arrays
    glass = model.meta["materials"].index("glass")
    return np.flatnonzero(a["voxel_material"] == glass)


@pytest.mark.parametrize("size", [0.1, 0.05])
def test_a_pane_is_one_voxel_deep_and_weighs_what_the_pane_does(mesh: Path,
                                                                size: float) -> None:
    said: list[str] = []
    model = _model(mesh, size, said=said)
    assert any("part 'pane'" in s and "voxelized as a sheet" in s for s in said), said
    a = model.arrays
    pane = _pane_voxels(model)
    centres = a["voxel_centroid"][pane]
    # every cell the plane y = 0.03 passes through above the box, one cell deep
    assert np.unique(np.round(centres[:, 1] / size, 6)).size == 1
    columns = round(1.0 / size)
    assert len(pane) == columns * columns
    np.testing.assert_allclose(a["voxel_mass"][pane].sum(),
                               PANE_AREA * THICKNESS * GLASS_DENSITY, rtol=1e-9)
    np.testing.assert_allclose(a["voxel_mass"][pane], a["voxel_volume"][pane] * GLASS_DENSITY)
    # the box keeps its volume (the pane stands on it, it takes none of its cells)
    box = np.setdiff1d(np.arange(len(a["voxel_mass"])), pane)
    np.testing.assert_allclose(a["voxel_volume"][box].sum(), 2.0 * 1.0 * 0.5, rtol=1e-9)


def test_a_pane_in_a_cell_face_is_still_one_voxel_deep(tmp_path: Path) -> None:
    """A pane (and the box top its edge stands on) lying exactly in cell faces takes the
    cells on one side: 10 x 10 voxels, not 10 x 10 x 2, and not none."""
    path = _box_and_pane(tmp_path / "face_pane.glb", y=0.0)
    model = _model(path, 0.1)
    pane = _pane_voxels(model)
    assert len(pane) == 100
    assert np.unique(np.round(model.arrays["voxel_centroid"][pane, 1], 6)).size == 1
    np.testing.assert_allclose(model.arrays["voxel_mass"][pane].sum(),
                               PANE_AREA * THICKNESS * GLASS_DENSITY, rtol=1e-9)


def test_links_through_a_pane_carry_its_section(mesh: Path) -> None:
    size = 0.1
    model = _model(mesh, size)
    a = model.arrays
    is_pane = np.zeros(len(a["voxel_mass"]), dtype=bool)
    is_pane[_pane_voxels(model)] = True
    lv = a["link_voxels"]
    thin = is_pane[lv[:, 0]] | is_pane[lv[:, 1]]
    assert thin.sum() > 0
    np.testing.assert_allclose(a["link_area"][thin], THICKNESS * size)  # t x face side
    np.testing.assert_allclose(a["link_area"][~thin], size * size)
    # the pane is held to the box by the links under its bottom row
    pane_box = is_pane[lv[:, 0]] != is_pane[lv[:, 1]]
    assert pane_box.sum() == round(1.0 / size)


def test_conform_keeps_the_pane_as_whole_cells(mesh: Path) -> None:
    model = _model(mesh, 0.1, shape="conform")
    pane = _pane_voxels(model)
    assert len(pane) == 100
    assert not np.isin(pane, model.arrays["conform_voxels"]).any()
    np.testing.assert_allclose(model.arrays["voxel_mass"][pane].sum(),
                               PANE_AREA * THICKNESS * GLASS_DENSITY, rtol=1e-9)


def test_a_lone_open_sheet_is_still_refused(tmp_path: Path) -> None:
    pane = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]],
                           faces=[[0, 1, 2], [0, 2, 3]])
    path = tmp_path / "pane.stl"
    pane.export(path)
    with pytest.raises(MeshError, match="open surface"):
        voxelize([ObjectRequest(mesh=path, voxel_size=(0.1,) * 3)],
                 VoxelizeSettings(up_axis="Z"))


def test_the_milk_truck_keeps_its_glass() -> None:
    """The truck's glass (2.73 m² of open surface, glTF material 'glass') becomes glass
    voxels weighing area x thickness x density: 41 kg at 6 mm."""
    said: list[str] = []
    model = voxelize([ObjectRequest(mesh=DATA / "CesiumMilkTruck.glb", voxel_size=(0.1,) * 3,
                                    material="steel", material_map={"glass": "glass"},
                                    sheet_thickness=THICKNESS)],
                     VoxelizeSettings(up_axis="Y"), warn=said.append)
    sheets = [s for s in said if "voxelized as a sheet" in s]
    assert len(sheets) == 2, said  # the glass and the window trim
    assert not [s for s in said if "material_map" in s], said  # 'glass' sets voxels now
    glass = _pane_voxels(model)
    assert len(glass) > 100
    scene = trimesh.load(DATA / "CesiumMilkTruck.glb")
    area = sum(g.area for name, g in scene.geometry.items() if name.endswith("_1"))
    # the window trim's sheet, applied after the glass, takes the cells both cross
    mass = model.arrays["voxel_mass"][glass].sum()
    assert 0.5 * area * THICKNESS * GLASS_DENSITY < mass <= area * THICKNESS * GLASS_DENSITY


def test_sheet_thickness_flag(tmp_path: Path, mesh: Path) -> None:
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "blastvox", "voxelize", *args],
                              capture_output=True, text=True, timeout=600, check=False)

    out = tmp_path / "m.npz"
    bad = run(str(mesh), "-o", str(out), "--sheet-thickness", "0")
    assert bad.returncode != 0 and not out.exists()
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and "--sheet-thickness" in lines[0], bad.stderr
    thin = run(str(mesh), "-o", str(out), "--voxel-size", "0.1", "--up-axis", "Z",
               "--sheet-thickness", "0.002", "-q")
    assert thin.returncode == 0, thin.stderr
    model = VoxelModel.load(out)
    assert model.meta["settings"]["objects"][0]["sheet_thickness"] == 0.002
    concrete = 2400.0  # no material_map on the command line: the pane is concrete
    pane_mass = model.arrays["voxel_mass"][model.arrays["voxel_centroid"][:, 2] > 0.5].sum()
    np.testing.assert_allclose(pane_mass, PANE_AREA * 0.002 * concrete, rtol=1e-9)


def test_a_soup_part_is_still_skipped_and_its_material_map_entry_said(tmp_path: Path) -> None:
    """A part of disconnected triangles has neither an inside nor a surface to make a
    sheet of: skipped with a warning, and a material_map entry for it sets nothing."""
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    rng = np.random.default_rng(0)
    corners = rng.uniform(-0.4, 0.4, size=(30, 3, 3))
    soup = trimesh.Trimesh(vertices=corners.reshape(-1, 3),
                           faces=np.arange(90).reshape(-1, 3), process=False)
    path = _glb(tmp_path / "box_soup.glb", {"box": (box, "body"), "junk": (soup, "junk")})
    said: list[str] = []
    model = voxelize([ObjectRequest(mesh=path, voxel_size=(0.1,) * 3,
                                    material_map={"junk": "wood"}, chunk_size=0.0)],
                     VoxelizeSettings(up_axis="Z"), warn=said.append)
    assert any("skipped" in s and "triangle soup" in s for s in said), said
    assert any("entry 'junk' matches only parts that were skipped" in s for s in said), said
    assert model.meta["materials"] == ["concrete"]


def test_a_file_of_open_parts_only_is_refused_in_one_line(tmp_path: Path) -> None:
    """Two panes and no closed part: nothing to hang the sheets on. One error line,
    no sheet warnings before it, no output."""
    scene = trimesh.Scene()
    for k, y in enumerate((0.03, 0.53)):
        pane = trimesh.Trimesh(vertices=[[0, y, 0], [1, y, 0], [1, y, 1], [0, y, 1]],
                               faces=[[0, 1, 2], [0, 2, 3]])
        scene.add_geometry(pane, node_name=f"pane{k}", geom_name=f"pane{k}")
    path = tmp_path / "panes.glb"
    scene.export(path)
    out = tmp_path / "m.npz"
    done = subprocess.run([sys.executable, "-m", "blastvox", "voxelize", str(path), "-o",
                           str(out), "--voxel-size", "0.1"], capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 1 and not out.exists()
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "panes.glb: no part encloses a volume" in lines[0] and "sheets" in lines[0]


def test_closed_parts_smaller_than_the_voxels_say_so_not_open(tmp_path: Path) -> None:
    """Two closed boxes (a multi-part file, as trimesh's multibody.stl) voxelized at a
    size that leaves no cell centre in either were refused as "no part encloses a
    volume (open surfaces ...)": both are closed. The error names the file, the voxel
    size and the cure, and a file of only open panes keeps its own message (above)."""
    path = _glb(tmp_path / "two.glb", {
        "a": (trimesh.creation.box(extents=(0.1, 0.7, 0.1)), "a"),
        "b": (trimesh.creation.box(extents=(0.07, 0.2, 0.1)).apply_translation((0.4, 0, 0)),
              "b")})
    for size in (0.7, 2.0):
        with pytest.raises(MeshError) as caught:
            _model(path, size)
        message = str(caught.value)
        assert message.startswith(f"{path}: no voxel centre lies inside any of its parts at "
                                  f"voxel size {size:g} m; use a smaller voxel size"), message
        assert "open surface" not in message and "encloses" not in message
