"""Tests for blastvox.materials: the built-in library, user extensions, perturbation, tables."""

from __future__ import annotations

import math
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from blastvox.errors import BlastvoxError, ContractError, MaterialError
from blastvox.materials import (
    Material,
    MaterialLibrary,
    material_table,
    materials_from_table,
    perturbed,
)

PSI = 6894.757  # Pa


@pytest.fixture(scope="module")
def lib() -> MaterialLibrary:
    return MaterialLibrary.builtin()


def test_builtin_has_required_materials(lib: MaterialLibrary) -> None:
    for name in ("concrete", "brick", "stone", "wood", "glass", "steel", "plaster",
                 "reinforced_concrete", "drywall"):
        assert name in lib
        assert lib[name].name == name
    assert len(lib) == len(lib.names()) == len(list(lib))


@pytest.mark.parametrize(("name", "lo_psi", "hi_psi"), [
    ("glass", 0.5, 1.0), ("wood", 1.0, 2.0), ("concrete", 1.5, 2.0), ("brick", 7.0, 8.0),
])
def test_link_yields_match_glasstone_table_5_139(lib: MaterialLibrary, name: str,
                                                 lo_psi: float, hi_psi: float) -> None:
    m = lib[name]
    assert lo_psi * PSI <= m.link_yield_mean <= hi_psi * PSI
    assert lo_psi * PSI - 100 <= m.link_yield_mean - m.link_yield_var
    assert m.link_yield_mean + m.link_yield_var <= hi_psi * PSI + 100


def test_builtin_values_are_physically_ordered(lib: MaterialLibrary) -> None:
    assert lib["concrete"].density == 2400.0
    assert lib["brick"].density == 1900.0
    assert lib["steel"].density == 7850.0
    for m in lib.values():
        assert m.voxel_yield_mean >= 1.5 * m.link_yield_mean
        assert m.foundation_yield > m.link_yield_mean
        assert m.foundation_yield > m.voxel_yield_mean or math.isinf(m.voxel_yield_mean)
        assert 0.0 <= m.restitution <= 1.0
        assert m.description
    burning = {m.name for m in lib.values() if math.isfinite(m.combustibility)}
    assert "wood" in burning
    assert burning <= {"wood", "thatch", "timber"}
    link = {name: m.link_yield_mean for name, m in lib.items()}
    assert link["glass"] < link["concrete"] < link["brick"] < link["reinforced_concrete"]


def test_lookup_is_case_insensitive_and_unknown_lists_known(lib: MaterialLibrary) -> None:
    assert lib["  Brick "] is lib["brick"]
    assert "GLASS" in lib and "nope" not in lib and 3 not in lib
    assert lib.get("nope") is None
    with pytest.raises(MaterialError, match=r"unknown material 'nope' \(known: brick, concrete"):
        lib["nope"]


def test_material_error_is_blastvox_error() -> None:
    assert issubclass(MaterialError, BlastvoxError)


def test_library_is_immutable(lib: MaterialLibrary) -> None:
    with pytest.raises(TypeError):
        lib["x"] = lib["brick"]  # type: ignore[index]
    with pytest.raises(AttributeError):
        lib["brick"].density = 1.0  # type: ignore[misc]


def test_extended_base_overrides_only_given_fields(lib: MaterialLibrary) -> None:
    new = lib.extended({"Weak_Brick": {"base": "BRICK", "link_yield_mean": 20000}}, "x.toml")
    weak, brick = new["weak_brick"], lib["brick"]
    assert weak.name == "weak_brick"
    assert weak.link_yield_mean == 20000.0 and isinstance(weak.link_yield_mean, float)
    for f in fields(Material):
        if f.name not in ("name", "link_yield_mean"):
            assert getattr(weak, f.name) == getattr(brick, f.name)
    assert "weak_brick" not in lib  # the original is untouched
    assert new.names()[: len(lib)] == lib.names()


def test_extended_redefinition_without_base_overrides_existing(lib: MaterialLibrary) -> None:
    new = lib.extended({"glass": {"restitution": 0.9}}, "x.toml")
    assert new["glass"].restitution == 0.9
    assert new["glass"].density == lib["glass"].density


def test_extended_base_within_same_table_any_order(lib: MaterialLibrary) -> None:
    new = lib.extended({"b": {"base": "a", "density": 10}, "a": {"base": "stone", "density": 5}},
                       "x.toml")
    assert new["b"].density == 10 and new["a"].density == 5
    assert new["b"].link_yield_mean == lib["stone"].link_yield_mean


def test_new_material_needs_all_fields(lib: MaterialLibrary) -> None:
    full = {f.name: getattr(lib["wood"], f.name) for f in fields(Material) if f.name != "name"}
    full["color"] = list(full["color"])
    assert lib.extended({"oak": full}, "x.toml")["oak"] == Material(name="oak", **{
        **full, "color": tuple(full["color"])})
    del full["restitution"]
    with pytest.raises(MaterialError, match=r"^x\.toml: oak: new material is missing restitution"):
        lib.extended({"oak": full}, "x.toml")


@pytest.mark.parametrize(("entry", "pattern"), [
    ({"base": "brick", "densty": 1.0}, r"m\.densty: unknown key \(did you mean 'density'\?\)"),
    ({"base": "brick", "density": -5.0}, r"m\.density: must be > 0"),
    ({"base": "brick", "density": 0}, r"m\.density: must be > 0"),
    ({"base": "brick", "density": "heavy"}, r"m\.density: must be a number"),
    ({"base": "brick", "density": True}, r"m\.density: must be a number"),
    ({"base": "brick", "restitution": 1.5}, r"m\.restitution: must be in \[0, 1\]"),
    ({"base": "brick", "restitution": -0.1}, r"m\.restitution: must be in \[0, 1\]"),
    ({"base": "brick", "color": [1, 1]}, r"m\.color: must be a list of 3 numbers"),
    ({"base": "brick", "color": [0.5, 0.5, 2.0]}, r"m\.color: components must be in \[0, 1\]"),
    ({"base": "brick", "damage_color": "red"}, r"m\.damage_color: must be a list of 3"),
    ({"base": "brick", "link_yield_var": math.inf}, r"m\.link_yield_var: must be finite"),
    ({"base": "brick", "link_yield_mean": -1}, r"m\.link_yield_mean: must be >= 0"),
    ({"base": "brick", "link_yield_mean": math.nan}, r"m\.link_yield_mean: must not be nan"),
    ({"base": "brick", "description": 5}, r"m\.description: must be a string"),
    ({"base": "nope"}, r"m\.base: unknown material 'nope'"),
    ({"base": 3}, r"m\.base: material name must be a non-empty string"),
])
def test_extended_errors_name_source_material_and_key(lib: MaterialLibrary, entry: dict,
                                                      pattern: str) -> None:
    with pytest.raises(MaterialError, match=r"^my\.toml: " + pattern):
        lib.extended({"m": entry}, "my.toml")


def test_extended_structural_errors(lib: MaterialLibrary) -> None:
    with pytest.raises(MaterialError, match=r"^s: m: must be a table"):
        lib.extended({"m": 3}, "s")
    with pytest.raises(MaterialError, match=r"circular inheritance"):
        lib.extended({"a": {"base": "b"}, "b": {"base": "a"}}, "s")
    with pytest.raises(MaterialError, match=r"defined twice"):
        lib.extended({"a": {"base": "brick"}, "A": {"base": "brick"}}, "s")
    with pytest.raises(MaterialError, match=r"^s: materials\.m\.density: must be > 0"):
        lib.extended({"m": {"base": "brick", "density": -1}}, "s", prefix="materials.")


def test_inf_allowed_for_thresholds(lib: MaterialLibrary) -> None:
    new = lib.extended({"m": {"base": "wood", "combustibility": math.inf,
                              "voxel_yield_mean": math.inf}}, "s")
    assert math.isinf(new["m"].combustibility) and math.isinf(new["m"].voxel_yield_mean)


def test_load_user_file(tmp_path: Path, lib: MaterialLibrary) -> None:
    path = tmp_path / "lib.toml"
    path.write_text('[oak]\nbase = "wood"\ncombustibility = inf\nlink_yield_mean = 15e3\n')
    loaded = MaterialLibrary.load(path)
    assert math.isinf(loaded["oak"].combustibility)
    assert loaded["oak"].link_yield_mean == 15000.0
    assert loaded["brick"] == lib["brick"]
    assert MaterialLibrary.load(None) == lib


def test_load_errors_are_one_line_and_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(MaterialError, match=r"missing\.toml: file not found$"):
        MaterialLibrary.load(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text('[oak]\nbase = "wood"\ndensity = = 3\n')
    with pytest.raises(MaterialError) as info:
        MaterialLibrary.load(bad)
    message = str(info.value)
    assert message.startswith(f"{bad}: TOML syntax error at line 3")
    assert "\n" not in message
    bad.write_text("[oak]\ndensity = 3\n")
    with pytest.raises(MaterialError, match=r"bad\.toml: oak: new material is missing"):
        MaterialLibrary.load(bad)


def test_perturbed_basic() -> None:
    rng = np.random.default_rng(1)
    out = perturbed(100.0, 10.0, rng, 1000)
    assert out.dtype == np.float64 and out.shape == (1000,)
    assert out.min() >= 90.0 and out.max() <= 110.0
    assert out.std() > 1.0  # actually random
    assert np.all(perturbed(math.inf, 5.0, rng, 4) == math.inf)
    assert np.all(perturbed(1.0, 5.0, np.random.default_rng(0), 1000) >= 0.0)
    assert np.any(perturbed(1.0, 5.0, np.random.default_rng(0), 1000) == 0.0)
    per_element = perturbed(np.array([1.0, 1e6, math.inf]), np.array([0.0, 1.0, 1.0]), rng, 3)
    assert per_element[0] == 1.0 and abs(per_element[1] - 1e6) <= 1.0 and per_element[2] == math.inf
    assert perturbed(1.0, 1.0, rng, 0).shape == (0,)
    with pytest.raises(ValueError):
        perturbed(1.0, -1.0, rng, 3)


@given(mean=st.floats(0.0, 1e9), var=st.floats(0.0, 1e9), seed=st.integers(0, 2**32),
       n=st.integers(0, 64))
def test_perturbed_bounds_and_determinism(mean: float, var: float, seed: int, n: int) -> None:
    a = perturbed(mean, var, np.random.default_rng(seed), n)
    b = perturbed(mean, var, np.random.default_rng(seed), n)
    assert a.shape == (n,)
    assert np.array_equal(a, b)
    assert np.all(a >= 0.0)
    assert np.all(a >= mean - var) and np.all(a <= mean + var)


def test_perturbed_draws_same_stream_regardless_of_values() -> None:
    r1, r2 = np.random.default_rng(5), np.random.default_rng(5)
    perturbed(math.inf, 0.0, r1, 10)
    perturbed(3.0, 2.0, r2, 10)
    assert r1.random() == r2.random()


def test_material_table_round_trip(lib: MaterialLibrary, tmp_path: Path) -> None:
    names = ["steel", "wood", "glass"]
    table = material_table(lib, names)
    assert table["material_density"].tolist() == [7850.0, 600.0, 2500.0]
    assert table["material_color"].shape == (3, 3)
    assert table["material_damage_color"].shape == (3, 3)
    assert all(not a.dtype.hasobject for a in table.values())
    np.savez(tmp_path / "t.npz", **table)
    with np.load(tmp_path / "t.npz", allow_pickle=False) as data:
        restored = materials_from_table(names, dict(data))
    assert restored == [lib[n] for n in names]


def test_materials_from_table_rejects_malformed(lib: MaterialLibrary) -> None:
    table = material_table(lib, ["brick"])
    with pytest.raises(ContractError, match="material_density"):
        materials_from_table(["brick", "wood"], table)
    del table["material_restitution"]
    with pytest.raises(ContractError, match="missing array 'material_restitution'"):
        materials_from_table(["brick"], table)
