"""Blender renders the exports: frame 0 and a mid frame of a shot, from USD and from .glb,
with Cycles on the CPU (``tools/blender/render_check.py`` in ``.venv-blender``).

An import that never renders missed two defects an artist met at once: the house's
USD cache crashed Cycles at frame 0 (an empty UsdGeomPoints: the dust before the
blast), and later frames rendered black (the shock sphere grew to about 1 km around
the camera). So these tests render, and check what the picture shows: something
covers the frame (the asset is in view), it is lit (not black), and its colour is
the asset's (the house's brick and plaster, not a white sphere). The scene camera
arrives with the lens the scene asked for. Textured assets (the Khronos Duck and
Cesium Milk Truck, voxelized here) keep their look: their render differs from the
render of the same shot with the look stripped (the physics material's flat
colour), and the duck is yellow.

The shots are the goldens' caches (examples/golden), exported here; tiny images
and few samples keep each render to a few seconds.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from test_smooth_normals import _surface_errors

from blastvox.cache import SimCache
from blastvox.export.api import ExportOptions, export
from blastvox.model import SURFACE_ARRAYS, VoxelModel

ROOT = Path(__file__).resolve().parents[1]
BLENDER_PYTHON = ROOT / ".venv-blender" / "bin" / "python"
RENDER_CHECK = ROOT / "tools" / "blender" / "render_check.py"
GOLDEN = ROOT / "examples" / "golden"
DATA = ROOT / "tests" / "data"
TIMEOUT = 600  # s per Blender run (about 10 s here)
SIZE = "96x54"

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not BLENDER_PYTHON.exists(),
                       reason="no Blender venv (.venv-blender): run `make blender-venv`"),
]


def render(path: Path, out_dir: Path, frames: list[int], size: str = SIZE,
           options: tuple[str, ...] = ()) -> dict:
    """Run render_check.py (``options``: more of its flags); a crash inside Blender fails
    here with its exit code."""
    done = subprocess.run([str(BLENDER_PYTHON), str(RENDER_CHECK), str(path), str(out_dir),
                           *map(str, frames), "--size", size, *options], capture_output=True,
                          text=True, timeout=TIMEOUT, check=False)
    assert done.returncode == 0, (done.returncode, done.stderr[-3000:])
    return json.loads(done.stdout)


@pytest.fixture(scope="module")
def house(tmp_path_factory: pytest.TempPathFactory) -> tuple[SimCache, Path]:
    cache = SimCache.load(GOLDEN / "house.sim.npz")
    return cache, tmp_path_factory.mktemp("render")


def mid_frame(cache: SimCache) -> int:
    return cache.frame_count // 2


@pytest.mark.parametrize("suffix", [".usdc", ".glb", ".usdz"])
def test_house_renders_at_frame_0_and_mid_shot(house: tuple[SimCache, Path], suffix: str
                                               ) -> None:
    cache, tmp = house
    path = tmp / f"house{suffix}"
    export(cache, path, ExportOptions())
    frames = [0, mid_frame(cache)]
    report = render(path, tmp / suffix[1:], frames)
    assert report["camera"]["from_file"]  # the house scene's camera, on its front
    for f in frames:
        got = report["frames"][str(f)]
        assert Path(got["png"]).stat().st_size > 0
        assert got["coverage"] > 0.03, (f, got)   # the asset is in view
        assert got["luminance"] > 0.08, (f, got)  # and lit: not a black frame
        r, g, b = got["rgb"]
        if suffix == ".usdc" and f == 0:
            # the fireball, born at the blast, is a volume (Blender's default volume
            # material: grey smoke, thin) inside its glow (Particles/fireball_glow,
            # translucent emissive balls) at the door: the house seen through a warm glow
            assert report["volumes"]["fireball"]["grids"] == ["density", "temperature"]
            assert r > 1.15 * b and r > 0.3, (f, got)
            continue
        assert r > b * 1.1, (f, got)  # brick walls: red over blue, not a white sphere


def test_a_shock_guide_changes_no_render(house: tuple[SimCache, Path]) -> None:
    """--shock writes the sphere as a guide: the render at mid shot, where the sphere
    is far larger than the house, is the render without it."""
    cache, tmp = house
    f = mid_frame(cache)
    reports = []
    for shock in (False, True):
        path = tmp / f"shock_{shock}.usdc"
        export(cache, path, ExportOptions(shock=shock))
        reports.append(render(path, tmp / f"shock_{shock}", [f])["frames"][str(f)])
    assert np.max(np.abs(cache.shock_radius[f])) > 20  # the sphere encloses everything
    assert reports[1]["coverage"] == pytest.approx(reports[0]["coverage"], abs=0.01)
    assert reports[1]["luminance"] == pytest.approx(reports[0]["luminance"], rel=0.05)


@pytest.mark.parametrize("suffix", [".usdc", ".glb"])
def test_scene_camera_arrives_with_its_lens(tmp_path: Path, suffix: str) -> None:
    """The logo's 50 mm camera: Blender read the USD lens (in tenths of a metre) as
    5000 mm before; it must be 50 mm, and the logo in its view."""
    cache = SimCache.load(GOLDEN / "logo.sim.npz")
    assert cache.meta["camera"]["focal_length_mm"] == 50.0
    path = tmp_path / f"logo{suffix}"
    export(cache, path, ExportOptions())
    report = render(path, tmp_path / "frames", [0])
    assert report["camera"]["from_file"]
    # glTF stores a vertical field of view; Blender turns it back into a lens on its
    # own sensor, so only USD keeps the 36 mm filmback: compare fields of view
    lens, sensor = report["camera"]["lens_mm"], report["camera"]["sensor_width_mm"]
    if suffix == ".usdc":
        assert lens == pytest.approx(50.0, rel=1e-4) and sensor == pytest.approx(36.0)
    assert report["frames"]["0"]["coverage"] > 0.02


def without_look(cache: SimCache) -> SimCache:
    """The same shot with the model's source look removed (flat material colours)."""
    arrays = {k: v for k, v in cache.model.arrays.items() if k not in SURFACE_ARRAYS}
    meta = {k: v for k, v in cache.model.meta.items() if k != "textures"}
    return SimCache(arrays=cache.arrays, model=VoxelModel(arrays=arrays, meta=meta),
                    meta=cache.meta)


@pytest.fixture(scope="module")
def textured(tmp_path_factory: pytest.TempPathFactory) -> dict[str, SimCache]:
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    shots = {}
    for name, size in (("Duck", 0.2), ("CesiumMilkTruck", 0.15)):
        model = voxelize([ObjectRequest(mesh=DATA / f"{name}.glb", voxel_size=(size,) * 3,
                                        material="concrete")],
                         VoxelizeSettings(up_axis="Y"), warn=lambda message: None)
        assert model.textures, name
        shots[name] = simulate(model, SimSettings(duration=0.05, fps=20.0, charges=()))
    return shots


@pytest.mark.parametrize(("asset", "suffix"), [("Duck", ".usdc"), ("Duck", ".glb"),
                                               ("CesiumMilkTruck", ".usdc")])
def test_a_textured_asset_keeps_its_look(textured: dict[str, SimCache], tmp_path: Path,
                                         asset: str, suffix: str) -> None:
    colours, images = [], []
    for look, cache in (("textured", textured[asset]), ("flat", without_look(textured[asset]))):
        path = tmp_path / look / f"{asset}{suffix}"
        path.parent.mkdir()
        export(cache, path, ExportOptions())
        got = render(path, tmp_path / look / "frames", [0])["frames"]["0"]
        assert got["coverage"] > 0.03 and got["luminance"] > 0.05, got
        colours.append(np.array(got["rgb"]))
        images.append(np.asarray(Image.open(got["png"]).convert("RGBA"), dtype=float) / 255)
    # the texture shows: pixel by pixel, the textured render is not the flat one
    both = (images[0][..., 3] > 0.5) & (images[1][..., 3] > 0.5)
    difference = np.abs(images[0][..., :3] - images[1][..., :3])[both].mean()
    assert difference > 0.04, difference
    if asset == "Duck":
        r, g, b = colours[0]
        assert r > 1.5 * b and g > 1.3 * b, colours[0]  # a yellow duck, not grey concrete


def _detail(png: str) -> tuple[float, np.ndarray]:
    """Mean |Laplacian| of the grey level over fully covered pixels, and the mean colour."""
    image = np.asarray(Image.open(png).convert("RGBA"), dtype=float) / 255
    grey = image[..., :3].mean(axis=2)
    laplacian = np.abs(4 * grey[1:-1, 1:-1] - grey[:-2, 1:-1] - grey[2:, 1:-1]
                       - grey[1:-1, :-2] - grey[1:-1, 2:])
    covered = image[1:-1, 1:-1, 3] > 0.99
    return float(laplacian[covered].mean()), image[..., :3][image[..., 3] > 0.99].mean(axis=0)


@pytest.mark.parametrize("suffix", [".usdc", ".glb"])
def test_fracture_faces_render_their_damage_texture(shattered_slab: SimCache, tmp_path: Path,
                                                    suffix: str) -> None:
    """Close to a shattered slab, its fracture faces show cracked concrete: the render
    has more fine detail than with the flat damage colour, and the same mean colour. The
    pieces cover at least a quarter of the frame (0.29 since the edge facing the charge,
    0.5 m from it, crushes to dust; 0.3 and more before craters)."""
    f = 3
    got = {}
    for flat in (False, True):
        path = tmp_path / f"flat_{flat}" / f"slab{suffix}"
        path.parent.mkdir()
        export(shattered_slab, path, ExportOptions(damage_textures=not flat))
        report = render(path, path.parent / "frames", [f], size="160x90")
        assert report["camera"]["from_file"]
        assert report["frames"][str(f)]["coverage"] > 0.25
        got[flat] = _detail(report["frames"][str(f)]["png"])
    assert got[False][0] > 1.15 * got[True][0], got
    np.testing.assert_allclose(got[False][1], got[True][1], atol=0.03)


@pytest.fixture(scope="module")
def truck_shot(tmp_path_factory: pytest.TempPathFactory) -> SimCache:
    """examples/truck at 0.15 m voxels: the textured truck (its scene's light vehicle and
    tyre materials, wheels held by part_bond, not anchored) thrown and broken by 50 kg,
    without the fireball (its glow, 5 m across, would cover the truck at frame 0,
    where its texture is checked)."""
    from blastvox.scene import load_scene
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    spec = load_scene(ROOT / "examples" / "truck" / "scene.toml")
    obj = spec.objects[0]
    model = voxelize([ObjectRequest(mesh=Path(obj.mesh), voxel_size=(0.15,) * 3,
                                    material=obj.material, material_map=obj.material_map,
                                    part_bond=obj.part_bond, anchored=obj.anchored,
                                    sheet_thickness=obj.sheet_thickness)],
                     VoxelizeSettings(up_axis="Y", library=spec.material_library()),
                     warn=lambda message: None)
    charge = spec.charges[0]
    return simulate(model, SimSettings(duration=0.5, fps=24.0, dt=1 / 960, fireball=False,
                                       charges=(ChargeSpec(tuple(charge.position),
                                                           charge.mass_kg),)))


@pytest.mark.parametrize("suffix", [".usdc", ".glb"])
def test_truck_renders_broken_and_textured_mid_shot(truck_shot: SimCache, tmp_path: Path,
                                                   suffix: str) -> None:
    cache = truck_shot
    assert cache.piece_count > 3
    # only glass (the windows' sheets) shatters to dust; steel and tyres stay pieces
    ended = np.flatnonzero(cache.piece_end_frame < cache.frame_count)
    glass = cache.model.meta["materials"].index("glass")
    of_ended = np.isin(cache.voxel_piece, ended)
    assert (cache.model.arrays["voxel_material"][of_ended] == glass).all()
    moved = np.linalg.norm(cache.piece_position[-1] - cache.piece_position[0], axis=1)
    assert moved.max() > 0.3  # the blast threw something
    path = tmp_path / f"truck{suffix}"
    export(cache, path, ExportOptions())
    frames = [0, mid_frame(cache)]
    report = render(path, tmp_path / "frames", frames)
    for f in frames:
        got = report["frames"][str(f)]
        assert got["coverage"] > 0.03 and got["luminance"] > 0.08, (f, got)
    # the truck's texture is mostly white and pale blue: light, not the flat grey steel
    r, g, b = report["frames"]["0"]["rgb"]
    assert b >= r - 0.02 and report["frames"]["0"]["luminance"] > 0.3


@pytest.fixture(scope="module")
def smooth_ball(tmp_path_factory: pytest.TempPathFactory) -> SimCache:
    """A 1 m concrete icosphere (1,280 flat triangles), conform 0.25 m voxels: its
    pieces' faces carry the sphere's smooth normals, and a few of its conform
    triangles collapse to a line in float32."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("ball")
    trimesh.creation.icosphere(subdivisions=3, radius=1.0).apply_translation(
        (0.0, 0.0, 1.0)).export(tmp / "ball.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "ball.stl", voxel_size=(0.25,) * 3,
                                    shape="conform", material="concrete")],
                     VoxelizeSettings(up_axis="Z"))
    assert "surface_normals" in model.arrays
    return simulate(model, SimSettings(duration=0.05, fps=20.0, charges=()))


_CORNER_NORMALS = """
import bpy, json, sys
import numpy as np
path = sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
if path.endswith(".glb"):
    bpy.ops.import_scene.gltf(filepath=path)
else:
    bpy.ops.wm.usd_import(filepath=path)
bpy.context.scene.frame_set(0)
graph = bpy.context.evaluated_depsgraph_get()
points, normals = [], []
for ob in bpy.context.scene.objects:
    if ob.type != "MESH" or not ob.name.startswith("piece_"):
        continue
    mesh = ob.evaluated_get(graph).data
    matrix = np.array(ob.matrix_world)
    assert all(len(poly.loop_indices) == 3 for poly in mesh.polygons)
    co = np.array([v.co for v in mesh.vertices]).reshape(-1, 3)
    corner_vertex = np.array([c.vertex_index for c in mesh.loops], dtype=np.int64)
    corner_normal = np.array([n.vector for n in mesh.corner_normals]).reshape(-1, 3)
    points += (co[corner_vertex] @ matrix[:3, :3].T + matrix[:3, 3]).tolist()
    normals += (corner_normal @ matrix[:3, :3].T).tolist()
print(json.dumps({"points": points, "normals": normals}))
"""


@pytest.mark.parametrize("suffix", [".usdc", ".glb"])
def test_a_smooth_asset_reaches_blender_with_its_normals(smooth_ball: SimCache, tmp_path: Path,
                                                         suffix: str) -> None:
    """Blender's shading normals at the sphere's corners (after import, at frame 0) are
    the sphere's own within 1 degree: smooth, and on the right corners. When a
    triangle that collapses in float32 was written, Blender's USD import dropped it,
    kept none of the file's normals (the corner count no longer matched) and shaded
    the conform cells' fans with normals averaged across their sharp cell edges:
    black patches in the render."""
    path = tmp_path / f"ball{suffix}"
    export(smooth_ball, path, ExportOptions())
    done = subprocess.run([str(BLENDER_PYTHON), "-c", _CORNER_NORMALS, str(path)],
                          capture_output=True, text=True, timeout=TIMEOUT, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    points, normals = np.array(got["points"]), np.array(got["normals"])
    # Blender is Z up, as the model: the importers turn the Y-up files back
    errors = _surface_errors(points.reshape(-1, 3, 3), normals.reshape(-1, 3, 3),
                             np.array([0.0, 0.0, 1.0]))
    assert len(errors) > 1000 and errors.max() < 1.0


@pytest.mark.parametrize("suffix", [".usdc", ".glb"])
def test_a_vertex_coloured_ply_renders_in_its_colours(tmp_path: Path, suffix: str) -> None:
    """A PLY ball red above its equator and blue below (per vertex): its colours,
    baked into a texture, render red on top and blue underneath."""
    from test_vertex_colors import colored_ball

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    model = voxelize([ObjectRequest(mesh=colored_ball(tmp_path / "ball.ply"),
                                    voxel_size=(0.25,) * 3, shape="conform",
                                    material="concrete")], VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.05, fps=20.0, charges=()))
    path = tmp_path / f"ball{suffix}"
    export(cache, path, ExportOptions())
    got = render(path, tmp_path / "frames", [0], size="160x160")["frames"]["0"]
    image = np.asarray(Image.open(got["png"]).convert("RGBA"), dtype=np.float64) / 255.0
    rows = np.flatnonzero((image[..., 3] > 0.5).any(axis=1))
    top, bottom = rows[: len(rows) // 3], rows[-(len(rows) // 3):]
    upper = image[top][image[top][..., 3] > 0.5][:, :3].mean(axis=0)
    lower = image[bottom][image[bottom][..., 3] > 0.5][:, :3].mean(axis=0)
    assert upper[0] > 2 * upper[2], upper  # red on top
    assert lower[2] > 2 * lower[0], lower  # blue underneath


@pytest.fixture(scope="module")
def fast_piece(tmp_path_factory: pytest.TempPathFactory) -> SimCache:
    """One 1 m concrete cube flying across the scene camera's view at 40 m/s (1.7 m a
    frame at 24 fps), 12 m in front of it: the shot of an unbroken cube with its
    motion replaced by that flight."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("fast")
    trimesh.creation.box(extents=(1.0, 1.0, 1.0)).apply_translation(
        (0.0, 0.0, 1.0)).export(tmp / "cube.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "cube.stl", voxel_size=(0.5,) * 3,
                                    material="concrete")], VoxelizeSettings(up_axis="Z",
                                                                             ground=None))
    cache = simulate(model, SimSettings(duration=0.25, fps=24.0, charges=()))
    assert cache.piece_count == 1
    arrays = dict(cache.arrays)
    t = cache.frame_time
    position = np.repeat(cache.piece_pivot[None], len(t), axis=0).astype(np.float64)
    position[:, 0, 0] += 40.0 * (t - t[len(t) // 2])  # in the middle of the view mid-shot
    arrays["piece_position"] = position.astype(np.float32)
    camera = {"position": [0.0, -12.0, 1.0], "look_at": [0.0, 0.0, 1.0],
              "focal_length_mm": 35.0}
    return SimCache(arrays=arrays, model=cache.model, meta={**cache.meta, "camera": camera})


@pytest.mark.parametrize("suffix", [".usdc", ".glb"])
def test_motion_blur_smears_a_fast_piece(fast_piece: SimCache, tmp_path: Path,
                                         suffix: str) -> None:
    """Cycles' motion blur reads the piece's motion from both formats: Blender evaluates
    the USD transform cache and the glTF keys at the shutter's sub-frames (it would add
    a mesh's ``velocities`` as vertex motion on top, blurring a piece twice, so the
    export writes none there; a PointInstancer's it does not import), so the
    mid-shot frame rendered with blur on differs from it rendered with blur off: the
    cube is smeared sideways into a wider, partly transparent band."""
    path = tmp_path / f"fast{suffix}"
    export(fast_piece, path, ExportOptions())
    f = mid_frame(fast_piece)
    alpha = {}
    for blur in (False, True):
        out = tmp_path / f"blur_{blur}"
        report = render(path, out, [f], options=("--motion-blur",) if blur else ())
        assert report["camera"]["from_file"]
        image = np.asarray(Image.open(report["frames"][str(f)]["png"]), dtype=np.float64)
        alpha[blur] = image[..., 3] / 255.0
    sharp, smeared = alpha[False], alpha[True]
    assert (sharp > 0.5).mean() > 0.01, "the cube should be in view"
    changed = np.abs(smeared - sharp) > 0.2
    assert changed.mean() > 0.01, f"motion blur changed {changed.mean():.2%} of the pixels"
    partial = ((smeared > 0.05) & (smeared < 0.95)).sum()
    assert partial > 2 * ((sharp > 0.05) & (sharp < 0.95)).sum()
    columns = (smeared > 0.05).any(axis=0).sum()
    assert columns > (sharp > 0.05).any(axis=0).sum() + 3  # wider along the flight
