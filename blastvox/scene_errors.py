"""One-line messages for scene validation errors: ``<source>: <key.path>: <problem>``.

Pydantic reports every problem with its location and type; a tired artist wants
the first one, on one line, with the key spelled as in the TOML and, for an
unknown key, the closest allowed one.
"""

from __future__ import annotations

import difflib
import json
import re
from typing import Any, get_args, get_origin

from pydantic import BaseModel, ValidationError


class At(ValueError):
    """A validation error about a key below the one being validated."""

    def __init__(self, path: tuple[str | int, ...], message: str) -> None:
        super().__init__(message)
        self.path = path


def shown(value: Any) -> str:
    """``repr(value)``, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def format_validation_error(exc: ValidationError, source: str, root: type[BaseModel]) -> str:
    """One line ``<source>: <key.path>: <problem> [(+N more)]`` for a pydantic error in
    validating the model ``root`` (the scene)."""
    errors = exc.errors()
    first = errors[0]
    loc = tuple(first["loc"])
    cause = (first.get("ctx") or {}).get("error")
    if isinstance(cause, At):
        loc += cause.path
    where = "".join(f"[{p}]" if isinstance(p, int) else toml_key(p) for p in loc).lstrip(".")
    text = f"{source}: {where + ': ' if where else ''}{_describe(first, loc, root)}"
    return text + (f" (+{len(errors) - 1} more)" if len(errors) > 1 else "")


def toml_key(part: str) -> str:
    return f".{part}" if re.fullmatch(r"[A-Za-z0-9_-]+", part) else f".{json.dumps(part)}"


def _describe(error: Any, loc: tuple[str | int, ...], root: type[BaseModel]) -> str:
    kind, ctx, got = error["type"], error.get("ctx") or {}, shown(error.get("input"))
    bounds = {"greater_than": ("gt", ">"), "greater_than_equal": ("ge", ">="),
              "less_than": ("lt", "<"), "less_than_equal": ("le", "<=")}
    if kind in ("value_error", "assertion_error"):
        return str(ctx["error"])
    if kind in bounds:
        name, op = bounds[kind]
        limit = ctx[name]
        text = (f"{limit:,}" if abs(limit) >= 10_000 else str(limit)) if isinstance(limit, int) \
            else f"{limit:g}"
        return f"must be {op} {text} (got {got})"
    simple = {
        "missing": "required key is missing",
        "finite_number": "must be finite",
        "float_type": f"must be a number (got {got})",
        "int_type": f"must be an integer (got {got})",
        "int_from_float": f"must be an integer (got {got})",
        "bool_type": f"must be true or false (got {got})",
        "string_type": f"must be a string (got {got})",
        "string_too_short": "must not be empty",
        "dict_type": f"must be a table (got {got})",
        "model_type": f"must be a table (got {got})",
        "model_attributes_type": f"must be a table (got {got})",
        "list_type": f"must be a list (got {got})",
    }
    if kind in simple:
        return simple[kind]
    if kind == "literal_error":
        return f"must be one of {ctx['expected'].replace(' or ', ', ')} (got {got})"
    if kind == "too_short":
        return f"must have at least {ctx['min_length']} entry (got {ctx.get('actual_length')})"
    if kind == "extra_forbidden":
        allowed = _fields_at(root, loc[:-1])
        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        if close:
            return f"unknown key (did you mean '{close[0]}'?)"
        return f"unknown key (allowed: {', '.join(allowed)})" if allowed else "unknown key"
    message = error["msg"]
    return message[:1].lower() + message[1:]


def _fields_at(root: type[BaseModel], loc: tuple[str | int, ...]) -> list[str]:
    """Keys allowed in the table at ``loc`` of ``root`` (empty if not a model)."""
    model: type[BaseModel] | None = root
    for part in loc:
        if isinstance(part, int):
            continue
        field = model.model_fields.get(part) if model else None
        model = _find_model(field.annotation) if field else None
    return list(model.model_fields) if model else []


def _find_model(annotation: Any) -> type[BaseModel] | None:
    if (get_origin(annotation) is None and isinstance(annotation, type)
            and issubclass(annotation, BaseModel)):
        return annotation
    for arg in get_args(annotation):
        found = _find_model(arg)
        if found is not None:
            return found
    return None
