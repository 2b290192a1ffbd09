"""USD files that point elsewhere (issue 36): ``blastvox diff`` follows a layer's
sublayers, references, payloads, value clips and asset paths only under the reader
policy (blastvox.io.references), checked layer by layer before USD opens any of them.
An absolute path or ``../`` outside the folder of the file named, a FIFO (which hung
the open), a symlink to /dev/zero, a URL, a missing or unreadable layer: exit 2, one
line naming the referring layer, the reference, what it is and the rule. Before, USD
followed or skipped each with a C++ warning and diff said "same", exit 0."""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import pytest
from bad_input import deadline, run_blastvox, unchanged

pytest.importorskip("pxr")

PRIM = 'def Xform "World"{meta}\n{{\n{body}}}\n'


def _layer(path: Path, layer_meta: str = "", prim_meta: str = "", body: str = "") -> Path:
    meta = f"(\n    {prim_meta}\n)" if prim_meta else ""
    head = f"#usda 1.0\n(\n    {layer_meta}\n)\n" if layer_meta else "#usda 1.0\n"
    path.write_text(head + PRIM.format(meta=meta, body=body))
    return path


#: how a layer names ``{ref}``: (layer metadata, prim metadata, prim body), and the word
#: the refusal uses for it
ARCS = {
    "sublayer": ("subLayers = [@{ref}@]", "", "", "sublayer"),
    "reference": ("", "references = @{ref}@</World>", "", "reference"),
    "payload": ("", "payload = @{ref}@</World>", "", "payload"),
    "clip": ("", 'clips = {{ dictionary default = {{ asset[] assetPaths = [@{ref}@]\n'
             '    string primPath = "/World"\n    double2[] active = [(0, 0)] }} }}', "",
             "reference"),
    "texture": ("", "", "    asset inputs:file = @{ref}@\n", "asset"),
}


def _target(work: Path, outside: Path, how: str, suffix: str) -> tuple[str, list[str]]:
    """(the reference as written in work/b.usda, words its refusal must say)."""
    if how == "absolute":
        return str(outside.with_suffix(suffix)), ["outside the folder", "--references-anywhere"]
    if how == "escape":
        return f"../{outside.with_suffix(suffix).name}", ["outside the folder"]
    if how == "fifo":
        os.mkfifo(work / f"pipe{suffix}")
        return f"pipe{suffix}", ["FIFO", "not a regular file"]
    if how == "device":
        os.symlink("/dev/zero", work / f"zero{suffix}")
        return f"zero{suffix}", ["/dev/zero", "character device"]
    assert how == "url"
    return f"http://example.com/x{suffix}", ["URL", "nothing is fetched"]


@pytest.fixture
def work(tmp_path: Path) -> tuple[Path, Path]:
    """(work folder with a.usda, a file outside it: outside.usda and outside.png)."""
    work = tmp_path / "shot"
    work.mkdir()
    _layer(work / "a.usda")
    _layer(tmp_path / "outside.usda")
    (tmp_path / "outside.png").write_bytes(b"\x89PNG not yours")
    return work, tmp_path / "outside.usda"


def _refused(work: Path, ref: str, words: list[str], referrer: str = "b.usda",
             *args: str) -> str:
    inputs = [p for p in work.rglob("*") if p.is_file() and not p.is_symlink()]
    with deadline(10.0), unchanged(work, inputs):
        outcome = run_blastvox("diff", "a.usda", "b.usda", "-v", *args, cwd=work)
    assert outcome.code == 2, (outcome.code, outcome.stdout, outcome.stderr)
    assert outcome.stdout == "", outcome.stdout  # never "same"
    lines = outcome.stderr.strip().splitlines()
    assert len(lines) == 1, outcome.stderr
    assert "Traceback" not in outcome.stderr
    line = lines[0]
    for word in [referrer, ref, *words]:
        assert word in line, (word, line)
    assert outcome.seconds < 10.0
    return line


@pytest.mark.parametrize("how", ["absolute", "escape", "fifo", "device", "url"])
@pytest.mark.parametrize("arc", sorted(ARCS))
def test_diff_refuses_what_a_layer_names_outside_the_policy(work, arc: str, how: str) -> None:
    folder, outside = work
    layer_meta, prim_meta, body, word = ARCS[arc]
    ref, words = _target(folder, outside, how, ".png" if arc == "texture" else ".usda")
    _layer(folder / "b.usda", layer_meta.format(ref=ref), prim_meta.format(ref=ref),
           body.format(ref=ref))
    _refused(folder, ref, [f"({word})", *words])


@pytest.mark.parametrize("content, words", [
    (None, ["no such file"]),
    ("not a layer\n", ["not a readable USD layer"]),
])
def test_a_missing_or_unreadable_layer_is_refused_not_skipped(work, content, words) -> None:
    """USD composed the stage without a sublayer it could not open (a C++ warning), and
    diff said "same"."""
    folder, _ = work
    if content is not None:
        (folder / "sub.usda").write_text(content)
    _layer(folder / "b.usda", "subLayers = [@sub.usda@]")
    _refused(folder, "sub.usda", ["(sublayer)", *words])


def test_a_layer_brought_in_is_judged_too_against_the_folder_named(work) -> None:
    """A sublayer's own references are followed under the same policy: the folder that
    bounds them is the one of the file the user named (a chain cannot walk out)."""
    folder, outside = work
    (folder / "sub").mkdir()
    _layer(folder / "sub" / "inner.usda", prim_meta="references = @../../outside.usda@")
    _layer(folder / "b.usda", "subLayers = [@sub/inner.usda@]")
    _refused(folder, "../../outside.usda", ["outside the folder of b.usda"],
             referrer="sub/inner.usda")


def test_layers_inside_the_folder_compose_and_compare(work) -> None:
    """A layer in a subfolder may name one beside the file named (still inside its
    folder); references that cycle are followed once."""
    folder, _ = work
    (folder / "sub").mkdir()
    _layer(folder / "lib.usda")
    _layer(folder / "sub" / "inner.usda", prim_meta="references = @../lib.usda@</World>")
    _layer(folder / "b.usda", "subLayers = [@sub/inner.usda@]")
    _layer(folder / "c.usda", "subLayers = [@sub/inner.usda@]")
    with deadline(10.0):
        outcome = run_blastvox("diff", "b.usda", "c.usda", "-v", cwd=folder)
    assert (outcome.code, outcome.stdout.strip()) == (0, "same"), outcome.stderr


def test_references_anywhere_lets_diff_follow_a_layer_elsewhere(work) -> None:
    folder, outside = work
    _layer(folder / "b.usda", f"subLayers = [@{outside}@]")
    _refused(folder, str(outside), ["outside the folder"])
    outcome = run_blastvox("diff", "a.usda", "b.usda", "--references-anywhere", cwd=folder)
    assert outcome.code == 0, outcome.stderr  # outside.usda holds the same /World
    os.unlink(outside)
    os.mkfifo(outside)  # the flag lifts the folder rule only
    _refused(folder, str(outside), ["FIFO"], "b.usda", "--references-anywhere")


def test_a_composition_error_is_one_line_not_same(work) -> None:
    """Sublayers that cycle: USD warned in C++ and composed what it could; diff said
    "same"."""
    folder, _ = work
    _layer(folder / "x.usda", "subLayers = [@b.usda@]")
    _layer(folder / "b.usda", "subLayers = [@x.usda@]")
    line = _refused(folder, "b.usda", ["could not compose", "cycles"])
    assert "Warning" not in line


def test_a_package_refers_only_to_its_own_files_and_the_folder(work) -> None:
    """Inside a .usdz, a relative path names a file of the package; an absolute one is
    judged like any other reference."""
    folder, outside = work
    root = _layer(folder / "root.usda", "subLayers = [@inner.usda@]",
                  body="    asset inputs:file = @tex.png@\n")
    _layer(folder / "inner.usda")
    (folder / "tex.png").write_bytes(b"\x89PNG")
    for name, members in (("a.usdz", ["root.usda", "inner.usda", "tex.png"]),
                          ("b.usdz", ["root.usda", "inner.usda", "tex.png"])):
        with zipfile.ZipFile(folder / name, "w", zipfile.ZIP_STORED) as package:
            for member in members:
                package.write(folder / member, member)
    outcome = run_blastvox("diff", "a.usdz", "b.usdz", "-v", cwd=folder)
    assert (outcome.code, outcome.stdout.strip()) == (0, "same"), outcome.stderr
    _layer(root, f"subLayers = [@inner.usda@, @{outside}@]")
    with zipfile.ZipFile(folder / "b.usdz", "w", zipfile.ZIP_STORED) as package:
        for member in ("root.usda", "inner.usda", "tex.png"):
            package.write(folder / member, member)
    with deadline(10.0):
        outcome = run_blastvox("diff", "a.usdz", "b.usdz", cwd=folder)
    assert outcome.code == 2, outcome.stderr
    line = outcome.stderr.strip()
    assert "b.usdz[root.usda]" in line and str(outside) in line and "outside the folder" in line
