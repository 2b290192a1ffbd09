"""The VALUES of ``--vary KEY=VALUES``: a list of TOML values or an evenly spaced range.

* ``10,50,100`` / ``"brick","stone"`` / ``brick,stone`` / ``[1,0,1],[2,0,1]``: a
  comma-separated list of TOML values (bare words are strings; a bracketed list is
  one vector value).
* ``START:STOP:COUNT``: COUNT values evenly spaced from START to STOP inclusive
  (integers when START, STOP and every step are whole: ``0:3:4`` is 0, 1, 2, 3);
  ``START:STOP:COUNT:log``: evenly spaced in log (both ends > 0), for masses and
  time steps that span orders of magnitude.

In a scene's ``[wedge.vary]`` table a key's value is a TOML array (the list) or a
range string.
"""

from __future__ import annotations

import math
import re
import tomllib
from typing import Any

from blastvox.errors import WedgeError

#: Most values one key may take (the grid is the product over keys; see plan.MAX_SHOTS).
MAX_VALUES = 1000
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_RANGE = re.compile(rf"^\s*({_NUMBER})\s*:\s*({_NUMBER})\s*:\s*(\d+)\s*(?::\s*(lin|log))?\s*$")


def parse_values(text: Any, where: str) -> list[Any]:
    """The values of one key: ``text`` is a VALUES string or (from a scene's
    ``[wedge.vary]``) a list; ``where`` names the option or key in errors.

    Raises :class:`~blastvox.errors.WedgeError` (one line) for an empty list, a bad
    range, more than :data:`MAX_VALUES` values or a value that is not finite.
    """
    if isinstance(text, list):
        values = list(text)
    elif isinstance(text, str):
        match = _RANGE.match(text)
        values = _range(match, where) if match else _list(text, where)
    else:
        raise WedgeError(f"{where}: expected a list of values or a 'START:STOP:COUNT' range "
                         f"(got {text!r})")
    if not values:
        raise WedgeError(f"{where}: no values")
    if len(values) > MAX_VALUES:
        raise WedgeError(f"{where}: {len(values):,} values; at most {MAX_VALUES:,} per key")
    for value in values:
        _check_finite(value, where)
    return values


def _range(match: re.Match[str], where: str) -> list[Any]:
    start_text, stop_text, count_text, spacing = match.groups()
    start, stop, count = float(start_text), float(stop_text), int(count_text)
    if not (math.isfinite(start) and math.isfinite(stop)):
        raise WedgeError(f"{where}: range ends must be finite")
    if count < 1 or count > MAX_VALUES:
        raise WedgeError(f"{where}: range COUNT must be 1 .. {MAX_VALUES:,} (got {count})")
    if count == 1:
        values = [start]
    elif spacing == "log":
        if start <= 0 or stop <= 0:
            raise WedgeError(f"{where}: a log range needs START and STOP > 0")
        ratio = math.log(stop / start) / (count - 1)
        values = [start * math.exp(ratio * i) for i in range(count)]
        values[-1] = stop
    else:
        values = [start + (stop - start) * i / (count - 1) for i in range(count)]
    whole = _is_int(start_text) and _is_int(stop_text) and spacing != "log"
    if whole and all(float(v).is_integer() for v in values):
        return [int(v) for v in values]
    return [float(f"{v:.12g}") for v in values]  # 0.1 + 0.2 steps print as written


def _is_int(text: str) -> bool:
    return re.fullmatch(r"[-+]?\d+", text.strip()) is not None


def _list(text: str, where: str) -> list[Any]:
    try:
        return list(tomllib.loads(f"v = [{text}]")["v"])
    except tomllib.TOMLDecodeError:
        pass
    if any(c in text for c in "[]{}\"'="):
        raise WedgeError(f"{where}: cannot read {text!r} as a list of TOML values or a "
                         f"'START:STOP:COUNT' range")
    words = [w.strip() for w in text.split(",")]
    if not all(words):
        raise WedgeError(f"{where}: empty value in {text!r}")
    return words


def _check_finite(value: Any, where: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise WedgeError(f"{where}: {value!r} is not a finite number")
    if isinstance(value, list):
        for item in value:
            _check_finite(item, where)
    if isinstance(value, dict):
        for item in value.values():
            _check_finite(item, where)


def format_value(value: Any) -> str:
    """A value as a short label (``50``, ``0.001``, ``brick``, ``[1, 0, 1]``)."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)
