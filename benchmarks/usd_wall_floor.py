"""Where a 20,000-piece .usdc's export time and bytes go (markdown lines).

    python benchmarks/usd_wall_floor.py                     # builds the wall (about a minute)
    python benchmarks/usd_wall_floor.py --cache wall.npz    # a saved cache instead

The floor under ``benchmarks/export_scale.py``'s wall.usdc (issue 35: < 5 s and < 25 MB
for 20,000 moving pieces). The export's own layer (``blastvox.export.usd._Writer``,
the default options, particles as volumes so none are in the layer) is built once and
written with ``SdfLayer.Export`` as it is, then again after taking parts out of it:

* "no time samples": every time-sampled attribute keeps its spec but loses its samples;
* "no meshes": the pieces' Mesh prims (and their subsets) removed, samples kept;
* "Xforms only": both removed: what the per-piece Xform specs alone cost.

"write s" is the ``Export`` call alone (best of 2); specs and samples are counted in the
layer written. The differences say what each part costs the crate writer.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from _machine import machine  # benchmarks/ is on sys.path
from pxr import Sdf


def _counts(layer: Sdf.Layer) -> tuple[int, int, int]:
    """(prim specs, property specs, time samples) of ``layer``."""
    prims = props = samples = 0

    def visit(path: Sdf.Path) -> None:
        nonlocal prims, props, samples
        if path.IsPrimPath():
            prims += 1
        elif path.IsPropertyPath():
            props += 1
            samples += layer.GetNumTimeSamplesForPath(path)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return prims, props, samples


def _strip_samples(layer: Sdf.Layer) -> None:
    paths: list[Sdf.Path] = []
    layer.Traverse(Sdf.Path.absoluteRootPath,
                   lambda p: paths.append(p) if p.IsPropertyPath()
                   and layer.GetNumTimeSamplesForPath(p) else None)
    with Sdf.ChangeBlock():
        for path in paths:
            layer.GetPropertyAtPath(path).ClearInfo("timeSamples")


def _strip_meshes(layer: Sdf.Layer) -> None:
    meshes: list[Sdf.PrimSpec] = []
    layer.Traverse(Sdf.Path.absoluteRootPath,
                   lambda p: meshes.append(layer.GetPrimAtPath(p)) if p.IsPrimPath()
                   and layer.GetPrimAtPath(p).typeName == "Mesh" else None)
    with Sdf.ChangeBlock():
        for mesh in meshes:
            del mesh.nameParent.nameChildren[mesh.name]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, default=None,
                        help="a saved cache (default: export_scale.py's wall, simulated)")
    args = parser.parse_args(argv)
    print(machine(("blastvox", "usd-core")))
    from blastvox.cache import SimCache
    from blastvox.export.options import ExportOptions
    from blastvox.export.usd import _Writer

    if args.cache is not None:
        cache = SimCache.load(args.cache)
    else:
        from export_scale import wall_cache  # benchmarks/export_scale.py
        cache = wall_cache()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "floor.usdc"
        t0 = time.perf_counter()
        writer = _Writer(cache, ExportOptions(), "textures", Path(tmp) / "volumes")
        t1 = time.perf_counter()
        full = writer.build()
        t2 = time.perf_counter()
        print(f"\n{cache.piece_count:,} pieces, {cache.frame_count} frames: prepare "
              f"{t1 - t0:.2f} s, Sdf build {t2 - t1:.2f} s\n")
        print("| layer | prims | properties | time samples | write s | MB |")
        print("|---|--:|--:|--:|--:|--:|")
        variants = (("as exported", ()), ("no time samples", (_strip_samples,)),
                    ("no meshes", (_strip_meshes,)),
                    ("Xforms only", (_strip_samples, _strip_meshes)))
        for name, strips in variants:
            layer = Sdf.Layer.CreateAnonymous("floor.usda")
            layer.TransferContent(full)
            for strip in strips:
                strip(layer)
            seconds = float("inf")
            for _ in range(2):
                t0 = time.perf_counter()
                layer.Export(str(out))
                seconds = min(seconds, time.perf_counter() - t0)
            prims, props, samples = _counts(layer)
            print(f"| {name} | {prims:,} | {props:,} | {samples:,} | {seconds:.2f} | "
                  f"{out.stat().st_size / 1e6:.1f} |", flush=True)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\nLoad average at the end: {load}.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
