"""A small OpenVDB writer: sparse float grids (fog volumes) from flat numpy arrays.

PyPI has no maintained OpenVDB binding, so blastvox writes the file format itself:
the subset it needs, read back by the real library in the tests (``bpy``'s
``openvdb`` module, OpenVDB 12; ``tests/test_export_volumes.py``). The layout is
OpenVDB's file version 224 (``openvdb/io/Archive.cc``, ``File.cc``, ``GridDescriptor.cc``,
``tree/RootNode.h``, ``InternalNode.h``, ``LeafNode.h``, ``io/Compression.h``), all
little-endian:

* header: magic ``0x56444220`` (int64), file version 224 (uint32), library version
  12.0 (2 x uint32), ``1`` (char: the file has grid offsets), a 36-character UUID
  (here a hash of the grids, so the same grids give the same bytes), the file's
  metadata (an empty map: int32 0) and the grid count (int32);
* per grid: its descriptor (name, type ``Tree_float_5_4_3``, instance parent "",
  strings as uint32 length + bytes), the stream offsets of the grid, its buffers and
  its end (3 x int64), the compression flags (uint32: ``COMPRESS_ACTIVE_MASK`` 0x2,
  with ``COMPRESS_ZIP`` 0x1 if zipped), the grid's metadata (count, then name, type
  name, byte size and value each, names sorted), the transform
  (``UniformScaleTranslateMap``: translation, scale, voxel size, 1/scale, 1/scale^2,
  1/(2 scale), 3 doubles each), the topology and the leaf buffers;
* topology: buffer count 1 (int32), the root (background 0.0 (float32), tile count 0,
  child count) and its children in coordinate order, each its origin (3 x int32) and
  an InternalNode of 32^3 (child mask, value mask, the mask-compressed tile values:
  a byte 0, no values), whose children are InternalNodes of 16^3 (likewise), whose
  children are LeafNodes of 8^3 (their value mask, 64 bytes); child order is the
  node's table offset, x major (``(x << 2 log2dim) + (y << log2dim) + z``);
* buffers: per leaf in the same depth-first order, its value mask, a byte 0 (every
  inactive value is the background 0) and the active values only, float32, raw or
  as a zip chunk (int64 byte count, then zlib's ``compress2`` stream at the default
  level; a negative count and the raw bytes where zlib would not save any).

Only active voxels are stored (a fog volume is 0 outside them); a grid class of
``fog volume`` tells renderers to read the values as density.
"""

from __future__ import annotations

import hashlib
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

MAGIC = 0x56444220
FILE_VERSION = 224
LIBRARY_VERSION = (12, 0)
COMPRESS_ZIP = 0x1
COMPRESS_ACTIVE_MASK = 0x2
#: log2 of the node sizes: leaf 8^3, internal 16^3 and 32^3 (Tree_float_5_4_3)
LEAF_LOG2, INTERNAL1_LOG2, INTERNAL2_LOG2 = 3, 4, 5
_LEAF_TOTAL = LEAF_LOG2                                    # 3: a leaf spans 8 voxels
_INT1_TOTAL = LEAF_LOG2 + INTERNAL1_LOG2                   # 7: 128 voxels
_INT2_TOTAL = LEAF_LOG2 + INTERNAL1_LOG2 + INTERNAL2_LOG2  # 12: 4096 voxels


@dataclass(frozen=True)
class FloatGrid:
    """A sparse float grid: ``ijk`` (N, 3) int32 voxel indices and ``values`` (N,)
    float32; a voxel is active (stored) where its value is > 0, every other voxel is
    the background 0. Voxel (i, j, k)'s centre is at ``voxel_size * (i, j, k) +
    translation`` in world space (metres): ``voxel_size`` (m) is the edge of the
    cubic voxels, ``translation`` (3,) m. ``grid_class``: "fog volume" (density-like
    values, 0 outside) or "unknown"."""

    name: str
    ijk: np.ndarray
    values: np.ndarray
    voxel_size: float
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    grid_class: str = "fog volume"
    metadata: dict[str, str] = field(default_factory=dict)


def _string(text: str) -> bytes:
    data = text.encode("utf-8")
    return struct.pack("<I", len(data)) + data


def _meta(name: str, type_name: str, value: bytes) -> bytes:
    return _string(name) + _string(type_name) + struct.pack("<I", len(value)) + value


def _masks(offsets: np.ndarray, groups: np.ndarray, count: int, bits: int) -> np.ndarray:
    """(count, bits / 64) uint64 bit masks: bit ``offsets[n]`` set in mask ``groups[n]``."""
    words = np.zeros((count, bits // 64), dtype=np.uint64)
    np.bitwise_or.at(words, (groups, offsets >> 6),
                     np.left_shift(np.uint64(1), (offsets & 63).astype(np.uint64)))
    return words


def _packed_runs(*keys: np.ndarray) -> np.ndarray:
    """Start index of each run of equal (keys[0][i], keys[1][i], ...) (sorted), and the
    end."""
    n = len(keys[0])
    if not n:
        return np.zeros(1, dtype=np.int64)
    new = np.zeros(n, dtype=bool)
    new[0] = True
    for key in keys:
        new[1:] |= key[1:] != key[:-1]
    return np.append(np.flatnonzero(new), n)


def _zip_chunk(data: bytes) -> bytes:
    """OpenVDB's zipToStream: int64 size + zlib stream, or -size + raw bytes."""
    packed = zlib.compress(data, -1)
    if len(packed) < len(data):
        return struct.pack("<q", len(packed)) + packed
    return struct.pack("<q", -len(data)) + data


def _grid_tree(grid: FloatGrid, zipped: bool | None
               ) -> tuple[bytes, bytes, np.ndarray, bool]:
    """(topology bytes, buffer bytes, active ijk (M, 3), zipped) of ``grid``; ``zipped``
    None zips where the leaves hold ZIP_MIN_VALUES_PER_LEAF values on average."""
    ijk = np.asarray(grid.ijk, dtype=np.int64).reshape(-1, 3)
    values = np.asarray(grid.values, dtype=np.float32).reshape(-1)
    if len(ijk) != len(values):
        raise ValueError(f"grid {grid.name!r}: {len(ijk)} voxels but {len(values)} values")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"grid {grid.name!r}: values must be finite")
    keep = values > 0
    ijk, values = ijk[keep], values[keep]
    if len(ijk) and (ijk.min() < -(2**31) or ijk.max() >= 2**31):
        raise ValueError(f"grid {grid.name!r}: voxel indices outside int32")
    # depth-first order: root children by origin, then each node's table offset: the
    # 12 keys (root origin x, y, z; the 32^3 node's offset x, y, z; the 16^3 node's;
    # the leaf's) packed into two uint64, whose order is theirs (root origins offset
    # by 2^19 to 20 bits each; 5 + 5 + 5, 4 + 4 + 4 and 3 + 3 + 3 bits below)
    u = (ijk >> _INT2_TOTAL) + (1 << 19)
    hi = (u[:, 0] << 40) | (u[:, 1] << 20) | u[:, 2]
    lo = np.zeros(len(ijk), dtype=np.int64)
    for shift, bits, mask in ((_INT1_TOTAL, 5, 31), (_LEAF_TOTAL, 4, 15), (0, 3, 7)):
        part = (ijk >> shift) & mask
        lo = (lo << (3 * bits)) | (part[:, 0] << (2 * bits)) | (part[:, 1] << bits) | part[:, 2]
    order = np.lexsort((lo, hi))
    ijk, values, hi, lo = ijk[order], values[order], hi[order], lo[order]
    if len(ijk) > 1 and np.any((hi[1:] == hi[:-1]) & (lo[1:] == lo[:-1])):
        raise ValueError(f"grid {grid.name!r}: a voxel is listed twice")
    leaf_runs = _packed_runs(hi, lo >> 9)
    leaf_ijk = ijk[leaf_runs[:-1]]
    int1_runs = _packed_runs(hi[leaf_runs[:-1]], lo[leaf_runs[:-1]] >> 21)
    int1_ijk = leaf_ijk[int1_runs[:-1]]
    int2_runs = _packed_runs(hi[leaf_runs[:-1]][int1_runs[:-1]])
    int2_keys = int1_ijk[int2_runs[:-1]] >> _INT2_TOTAL
    n_leaf = len(leaf_ijk)
    if zipped is None:
        zipped = len(values) >= ZIP_MIN_VALUES_PER_LEAF * max(n_leaf, 1)
    voxel_leaf = np.repeat(np.arange(n_leaf), np.diff(leaf_runs))
    leaf_masks = _masks(lo & 511, voxel_leaf, n_leaf, 512)  # the leaf offset's 9 bits
    leaf_int1 = np.repeat(np.arange(len(int1_ijk)), np.diff(int1_runs))
    lk = (leaf_ijk >> _LEAF_TOTAL) & 15
    int1_masks = _masks((lk[:, 0] << 8) | (lk[:, 1] << 4) | lk[:, 2], leaf_int1,
                        len(int1_ijk), 4096)
    int1_int2 = np.repeat(np.arange(len(int2_keys)), np.diff(int2_runs))
    ik = (int1_ijk >> _INT1_TOTAL) & 31
    int2_masks = _masks((ik[:, 0] << 10) | (ik[:, 1] << 5) | ik[:, 2], int1_int2,
                        len(int2_keys), 32768)
    no_values = b"\x00" + (struct.pack("<q", 0) if zipped else b"")  # no tile values
    topo = [struct.pack("<i", 1), struct.pack("<fII", 0.0, 0, len(int2_keys))]
    leaf_bytes = leaf_masks.astype("<u8").tobytes()
    for a in range(len(int2_keys)):
        origin = (int2_keys[a] << _INT2_TOTAL).astype("<i4")
        topo += [origin.tobytes(), int2_masks[a].astype("<u8").tobytes(), bytes(4096),
                 no_values]
        for b in range(int2_runs[a], int2_runs[a + 1]):
            topo += [int1_masks[b].astype("<u8").tobytes(), bytes(512), no_values,
                     leaf_bytes[int1_runs[b] * 64:int1_runs[b + 1] * 64]]
    raw = values.astype("<f4")
    if not zipped:
        return b"".join(topo), _raw_buffers(leaf_masks, raw, leaf_runs), ijk, False
    buffers = []
    for n in range(n_leaf):
        data = raw[leaf_runs[n]:leaf_runs[n + 1]].tobytes()
        buffers += [leaf_bytes[n * 64:(n + 1) * 64], b"\x00", _zip_chunk(data)]
    return b"".join(topo), b"".join(buffers), ijk, True


def _raw_buffers(leaf_masks: np.ndarray, raw: np.ndarray, leaf_runs: np.ndarray) -> bytes:
    """The unzipped leaf buffers at once: per leaf its mask (64 bytes), a 0 byte and
    its active values (float32), in leaf order."""
    n_leaf = len(leaf_masks)
    counts = np.diff(leaf_runs)
    start = 65 * np.arange(n_leaf) + 4 * leaf_runs[:-1]  # each leaf's record
    out = np.zeros(65 * n_leaf + 4 * len(raw), dtype=np.uint8)
    out[(start[:, None] + np.arange(64)).ravel()] = leaf_masks.astype("<u8").view(np.uint8).ravel()
    first = np.repeat(start + 65 - 4 * leaf_runs[:-1], counts) + 4 * np.arange(len(raw))
    out[(first[:, None] + np.arange(4)).ravel()] = raw.view(np.uint8)
    return out.tobytes()


def _grid_metadata(grid: FloatGrid, active: np.ndarray, compression: str) -> bytes:
    items = {"class": ("string", grid.grid_class.encode()),
             "file_compression": ("string", compression.encode()),
             "file_voxel_count": ("int64", struct.pack("<q", len(active))),
             "name": ("string", grid.name.encode())}
    if len(active):
        items["file_bbox_min"] = ("vec3i", active.min(axis=0).astype("<i4").tobytes())
        items["file_bbox_max"] = ("vec3i", active.max(axis=0).astype("<i4").tobytes())
    for key, value in grid.metadata.items():
        items[key] = ("string", str(value).encode())
    body = b"".join(_meta(k, *items[k]) for k in sorted(items))
    return struct.pack("<I", len(items)) + body


def _transform(grid: FloatGrid) -> bytes:
    h = float(grid.voxel_size)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"grid {grid.name!r}: voxel size must be > 0 (got {h})")
    t = [float(v) for v in grid.translation]
    rows = [t, [h] * 3, [h] * 3, [1 / h] * 3, [1 / h**2] * 3, [0.5 / h] * 3]
    return _string("UniformScaleTranslateMap") + struct.pack("<18d", *sum(rows, []))


#: ``zipped=None`` zips a file whose leaves hold at least this many active values on
#: average: zlib saves about a third of a dense leaf's bytes, but a chunk's 8-byte
#: header costs more than it saves on a leaf of a few values (sparse dust)
ZIP_MIN_VALUES_PER_LEAF = 64


def vdb_bytes(grids: list[FloatGrid], zipped: bool | None = None) -> bytes:
    """The bytes of a .vdb file holding ``grids`` (distinct, non-empty names): the same
    grids give the same bytes. ``zipped``: zlib-compress each leaf's values (smaller
    for dense grids, slower to write; OpenVDB reads both); None: each grid whose
    leaves hold :data:`ZIP_MIN_VALUES_PER_LEAF` values or more on average (the
    compression flags are per grid)."""
    names = [g.name for g in grids]
    if len(set(names)) != len(names) or not all(names):
        raise ValueError(f"grid names must be distinct and non-empty: {names}")
    parts = []
    for grid in grids:
        topology, buffers, active, zips = _grid_tree(grid, zipped)
        flags = COMPRESS_ACTIVE_MASK | (COMPRESS_ZIP if zips else 0)
        compression = "zip + active values" if zips else "active values"
        head = (struct.pack("<I", flags) + _grid_metadata(grid, active, compression)
                + _transform(grid))
        descriptor = _string(grid.name) + _string("Tree_float_5_4_3") + _string("")
        parts.append((descriptor, head + topology, buffers))
    digest = hashlib.sha256()
    for descriptor, body, buffers in parts:
        digest.update(descriptor + body + buffers)
    h = digest.hexdigest().upper()
    uuid = f"{h[:8]}-{h[8:12]}-{h[12:16]}-{h[16:20]}-{h[20:32]}".encode()
    out = bytearray(struct.pack("<qIII", MAGIC, FILE_VERSION, *LIBRARY_VERSION) + b"\x01"
                    + uuid + struct.pack("<Ii", 0, len(grids)))
    for descriptor, body, buffers in parts:
        out += descriptor
        grid_pos = len(out) + 24
        block_pos = grid_pos + len(body)
        end_pos = block_pos + len(buffers)
        out += struct.pack("<qqq", grid_pos, block_pos, end_pos) + body + buffers
    return bytes(out)


def write_vdb(path: str | Path, grids: list[FloatGrid], zipped: bool | None = None) -> int:
    """Write ``grids`` to ``path`` (.vdb, not atomically: callers stage the folder);
    returns the file's size in bytes."""
    data = vdb_bytes(grids, zipped)
    Path(path).write_bytes(data)
    return len(data)
