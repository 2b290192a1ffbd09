"""The documentation stays true to the code.

* docs/scene-reference.md is what tools/scene_reference.py prints from the scene
  schema, and every scene key has a description (and a unit if it is a number);
* every relative link in README.md and docs/*.md points at a file that exists
  (and, into a markdown file, at a heading that exists);
* every array named in the VoxelModel and SimCache tables of docs/file-formats.md
  is one the code knows, and every array a loader requires is in the tables;
* every option of every command is in the user guide's section for it;
* the README keeps the two fresh-machine commands that CI runs.
"""

from __future__ import annotations

import importlib.util
import re
import sys
import tomllib
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
MARKDOWN = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
#: Written by another change; links to it are checked once it exists.
NOT_YET = {DOCS / "developing.md"}


def _generator() -> ModuleType:
    name = "scene_reference"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / "scene_reference.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up while it loads
        spec.loader.exec_module(module)
    return sys.modules[name]


# ------------------------------------------------------------------ scene reference

def test_scene_reference_is_generated_from_the_schema():
    expected = _generator().render()
    current = (DOCS / "scene-reference.md").read_text(encoding="utf-8")
    assert current == expected, (
        "docs/scene-reference.md differs from the schema: run "
        "`python tools/scene_reference.py > docs/scene-reference.md` and commit it")


def test_every_scene_key_is_documented():
    assert _generator().undocumented() == [], (
        "give each new scene key a Field(description=...) in blastvox/scene.py and, if it "
        "is a number, a unit in tools/scene_reference.py UNITS")


def test_scene_examples_are_valid_scenes():
    from blastvox.scene import scene_from_dict

    _generator().check_example()
    blocks = re.findall(r"```toml\n(.*?)```", (ROOT / "README.md").read_text("utf-8"), re.S)
    assert blocks, "README.md has no scene example"
    for block in blocks:
        scene_from_dict(tomllib.loads(block), "README.md", ROOT)


# ------------------------------------------------------------------ links

def _prose(text: str) -> str:
    """Markdown without fenced code blocks and inline code spans."""
    text = re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def _anchors(path: Path) -> set[str]:
    slug = _generator().github_anchor
    seen: dict[str, int] = {}
    out = set()
    for line in _prose_lines(path):
        match = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not match:
            continue
        base = slug(match.group(1))
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f"{base}-{count}")
    return out


def _prose_lines(path: Path) -> list[str]:
    """Lines outside fenced code blocks (headings keep their inline code)."""
    lines, fenced = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith(("```", "~~~")):
            fenced = not fenced
        elif not fenced:
            lines.append(line)
    return lines


def _links(path: Path) -> list[str]:
    return re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", _prose(path.read_text("utf-8")))


@pytest.mark.parametrize("doc", MARKDOWN, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_at_existing_files(doc: Path):
    broken = []
    for link in _links(doc):
        if re.match(r"^[a-z][a-z0-9+.-]*:", link):  # http:, https:, mailto:
            continue
        target, _, fragment = link.partition("#")
        path = (doc.parent / target).resolve() if target else doc
        if path in NOT_YET and not path.exists():
            continue
        if not path.exists():
            broken.append(f"{link}: no such file")
        elif fragment and path.suffix == ".md" and fragment not in _anchors(path):
            broken.append(f"{link}: no heading #{fragment} in {path.relative_to(ROOT)}")
    assert not broken, f"{doc.relative_to(ROOT)}: " + "; ".join(broken)


def test_the_link_check_sees_links():
    readme = _links(ROOT / "README.md")
    assert "docs/user-guide.md" in readme and "docs/images/house.png" in readme
    assert "docs/developing.md" in readme  # written elsewhere; checked once it exists


# ------------------------------------------------------------------ file formats

def _table_names(heading: str) -> set[str]:
    """Backticked names in the first column of the table under ``### heading``."""
    text = (DOCS / "file-formats.md").read_text(encoding="utf-8")
    match = re.search(rf"^### {re.escape(heading)}\n(.*?)(?=^#)", text, re.S | re.M)
    assert match, f"docs/file-formats.md has no section '### {heading}'"
    names = set()
    for line in match.group(1).splitlines():
        if line.startswith("|") and not line.startswith("|---"):
            names.update(re.findall(r"`([A-Za-z_][A-Za-z0-9_.]*)`", line.split("|")[1]))
    assert names, f"no array names under '### {heading}'"
    return names


def test_voxelmodel_arrays_in_file_formats_exist():
    from blastvox import model
    from blastvox.materials import MaterialLibrary, material_table

    known = (set(model._REQUIRED) | set(model.OPTIONAL_ARRAYS) | set(model.SURFACE_ARRAYS)
             | set(material_table(MaterialLibrary.builtin(), ["brick"])))
    documented = _table_names("VoxelModel arrays")
    assert documented - known == set(), "documented VoxelModel arrays the code does not write"
    assert known - documented == set(), "VoxelModel arrays missing from docs/file-formats.md"


def test_simcache_arrays_in_file_formats_exist():
    from blastvox import cache

    known = set(cache._REQUIRED)
    documented = _table_names("SimCache arrays")
    assert documented - known == set(), "documented SimCache arrays the code does not write"
    assert known - documented == set(), "SimCache arrays missing from docs/file-formats.md"


# ------------------------------------------------------------------ commands

def _commands():
    import typer

    from blastvox.cli.app import app

    group = typer.main.get_command(app)
    return {name: group.get_command(None, name) for name in group.list_commands(None)}


def test_every_command_option_is_in_the_user_guide():
    text = (DOCS / "user-guide.md").read_text(encoding="utf-8")
    missing = []
    for name, command in _commands().items():
        match = re.search(rf"^## {name}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
        if not match:
            missing.append(f"section '## {name}'")
            continue
        for param in command.params:
            flags = [o for o in param.opts if o.startswith("--")] or param.opts
            if param.param_type_name == "option" and "--help" not in flags and not any(
                    re.search(rf"`{re.escape(flag)}[`\s]", match.group(1)) for flag in flags):
                missing.append(f"{name} {flags[0]}")
    assert not missing, "not in docs/user-guide.md: " + ", ".join(missing)


def test_readme_keeps_the_fresh_machine_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"## Quick start \(fresh machine\)\n.*?```sh\n(.*?)```", text, re.S)
    assert block, "README.md lost its quick start block"
    commands = [line.split("#")[0].strip() for line in block.group(1).splitlines()]
    assert "make demo" in commands and "make test" in commands  # CI runs `make test`
