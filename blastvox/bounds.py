"""Numeric bounds of the values a user gives (flags, scene keys, Python settings), the
one-line refusal of a value outside them, and the budgets' defaults.

A :class:`Bound` is a documented range (docs/user-guide.md, "Limits and exit codes"):
a value that is NaN, infinite or outside it is refused with a
:class:`~blastvox.errors.BlastvoxError` naming the value's source (a file), its name (a
flag such as ``--dt`` or a scene key such as ``[simulation] dt``), the value and the
range. The bounds are wide enough for every physical use and narrow enough that
everything computed from the value stays finite in float64 (and float32 where stored).

Budgets (how much work or memory a run may take) are not bounds: they have defaults,
here (this module imports nothing heavy, so the CLI can show them), that a flag raises;
see :class:`blastvox.simulate.settings.Budget` and :mod:`blastvox.preview.options`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from blastvox.errors import BlastvoxError

#: Charges: 1 µg to 1 Mt of explosive (kg), within +-1000 km (m), going off within 1e9 s.
MIN_CHARGE_KG = 1e-9
MAX_CHARGE_KG = 1e9
MAX_COORDINATE_M = 1e6
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


@dataclass(frozen=True)
class Bound:
    """A closed (or, with ``open_low``, left-open) range ``[low, high]`` of finite numbers;
    None: unbounded on that side. ``unit`` is printed after numbers ("s", "kg")."""

    low: float | None = None
    high: float | None = None
    unit: str = ""
    open_low: bool = False

    def describe(self) -> str:
        """The range in words: "> 0 s", "between 1e-09 and 1 s", ">= 0"."""
        u = f" {self.unit}" if self.unit else ""
        low = None if self.low is None else ("> " if self.open_low else ">= ") + fmt(self.low)
        if self.high is None:
            return f"{low}{u}" if low else "finite"
        if low is None:
            return f"<= {fmt(self.high)}{u}"
        if self.open_low:
            return f"> {fmt(self.low)} and <= {fmt(self.high)}{u}"
        return f"between {fmt(self.low)} and {fmt(self.high)}{u}"

    def contains(self, value: float) -> bool:
        """Is ``value`` a finite number in the range?"""
        if not math.isfinite(value):
            return False
        if self.low is not None and (value <= self.low if self.open_low else value < self.low):
            return False
        return self.high is None or value <= self.high

    def check(self, value: Any, name: str, source: str | None = None) -> float:
        """``value`` as a float if it is in the range, else a one-line BlastvoxError
        "<source>: <name> <value> <unit> must be <range>"."""
        where = f"{source}: " if source else ""
        try:
            number = float(value)
        except (TypeError, ValueError, OverflowError):
            raise BlastvoxError(f"{where}{name} {value!r} is not a number") from None
        if isinstance(value, bool) or not self.contains(number):
            u = f" {self.unit}" if self.unit and math.isfinite(number) else ""
            shown = fmt(number) if not isinstance(value, bool) else str(value)
            raise BlastvoxError(f"{where}{name} {shown}{u} is {self._problem(number)}: it must "
                                f"be {self.describe()}")
        return number

    def _problem(self, number: float) -> str:
        if math.isnan(number):
            return "not a number"
        if math.isinf(number):
            return "infinite"
        if self.low is not None and number <= self.low:
            return "negative" if number < 0.0 <= self.low else (
                "zero" if number == 0.0 else "too small")
        return "too large"


#: The bounds of a charge (see the module constants).
CHARGE_KG = Bound(MIN_CHARGE_KG, MAX_CHARGE_KG, "kg")
COORDINATE_M = Bound(-MAX_COORDINATE_M, MAX_COORDINATE_M, "m")
CHARGE_TIME_S = Bound(0.0, MAX_TIME_S, "s")
DISTANCE_M = Bound(0.0, MAX_DISTANCE_M, "m")


def check_count(value: Any, name: str, low: int = 1, source: str | None = None) -> int:
    """A whole number >= ``low`` (a budget flag, a particle budget), else BlastvoxError."""
    where = f"{source}: " if source else ""
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise BlastvoxError(f"{where}{name} {value!r} must be a whole number >= {low:,}")
    return value
