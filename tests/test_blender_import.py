"""Blender imports the exports: USD (.usdc) and glTF (.glb) through Blender's own Python
module (``bpy``), checked against the SimCache.

bpy lives in its own virtualenv, ``.venv-blender`` (``make blender-venv``; it pins
its own numpy), so the test runs ``tools/blender/import_check.py`` in that venv's
python as a subprocess and reads the one JSON object it prints.

The shot: a 2 x 0.5 x 2 m brick wall voxelized Z-up (so the Z-up -> Y-up export and
Blender's Y-up -> Z-up import are both exercised), 2 kg TNT 2 m in front, 0.5 s at
24 fps (13 frames, frame_time[f] = f / 24), exported with the default up axis Y.

What Blender 5.0.1 does (found out with this test, and asserted exactly):

* Y-up -> Z-up: both importers map (x, y, z) to (x, -z, y) (``BLENDER_FROM_Y_UP``).
  The glTF importer converts every node's transform and the vertices, so a piece's
  world rotation is B R B^T (B that map, R the exported rotation); the USD importer
  keeps the stage's Y-up data and rotates the root prim's object by B, so a piece's
  world rotation is B R and its mesh data stays Y-up. Either way the world-space
  geometry is B applied to the exported world-space geometry: with a Z-up model
  that is the model frame itself.
* Frames, USD: Blender frame = USD time code = cache frame index. With
  ``set_frame_range`` the scene range is the stage's startTimeCode..endTimeCode,
  0..frame_count - 1. The scene's fps is not read from the stage
  (timeCodesPerSecond): it stays Blender's default 24, which this shot happens to use.
* Frames, glTF: keys go to Blender frame = time x scene fps (24 in a new scene) with
  no offset, so frame f is cache frame f for a 24 fps shot; the action spans
  0..frame_count - 1. glTF has no frame range and the importer leaves the scene's
  (1..250, the empty factory scene's).
* Pieces, glTF: one object per node, named piece_00000...; a piece that vanishes is
  scaled to 0 from its end frame (STEP), so its geometry collapses to a point.
* Pieces, USD: with the importer's default ``merge_parent_xform=True`` each
  Xform piece_NNNNN and its only child Mesh become one object named after the
  mesh, which is why the export names the mesh after its piece (it was "geom",
  and the names came out as "geom.001"... in no order).
  Transforms arrive as Transform Cache constraints (only for prims with more than
  one time sample; a piece that never moves is imported static).
* Vanishing, USD: Blender 5.0 does not import time-sampled ``visibility``, so the
  export also scales a vanishing piece to 0 at its end frame (as glTF does).
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from blastvox.export.options import KEY_TOLERANCE_DEG

ROOT = Path(__file__).resolve().parents[1]
BLENDER_PYTHON = ROOT / ".venv-blender" / "bin" / "python"
IMPORT_CHECK = ROOT / "tools" / "blender" / "import_check.py"
MAKE_COMMAND = "make blender-venv"
TIMEOUT = 300  # s per Blender run (about 2 s here)
TOL = 1e-3  # m
#: the exports' default key tolerance (blastvox.export.keys) with a margin for Blender's
#: own quaternion interpolation
ROTATION_TOL_DEG = 1.2 * KEY_TOLERANCE_DEG
FPS = 24
#: the scene camera: position, look-at (model frame, Z up) and a 50 mm lens
CAMERA = ((1.0, -9.0, 1.5), (0.0, 0.0, 1.0), 50.0)
# Blender's Y-up -> Z-up conversion: (x, y, z) -> (x, -z, y)
BLENDER_FROM_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

pytestmark = pytest.mark.skipif(
    not BLENDER_PYTHON.exists(),
    reason=f"no Blender venv ({BLENDER_PYTHON.relative_to(ROOT)}): run `{MAKE_COMMAND}`")


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) (w, x, y, z), normalised first
    (Blender's are unit only to float32). This test runs in the main venv; only
    import_check.py runs in the Blender venv."""
    from blastvox.geometry import quaternion

    return quaternion.to_matrix(quaternion.normalize(q))


class Shot:
    """The cache, its exports and what Blender should show (Blender's Z-up world)."""

    def __init__(self, cache, usd: Path, glb: Path) -> None:
        from blastvox.export.pieces import animation, piece_meshes

        self.cache, self.usd, self.glb = cache, usd, glb
        self.frames = cache.frame_count
        self.pieces = cache.piece_count
        self.mid, self.late = self.frames // 2, self.frames - 1
        anim = animation(cache, "Y")  # what both files hold (default up axis Y)
        b = BLENDER_FROM_Y_UP
        self.rot_y = _quat_matrix(anim.orientation)                 # (F, P, 3, 3), Y-up
        self.position = anim.position @ b.T                          # (F, P, 3), Z-up
        self.rot_gltf = b @ self.rot_y @ b.T                         # node TRS converted
        self.rot_usd = b @ self.rot_y                                # root object turned by B
        self.end = cache.piece_end_frame.astype(np.int64)
        meshes = piece_meshes(cache, "Y")
        local = meshes.vertices.reshape(-1, 3)                       # piece-local, Y-up
        owner = np.repeat(np.arange(self.pieces), 3 * np.diff(meshes.offsets))
        self.bounds = np.zeros((self.frames, self.pieces, 2, 3))
        for f in range(self.frames):
            world = np.einsum("pij,pj->pi", self.rot_y[f][owner], local) \
                + anim.position[f][owner]
            world = world @ b.T
            for p in range(self.pieces):
                mine = world[owner == p]
                self.bounds[f, p] = (mine.min(axis=0), mine.max(axis=0))
        shown = self.end > self.late
        moved = np.linalg.norm(self.position[self.late] - self.position[0], axis=1)
        moved[~shown] = -1.0
        self.mover = int(np.argmax(moved))  # the shown piece that moved the most
        self.moved = float(moved[self.mover])
        self.gone = np.flatnonzero(self.end <= self.late)  # vanished by the late frame

    def name(self, p: int) -> str:
        return f"piece_{p:05d}"


@pytest.fixture(scope="module")
def shot(tmp_path_factory) -> Shot:
    import trimesh

    from blastvox.export.api import export
    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("blender")
    trimesh.creation.box(extents=(2, 0.5, 2)).export(tmp / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.5, fps=FPS, camera=CAMERA,
                                        charges=(ChargeSpec((0, -2.0, 1.0), 40.0),)))
    assert cache.model.meta["up_axis"] == "Z"
    export(cache, tmp / "shot.usdc")
    export(cache, tmp / "shot.glb")
    s = Shot(cache, tmp / "shot.usdc", tmp / "shot.glb")
    assert s.frames == 13 and np.allclose(cache.frame_time, np.arange(13) / FPS)
    assert s.moved > 0.1, "the shot should throw a piece that stays shown to the end"
    return s


def _blender(path: Path, frames: list[int], **options) -> dict:
    """Run import_check.py in the Blender venv; its JSON report."""
    cmd = [str(BLENDER_PYTHON), str(IMPORT_CHECK), str(path), *map(str, frames)]
    for key, value in options.items():
        cmd += ["--set", f"{key}={json.dumps(value)}"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    assert run.returncode == 0, f"{' '.join(cmd)} failed:\n{run.stderr[-4000:]}"
    return json.loads(run.stdout)


@pytest.fixture(scope="module")
def gltf(shot: Shot) -> dict:
    return _blender(shot.glb, [shot.mid, shot.late])


@pytest.fixture(scope="module")
def usd(shot: Shot) -> dict:
    return _blender(shot.usd, [shot.mid, shot.late])


def _check_pieces(shot: Shot, report: dict, rotation: np.ndarray) -> None:
    """Every shown piece's world location, rotation and mesh box at mid and late frames."""
    for f in (shot.mid, shot.late):
        at = report["frames"][str(f)]
        for p in np.flatnonzero(shot.end > f).tolist():
            got = at[shot.name(p)]
            where = f"{shot.name(p)} at frame {f}"
            np.testing.assert_allclose(got["location"], shot.position[f, p], atol=TOL,
                                       err_msg=f"{where}: location")
            # keyframe-reduced: within the key tolerance of the cache's rotation (and a
            # little more: Blender's quaternion F-curves, 0.108 deg on the house shot)
            turn = _quat_matrix(got["rotation"]) @ np.asarray(rotation[f, p]).T
            angle = np.degrees(np.arccos(np.clip((np.trace(turn) - 1.0) / 2.0, -1.0, 1.0)))
            assert angle <= ROTATION_TOL_DEG, f"{where}: rotation off by {angle:.3f} deg"
            assert got["bounds"] is not None, f"{where}: not shown"
            np.testing.assert_allclose(got["bounds"], shot.bounds[f, p], atol=TOL,
                                       err_msg=f"{where}: world-space mesh box")


def _check_mover(shot: Shot, report: dict) -> None:
    """The piece that moved the most is where the cache has it at the late frame."""
    got = report["frames"][str(shot.late)][shot.name(shot.mover)]["location"]
    # the model is Z-up like Blender, so Blender's world is the model frame
    expected = shot.cache.piece_position[shot.late, shot.mover]
    np.testing.assert_allclose(shot.position[shot.late, shot.mover], expected, atol=1e-6)
    np.testing.assert_allclose(got, expected, atol=TOL, err_msg=(
        f"{shot.name(shot.mover)} (moved {shot.moved:.2f} m) at frame {shot.late}"))


@pytest.mark.parametrize("kind", ["gltf", "usd"])
def test_pieces_hang_under_their_object(shot: Shot, gltf: dict, usd: dict, kind: str) -> None:
    """/Shot/<object>/<piece> (USD) and the object node (glTF) arrive as a parent named
    after the source object, so an artist selects an object's pieces by its children."""
    report = {"gltf": gltf, "usd": usd}[kind]
    name = shot.cache.model.meta["objects"][0]["name"]
    assert report["parents"] == {shot.name(p): name for p in range(shot.pieces)}


def test_gltf_import(shot: Shot, gltf: dict) -> None:
    assert gltf["format"] == "gltf"
    assert gltf["piece_count"] == shot.pieces
    # glTF has no frame range, and Blender 5.0's importer never sets the scene's (its
    # io_scene_gltf2/blender/imp writes keys at time x fps and reads scene extras as
    # custom properties only): the scene keeps the empty factory scene's 1..250, and
    # the animation (one action) spans frames 0..F-1 (frame = time x 24 fps, no offset)
    assert (gltf["frame_start"], gltf["frame_end"]) == (1, 250)
    assert gltf["fps"] == FPS
    assert gltf["actions"] == 1
    assert gltf["action_frame_range"] == pytest.approx([0, shot.frames - 1], abs=1e-4)
    _check_mover(shot, gltf)
    _check_pieces(shot, gltf, shot.rot_gltf)


def test_gltf_vanished_pieces_collapse(shot: Shot, gltf: dict) -> None:
    """A piece gone by the late frame is scaled to 0 there (its mesh box is a point)."""
    assert len(shot.gone), "the shot should have pieces that vanish"
    at = gltf["frames"][str(shot.late)]
    for p in shot.gone.tolist():
        lo, hi = np.asarray(at[shot.name(p)]["bounds"])
        assert np.all(hi - lo < 1e-6), f"{shot.name(p)} still has a size after its end frame"


def test_usd_import(shot: Shot, usd: dict) -> None:
    assert usd["format"] == "usd"
    assert usd["piece_count"] == shot.pieces
    # set_frame_range: the stage's startTimeCode..endTimeCode; time code = frame index
    assert (usd["frame_start"], usd["frame_end"]) == (0, shot.frames - 1)
    assert usd["fps"] == FPS  # Blender's default: the stage's fps is not read
    assert usd["transform_caches"] > 0
    _check_mover(shot, usd)
    _check_pieces(shot, usd, shot.rot_usd)


def test_usd_default_import_keeps_piece_names(shot: Shot) -> None:
    report = _blender(shot.usd, [shot.late])
    assert report["frame_start"] == 0 and report["frame_end"] == shot.frames - 1
    assert report["piece_count"] == shot.pieces


def test_usd_vanished_pieces_hidden(shot: Shot, usd: dict) -> None:
    """A piece gone by the late frame is scaled to 0 there (visibility is not imported)."""
    assert len(shot.gone), "the shot should have pieces that vanish"
    at = usd["frames"][str(shot.late)]
    shown = [shot.name(p) for p in shot.gone.tolist()
             if at[shot.name(p)]["bounds"] is not None
             and np.any(np.ptp(np.asarray(at[shot.name(p)]["bounds"]), axis=0) > 1e-6)]
    assert not shown, f"{len(shown)} of {len(shot.gone)} vanished pieces still shown"


def test_gltf_skinned_layout_imports_as_one_object(shot: Shot, gltf: dict, tmp_path: Path
                                                   ) -> None:
    """--layout skinned (one skin here: fewer pieces than SKIN_JOINTS) arrives as one
    armature and one mesh, and every shown vertex is
    where the node-per-piece import puts it (the same scene bounds at mid and late
    frames)."""
    from blastvox.export.api import ExportOptions, export

    path = tmp_path / "skinned.glb"
    export(shot.cache, path, ExportOptions(layout="skinned"))
    report = _blender(path, [shot.mid, shot.late])
    assert report["objects"].get("ARMATURE") == 1 and report["piece_count"] == 0
    # the root and object empties, the armature (its skin), the mesh, a bone shape and
    # the scene camera
    assert sum(report["objects"].values()) <= 6, report["objects"]
    for f in (shot.mid, shot.late):
        np.testing.assert_allclose(report["scene_bounds"][str(f)],
                                   gltf["scene_bounds"][str(f)], atol=TOL)


@pytest.mark.parametrize("kind", ["gltf", "usd"])
def test_piece_data_arrives_as_custom_properties(shot: Shot, gltf: dict, usd: dict,
                                                 kind: str) -> None:
    """Each piece object carries its index, mass and source object as custom properties
    of the same names from both formats: glTF node extras, USD ``userProperties:``
    (Blender drops the namespace), for scripts, drivers and a shader's Attribute node
    (type Object)."""
    report = {"gltf": gltf, "usd": usd}[kind]
    name = shot.cache.model.meta["objects"][0]["name"]
    got = report["properties"]
    assert len(got) == shot.pieces
    for p in range(shot.pieces):
        props = got[shot.name(p)]
        assert props["piece"] == p and props["object"] == name, props
        assert props["mass_kg"] == pytest.approx(float(shot.cache.piece_mass[p]), rel=1e-12)


def test_cameras_frame_alike(gltf: dict, usd: dict) -> None:
    """The scene camera frames the same from both formats at Blender's default render
    (1920 x 1080): 36 mm of film across behind the scene's lens. USD arrives with its
    filmback and a horizontal fit, glTF with its yfov and a vertical fit (the importer
    ignores aspectRatio), so the glTF's yfov is the 16:9 frame's (it was 24 mm of a 3:2
    frame: 19 % wider in Blender)."""
    (cam_usd,), (cam_gltf,) = usd["cameras"], gltf["cameras"]
    assert cam_usd["render"] == cam_gltf["render"] == [1920, 1080]
    assert cam_usd["sensor_fit"] == "HORIZONTAL" and cam_gltf["sensor_fit"] == "VERTICAL"
    width = 2 * np.arctan(18.0 / CAMERA[2])
    np.testing.assert_allclose(cam_usd["fov"], cam_gltf["fov"], rtol=1e-5)
    assert cam_usd["fov"][0] == pytest.approx(width, rel=1e-5)
