"""Materials: per-voxel physical and destruction parameters.

A :class:`Material` holds what the simulator needs per voxel (Martins 2001 §4.2
and §6): density, link and voxel yield limits with their random variance,
foundation yield, coefficient of restitution, combustibility, and the colours
of outside and fracture faces.

Yield limits are *effective blast overpressure thresholds* (Pa) for destroying
a building element, not tensile strengths. The built-in library
(``blastvox/data/materials.toml``) calibrates link yields against the failure
overpressures of building elements in Glasstone & Dolan (1977), "The Effects of
Nuclear Weapons", Table 5.139 (glass windows 0.5-1 psi, wood siding panels
1-2 psi, unreinforced concrete/cinder-block wall panels 1.5-2 psi, unreinforced
brick wall panels 7-8 psi); the other materials are set by analogy, as the file
notes.

User libraries are TOML files whose top-level tables are materials::

    [weak_brick]
    base = "brick"               # inherit every field, then override
    link_yield_mean = 20000.0

A table without ``base`` that names an existing material overrides that
material's fields; a new name without ``base`` must give every field
(``description`` is optional).
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields, replace
from functools import cache
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from blastvox.bounds import MAX_TOML_BYTES, Bound, printable, regular_file
from blastvox.damage_look import PATTERNS
from blastvox.errors import BlastvoxError, ContractError, InputError, MaterialError

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class Material:
    """One material. All quantities SI; yields are blast overpressures.

    Attributes:
        name: Lower-case library name.
        density: kg/m^3.
        link_yield_mean: Pa; overpressure at a link midpoint that breaks the link.
        link_yield_var: Pa; half-width of the uniform perturbation of the link yield.
        voxel_yield_mean: Pa; overpressure at a voxel centre that turns it to dust.
        voxel_yield_var: Pa; half-width of the uniform perturbation of the voxel yield.
        foundation_yield: Pa; foundation strength, diminished by the overpressure at
            the voxel centre until the voxel stops being a foundation voxel.
        restitution: Coefficient of restitution, 0 (inelastic) .. 1 (elastic).
        combustibility: Pa of scaled overpressure needed to ignite; ``inf`` never burns.
        color: Linear RGB 0..1 of outside faces.
        damage_color: Linear RGB 0..1 of faces that were inside the object.
        description: Free text, including the source of the values.
        link_impulse: Pa s; impulse asymptote of the pressure-impulse criterion of a
            link, for an element 0.25 m thick (scaled with the thickness); 0 = peak
            pressure only (the papers' model). See docs/physics.md.
        voxel_impulse: Pa s; the same for a voxel turning to dust.
        pi_shape: K / (P0 I0) of the hyperbola (P - P0)(I - I0) = K (0 = two
            independent asymptotes).
        compressive_strength, tensile_strength, shear_strength: Pa; the stresses
            a link carries under gravity and impact before it breaks (the stress
            solver, :mod:`blastvox.simulate.stress`); ``inf`` = never.
        youngs_modulus: Pa; the links' stiffness, which shares loads between the
            paths of a statically indeterminate structure.
        crush_pressure: Pa; under pressure-impulse fracture, the face or impact
            pressure below which a voxel never turns to dust (its compressive
            strength for a quasi-brittle solid); 0 = the voxel yield alone decides.
        chunk_size: m; mean size of the chunks voxelize groups voxels into (0 =
            every voxel its own chunk).
        chunk_weibull: Weibull modulus of the chunk volumes (large = uniform).
        chunk_bond_scale: factor (>= 1) on the strength of links inside a chunk.
        damage_pattern: the texture drawn on fracture faces on export, one of
            :data:`blastvox.damage_look.PATTERNS`; "" = the pattern named like the
            material (:func:`blastvox.damage_look.pattern_for`).
    """

    name: str
    density: float
    link_yield_mean: float
    link_yield_var: float
    voxel_yield_mean: float
    voxel_yield_var: float
    foundation_yield: float
    restitution: float
    combustibility: float
    color: RGB
    damage_color: RGB
    description: str = ""
    link_impulse: float = 0.0
    voxel_impulse: float = 0.0
    pi_shape: float = 0.0
    compressive_strength: float = math.inf
    tensile_strength: float = math.inf
    shear_strength: float = math.inf
    youngs_modulus: float = 30e9
    crush_pressure: float = 0.0
    chunk_size: float = 0.0
    chunk_weibull: float = 2.0
    chunk_bond_scale: float = 1.0
    damage_pattern: str = ""


# Field name -> kind; the kind selects the check in _check_field.
_FIELD_KINDS: dict[str, str] = {
    "density": "positive",
    "link_yield_mean": "threshold",
    "link_yield_var": "variance",
    "voxel_yield_mean": "threshold",
    "voxel_yield_var": "variance",
    "foundation_yield": "threshold",
    "restitution": "unit",
    "combustibility": "threshold",
    "color": "rgb",
    "damage_color": "rgb",
    "description": "text",
    "link_impulse": "impulse",
    "voxel_impulse": "impulse",
    "pi_shape": "shape",
    "compressive_strength": "strength",
    "tensile_strength": "strength",
    "shear_strength": "strength",
    "youngs_modulus": "modulus",
    "crush_pressure": "threshold",
    "chunk_size": "length",
    "chunk_weibull": "weibull",
    "chunk_bond_scale": "bond_scale",
    "damage_pattern": "pattern",
}
#: The range of each numeric kind (documented in docs/user-guide.md, Limits): finite
#: limits keep the simulator's products of yields, impulses and areas far from overflow.
MAX_DENSITY = 1e5        # kg/m^3 (osmium: 22,590)
MAX_PRESSURE_PA = 1e12   # a yield or threshold; inf means "never"
MAX_IMPULSE_PA_S = 1e9
MAX_PI_SHAPE = 1e6
MAX_MODULUS_PA = 1e13    # diamond: 1.2e12
MAX_CHUNK_M = 1e4
_BOUNDS: dict[str, Bound] = {
    "positive": Bound(0.0, MAX_DENSITY, lo_open=True, unit="kg/m^3"),
    "threshold": Bound(0.0, MAX_PRESSURE_PA, unit="Pa", allow_inf=True),
    "variance": Bound(0.0, MAX_PRESSURE_PA, unit="Pa"),
    "impulse": Bound(0.0, MAX_IMPULSE_PA_S, unit="Pa s"),
    "shape": Bound(0.0, MAX_PI_SHAPE),
    "unit": Bound(0.0, 1.0, interval=True),
    "strength": Bound(0.0, MAX_PRESSURE_PA, lo_open=True, unit="Pa", allow_inf=True),
    "modulus": Bound(0.0, MAX_MODULUS_PA, lo_open=True, unit="Pa"),
    "length": Bound(0.0, MAX_CHUNK_M, unit="m"),
    "weibull": Bound(0.1, 100.0),
    "bond_scale": Bound(1.0, 1e6),
}
_OPTIONAL = ("description", "link_impulse", "voxel_impulse", "pi_shape",
             "compressive_strength", "tensile_strength", "shear_strength", "youngs_modulus",
             "crush_pressure", "chunk_size", "chunk_weibull", "chunk_bond_scale", "damage_pattern")
_REQUIRED = [k for k in _FIELD_KINDS if k not in _OPTIONAL]
_SCALARS = [k for k, kind in _FIELD_KINDS.items() if kind not in ("rgb", "text", "pattern")]
_TOML_POSITION = re.compile(r"\s*\(at (line \d+, column \d+|end of document)\)$")


def read_toml(path: Path, error: type[BlastvoxError]) -> dict[str, Any]:
    """Read a TOML file, turning every failure into a one-line ``error`` naming ``path``."""
    path = Path(path)
    shown = printable(path)
    try:
        regular_file(path, "TOML file", MAX_TOML_BYTES)
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
        _check_depth(data, shown, error)
        return data
    except RecursionError:  # tomllib parses nested arrays and tables recursively
        raise error(f"{shown}: nested more than Python can parse; a scene or materials "
                    f"file nests at most {MAX_TOML_DEPTH} levels") from None
    except FileNotFoundError:
        raise error(f"{shown}: file not found") from None
    except IsADirectoryError:
        raise error(f"{shown}: is a directory, not a TOML file") from None
    except InputError as exc:
        raise error(str(exc)) from None
    except OSError as exc:
        raise error(f"{shown}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise error(f"{shown}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        text = str(exc)
        match = _TOML_POSITION.search(text)
        if match:
            text = f"at {match.group(1)}: {text[: match.start()]}"
        raise error(f"{shown}: TOML syntax error {text}") from None


#: The deepest nesting of tables and arrays a TOML input may have (a scene nests 4).
MAX_TOML_DEPTH = 32


def _check_depth(data: Any, shown: str, error: type[BlastvoxError]) -> None:
    """Refuse TOML data nested deeper than :data:`MAX_TOML_DEPTH` (walked without
    recursion: later stages walk it recursively)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_TOML_DEPTH:
            raise error(f"{shown}: nested more than {MAX_TOML_DEPTH} levels deep (tables and "
                        "arrays); a scene or materials file nests a few")
        children = value.values() if isinstance(value, dict) else (
            value if isinstance(value, list) else ())
        stack.extend((child, depth + 1) for child in children
                     if isinstance(child, dict | list))


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MaterialError(f"{where}: must be a number (got {value!r})")
    number = float(value)
    if math.isnan(number):
        raise MaterialError(f"{where}: must not be nan")
    return number


def _check_field(key: str, value: Any, where: str) -> Any:
    """Validate one material field from a TOML table and return its stored form."""
    kind = _FIELD_KINDS[key]
    if kind == "text":
        if not isinstance(value, str):
            raise MaterialError(f"{where}: must be a string (got {value!r})")
        return value
    if kind == "pattern":
        if value != "" and value not in PATTERNS:
            close = difflib.get_close_matches(str(value), list(PATTERNS), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise MaterialError(f"{where}: unknown damage pattern {value!r} "
                                f"(known: {', '.join(PATTERNS)}){hint}")
        return value
    if kind == "rgb":
        if not isinstance(value, list | tuple) or len(value) != 3:
            raise MaterialError(f"{where}: must be a list of 3 numbers in [0, 1] (got {value!r})")
        rgb = tuple(_number(c, where) for c in value)
        if not all(0.0 <= c <= 1.0 for c in rgb):
            raise MaterialError(f"{where}: components must be in [0, 1] (got {list(rgb)})")
        return rgb
    try:
        return _BOUNDS[kind].check(value)
    except ValueError as exc:
        raise MaterialError(f"{where}: {exc}") from None


def _normalise(name: Any, where: str) -> str:
    if not isinstance(name, str) or not name.strip():
        raise MaterialError(f"{where}: material name must be a non-empty string (got {name!r})")
    return name.strip().lower()


class MaterialLibrary(Mapping[str, Material]):
    """Immutable, case-insensitive mapping from material name to :class:`Material`."""

    __slots__ = ("_materials",)

    def __init__(self, materials: Mapping[str, Material] | None = None) -> None:
        """Wrap ``materials`` (name -> Material); names are normalised to lower case."""
        items = {m.name.strip().lower(): m for m in (materials or {}).values()}
        self._materials: Mapping[str, Material] = MappingProxyType(items)

    @classmethod
    def builtin(cls) -> MaterialLibrary:
        """The library shipped in ``blastvox/data/materials.toml``."""
        return _builtin()

    @classmethod
    def load(cls, path: Path | None) -> MaterialLibrary:
        """The built-in library extended by the TOML file at ``path`` (if not None)."""
        library = cls.builtin()
        if path is None:
            return library
        return library.extended(read_toml(Path(path), MaterialError), str(path))

    def extended(self, table: Mapping[str, Any], source: str, prefix: str = "") -> MaterialLibrary:
        """A new library with the materials of ``table`` added or overridden.

        Each entry maps a material name to a table of fields. ``base = "name"``
        inherits every field from that material (of this library, or earlier or
        later in ``table``) before the entry's own fields override them.
        Errors name ``source``, then ``prefix`` + material + key.
        """
        if not isinstance(table, Mapping):
            raise MaterialError(f"{source}: {prefix or 'materials'}: must be a table of materials")
        raw: dict[str, tuple[str, Mapping[str, Any]]] = {}
        for key, entry in table.items():
            where = f"{source}: {prefix}{key}"
            name = _normalise(key, where)
            if name in raw:
                raise MaterialError(f"{where}: defined twice (names are case-insensitive)")
            if not isinstance(entry, Mapping):
                raise MaterialError(f"{where}: must be a table of material fields (got {entry!r})")
            raw[name] = (key, entry)

        new = dict(self._materials)
        done: set[str] = set()
        resolving: set[str] = set()

        def resolve(name: str) -> Material:
            if name in done:
                return new[name]
            key, entry = raw[name]
            where = f"{source}: {prefix}{key}"
            resolving.add(name)
            parent = self._materials.get(name)
            if "base" in entry:
                base = _normalise(entry["base"], f"{where}.base")
                if base in resolving and base != name:
                    raise MaterialError(f"{where}.base: circular inheritance via '{base}'")
                if base in raw and base != name:
                    parent = resolve(base)
                elif base in self._materials:
                    parent = self._materials[base]
                else:
                    known = [n for n in (*new, *raw) if n != name]
                    raise MaterialError(f"{where}.base: {_unknown(base, known)}")
            values = {}
            for field, value in entry.items():
                if field == "base":
                    continue
                if field not in _FIELD_KINDS:
                    raise MaterialError(f"{where}.{field}: unknown key{_suggest(field)}")
                values[field] = _check_field(field, value, f"{where}.{field}")
            if parent is not None:
                material = replace(parent, name=name, **values)
            else:
                missing = [k for k in _REQUIRED if k not in values]
                if missing:
                    raise MaterialError(
                        f"{where}: new material is missing {', '.join(missing)} "
                        "(give them, or inherit with base = \"<material>\")"
                    )
                material = Material(name=name, **values)
            new[name] = material
            done.add(name)
            resolving.discard(name)
            return material

        for name in raw:
            resolve(name)
        return MaterialLibrary(new)

    def names(self) -> list[str]:
        """Material names in library order (built-ins first, then additions)."""
        return list(self._materials)

    def __getitem__(self, name: str) -> Material:
        """Look up ``name`` case-insensitively; unknown names raise :class:`MaterialError`."""
        key = name.strip().lower() if isinstance(name, str) else name
        try:
            return self._materials[key]
        except (KeyError, TypeError):
            raise MaterialError(_unknown(name, self._materials)) from None

    def get(self, name: str, default: Material | None = None) -> Material | None:
        """Like ``lib[name]`` but returns ``default`` for an unknown name."""
        return self[name] if name in self else default

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.strip().lower() in self._materials

    def __iter__(self) -> Iterator[str]:
        return iter(self._materials)

    def __len__(self) -> int:
        return len(self._materials)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, MaterialLibrary):
            return NotImplemented
        return dict(self._materials) == dict(other._materials)

    def __repr__(self) -> str:
        return f"MaterialLibrary({', '.join(self._materials)})"


def _unknown(name: object, known: Any) -> str:
    return f"unknown material {name!r} (known: {', '.join(sorted(set(known)))})"


def field_names() -> list[str]:
    """The keys a material table may set (besides ``base``), in the library's order."""
    return list(_FIELD_KINDS)


def _suggest(key: str) -> str:
    close = difflib.get_close_matches(key, list(_FIELD_KINDS), n=1)
    if close:
        return f" (did you mean '{close[0]}'?)"
    return f" (known: base, {', '.join(_FIELD_KINDS)})"


@cache
def _builtin() -> MaterialLibrary:
    text = resources.files("blastvox").joinpath("data/materials.toml").read_text("utf-8")
    return MaterialLibrary().extended(tomllib.loads(text), "built-in materials.toml")


def perturbed(mean: float | np.ndarray, var: float | np.ndarray, rng: np.random.Generator,
              n: int) -> np.ndarray:
    """Random yield limits ``mean + U(-var, var)`` (Martins 2001, eq. 4-1), in Pa.

    ``mean`` and ``var`` are scalars or arrays broadcastable to ``(n,)``. The
    result is float64 of shape ``(n,)``, clipped at 0; an infinite mean stays
    infinite. Exactly ``n`` uniforms are always drawn, so the random stream
    consumed does not depend on the values.
    """
    if n < 0:
        raise ValueError(f"n must be >= 0 (got {n})")
    mean_a = np.broadcast_to(np.asarray(mean, dtype=np.float64), (n,))
    var_a = np.broadcast_to(np.asarray(var, dtype=np.float64), (n,))
    if np.isnan(mean_a).any() or not (np.isfinite(var_a) & (var_a >= 0.0)).all():
        raise ValueError("mean must not be nan and var must be finite and >= 0")
    return np.maximum(mean_a + var_a * rng.uniform(-1.0, 1.0, n), 0.0)


def material_table(lib: MaterialLibrary, names: list[str]) -> dict[str, np.ndarray]:
    """Flat arrays describing the materials ``names`` (in that order), for a ``.npz``.

    Keys are ``material_<field>``: float64 ``(M,)`` for scalar fields, float64
    ``(M, 3)`` for ``material_color`` and ``material_damage_color``, and a
    unicode ``(M,)`` arrays ``material_description`` and ``material_damage_pattern``
    (no pickles needed).
    The names themselves are not included; store them alongside.
    """
    materials = [lib[n] for n in names]
    table = {
        f"material_{k}": np.array([getattr(m, k) for m in materials], dtype=np.float64)
        for k in _SCALARS
    }
    for k in ("color", "damage_color"):
        table[f"material_{k}"] = np.array(
            [getattr(m, k) for m in materials], dtype=np.float64).reshape(len(materials), 3)
    table["material_description"] = np.array([m.description for m in materials], dtype=np.str_)
    table["material_damage_pattern"] = np.array([m.damage_pattern for m in materials],
                                                dtype=np.str_)
    return table


def materials_from_table(names: list[str], arrays: Mapping[str, np.ndarray]) -> list[Material]:
    """Inverse of :func:`material_table`; raises :class:`ContractError` if arrays are malformed."""
    count = len(names)
    columns: dict[str, np.ndarray] = {}
    for f in fields(Material):
        if f.name == "name":
            continue
        key = f"material_{f.name}"
        if key not in arrays:
            if f.name in _OPTIONAL:
                continue
            raise ContractError(f"material table: missing array {key!r}")
        column = np.asarray(arrays[key])
        shape = (count, 3) if f.name in ("color", "damage_color") else (count,)
        if column.shape != shape:
            raise ContractError(f"material table: {key} has shape {column.shape}, expected {shape}")
        columns[f.name] = column
    result = []
    for i, name in enumerate(names):
        values: dict[str, Any] = {k: float(columns[k][i]) for k in _SCALARS if k in columns}
        for k in ("color", "damage_color"):
            values[k] = tuple(float(c) for c in columns[k][i])
        for k in ("description", "damage_pattern"):
            if k in columns:
                values[k] = str(columns[k][i])
        result.append(Material(name=name, **values))
    return result
