"""Numeric limits of user input and the budgets of work, and the one check that enforces
them.

Every number a user gives -- a command-line flag, a scene key, a material field, a
Python setting -- goes through a :class:`Bound` before it reaches a stage: it must be
a number (not a bool or a string), finite (``inf`` only where a bound allows it, as
"never" for a material threshold) and within the documented range. Huge but finite
values (1e300) would otherwise become ``inf`` or NaN downstream, and integers would
overflow NumPy's fixed-width types.

``Bound.check(value)`` raises :class:`ValueError` with the problem only ("must be <=
1e+06 m (got 1e+300)"): the scene schema (pydantic) adds the file and key.
``Bound.at(value, where)`` and ``Bound.named(value, name, source)`` raise a one-line
:class:`~blastvox.errors.BlastvoxError` ``"<source>: <name>: <problem>"``.

Budgets (how much work or memory a run may take: steps, frames, particles, pixels,
voxels) are not bounds: they have defaults here, which a flag raises (see
:class:`blastvox.simulate.settings.Budget`, :mod:`blastvox.preview.options`,
:mod:`blastvox.voxelize.budget`). This module imports nothing heavy, so the CLI can show
them. docs/user-guide.md, "Limits and exit codes", lists them all.
"""

from __future__ import annotations

import math
import os
import stat
from dataclasses import dataclass
from typing import Any

from blastvox.errors import BlastvoxError, InputError

#: Largest |coordinate| (m) anywhere in the world frame: mesh vertices after the
#: transform, translations, rule regions, charges, camera, ground height.
MAX_COORDINATE_M = 1e6
#: Smallest voxel edge (m) the voxelizer makes (checked after the budget).
MIN_VOXEL_SIZE_M = 1e-6
#: Largest voxel edge (m).
MAX_VOXEL_SIZE_M = 1e6
#: Largest seed: seeds are unsigned 64-bit integers, 0 .. 2**64 - 1 (a scene's TOML
#: integers stop at 2**63 - 1), as simulate.settings.check_seed takes them.
MAX_SEED = 2**64 - 1
#: Largest --max-voxels (voxel and vertex indices are stored as int32).
MAX_VOXELS_LIMIT = 100_000_000
#: Voxels one voxelize makes unless --max-voxels says otherwise.
DEFAULT_MAX_VOXELS = 4_000_000
#: Largest scene or materials TOML file read (bytes).
MAX_TOML_BYTES = 64 * 2**20


#: Charges: 1 µg to 1 Mt of explosive (kg), within +-1000 km (m), going off within 1e9 s.
MIN_CHARGE_KG = 1e-9
MAX_CHARGE_KG = 1e9
MAX_TIME_S = 1e9
#: Distances of the blast calculator (m), and how many one call takes (its table prints
#: about 150 rows a second).
MAX_DISTANCE_M = 1e6
MAX_DISTANCES = 1_000

#: ``blastvox simulate``'s budgets: fixed steps, output frames, particles of all systems,
#: memory of the recorded frames (GiB); --max-steps, --max-frames, --max-particles and
#: --max-memory raise them.
MAX_STEPS = 10_000_000
MAX_FRAMES = 100_000
MAX_PARTICLES = 1_000_000
MAX_MEMORY_GIB = 4.0
#: ``blastvox preview``'s budgets: pixels rendered per frame (W x H x S^2, --max-pixels)
#: and pixels of a sheet's or a GIF's frames together (--max-output-pixels).
MAX_PIXELS = 2**26
MAX_OUTPUT_PIXELS = 2**29


def fmt(value: float) -> str:
    """A number as a user typed it, shortly: 0.5, 1e+12, 1,000,000 for whole numbers."""
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    if math.isfinite(value) and value == int(value) and abs(value) < 1e7:
        return f"{int(value):,}"
    return f"{value:.6g}"


def _fmt(value: float) -> str:
    return f"{value:g}"


def got(value: Any) -> str:
    """How messages quote a rejected value (short, one line)."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def printable(text: str | os.PathLike) -> str:
    """``text`` safe to print and to store as UTF-8 JSON: a byte of a non-UTF-8 file
    name (a surrogate escape on Linux) is shown as ``\\xff``. Whatever the file system's
    encoding (Python under ``LC_ALL=C`` without its UTF-8 mode encodes names as ASCII)."""
    text = os.fspath(text)
    if isinstance(text, bytes):
        return text.decode("utf-8", "backslashreplace")
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


def shortened(text: str, limit: int = 120) -> str:
    """``text`` cut to ``limit`` characters (its start and end kept) for a message that
    must stay one readable line."""
    if len(text) <= limit:
        return text
    keep = (limit - 3) // 2
    return f"{text[:keep]}...{text[-keep:]}"


@dataclass(frozen=True)
class Bound:
    """An allowed range ``lo .. hi`` (open or closed ends) of a number in ``unit``.

    integer: the value must be an int (bools refused), compared exactly (no
    float conversion, so 2**64 is refused and not rounded). allow_inf: ``+inf``
    is accepted as "never" (material thresholds). interval: say the whole range
    in messages ("must be in [0, 1]") rather than the side that was crossed.
    """

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""
    integer: bool = False
    allow_inf: bool = False
    interval: bool = False

    def describe(self, with_unit: bool = True, kind: bool = True) -> str:
        """The range as text: ``in [-1e+06, 1e+06] m``, ``> 0``, ``an integer >= 1``."""
        unit = f" {self.unit}" if self.unit and with_unit else ""
        kind_text = "an integer " if self.integer and kind else ""
        if math.isinf(self.lo) and math.isinf(self.hi):
            text = "finite"
        elif math.isinf(self.hi):
            text = f"{'>' if self.lo_open else '>='} {self._num(self.lo)}"
        elif math.isinf(self.lo):
            text = f"{'<' if self.hi_open else '<='} {self._num(self.hi)}"
        else:
            text = (f"in {'(' if self.lo_open else '['}{self._num(self.lo)}, "
                    f"{self._num(self.hi)}{')' if self.hi_open else ']'}")
        return f"{kind_text}{text}{unit}" + (" (or inf)" if self.allow_inf else "")

    def _num(self, value: float) -> str:
        if self.integer and float(value).is_integer():
            return f"{int(value):,}" if abs(value) >= 1e4 else str(int(value))
        return _fmt(value)

    def check(self, value: Any) -> Any:
        """``value`` as a float (an int for integer bounds), or ValueError with the problem."""
        unit = f" {self.unit}" if self.unit else ""
        if self.integer:
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(f"must be an integer (got {got(value)})")
            number: Any = value
        else:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"must be a number (got {got(value)})")
            try:
                number = float(value)
            except OverflowError:  # an int beyond float's range
                number = math.copysign(math.inf, value)
            if math.isnan(number):
                raise ValueError("must not be nan" if self.allow_inf else
                                 f"must be finite (got {got(value)})")
            if math.isinf(number):
                if not self.allow_inf:
                    raise ValueError(f"must be finite (got {got(value)})")
                if number > 0:
                    return number  # "never"; -inf falls to the range check
        low = number <= self.lo if self.lo_open else number < self.lo
        high = number >= self.hi if self.hi_open else number > self.hi
        if low or high:
            if self.interval:
                raise ValueError(f"must be {self.describe()} (got {got(number)})")
            if low:
                op, limit = (">" if self.lo_open else ">="), self.lo
            else:
                op, limit = ("<" if self.hi_open else "<="), self.hi
            raise ValueError(f"must be {op} {self._num(limit)}{unit} (got {got(number)})")
        return number

    def constraints(self) -> Any:
        """The bound as pydantic field constraints (strict: no bools, no strings), for the
        scene schema, whose messages then say ``must be <= 1e+06 (got 1e+300)``."""
        from pydantic import Field

        lower = {"gt" if self.lo_open else "ge": self.lo} if math.isfinite(self.lo) else {}
        upper = {"lt" if self.hi_open else "le": self.hi} if math.isfinite(self.hi) else {}
        if self.integer:
            return Field(strict=True, **lower, **upper)
        return Field(strict=True, allow_inf_nan=self.allow_inf, **lower, **upper)

    def at(self, value: Any, where: str) -> Any:
        """Like :meth:`check`, but the error is a one-line BlastvoxError ``"<where>: ..."``."""
        try:
            return self.check(value)
        except ValueError as exc:
            raise BlastvoxError(f"{where}: {exc}") from None

    def named(self, value: Any, name: str, source: str | None = None) -> Any:
        """:meth:`at` with the error at ``"<source>: <name>"`` (a file and its key, or a
        flag without a file)."""
        return self.at(value, f"{source}: {name}" if source else name)

    def parse(self, text: str, where: str) -> Any:
        """Parse a command-line string as a number and :meth:`at` check it."""
        try:
            value: Any = int(text) if self.integer else float(text)
        except (ValueError, OverflowError):
            kind = "an integer" if self.integer else "a number"
            raise BlastvoxError(f"{where}: must be {kind} (got {got(text)})") from None
        return self.at(value, where)


# The bounds of the values users give; docs/user-guide.md lists them (Limits).
COORDINATE = Bound(-MAX_COORDINATE_M, MAX_COORDINATE_M, unit="m")
DIRECTION = Bound(-MAX_COORDINATE_M, MAX_COORDINATE_M)
ANGLE_DEG = Bound(-1e6, 1e6, unit="degrees")
SCALE = Bound(0.0, 1e6, lo_open=True)
VOXEL_SIZE = Bound(0.0, MAX_VOXEL_SIZE_M, lo_open=True, unit="m")
RESOLUTION = Bound(1, 2**63 - 1, integer=True)
CONTACT_SUBSTEPS = Bound(1, 1_000, integer=True)
FOCAL_LENGTH_MM = Bound(1.0, 10_000.0, unit="mm")  # a 36 mm film back
JITTER = Bound(0.0, 0.5, hi_open=True)
SEED = Bound(0, MAX_SEED, integer=True)
MAX_VOXELS = Bound(1, MAX_VOXELS_LIMIT, integer=True)
#: the highest --max-triangles (triangles read by one voxelize) and --max-objects
MAX_TRIANGLES_LIMIT = 100_000_000
MAX_OBJECTS_LIMIT = 1_000_000
MAX_TRIANGLES = Bound(1, MAX_TRIANGLES_LIMIT, integer=True)
MAX_OBJECTS = Bound(1, MAX_OBJECTS_LIMIT, integer=True)
LENGTH = Bound(0.0, MAX_COORDINATE_M, lo_open=True, unit="m")
STRENGTH_SCALE = Bound(0.0, 1e6, lo_open=True)
#: A chunk size (m): 0 = no chunks; the voxelizer also refuses one below a voxel or above
#: the object (blastvox.voxelize.chunks). The top is the materials' chunk_size limit.
CHUNK_SIZE = Bound(0.0, 1e4, unit="m")
#: factor on the yields of links between two touching parts of one input
PART_BOND = Bound(0.0, 1e6, lo_open=True)
#: thickness (m) of an open part voxelized as a sheet (blastvox.voxelize.sheets)
SHEET_THICKNESS = Bound(0.0, 100.0, lo_open=True, unit="m")
#: its default: window glass is 4-10 mm
DEFAULT_SHEET_THICKNESS_M = 0.01
CHARGE_KG = Bound(MIN_CHARGE_KG, MAX_CHARGE_KG, unit="kg")
CHARGE_TIME_S = Bound(0.0, MAX_TIME_S, unit="s")
DISTANCE_M = Bound(0.0, MAX_DISTANCE_M, unit="m")

def check_seed(value: Any, where: str = "--seed") -> int:
    """The shared seed check: an integer in 0 .. 2**64 - 1, else a one-line error
    ``"<where>: must be >= 0 (got -1)"`` (numpy accepts any non-negative seed; the
    jitter's hash takes it as an unsigned 64-bit integer)."""
    return SEED.at(value, where)


def regular_file(path: str | os.PathLike, what: str, max_bytes: int | None = None) -> int:
    """Refuse, before opening it, an input that is not a regular file: a directory, a
    device (/dev/zero would be read forever), a FIFO (would block), a socket; with
    ``max_bytes``, a larger file. Returns its size. A missing or unreadable path raises
    the OSError (FileNotFoundError, PermissionError, ...) for the caller to word;
    the refusals here are :class:`InputError` ``"<path>: <problem>"``.
    """
    shown = printable(path)
    try:
        info = os.stat(path)
    except ValueError:  # a NUL, or a character the file system's encoding cannot hold
        raise InputError(f"{shown!r}: not a valid file name (a NUL character, or one this "
                         "system's file names cannot hold)") from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(f"{shown}: is a directory, not a {what}")
    if not stat.S_ISREG(info.st_mode):
        from blastvox.io.outputs import file_kind  # one naming of file kinds, in and out

        raise InputError(f"{shown}: is {file_kind(info.st_mode)}, not a regular file; "
                         f"give a {what}")
    if max_bytes is not None and info.st_size > max_bytes:
        raise InputError(f"{shown}: {info.st_size:,} bytes is too large for a {what} "
                         f"(at most {max_bytes:,})")
    return info.st_size


def check_count(value: Any, name: str, low: int = 1, source: str | None = None) -> int:
    """A whole number >= ``low`` (a budget flag, a particle budget), else BlastvoxError."""
    where = f"{source}: " if source else ""
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise BlastvoxError(f"{where}{name} {value!r} must be a whole number >= {low:,}")
    return value
