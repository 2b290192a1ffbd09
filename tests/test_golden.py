"""The house example bakes to the committed golden files (what a shot CI checks)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_house_shot_matches_its_goldens(tmp_path: Path) -> None:
    shot = tmp_path / "house"
    shutil.copytree(ROOT / "examples" / "house", shot)
    scene = (shot / "scene.toml").read_text().replace("../../out/house/", "out/")
    (shot / "scene.toml").write_text(scene)
    blastvox = [sys.executable, "-m", "blastvox"]
    run = subprocess.run([*blastvox, "run", "scene.toml", "-q"], cwd=shot, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    for name in ("house.usda", "house.glb"):
        baked = shot / "out" / f"shot{Path(name).suffix}"
        diff = subprocess.run([*blastvox, "diff", str(baked), str(ROOT / "examples" / "golden" /
                                                                  name), "--atol", "1e-4"],
                              capture_output=True, text=True, timeout=600)
        assert diff.returncode == 0, diff.stdout + diff.stderr
