"""``blastvox preview`` and ``blastvox blast --plot``.

Two kinds of input, both small:

* a *known scene*: a 1 x 0.5 x 1 m brick box (32 voxels of 0.25 m, Z up) in a
  hand-made SimCache whose pieces never move, so the image is predictable; the
  silhouette is compared with the box's corners projected by a pinhole written
  here (36 mm film back fitted to the width), and pixel colours with the
  brick's material and damage colours;
* a real shot: a wooden wall blown up by ``simulate`` for 0.5 s (fire, dust,
  fireball and shock sphere on) for the animations, layers and determinism.

The CLI runs in-process through its console entry point (``blastvox.cli.entry.main``)
so that error handling, exit codes and the one-line messages are the real ones.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from blastvox.cache import SimCache
from blastvox.model import VoxelModel

BOX = (1.0, 0.5, 1.0)  # extents, m, centred on the origin
VOXEL = 0.25
SIZE = (320, 180)
FRAMES = 6


# --------------------------------------------------------------------------- helpers


def run_main(*args: str | Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``blastvox ARGS`` through the console entry point: (exit code, stdout, stderr)."""
    from blastvox.cli.entry import main

    argv = sys.argv
    sys.argv = ["blastvox", *map(str, args)]
    code = 0
    try:
        main()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    finally:
        sys.argv = argv
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(code: int, err: str, *needles: str) -> str:
    assert code == 1, f"expected exit 1, got {code}: {err}"
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("blastvox: error: "), lines[0]
    for needle in needles:
        assert needle in lines[0], f"{needle!r} not in {lines[0]!r}"
    return lines[0]


def read_png(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def to_linear(rgb: np.ndarray) -> np.ndarray:
    s = np.asarray(rgb, dtype=np.float64) / 255.0
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def project(points: np.ndarray, eye, target, focal_mm: float, size,
            up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Pixel (x, y) of world points for a pinhole kept level with ``up``: 36 mm film back
    across the width, image y down, pixel centres at +0.5. Written independently of
    blastvox.preview."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    rel = np.asarray(points, float) - eye
    x, y, z = rel @ right, rel @ up, rel @ forward
    f = focal_mm / 36.0 * size[0]
    return np.stack([size[0] / 2 + f * x / z, size[1] / 2 - f * y / z], axis=1)


LABEL = (slice(0, 20), slice(0, 130))  # where a frame's label may be (top-left)


def silhouette_box(image: np.ndarray, background: np.ndarray) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) inclusive pixel box of where ``image`` differs from ``background``,
    the frame label's corner left out."""
    mask = np.any(np.abs(image.astype(int) - background.astype(int)) > 8, axis=2)
    mask[LABEL] = False
    ys, xs = np.nonzero(mask)
    assert len(xs), "nothing drawn"
    return int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())


def static_cache(model: VoxelModel, voxel_piece: np.ndarray, frames: int,
                 end_frame: np.ndarray | None = None, camera: dict | None = None,
                 offsets: np.ndarray | None = None) -> SimCache:
    """A SimCache whose pieces stay at rest: no charges, particles or events."""
    a = model.arrays
    n = model.voxel_count
    pieces = int(voxel_piece.max()) + 1
    mass = np.bincount(voxel_piece, weights=a["voxel_mass"], minlength=pieces)
    pivot = np.stack([np.bincount(voxel_piece, weights=a["voxel_mass"] * a["voxel_centroid"][:, i],
                                  minlength=pieces) for i in range(3)], axis=1) / mass[:, None]
    i4, f8 = np.zeros(0, np.int32), np.zeros(0)
    orientation = np.zeros((frames, pieces, 4), np.float32)
    orientation[..., 0] = 1.0
    arrays = {
        "frame_time": np.arange(frames) / 24.0, "voxel_piece": voxel_piece.astype(np.int32),
        "piece_pivot": pivot, "piece_mass": mass,
        "piece_position": np.repeat(pivot[None], frames, axis=0).astype(np.float32),
        "piece_orientation": orientation,
        "piece_end_frame": (np.full(pieces, frames) if end_frame is None
                            else end_frame).astype(np.int32),
        "voxel_destroyed_frame": np.full(n, -1, np.int32),
        "damage_frame": i4, "damage_voxel": i4, "damage_value": np.zeros(0, np.uint8),
        "link_break_link": i4, "link_break_time": f8, "dust_voxel": i4, "dust_time": f8,
        "dust_mass": f8, "dust_position": np.zeros((0, 3)), "dust_velocity": np.zeros((0, 3)),
        "charge_position": np.zeros((0, 3)), "charge_tnt_kg": f8, "charge_time": f8,
        "shock_radius": np.zeros((frames, 0)), "shock_opacity": np.zeros((frames, 0)),
        "camera_offset": np.zeros((frames, 3)) if offsets is None else offsets,
        "voxel_ignite_frame": np.full(n, -1, np.int32),
        "particle_system": np.zeros(0, np.uint8), "particle_birth": f8,
        "particle_position": np.zeros((0, 3)), "particle_velocity": np.zeros((0, 3)),
        "particle_size": np.zeros(0, np.float32),
    }
    up = model.meta.get("up_axis", "Z")
    meta = {"fps": 24.0, "ground_height": model.meta.get("ground_height"), "up_axis": up,
            "gravity_vector": [0.0, -9.81, 0.0] if up == "Y" else [0.0, 0.0, -9.81]}
    if camera is not None:
        meta["camera"] = camera
    return SimCache(arrays=arrays, model=model, meta=meta)


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def box_model(tmp_path_factory: pytest.TempPathFactory) -> VoxelModel:
    import trimesh

    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("box")
    trimesh.creation.box(extents=BOX).export(tmp / "box.stl")
    return voxelize([ObjectRequest(mesh=tmp / "box.stl", voxel_size=(VOXEL,) * 3,
                                   material="brick")], VoxelizeSettings(up_axis="Z"))


@pytest.fixture(scope="module")
def known(tmp_path_factory: pytest.TempPathFactory, box_model: VoxelModel) -> Path:
    """The box as one piece at rest, with a scene camera that shakes +0.5 m in x at frame 3."""
    offsets = np.zeros((FRAMES, 3))
    offsets[3] = (0.5, 0.0, 0.0)
    cache = static_cache(box_model, np.zeros(box_model.voxel_count, np.int64), FRAMES,
                         camera={"position": [0.0, -6.0, 0.5], "look_at": [0.0, 0.0, 0.0],
                                 "focal_length_mm": 50.0}, offsets=offsets)
    path = tmp_path_factory.mktemp("known") / "known.npz"
    cache.save(path)
    return path


@pytest.fixture(scope="module")
def halves(tmp_path_factory: pytest.TempPathFactory, box_model: VoxelModel) -> Path:
    """The box cut at x = 0 into two pieces; the +x half is gone from frame 0, which
    exposes the -x half's inside face (a damage face) to a camera on the +x side."""
    piece = (box_model.arrays["voxel_centroid"][:, 0] > 0).astype(np.int64)
    cache = static_cache(box_model, piece, 2, end_frame=np.array([2, 0]))
    path = tmp_path_factory.mktemp("halves") / "halves.npz"
    cache.save(path)
    return path


@pytest.fixture(scope="module")
def shot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A real shot: a wooden wall (48 voxels) on the ground, 0.2 kg TNT 3 m in front,
    0.5 s: it cracks into pieces and catches fire; fireball, dust and shock sphere."""
    import trimesh

    from blastvox.simulate.engine import simulate
    from blastvox.simulate.settings import ChargeSpec, SimSettings
    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    tmp = tmp_path_factory.mktemp("shot")
    trimesh.creation.box(extents=(1.5, 0.5, 1.0)).export(tmp / "wall.stl")
    model = voxelize([ObjectRequest(mesh=tmp / "wall.stl", voxel_size=(0.25,) * 3,
                                    material="wood")], VoxelizeSettings(up_axis="Z"))
    cache = simulate(model, SimSettings(duration=0.5, fps=24.0,
                                        camera=((5.0, -6.0, 2.0), (0.0, -1.0, 0.0), 35.0),
                                        charges=(ChargeSpec((0.0, -3.0, 0.0), 0.2),)))
    cache.save(tmp / "sim.npz")
    return tmp / "sim.npz"


@pytest.fixture()
def out(tmp_path: Path) -> Path:
    return tmp_path


# --------------------------------------------------------------------------- known scene

EYE, TARGET, FOCAL = (0.0, -6.0, 0.5), (0.0, 0.0, 0.0), 50.0
CAMERA = "0,-6,0.5:0,0,0:50"


def box_corners() -> np.ndarray:
    half = np.array(BOX) / 2
    return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half


def render_known(path: Path, out: Path, capsys, *extra: str, name: str = "f.png") -> np.ndarray:
    target = out / name
    code, _, err = run_main("preview", path, "-o", target, "--size", f"{SIZE[0]}x{SIZE[1]}",
                            "--hide", "ground", "-q", *extra, capsys=capsys)
    assert code == 0, err
    return read_png(target)


def test_silhouette_matches_projected_box(known: Path, out: Path, capsys) -> None:
    image = render_known(known, out, capsys, "--frames", "0", "--camera", CAMERA)
    empty = render_known(known, out, capsys, "--frames", "0", "--camera", CAMERA, "--hide",
                         "ground,pieces", name="empty.png")
    px = project(box_corners(), EYE, TARGET, FOCAL, SIZE)
    x0, y0, x1, y1 = silhouette_box(image, empty)
    assert abs(x0 - px[:, 0].min()) <= 1.5 and abs(x1 + 1 - px[:, 0].max()) <= 1.5
    assert abs(y1 + 1 - px[:, 1].max()) <= 1.5
    # the frame label (top-left) may cover the top edge only if the box reached it
    assert abs(y0 - px[:, 1].min()) <= 1.5
    # background everywhere outside the silhouette's box, except the label
    outside = np.ones(image.shape[:2], bool)
    outside[y0:y1 + 1, x0:x1 + 1] = False
    outside[LABEL] = False
    assert np.array_equal(image[outside], empty[outside])
    # the background is the sky, not black or the box's colour
    corner = to_linear(image[-1, -1])
    assert corner[2] > corner[0]


def test_silhouette_y_up(out: Path, capsys) -> None:
    import trimesh

    from blastvox.voxelize.pipeline import ObjectRequest, VoxelizeSettings, voxelize

    # the same box in a Y-up model, seen from +Z (the glTF front) and above
    trimesh.creation.box(extents=BOX).export(out / "box.stl")
    model = voxelize([ObjectRequest(mesh=out / "box.stl", voxel_size=(VOXEL,) * 3,
                                    material="brick")], VoxelizeSettings(up_axis="Y"))
    static_cache(model, np.zeros(model.voxel_count, np.int64), 1).save(out / "y.npz")
    camera = "1,1.5,5:0,0,0:40"
    image = render_known(out / "y.npz", out, capsys, "--camera", camera)
    empty = render_known(out / "y.npz", out, capsys, "--camera", camera, "--hide",
                         "ground,pieces", name="empty.png")
    px = project(box_corners(), (1.0, 1.5, 5.0), (0.0, 0.0, 0.0), 40.0, SIZE,
                 up=(0.0, 1.0, 0.0))
    x0, y0, x1, y1 = silhouette_box(image, empty)
    assert abs(x0 - px[:, 0].min()) <= 1.5 and abs(x1 + 1 - px[:, 0].max()) <= 1.5
    assert abs(y0 - px[:, 1].min()) <= 1.5 and abs(y1 + 1 - px[:, 1].max()) <= 1.5


def test_object_colour_is_the_material_colour(known: Path, out: Path, capsys) -> None:
    from blastvox.materials import MaterialLibrary

    brick = MaterialLibrary.builtin()["brick"]
    image = render_known(known, out, capsys, "--frames", "0", "--camera", CAMERA)
    # the middle of the front face (y = -0.25), which faces the camera
    front = project(np.array([[0.0, -0.25, 0.0]]), EYE, TARGET, FOCAL, SIZE)[0]
    lin = to_linear(image[int(front[1]), int(front[0])])
    ratio = lin / np.asarray(brick.color)
    assert ratio.max() / ratio.min() < 1.08, (lin, brick.color)   # brick's hue, lit
    damage_ratio = lin / np.asarray(brick.damage_color)
    assert damage_ratio.max() / damage_ratio.min() > 1.2          # not the damage colour
    assert 0.2 < ratio.mean() < 1.3


def test_damage_faces_take_the_damage_colour(halves: Path, out: Path, capsys) -> None:
    from blastvox.materials import MaterialLibrary

    brick = MaterialLibrary.builtin()["brick"]
    eye, target = (6.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    image = render_known(halves, out, capsys, "--frames", "0", "--camera", "6,0,0:0,0,0:50")
    centre = project(np.array([[0.0, 0.0, 0.0]]), eye, target, 50.0, SIZE)[0]
    lin = to_linear(image[int(centre[1]), int(centre[0])])
    ratio = lin / np.asarray(brick.damage_color)
    assert ratio.max() / ratio.min() < 1.08, (lin, brick.damage_color)
    surface = lin / np.asarray(brick.color)
    assert surface.max() / surface.min() > 1.2
    # frame 1: the +x half is still gone; the -x half's face is the silhouette
    x0, y0, x1, y1 = silhouette_box(image, render_known(
        halves, out, capsys, "--frames", "0", "--camera", "6,0,0:0,0,0:50", "--hide",
        "ground,pieces", name="empty.png"))
    face = project(np.array([[0.0, sy, sz] for sy in (-0.25, 0.25) for sz in (-0.5, 0.5)]),
                   eye, target, 50.0, SIZE)
    assert abs(x0 - face[:, 0].min()) <= 1.5 and abs(x1 + 1 - face[:, 0].max()) <= 1.5


@pytest.mark.parametrize("camera", [CAMERA, "3,-6,2:0,0,0:50", "-4,-3,0.2:0,0,0:35"])
def test_pieces_at_rest_look_like_the_intact_box(box_model: VoxelModel, out: Path, capsys,
                                                  camera: str) -> None:
    # eight pieces (cut at x = 0, y = 0 and z = 0) at rest: their inside faces (damage
    # faces) touch and must stay hidden, even seen edge-on along the cuts
    c = box_model.arrays["voxel_centroid"]
    piece = (c[:, 0] > 0) * 4 + (c[:, 1] > 0) * 2 + (c[:, 2] > 0)
    static_cache(box_model, piece.astype(np.int64), 1).save(out / "cut.npz")
    static_cache(box_model, np.zeros(len(piece), np.int64), 1).save(out / "whole.npz")
    cut = render_known(out / "cut.npz", out, capsys, "--camera", camera, name="cut.png")
    whole = render_known(out / "whole.npz", out, capsys, "--camera", camera, name="whole.png")
    differ = np.any(np.abs(cut.astype(int) - whole.astype(int)) > 8, axis=2)
    assert differ.sum() <= 3, np.argwhere(differ)[:10]


def test_scene_camera_and_its_shake(known: Path, out: Path, capsys) -> None:
    from blastvox.preview.sheet import GAP_PX

    # frames 2 and 3 side by side; at frame 3 the camera is shaken 0.5 m along +x
    sheet = render_known(known, out, capsys, "--frames", "2:3")
    h, w = SIZE[1], SIZE[0]
    assert sheet.shape == (h + 2 * GAP_PX, 2 * w + 3 * GAP_PX, 3)
    still = sheet[GAP_PX:GAP_PX + h, GAP_PX:GAP_PX + w]
    shaken = sheet[GAP_PX:GAP_PX + h, 2 * GAP_PX + w:2 * GAP_PX + 2 * w]
    empty = render_known(known, out, capsys, "--frames", "2", "--hide", "ground,pieces",
                         name="empty.png")
    for image, eye in ((still, (0.0, -6.0, 0.5)), (shaken, (0.5, -6.0, 0.5))):
        # the shake moves the camera, not its aim: the target moves with it
        target = (eye[0], 0.0, 0.0)
        px = project(box_corners(), eye, target, 50.0, SIZE)
        x0, _, x1, _ = silhouette_box(image, empty)
        assert abs(x0 - px[:, 0].min()) <= 1.5 and abs(x1 + 1 - px[:, 0].max()) <= 1.5


def test_auto_camera_frames_the_object(known: Path, out: Path, capsys) -> None:
    image = render_known(known, out, capsys, "--frames", "0", "--camera", "auto")
    empty = render_known(known, out, capsys, "--frames", "0", "--camera", "auto", "--hide",
                         "ground,pieces", name="empty.png")
    x0, y0, x1, y1 = silhouette_box(image, empty)
    assert x0 > 0 and y0 > 0 and x1 < SIZE[0] - 1 and y1 < SIZE[1] - 1  # all in view
    assert (x1 - x0) > 0.3 * SIZE[0] or (y1 - y0) > 0.3 * SIZE[1]       # and large


def test_contact_sheet_labels_and_layout(known: Path, out: Path, capsys) -> None:
    from blastvox.preview.sheet import GAP_PX

    sheet = render_known(known, out, capsys)  # default: 6 frames in 3 columns
    assert sheet.shape == (2 * SIZE[1] + 3 * GAP_PX, 3 * SIZE[0] + 4 * GAP_PX, 3)
    # each tile carries a label: a black box with light text at its top-left
    for r in range(2):
        for c in range(3):
            y, x = GAP_PX + r * (SIZE[1] + GAP_PX), GAP_PX + c * (SIZE[0] + GAP_PX)
            tile = sheet[y:y + 14, x:x + 60]
            assert (tile.sum(axis=2) == 0).mean() > 0.4 and tile.max() > 200


# --------------------------------------------------------------------------- rasteriser


def test_triangle_culling_and_near_clipping() -> None:
    from blastvox.preview import raster

    color = np.zeros((40, 40, 3), np.float32)
    depth = np.zeros((40, 40), np.float32)

    def draw(tri) -> int:
        target = raster.Target(color, depth)
        raster.fill_background(target, np.zeros(3), np.zeros(3))
        camera = raster.Pinhole(np.eye(3), np.zeros(3), fpx=40.0, cx=20.0, cy=20.0, near=0.05)
        return raster.draw_triangles(target, camera, np.asarray([tri], float),
                                     np.ones((1, 3), np.float32))

    # view space: x right, y up, z forward; a triangle at z = 2 facing the camera is
    # counter-clockwise seen from the camera (the outward normal points at it)
    facing = [[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0]]
    assert draw(facing) == 1 and color[20, 20, 0] == 1.0
    assert abs(depth[20, 20] - 0.5) < 1e-6
    assert draw(facing[::-1]) == 0 and color.max() == 0.0          # seen from behind
    # a triangle reaching behind the camera is clipped, not dropped
    crossing = [[-1.0, -1.0, 2.0], [1.0, -1.0, -2.0], [0.0, 1.0, 2.0]]
    assert draw(crossing) == 1 and color.max() == 1.0


# --------------------------------------------------------------------------- real shot


def test_gif_has_the_requested_frames(shot: Path, out: Path, capsys) -> None:
    from PIL import Image

    code, _, err = run_main("preview", shot, "-o", out / "a.gif", "--frames", "0:11:2",
                            "--size", "160x90", "-q", capsys=capsys)
    assert code == 0, err
    with Image.open(out / "a.gif") as im:
        assert im.n_frames == 6
        assert im.size == (160, 90)
        assert im.info["duration"] == 80  # 24 fps / step 2 = 12 fps: 83 ms, in 1/100 s


def test_mp4_has_the_requested_frames(shot: Path, out: Path, capsys) -> None:
    import imageio_ffmpeg

    code, _, err = run_main("preview", shot, "-o", out / "a.mp4", "--frames", "3:9",
                            "--size", "160x90", "--fps", "10", "-q", capsys=capsys)
    assert code == 0, err
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(out / "a.mp4"))
    assert frames == 7 and abs(seconds - 0.7) < 0.05


def test_layers_are_drawn(shot: Path, out: Path, capsys) -> None:
    from blastvox.cache import SimCache
    from blastvox.preview.api import prepare
    from blastvox.preview.options import PreviewOptions

    cache = SimCache.load(shot)
    frame = 1  # the shock front is still visible (weak waves fade out)
    assert cache.shock_radius[frame, 0] > 0 and cache.shock_opacity[frame, 0] > 0
    assert (cache.particle_birth <= cache.frame_time[frame]).any()
    images = {}
    for hide in ((), ("particles",), ("shock",), ("ground",), ("pieces",)):
        options = PreviewOptions(size=(160, 90), hide=frozenset(hide))
        images[hide] = prepare(cache, [frame], options).render(frame)
    for hide in (("particles",), ("shock",), ("ground",), ("pieces",)):
        assert not np.array_equal(images[()], images[hide]), hide


def test_same_input_same_bytes(shot: Path, out: Path, capsys) -> None:
    for name in ("a.png", "b.png", "a.gif", "b.gif"):
        code, _, err = run_main("preview", shot, "-o", out / name, "--frames", "0:8:4",
                                "--size", "96x54", "-q", capsys=capsys)
        assert code == 0, err
    assert (out / "a.png").read_bytes() == (out / "b.png").read_bytes()
    assert (out / "a.gif").read_bytes() == (out / "b.gif").read_bytes()


def test_summary_line(shot: Path, out: Path, capsys) -> None:
    code, _, err = run_main("preview", shot, "-o", out / "s.png", "--frames", "2",
                            "--size", "64x36", capsys=capsys)
    assert code == 0
    assert "contact sheet of 1 frame," in err and "64x36 px" in err


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize("args, needles", [
    (("-o", "{out}/x.bmp"), ("x.bmp", ".bmp", ".png")),
    (("-o", "{out}/x"), ("(no suffix)",)),
    (("-o", "{out}/x.png", "--frames", "5:2"), ("--frames", "5:2")),
    (("-o", "{out}/x.png", "--frames", "a:b"), ("--frames", "'a'")),
    (("-o", "{out}/x.png", "--frames", "1:2:0"), ("--frames", "step")),
    (("-o", "{out}/x.png", "--frames", "0:999"), ("--frames", "999", "0..")),
    (("-o", "{out}/x.gif", "--frames", "999"), ("--frames", "999")),
    (("-o", "{out}/x.png", "--size", "960"), ("--size", "'960'")),
    (("-o", "{out}/x.png", "--size", "8x8"), ("--size", "width 8")),
    (("-o", "{out}/x.mp4", "--size", "161x90"), ("--size", "even")),
    (("-o", "{out}/x.png", "--camera", "1,2:3,4,5"), ("--camera", "1,2")),
    (("-o", "{out}/x.png", "--camera", "0,0,0:0,0,0"), ("--camera", "same")),
    (("-o", "{out}/x.png", "--hide", "trees"), ("--hide", "trees")),
    (("-o", "{out}/x.png", "--supersample", "9"), ("--supersample",)),
    (("-o", "{out}/x.gif", "--fps", "0"), ("--fps",)),
])
def test_bad_arguments(shot: Path, out: Path, capsys, args, needles) -> None:
    args = tuple(a.format(out=out) for a in args)
    code, _, err = run_main("preview", shot, *args, capsys=capsys)
    one_line_error(code, err, *needles)
    assert sorted(p.name for p in out.iterdir()) == []  # nothing written, no temporaries


def test_bad_inputs(known: Path, box_model: VoxelModel, out: Path, capsys) -> None:
    (out / "garbage.npz").write_bytes(b"not a zip file at all")
    box_model.save(out / "model.npz")
    cases = [("missing.npz", ("missing.npz", "no such")),
             ("garbage.npz", ("garbage.npz",)),
             ("model.npz", ("model.npz", "SimCache"))]
    for name, needles in cases:
        code, _, err = run_main("preview", out / name, "-o", out / "x.png", capsys=capsys)
        one_line_error(code, err, *needles)
    # the halves cache has no scene camera
    static = static_cache(box_model, np.zeros(box_model.voxel_count, np.int64), 2)
    static.save(out / "nocam.npz")
    code, _, err = run_main("preview", out / "nocam.npz", "-o", out / "x.png", "--camera",
                            "scene", capsys=capsys)
    one_line_error(code, err, "--camera scene", "nocam.npz")
    assert not (out / "x.png").exists()
    assert not [p for p in out.iterdir() if p.name.endswith(".partial")]


def test_a_failed_run_keeps_the_previous_output(shot: Path, out: Path, capsys) -> None:
    previous = b"a previous preview"
    (out / "x.png").write_bytes(previous)
    code, _, err = run_main("preview", shot, "-o", out / "x.png", "--frames", "0:999",
                            capsys=capsys)
    one_line_error(code, err, "--frames")
    assert (out / "x.png").read_bytes() == previous


def test_frame_selection() -> None:
    from blastvox.preview.options import select_frames

    assert select_frames(None, 121, ".png") == [0, 24, 48, 72, 96, 120]
    assert select_frames(None, 4, ".png") == [0, 1, 2, 3]
    assert select_frames(None, 5, ".gif") == [0, 1, 2, 3, 4]
    assert select_frames("::10", 25, ".gif") == [0, 10, 20]
    assert select_frames("5", 25, ".png") == [5]
    assert select_frames("3:", 6, ".gif") == [3, 4, 5]
    assert select_frames(":2", 6, ".gif") == [0, 1, 2]


# --------------------------------------------------------------------------- blast --plot


def test_blast_plot(out: Path, capsys) -> None:
    from PIL import Image

    code, stdout, err = run_main("blast", "--charge", "10", "--distance", "1,5,20", "--json",
                                 "--plot", out / "blast.png", capsys=capsys)
    assert code == 0, err
    assert stdout.lstrip().startswith("[")  # --json output untouched by the plot
    with Image.open(out / "blast.png") as im:
        im.load()
        assert im.format == "PNG" and im.size[0] >= 800 and im.size[1] >= 600
        assert len(im.convert("RGB").getcolors(1 << 20)) > 20  # curves, not a blank page
    code, _, err = run_main("blast", "--charge", "10", "--distance", "1", "--plot",
                            out / "blast.jpg", capsys=capsys)
    one_line_error(code, err, "--plot", "blast.jpg", ".png")
    assert not (out / "blast.jpg").exists()


def test_pressure_time_curve_has_its_negative_phase() -> None:
    from blastvox.blast import blast_parameters
    from blastvox.preview.plots import pressure_time

    p = blast_parameters(5.0, 10.0)
    t, pressure = pressure_time(5.0, 10.0)
    assert np.all(np.diff(t) >= 0)
    assert pressure[t < p.arrival_time_s].max() == 0.0
    assert abs(pressure.max() - float(p.peak_overpressure_pa)) < 1e-6 * pressure.max()
    assert pressure[-1] == 0.0   # the negative phase ends
    # the simulator's negative phase (Granström/Rigby): depth Pmin and impulse i-
    from blastvox.blast import negative_parameters, tnt_equivalent

    z = 5.0 / np.cbrt(10.0 * tnt_equivalent("TNT"))
    p_min, i_neg, _ = (float(v) for v in negative_parameters(z, p.impulse_pa_s))
    assert abs(pressure.min() + p_min) < 1e-3 * p_min
    after = t > p.arrival_time_s + p.positive_duration_s
    area = -np.trapezoid(pressure[after], t[after])
    assert abs(area - i_neg) < 1e-3 * i_neg, (area, i_neg)
