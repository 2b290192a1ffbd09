"""Contact cost against the number of boundary voxels of moving bodies.

    python benchmarks/contacts.py [--quick]

A cloud of n^3 separate 0.2 m pieces (one voxel each, so every voxel is a
boundary voxel of a moving body; see ``benchmarks/_debris.py``) 0.4 m apart is
dropped from 1 m onto the ground with a small random spin, and falls into a
pile: bodies collide with the ground and each other. The first table gives
wall ms per step with collisions on and off (ground contact on in both), and
per boundary voxel, so near-linear growth shows as a near-constant last column.
The second is frames per second against boundary voxels laid out like Mazarak
1999 Table 5-1, the same table (same code) as ``benchmarks/performance.py`` (b).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from _debris import cloud, ms_per_step, print_table_5_1, table_5_1
from _machine import machine  # benchmarks/ is on sys.path when run as a script


def main() -> None:
    """Print both tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1k and 10k only")
    args = parser.parse_args()
    sizes = (10, 22) if args.quick else (10, 22, 46)
    print(machine() + "\n")
    print("| boundary voxels (moving) | ms/step, collisions on | ms/step, off | "
          "µs per voxel-step (on) |")
    print("|--:|--:|--:|--:|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            model, start = cloud(n, Path(tmp))
            steps = max(20, 2000 // n)
            on = ms_per_step(model, start, True, steps)
            off = ms_per_step(model, start, False, steps)
            print(f"| {model.voxel_count:,} | {on:.2f} | {off:.2f} | "
                  f"{1e3 * on / model.voxel_count:.2f} |", flush=True)
        print("\nFrames per second (24 fps shot, 10 steps a frame) beside Mazarak 1999 "
              "Table 5-1:\n")
        print_table_5_1(table_5_1(Path(tmp)))


if __name__ == "__main__":
    main()
