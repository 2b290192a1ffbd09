"""Print docs/scene-reference.md: every scene-file key, generated from the schema.

The tables come from the pydantic models in ``blastvox/scene.py`` (their fields,
types, constraints, defaults and ``Field(description=...)``), the material
fields and the built-in library from ``blastvox/materials.py`` and
``blastvox/data/materials.toml``, and the explosives from ``blastvox/blast``.
Units, which the schema does not hold, are the ``UNITS`` tables below.

    python tools/scene_reference.py > docs/scene-reference.md   # regenerate
    python tools/scene_reference.py --check                     # exit 1 if it is stale

``tests/test_docs.py`` fails when the file differs from what this prints, or
when a key has no description or a numeric key no unit.
"""

from __future__ import annotations

import argparse
import difflib
import math
import re
import sys
import textwrap
import types
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel
from pydantic.fields import FieldInfo

from blastvox.blast import explosives as _explosives
from blastvox.damage_look import PATTERNS
from blastvox.materials import _BOUNDS as _MATERIAL_BOUNDS
from blastvox.materials import _FIELD_KINDS, Material, MaterialLibrary
from blastvox.scene import Scene, scene_from_dict

TNT_EQUIVALENTS: dict[str, float] = _explosives.TNT_EQUIVALENTS
EXPLOSIVE_ALIASES: dict[str, str] = getattr(_explosives, "_ALIASES", {})

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "docs" / "scene-reference.md"

#: Units of the scene keys, by dotted path ("-": dimensionless). Every key whose type
#: is a number needs one.
UNITS: dict[str, str] = {
    "seed": "-",
    "ground": "m",
    "objects.voxel_size": "m",
    "objects.resolution": "voxels",
    "objects.jitter": "voxel edges",
    "objects.chunk_size": "m",
    "objects.part_bond": "-",
    "objects.sheet_thickness": "m",
    "objects.transform.translate": "m",
    "objects.transform.rotate_deg": "degrees",
    "objects.transform.scale": "-",
    "objects.rules.box.min": "m",
    "objects.rules.box.max": "m",
    "objects.rules.sphere.center": "m",
    "objects.rules.sphere.radius": "m",
    "objects.rules.halfspace.point": "m",
    "objects.rules.halfspace.normal": "-",
    "objects.rules.strength_scale": "-",
    "objects.rules.chunk_size": "m",
    "charges.position": "m",
    "charges.mass_kg": "kg",
    "charges.time_s": "s",
    "simulation.dt": "s",
    "simulation.fps": "1/s",
    "simulation.duration": "s",
    "simulation.gravity": "m/s²",
    "simulation.linear_drag": "1/s",
    "simulation.angular_drag": "1/s",
    "simulation.weakening": "-",
    "simulation.orientation_factor": "-",
    "simulation.damage_b": "-",
    "simulation.damage_c": "1/(Pa s)",
    "simulation.friction": "-",
    "simulation.contact_substeps": "sweeps",
    "simulation.fire_pressure_scale": "-",
    "simulation.fire_spread": "Pa/s",
    "simulation.burn_rate": "1/s",
    "particles.dust": "particles",
    "particles.fire": "particles",
    "particles.smoke": "particles",
    "particles.fireball": "particles",
    "camera.position": "m",
    "camera.look_at": "m",
    "camera.focal_length_mm": "mm",
    "wedge.sample": "shots",
    "wedge.sample_seed": "-",
    "output.volume_voxel_m": "m",
    "output.key_tolerance_m": "m", "output.key_tolerance_deg": "degrees",
}

#: Defaults that a model validator computes (the schema marks these keys required or unset).
COMPUTED_DEFAULTS: dict[str, str] = {
    "objects.name": "the mesh file's stem",
    "objects.resolution": "32 if no voxel_size",
}

#: Units of the material fields (``blastvox/materials.py``; all SI).
MATERIAL_UNITS: dict[str, str] = {
    "density": "kg/m³",
    "link_yield_mean": "Pa",
    "link_yield_var": "Pa",
    "voxel_yield_mean": "Pa",
    "voxel_yield_var": "Pa",
    "foundation_yield": "Pa",
    "restitution": "-",
    "combustibility": "Pa",
    "color": "linear RGB",
    "damage_color": "linear RGB",
    "description": "",
    "damage_pattern": "",
    "link_impulse": "Pa s",
    "voxel_impulse": "Pa s",
    "pi_shape": "-",
    "compressive_strength": "Pa",
    "crush_pressure": "Pa",
    "tensile_strength": "Pa",
    "shear_strength": "Pa",
    "youngs_modulus": "Pa",
    "chunk_size": "m",
    "chunk_weibull": "-",
    "chunk_bond_scale": "-",
}

#: Meanings that replace the Material docstring's where it gives only a unit.
MATERIAL_MEANINGS: dict[str, str] = {
    "density": "Mass per unit volume: a voxel's mass is its volume times this.",
    "chunk_size": ("Mean chunk size, the equivalent cube side of the mean chunk: voxelize "
                   "groups the voxels into irregular chunks of about this size cubed. 0, or "
                   "a size below one voxel: every voxel its own chunk. An object's or a "
                   "rule's `chunk_size` replaces it."),
    "chunk_weibull": ("Weibull modulus of the chunk volumes (Grady-Kipp fragment "
                      "statistics): small = a wide spread of sizes, large = even sizes."),
    "chunk_bond_scale": ("Factor (>= 1) on the yield of links inside a chunk, so fracture "
                         "runs along chunk boundaries first (1 = chunks change nothing)."),
}

#: How each kind of material field (``_FIELD_KINDS``) is checked, in words.
def _range(bound: Any) -> str:
    """A :class:`blastvox.bounds.Bound` in the tables' words (no unit)."""
    return bound.describe(with_unit=False, kind=False).replace(">=", "≥").replace("<=", "≤")


MATERIAL_KINDS: dict[str, str] = {
    **{kind: f"number {_range(bound)}" for kind, bound in _MATERIAL_BOUNDS.items()},
    "rgb": "3 numbers in [0, 1]",
    "text": "string",
    "pattern": "one of " + ", ".join(PATTERNS) + ', or ""',
}

EXAMPLE = """\
seed = 1
up_axis = "Z"                      # the meshes are Z-up
ground = "auto"                    # the lowest voxel stands on the ground

[materials.weak_brick]             # a library material with one value changed
base = "brick"
link_yield_mean = 30000.0

[[objects]]
name = "house"
mesh = "house.obj"                 # relative to this file
voxel_size = 0.5
jitter = 0.2
material = "brick"

[[objects.rules]]                  # everything above 2.5 m is plaster
halfspace = { point = [0.0, 0.0, 2.5], normal = [0.0, 0.0, 1.0] }
material = "plaster"

[[objects.rules]]                  # a weaker east wall
box = { min = [3.0, -1.0, 0.0], max = [5.0, 5.0, 2.5] }
material = "weak_brick"

[[charges]]
position = [2.0, -2.0, 1.0]
mass_kg = 1.0
explosive = "TNT"

[simulation]
duration = 4.0

[camera]
position = [2.0, -15.0, 3.0]
look_at = [2.0, 0.0, 1.5]

[output]
model = "out/model.npz"
cache = "out/sim.npz"
export = ["out/shot.usdc", "out/shot.glb"]
"""

INTRO = """\
# Scene file reference

<!-- Generated by `python tools/scene_reference.py` from blastvox/scene.py, \
blastvox/materials.py and blastvox/data/materials.toml. Do not edit by hand: \
tests/test_docs.py fails when this file differs from what the generator prints. -->

A scene is one TOML file that every stage reads: the meshes to voxelize, their
materials, the charges, the simulation settings, which effects to model, a camera
and the output paths. `blastvox run SCENE.toml` builds the whole shot from it;
`voxelize --scene`, `simulate --scene` take the parts they need. The
[user guide](user-guide.md) shows the commands, and
[examples/](../examples/) holds three complete scenes.

Conventions:

* Units are SI: metres, seconds, kilograms, pascals; angles in degrees.
* Every coordinate (transforms, rule regions, charges, camera, `ground`) is in the
  scene's world frame, whose up axis is `up_axis`, the axis that points up in the
  meshes. Rule regions are tested against voxel centres after the object's
  transform.
* Relative paths are relative to the scene file.
* Unknown keys and bad values are errors. The message is one line naming the file
  and the key, e.g. `scene.toml: simulation.dtt: unknown key (did you mean 'dt'?)`.
* Names of materials and explosives, and the values of `up_axis`, `shape` and
  `fracture`, are case-insensitive.
* "unset" in the Default column means the key is optional and has no value.

An example using most tables:

```toml
{example}```
"""


@dataclass
class Row:
    key: str
    path: str
    type: str
    default: str
    unit: str
    meaning: str


@dataclass
class Section:
    title: str       # e.g. "[[objects.rules]]"
    path: str        # dotted prefix, "" for the top level
    doc: str         # the model's docstring summary
    rows: list[Row]


# --------------------------------------------------------------------------- types

def _flatten(metadata: list[Any]) -> list[Any]:
    out: list[Any] = []
    for item in metadata:
        if isinstance(item, FieldInfo):
            out += _flatten(list(item.metadata))
        else:
            out.append(item)
    return out


def _bound_text(metadata: list[Any]) -> tuple[str, bool]:
    """Constraint text from annotated-types metadata, and whether it is case-insensitive."""
    lower = upper = None
    words = []
    folded = False
    for item in metadata:
        name = type(item).__name__
        if name in ("Gt", "Ge"):
            value = item.gt if name == "Gt" else item.ge
            lower = ("(" if name == "Gt" else "[", _number(value))
        elif name in ("Lt", "Le"):
            value = item.lt if name == "Lt" else item.le
            upper = (")" if name == "Lt" else "]", _number(value))
        elif name == "MinLen":
            words.append(f"at least {item.min_length}")
        elif name == "StringConstraints" and item.min_length:
            words.append("not empty")
        elif name == "BeforeValidator" and item.func.__qualname__.startswith("_case."):
            folded = True
    if lower and upper:
        words.insert(0, f"in {lower[0]}{lower[1]}, {upper[1]}{upper[0]}")
    elif lower:
        words.insert(0, f"{'>' if lower[0] == '(' else '≥'} {lower[1]}")
    elif upper:
        words.insert(0, f"{'<' if upper[0] == ')' else '≤'} {upper[1]}")
    return ", ".join(words), folded


_VALIDATED = {
    "_vec3": "3 numbers",
    "_size3": "number or 3 numbers",
    "_path": "path",
    "_ground": '"auto", "none" or a number',
    "_material_name": "material name",
}


def _model_of(annotation: Any) -> tuple[type[BaseModel] | None, bool]:
    """The model inside ``annotation`` and whether it is a list of them."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation, False
    origin = get_origin(annotation)
    if origin is list:
        model, _ = _model_of(get_args(annotation)[0])
        return model, model is not None
    if origin is Annotated or origin in (Union, types.UnionType):
        for arg in get_args(annotation):
            model, is_list = _model_of(arg)
            if model is not None:
                return model, is_list
    return None, False


def type_text(annotation: Any, metadata: list[Any] | None = None) -> str:
    """A field type in words, e.g. ``number > 0`` or ``"cube" or "conform"``."""
    metadata = _flatten(list(metadata or []))
    origin = get_origin(annotation)
    if origin is Annotated:
        base, *extra = get_args(annotation)
        return type_text(base, [*_flatten(extra), *metadata])
    for item in metadata:
        func = getattr(item, "func", None)
        if type(item).__name__ == "BeforeValidator" and func.__name__ in _VALIDATED:
            base = _VALIDATED[func.__name__]
            bounds, _ = _bound_text(metadata)
            if hasattr(func, "bound"):  # the scene's vector and ground validators
                each = "" if func.__name__ == "_ground" else "each "
                bounds = f"{each}{_range(func.bound)}"
            return f"{base}, {bounds}" if bounds else base
    bounds, folded = _bound_text(metadata)
    if origin in (Union, types.UnionType):
        args = [a for a in get_args(annotation) if a is not type(None)]
        text = " or ".join(type_text(a) for a in args)
        return f"{text}, {bounds}" if bounds else text
    if origin is Literal:
        text = " or ".join(f'"{v}"' for v in get_args(annotation))
        return text + (" (any case)" if folded else "")
    if origin is list:
        model, _ = _model_of(annotation)
        item = type_text(get_args(annotation)[0])
        text = ("array of tables" if model
                else f"list of {item}s" if item.isalpha() else f"list of {item}")
        return f"{text}, {bounds}" if bounds else text
    if origin is dict:
        value = get_args(annotation)[1]
        return ("table of tables" if get_origin(value) is dict
                else f"table (name = {type_text(value)})")
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "table"
    names = {bool: "true or false", int: "integer", float: "number", str: "string",
             Path: "path"}
    text = names.get(annotation, getattr(annotation, "__name__", str(annotation)))
    return f"{text} {bounds}" if bounds and bounds[0] in "<>≤≥" else (
        f"{text}, {bounds}" if bounds else text)


def _number(value: Any) -> str:
    x = float(value)
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x and abs(x) < 1 and len(repr(x)) > 8 and abs(1 / x - round(1 / x)) < 1e-9:
        return f"1/{round(1 / x)}"
    if isinstance(value, int) and value >= 2**31 - 1 and (value + 1).bit_count() == 1:
        return f"2^{(value + 1).bit_length() - 1} - 1"
    return f"{x:g}" if x != int(x) or abs(x) >= 1e5 else str(int(x))


def default_text(field: FieldInfo) -> str:
    if field.is_required():
        return "required"
    value = field.get_default(call_default_factory=True)
    if value is None:
        return "unset"
    if isinstance(value, BaseModel):
        return "see below"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return _number(value)
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_number(v) if isinstance(v, int | float) else repr(v)
                               for v in value) + "]"
    if isinstance(value, dict):
        return "{}" if not value else repr(value)
    return repr(value)


# --------------------------------------------------------------------------- walking

def _title(path: str, is_list: bool) -> str:
    return f"`[[{path}]]`" if is_list else f"`[{path}]`"


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a markdown heading (without duplicate suffixes)."""
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def sections(model: type[BaseModel] = Scene, path: str = "", title: str = "Top level",
             out: list[Section] | None = None) -> list[Section]:
    """One section per table of the scene, depth first in field order."""
    out = [] if out is None else out
    section = Section(title=title, path=path, doc=_summary(model), rows=[])
    out.append(section)
    nested: list[tuple[type[BaseModel], str, str]] = []
    for name, field in model.model_fields.items():
        dotted = f"{path}.{name}" if path else name
        sub, is_list = _model_of(field.annotation)
        kind = type_text(field.annotation, list(field.metadata))
        if sub is not None:
            sub_title = _title(dotted, is_list)
            kind = f"{kind}, see [{sub_title}](#{github_anchor(sub_title)})"
            nested.append((sub, dotted, sub_title))
        elif name in ("materials", "materials_file"):
            kind = f"{kind}, see [Materials](#materials)"
        default = COMPUTED_DEFAULTS.get(dotted, default_text(field))
        if sub is not None and default == "see below":
            default = "see its table"
        section.rows.append(Row(key=name, path=dotted, type=kind, default=default,
                                unit=UNITS.get(dotted, ""), meaning=field.description or ""))
    for sub, dotted, sub_title in nested:
        sections(sub, dotted, sub_title, out)
    return out


def _summary(model: type[BaseModel]) -> str:
    doc = (model.__doc__ or "").strip()
    text = " ".join(doc.split("\n\n")[0].split())
    if model is Scene:
        return "Keys at the top of the file, before any table."
    return re.sub(r"``([^`]+)``", r"`\1`", text)


def undocumented() -> list[str]:
    """Dotted keys without a description, numeric keys without a unit, unknown material kinds."""
    problems = []
    for section in sections():
        for row in section.rows:
            if not row.meaning.strip():
                problems.append(f"{row.path}: no description")
            if ("number" in row.type or "integer" in row.type) and not row.unit:
                problems.append(f"{row.path}: no unit (add it to UNITS in "
                                f"tools/scene_reference.py)")
    descriptions = material_descriptions()
    for key, kind in _FIELD_KINDS.items():
        if kind not in MATERIAL_KINDS:
            problems.append(f"materials.{key}: kind {kind!r} not in MATERIAL_KINDS")
        if key not in MATERIAL_UNITS:
            problems.append(f"materials.{key}: no unit in MATERIAL_UNITS")
        if key not in descriptions:
            problems.append(f"materials.{key}: not in the Material docstring")
    return problems


# --------------------------------------------------------------------------- materials

def material_descriptions() -> dict[str, str]:
    """Field -> text from the ``Attributes:`` section of :class:`Material`'s docstring."""
    doc = textwrap.dedent("\n".join((Material.__doc__ or "").splitlines()[1:]))
    found: dict[str, str] = {}
    current = None
    in_attributes = False
    for line in doc.splitlines():
        if line.strip() == "Attributes:":
            in_attributes = True
            continue
        if not in_attributes:
            continue
        match = re.match(r"^    (\w+(?:, \w+)*): (.*)$", line)  # "a, b: text" gives both
        if match:
            current = match.group(1).split(", ")
            found.update({name: match.group(2).strip() for name in current})
        elif current and line.startswith("        "):
            found.update({name: found[name] + " " + line.strip() for name in current})
    found = {k: re.sub(r"(:\w+:)?``?([^`]+)``?", r"`\2`", v) for k, v in found.items()}
    # the units have their own column: drop a leading "Pa; ", "Pa s; ", "m; " or "kg/m^3."
    found = {k: re.sub(r"^(Pa s|Pa|m|kg/m\^3)[;.]\s*", "", v) for k, v in found.items()}
    found.update(MATERIAL_MEANINGS)
    return {k: v[:1].upper() + v[1:] for k, v in found.items() if v}


def _kpa(value: float) -> str:
    return "inf" if math.isinf(value) else f"{value / 1000:g}"


def materials_text() -> str:
    descriptions = material_descriptions()
    lines = [
        "## Materials", "",
        "The built-in library is `blastvox/data/materials.toml`; `blastvox materials` "
        "lists it (`--json` for scripts, `--materials FILE` with a file's additions). A "
        "scene extends it with `materials_file` (a TOML file whose top-level tables are "
        "materials) and then with inline `[materials.NAME]` tables; `blastvox voxelize "
        "--materials FILE` does the same without a scene. Material names are "
        "case-insensitive.", "",
        "A table whose name is a library material overrides the fields it gives. "
        '`base = "NAME"` copies every field of another material first (a built-in one, '
        "or one defined in the same file or scene). A new name without `base` must give "
        "every field except `description`.", "",
        "```toml",
        "[weak_brick]                 # in a materials file; [materials.weak_brick] in a scene",
        'base = "brick"',
        "link_yield_mean = 20000.0",
        "",
        "[glass]                      # overrides one field of the built-in glass",
        "damage_color = [0.9, 0.95, 0.95]",
        "```", "",
        "Yields are blast overpressures at which a building element fails, not tensile "
        "strengths. Each link, voxel and foundation draws its own yield as mean ± U(var) "
        "from the seed (Martins 2001 eq. 4-1); a link takes the weaker material of its "
        "two voxels. See [physics.md](physics.md) for how each value is used.", "",
        "| key | type | units | meaning |",
        "|---|---|---|---|",
        '| `base` | string | | Material to copy every field from before this table\'s '
        "own fields apply. |",
    ]
    for key, kind in _FIELD_KINDS.items():
        lines.append(f"| `{key}` | {MATERIAL_KINDS.get(kind, kind)} | "
                     f"{MATERIAL_UNITS.get(key, '')} | {_cell(descriptions.get(key, ''))} |")
    lines += ["", "### Built-in materials", "",
              "Yields in kPa, as mean ± variance (the half-width of the uniform "
              "perturbation); inf: never (steel never turns to dust, only wood and thatch "
              "burn).", "",
              "| name | density kg/m³ | link yield kPa | voxel yield kPa | foundation yield "
              "kPa | restitution | combustibility kPa | description |",
              "|---|--:|--:|--:|--:|--:|--:|---|"]
    for name, m in MaterialLibrary.builtin().items():
        voxel = ("inf" if math.isinf(m.voxel_yield_mean)
                 else f"{_kpa(m.voxel_yield_mean)} ± {_kpa(m.voxel_yield_var)}")
        lines.append(
            f"| `{name}` | {m.density:g} | {_kpa(m.link_yield_mean)} ± "
            f"{_kpa(m.link_yield_var)} | {voxel} | {_kpa(m.foundation_yield)} | "
            f"{m.restitution:g} | {_kpa(m.combustibility)} | {_cell(m.description)} |")
    return "\n".join(lines) + "\n"


def explosives_text() -> str:
    aliases: dict[str, list[str]] = {}
    for alias, name in sorted(EXPLOSIVE_ALIASES.items()):
        aliases.setdefault(name, []).append(alias)
    lines = ["## Explosives", "",
             "`charges.explosive` (and `--explosive`) names an explosive whose mass is "
             "converted to TNT-equivalent kg. Case, spaces, `-` and `_` are ignored. "
             "Factors from UFC 3-340-02 (2008) Table 2-1 where it lists them, otherwise "
             "the ratio of heats of detonation in Karlos & Solomos (2013) Table 1 (see "
             "[physics.md](physics.md#sources)).", "",
             "| explosive | kg TNT per kg | also accepted |", "|---|--:|---|"]
    for name, factor in TNT_EQUIVALENTS.items():
        also = ", ".join(f"`{a}`" for a in aliases.get(name, []))
        lines.append(f"| `{name}` | {factor:g} | {also} |")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- output

def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def render() -> str:
    """The whole of docs/scene-reference.md."""
    parts = [INTRO.format(example=EXAMPLE)]
    all_sections = sections()
    parts.append("Tables: " + ", ".join(
        f"[{s.title}](#{github_anchor(s.title)})" for s in all_sections)
        + ", [Materials](#materials), [Explosives](#explosives).\n")
    for section in all_sections:
        lines = [f"## {section.title}", ""]
        if section.doc:
            lines += [section.doc, ""]
        lines += ["| key | type | default | units | meaning |", "|---|---|---|---|---|"]
        for row in section.rows:
            lines.append(f"| `{row.key}` | {_cell(row.type)} | {_cell(row.default)} | "
                         f"{row.unit} | {_cell(row.meaning)} |")
        parts.append("\n".join(lines) + "\n")
    parts.append(materials_text())
    parts.append(explosives_text())
    return "\n".join(parts)


def check_example() -> None:
    """Validate the reference's example against the schema (no files are read)."""
    import tomllib

    scene_from_dict(tomllib.loads(EXAMPLE), "scene-reference example", ROOT)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help=f"compare with {OUTPUT.relative_to(ROOT)} instead of printing; "
                             "exit 1 if it differs")
    args = parser.parse_args(argv)
    text = render()
    if not args.check:
        sys.stdout.write(text)
        return 0
    current = OUTPUT.read_text(encoding="utf-8") if OUTPUT.exists() else ""
    problems = undocumented()
    for problem in problems:
        print(f"scene_reference: {problem}", file=sys.stderr)
    if current != text:
        sys.stderr.writelines(difflib.unified_diff(
            current.splitlines(keepends=True), text.splitlines(keepends=True),
            str(OUTPUT.relative_to(ROOT)), "generated"))
        print("scene_reference: docs/scene-reference.md is stale; run "
              "python tools/scene_reference.py > docs/scene-reference.md", file=sys.stderr)
        return 1
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
