"""Render one shot in Blender from each export format at a few frames: a contact sheet.

Run by the project's python (it calls ``blastvox export`` and, in ``.venv-blender``,
``render_check.py``)::

    python tools/blender/format_sheet.py SIM OUT.png FRAME [FRAME ...]
        [--formats usdc,glb,usdz] [--size 480x270] [--samples 16] [--fire]
        [--ground Z] [--volume-voxel 0.2] [--work DIR] [--cell 400x225] [--colors 192] [--reuse]

SIM (a SimCache) is exported to ``DIR/shot.<format>`` for each format (unless that
file is newer than SIM), each file is
imported into an empty Blender scene with the importer's defaults and rendered with
Cycles (denoised) at each FRAME from the file's own camera (the scene's), with
render_check.py's sun, sky and ground (``--ground``, default 0), opaque; the sheet
has a row per format and a column per frame, each
cell labelled, saved as a PNG of ``--colors`` colours (small enough for docs;
``--reuse`` rebuilds it from the renders already in DIR). ``--fire`` gives
the USD volumes that carry temperature (fire, fireball) the flame material an artist
adds and hides the exports' own glow (render_check.py ``--fire``); a plain import
renders the volumes as grey smoke, fire and the fireball glowing through their
``<system>_glow`` shells. What each format carries: .usdc the particles as volumes
(``DIR/shot_volumes/``) and the glow, .usdz as instanced soft spheres and the glow,
.glb none (the pieces and the camera only). Prints the render
reports (coverage, luminance) as one JSON object.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[2]
BLENDER_PYTHON = ROOT / ".venv-blender" / "bin" / "python"
RENDER_CHECK = Path(__file__).resolve().parent / "render_check.py"


def _size(text: str) -> tuple[int, int]:
    w, h = (int(v) for v in text.lower().split("x"))
    return w, h


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sim", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("frames", type=int, nargs="+")
    parser.add_argument("--formats", default="usdc,glb,usdz")
    parser.add_argument("--size", type=_size, default=(480, 270))
    parser.add_argument("--cell", type=_size, default=None,
                        help="each cell's size in the sheet (default: --size)")
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--fire", action="store_true")
    parser.add_argument("--ground", type=float, default=0.0,
                        help="height of render_check.py's ground (Blender's Z, m)")
    parser.add_argument("--volume-voxel", type=float, default=0.2)
    parser.add_argument("--work", type=Path, default=None)
    parser.add_argument("--colors", type=int, default=192, help="the PNG's palette")
    parser.add_argument("--reuse", action="store_true",
                        help="keep the renders already in --work (rebuild the sheet only)")
    parser.add_argument("--blender-python", type=Path, default=BLENDER_PYTHON)
    args = parser.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="format_sheet_"))
    work.mkdir(parents=True, exist_ok=True)
    formats = [f.strip().lstrip(".") for f in args.formats.split(",") if f.strip()]
    cell = args.cell or args.size
    reports = {}
    rows = []
    for fmt in formats:
        shot = work / f"shot.{fmt}"
        if not shot.exists() or shot.stat().st_mtime < args.sim.stat().st_mtime:
            subprocess.run([sys.executable, "-m", "blastvox", "export", str(args.sim), "-o",
                            str(shot), "--volume-voxel", str(args.volume_voxel), "-q"],
                           check=True)
        options = ["--size", "x".join(map(str, args.size)), "--samples", str(args.samples),
                   "--opaque", "--denoise", "--ground", str(args.ground),
                   *(["--fire"] if args.fire else [])]
        saved = work / f"{fmt}.json"
        report = json.loads(saved.read_text()) if args.reuse and saved.exists() else None
        if report is None or any(str(f) not in report["frames"] for f in args.frames):
            done = subprocess.run([str(args.blender_python), str(RENDER_CHECK), str(shot),
                                   str(work / fmt), *map(str, args.frames), *options],
                                  capture_output=True, text=True, check=False)
            if done.returncode != 0:
                sys.stderr.write(done.stderr[-3000:])
                return done.returncode
            report = json.loads(done.stdout)
            saved.write_text(json.dumps(report))
        reports[fmt] = report
        rows.append([Image.open(report["frames"][str(f)]["png"]).convert("RGB").resize(
            cell, Image.LANCZOS) for f in args.frames])
    sheet = Image.new("RGB", (cell[0] * len(args.frames), cell[1] * len(formats)))
    draw = ImageDraw.Draw(sheet)
    for r, (fmt, row) in enumerate(zip(formats, rows, strict=True)):
        camera = "file camera" if reports[fmt]["camera"]["from_file"] else "added camera"
        for c, (frame, image) in enumerate(zip(args.frames, row, strict=True)):
            x, y = c * cell[0], r * cell[1]
            sheet.paste(image, (x, y))
            label = f".{fmt}  frame {frame}  ({camera})"
            box = draw.textbbox((x + 4, y + 3), label)
            draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 2), fill=(20, 20, 20))
            draw.text((x + 4, y + 3), label, fill=(235, 235, 235))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.quantize(args.colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(
        args.out, optimize=True)
    print(json.dumps({fmt: {"camera": rep["camera"], "frames": {
        f: {k: v for k, v in got.items() if k != "png"} for f, got in rep["frames"].items()}}
        for fmt, rep in reports.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
