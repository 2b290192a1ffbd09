"""OpenUSD's crate cost per attribute spec and per time sample (markdown lines).

    python benchmarks/usd_crate_cost.py

The bound under the .usdc rows of ``benchmarks/export_scale.py``: synthetic layers of
18,000 Xform prims (the wall's pieces) built through the Sdf API, each with 1 or 10
attributes and 0 or 45 time samples of a double3 or float3 each (45: about the keys a
flying piece of the wall keeps under linear interpolation), written with
``SdfLayer.Export`` to a .usdc; "write s" is that call alone, best of 3. The differences give
the crate writer's cost per attribute spec and per sample, in seconds and bytes.
"""

from __future__ import annotations

import itertools
import os
import sys
import tempfile
import time
from collections import deque
from pathlib import Path

import numpy as np
from _machine import machine  # benchmarks/ is on sys.path
from pxr import Sdf, Vt

PRIMS = 18_000


def layer(samples: int, attributes: int, double: bool) -> Sdf.Layer:
    """PRIMS Xforms with ``attributes`` attributes of ``samples`` random samples each."""
    out = Sdf.Layer.CreateAnonymous("cost.usda")
    rng = np.random.default_rng(0)
    kind = Sdf.ValueTypeNames.Double3 if double else Sdf.ValueTypeNames.Float3
    with Sdf.ChangeBlock():
        root = Sdf.PrimSpec(out.pseudoRoot, "Shot", Sdf.SpecifierDef, "Xform")
        paths = []
        for p in range(PRIMS):
            prim = Sdf.PrimSpec(root, f"piece_{p:05d}", Sdf.SpecifierDef, "Xform")
            paths += [Sdf.AttributeSpec(prim, f"a{a}", kind).path for a in range(attributes)]
        if samples:
            values = rng.normal(size=(len(paths) * samples, 3))
            array = (Vt.Vec3dArray.FromNumpy(values) if double
                     else Vt.Vec3fArray.FromNumpy(values.astype(np.float32)))
            rows = itertools.chain.from_iterable(itertools.repeat(p, samples) for p in paths)
            times = (float(t) for _ in paths for t in range(samples))
            deque(itertools.starmap(out.SetTimeSample, zip(rows, times, array, strict=True)),
                  maxlen=0)
    return out


def main() -> int:
    print(machine(("usd-core",)))
    print("\n| prims | attributes each | samples each | type | write s | MB |")
    print("|--:|--:|--:|---|--:|--:|")
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "cost.usdc"
        for samples, attributes, double in ((0, 1, True), (0, 10, True), (45, 1, True),
                                            (45, 1, False)):
            built = layer(samples, attributes, double)
            seconds = float("inf")
            for _ in range(3):  # best of 3: a shared machine disturbs single runs
                t0 = time.perf_counter()
                built.Export(str(path))
                seconds = min(seconds, time.perf_counter() - t0)
            mb = path.stat().st_size / 1e6
            rows[(samples, attributes, double)] = seconds, mb
            print(f"| {PRIMS:,} | {attributes} | {samples} | "
                  f"{'double3' if double else 'float3'} | {seconds:.2f} | {mb:.1f} |")
    base, ten = rows[(0, 1, True)], rows[(0, 10, True)]
    spec = (ten[0] - base[0]) / (9 * PRIMS)
    print(f"\n* per attribute spec: {spec * 1e6:.0f} µs")
    for double in (True, False):
        s, mb = rows[(45, 1, double)]
        n = 45 * PRIMS
        print(f"* per {'double3' if double else 'float3'} sample: "
              f"{(s - base[0]) / n * 1e6:.1f} µs, {(mb - base[1]) * 1e6 / n:.0f} bytes")
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"\nLoad average at the end: {load}.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
