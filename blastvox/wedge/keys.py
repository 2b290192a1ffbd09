"""KEY paths of ``--vary KEY=VALUES``: where a value goes in the scene file as it is written.

A KEY is dotted, with list items by index: ``charges.0.mass_kg``, ``seed``,
``simulation.dt``, ``objects.0.voxel_size``, ``objects.1.transform.translate``,
``materials.brick.link_yield_mean`` (a property of a built-in or library material:
the scene's inline ``[materials.brick]`` table overrides just that field).
``charges[0].mass_kg``, the spelling of error messages, is accepted too.

Valid keys are the scene schema's fields (:class:`blastvox.scene.Scene`), through
the lists as long as the scene writes them, except the output paths a wedge sets
for each shot (``output.model``, ``output.cache``, ``output.export``) and the
``[wedge]`` table itself. A key the scene does not write (``simulation.dt`` when
there is no ``[simulation]`` table) is valid: setting it creates the table.
"""

from __future__ import annotations

import copy
import difflib
import json
import re
import types
import typing
from collections.abc import Iterator, Mapping
from typing import Any

from pydantic import BaseModel

from blastvox.errors import WedgeError
from blastvox.scene_errors import toml_key

#: Keys a wedge sets itself (each shot's outputs) or reads (the wedge table).
RESERVED = ("output.model", "output.cache", "output.export", "wedge")
#: A KEY: parts (plain, or "quoted" as in TOML) joined by dots, list items as [N] too.
_PART = r'"(?:[^"\\]|\\.)*"|[A-Za-z0-9_-]+'
_KEY = re.compile(rf"(?:{_PART})(?:\.(?:{_PART})|\[\d+\])*")
_TOKEN = re.compile(rf"({_PART})|\[(\d+)\]")


def split_key(key: str, where: str = "--vary") -> list[str]:
    """``'charges[0].mass_kg'`` -> ``["charges", "0", "mass_kg"]``; a part with dots or
    spaces is quoted as in TOML: ``'objects.0.material_map."Wheels.001"'``. ``where``
    names the option or scene key in the error."""
    text = key.strip()
    try:
        if _KEY.fullmatch(text):
            return [json.loads(part) if part.startswith('"') else part or index
                    for part, index in _TOKEN.findall(text)]
    except ValueError:  # a bad escape inside quotes
        pass
    raise WedgeError(f"{where} {key!r}: a KEY is a dotted path such as charges.0.mass_kg "
                     f'(quote a part with dots: material_map."Wheels.001")')


def join_key(parts: list[str]) -> str:
    """The key of ``parts`` as :func:`split_key` reads it (quoted where needed, as the
    scene's error messages spell keys)."""
    return "".join(toml_key(p) for p in parts).removeprefix(".")


def valid_keys(scene_model: type[BaseModel], data: Mapping[str, Any],
               material_names: list[str], material_fields: list[str]) -> list[str]:
    """Every settable leaf key of a scene whose parsed file is ``data`` (sorted).

    ``material_names``: the materials the scene can see (built-in, file, inline);
    ``material_fields``: the keys of a material table.
    """
    keys = set(_model_keys(scene_model, data, ""))
    for name in material_names:
        keys.update(join_key(["materials", name, field]) for field in material_fields)
    return sorted(k for k in keys if not any(k == r or k.startswith(r + ".") for r in RESERVED))


def _model_keys(model: type[BaseModel], data: Any, prefix: str) -> Iterator[str]:
    data = data if isinstance(data, Mapping) else {}
    for name, field in model.model_fields.items():
        key = prefix + name
        sub, in_list = _nested(field.annotation)
        written = data.get(name)
        if sub is not None and in_list:
            for i, item in enumerate(written if isinstance(written, list) else []):
                yield from _model_keys(sub, item, f"{key}.{i}.")
        elif sub is not None:
            yield from _model_keys(sub, written, key + ".")
        elif _is_dict(field.annotation) and name != "materials":
            yield key
            yield from (join_key([*key.split("."), str(k)]) for k in (written or {})
                        if isinstance(written, Mapping))
        elif name != "materials":
            yield key


def _nested(annotation: Any) -> tuple[type[BaseModel] | None, bool]:
    """(model, is_list) for a field typed as a model, an optional model or a list of models."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation, False
    if origin is list and args and isinstance(args[0], type) and issubclass(args[0], BaseModel):
        return args[0], True
    if origin in (typing.Union, types.UnionType):
        for arg in args:
            model, in_list = _nested(arg)
            if model is not None:
                return model, in_list
    if origin is typing.Annotated:
        return _nested(args[0])
    return None, False


def _is_dict(annotation: Any) -> bool:
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _is_dict(typing.get_args(annotation)[0])
    return origin is dict


def check_key(key: str, valid: list[str], where: str) -> str:
    """``key`` in its dotted form if it is in ``valid``; else a WedgeError naming it and
    the nearest valid keys (``where`` names the option or scene key)."""
    dotted = join_key(split_key(key, where))
    if dotted in valid:
        return dotted
    if any(dotted == r or dotted.startswith(r + ".") for r in RESERVED):
        raise WedgeError(f"{where}: {key!r}: a wedge sets each shot's outputs itself; vary "
                         f"something that makes the shot")
    near = difflib.get_close_matches(dotted, valid, n=3, cutoff=0.6)
    if not near:  # a wrong index or a deeper typo: the keys under the longest valid prefix
        near = _under_prefix(dotted, valid)
    hint = f"; nearest: {', '.join(near)}" if near else ""
    raise WedgeError(f"{where}: unknown key {key!r}{hint}")


def _under_prefix(dotted: str, valid: list[str]) -> list[str]:
    parts = dotted.split(".")
    for n in range(len(parts) - 1, 0, -1):
        head = ".".join(parts[:n]) + "."
        under = [k for k in valid if k.startswith(head)]
        if under:
            return difflib.get_close_matches(dotted, under, n=3, cutoff=0.0)
    return []


def with_values(data: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of the parsed scene ``data`` with each dotted key of ``values`` set
    (creating missing tables; list items must exist, as :func:`check_key` ensures)."""
    out = copy.deepcopy(dict(data))
    for key, value in values.items():
        parts = split_key(key)
        node: Any = out
        for part in parts[:-1]:
            if isinstance(node, list):
                node = node[int(part)]
                continue
            child = node.get(part)
            if not isinstance(child, (dict, list)):
                child = node[part] = {}
            node = child
        last = parts[-1]
        if isinstance(node, list):
            node[int(last)] = copy.deepcopy(value)
        else:
            node[last] = copy.deepcopy(value)
    return out
