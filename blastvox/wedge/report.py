"""A wedge's outputs: the summary table (CSV and JSON) and a contact sheet of its shots.

``summary.csv`` has one row per shot in grid order: the shot's index and key, one
column per varied key, its status and error, what it made (pieces, moving
pieces, broken links, dust voxels, mass and moved mass in kg, moved fraction) and
its stage times (s). ``summary.json`` holds the same records with the wedge's
axes. ``sheet.png`` stacks each shot's preview strip under a caption naming its
values, so the variants compare side by side.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from blastvox.io.atomic import atomic_path
from blastvox.preview.sheet import GAP_PX, LABEL_TEXT, SHEET_BACKGROUND
from blastvox.wedge.plan import Axis
from blastvox.wedge.values import format_value

STAT_COLUMNS = ("pieces", "moving_pieces", "broken_links", "dust_voxels", "mass_kg",
                "moved_mass_kg", "moved_fraction", "single_voxel_fraction",
                "chunky_mass_fraction")
TIME_COLUMNS = ("voxelize", "simulate", "export", "preview")
CAPTION_PX = 22
FAILED_TEXT = (255, 120, 110)
#: Shots the contact sheet shows (the first ones, in grid order): 100 strips of 180 px.
MAX_SHEET_SHOTS = 100


def summary_rows(axes: list[Axis], results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One flat row per result (the CSV's columns, in order)."""
    rows = []
    for r in results:
        row: dict[str, Any] = {"shot": r["shot"], "key": r["key"]}
        row.update({a.key: format_value(r["params"][a.key]) for a in axes})
        row.update(status=r["status"], error=r.get("error") or "")
        stats = r.get("stats") or {}
        row.update({c: stats.get(c, "") for c in STAT_COLUMNS})
        seconds = r.get("seconds") or {}
        row.update({f"{c}_s": seconds.get(c, "") for c in TIME_COLUMNS})
        row["total_s"] = r.get("total_s", "")
        rows.append(row)
    return rows


def write_summary(out: Path, axes: list[Axis], grid_size: int,
                  results: list[dict[str, Any]]) -> tuple[Path, Path]:
    """Write ``summary.csv`` and ``summary.json`` in ``out`` (atomically)."""
    rows = summary_rows(axes, results)
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    csv_path, json_path = out / "summary.csv", out / "summary.json"
    with atomic_path(csv_path) as tmp:
        tmp.write_text(text.getvalue())
    document = {"axes": [{"key": a.key, "values": a.values} for a in axes],
                "grid_size": grid_size, "shots": results}
    with atomic_path(json_path) as tmp:
        tmp.write_text(json.dumps(document, indent=1) + "\n")
    return csv_path, json_path


def write_sheet(path: Path, results: list[dict[str, Any]], labels: list[str]) -> Path | None:
    """Stack the shots' preview strips (``<directory>/preview.png``) under their
    ``labels``, the first :data:`MAX_SHEET_SHOTS`; a failed shot is a caption with its
    error. None if no shot has a strip."""
    from PIL import Image, ImageDraw, ImageFont

    results, labels = results[:MAX_SHEET_SHOTS], labels[:MAX_SHEET_SHOTS]
    strips = [_strip(r) for r in results]
    width = max((s.shape[1] for s in strips if s is not None), default=0)
    if width == 0:
        return None
    font = ImageFont.load_default(size=13)
    rows = []
    for result, strip, label in zip(results, strips, labels, strict=True):
        failed = strip is None
        text = f"{label}  FAILED: {result.get('error') or 'no preview'}" if failed else label
        caption = Image.new("RGB", (width, CAPTION_PX), SHEET_BACKGROUND)
        ImageDraw.Draw(caption).text((GAP_PX, 4), text[:200], font=font,
                                     fill=FAILED_TEXT if failed else LABEL_TEXT)
        rows.append(np.asarray(caption))
        if strip is not None:
            padded = np.empty((strip.shape[0], width, 3), dtype=np.uint8)
            padded[:] = SHEET_BACKGROUND
            padded[:, :strip.shape[1]] = strip
            rows.append(padded)
    sheet = np.concatenate(rows, axis=0)
    with atomic_path(path) as tmp:
        Image.fromarray(sheet).save(tmp, format="PNG")
    return path


def _strip(result: dict[str, Any]) -> np.ndarray | None:
    from PIL import Image

    if result["status"] == "failed":
        return None
    try:
        with Image.open(Path(result["directory"]) / "preview.png") as image:
            return np.asarray(image.convert("RGB"))
    except (OSError, ValueError):
        return None
