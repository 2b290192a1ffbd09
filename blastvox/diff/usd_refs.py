"""What a USD file refers to, checked before USD opens any of it (issue 36).

``Usd.Stage.Open`` follows a layer's sublayers, references, payloads and value
clips wherever they point: an absolute path, ``../../etc/passwd``, a FIFO (which
hangs the open), a symlink to /dev/zero or an ``http://`` URL, and a layer it
cannot open is only a C++ warning, after which ``diff`` said "same". So before a
stage is opened, :func:`check_usd_references` walks the composition arcs layer by
layer with ``UsdUtils.ExtractExternalReferences`` (which parses one layer and
lists what it names: sublayers, references and payloads, clip and asset paths,
opening none of them) and judges every one under the reader policy
(:mod:`blastvox.io.references`): regular files only, inside the folder of the file
the user named unless ``--references-anywhere``, never a URL, size-capped. A layer
it names that does not exist or that USD cannot parse is refused too (the stage
would be composed without it). Inside a .usdz, a relative path names a file of the
package. Each refusal is one line naming the referring layer, the reference, what
it is and the rule.
"""

from __future__ import annotations

import os
import posixpath
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

from blastvox.bounds import printable
from blastvox.diff.common import DiffError
from blastvox.io.references import ReferencePolicy, ReferenceRefused

#: At most this many layers are followed from one file (each is parsed to list its
#: references): a layer graph larger than this is refused rather than walked.
MAX_LAYERS = 10_000
#: An asset path USD would compute from variables: ``\\`"${X}.usda"\\```.
_EXPRESSION = re.compile(r"`|\$\{")
#: A UDIM tile pattern (textures): one file per tile, looked up by USD.
_UDIM = "<UDIM>"


@dataclass(frozen=True)
class _Layer:
    """A layer to read: ``file`` on disk, or the ``inner`` file of the package ``file``
    (whose files are ``members``)."""

    file: Path
    inner: str | None = None
    members: frozenset[str] = frozenset()
    #: how the layer that named it refers to it (the start of an error line about it)
    via: str | None = None

    @property
    def identifier(self) -> str:
        return str(self.file) if self.inner is None else f"{self.file}[{self.inner}]"

    @property
    def shown(self) -> str:
        return printable(self.identifier)


def check_usd_references(path: Path, policy: ReferencePolicy) -> None:
    """Refuse (:class:`DiffError`, one line) a USD file that refers to anything the
    reader ``policy`` does not read, directly or through the layers it brings in."""
    try:
        from pxr import UsdUtils  # noqa: F401
    except ImportError:
        return  # _open_stage says what is missing
    root = Path(path)
    first = _package(root) if root.suffix.lower() == ".usdz" else _Layer(root)
    queue, seen = [first], {first.identifier}
    while queue:
        layer = queue.pop()
        for found in _names(layer, root, policy):
            if found.identifier not in seen:
                if len(seen) >= MAX_LAYERS:
                    raise DiffError(f"{printable(root)}: brings in more than {MAX_LAYERS:,} "
                                    "layers; diff does not follow that many")
                seen.add(found.identifier)
                queue.append(found)


def _package(path: Path, via: str | None = None) -> _Layer:
    """The root layer of the .usdz ``path`` (its first file), with the package's files."""
    try:
        with zipfile.ZipFile(path) as package:
            names = package.namelist()
    except (OSError, zipfile.BadZipFile, ValueError) as exc:
        raise DiffError(f"{via or printable(path)}: not a readable .usdz package "
                        f"({exc})") from None
    if not names:
        raise DiffError(f"{via or printable(path)}: an empty .usdz package")
    return _Layer(path, names[0], frozenset(names), via)


def _extract(layer: _Layer) -> tuple[list[str], list[str], list[str]]:
    """(sublayers, references (with clips and assets), payloads) that ``layer`` names."""
    from pxr import Tf, UsdUtils

    try:
        sub, refs, payloads = UsdUtils.ExtractExternalReferences(layer.identifier)
    except Tf.ErrorException as exc:
        from blastvox.diff.usd import _first_line

        raise DiffError(f"{layer.via or layer.shown}: not a readable USD layer "
                        f"({_first_line(exc)})") from None
    return list(sub), list(refs), list(payloads)


def _names(layer: _Layer, root: Path, policy: ReferencePolicy) -> list[_Layer]:
    """The layers ``layer`` brings in, each checked; raises DiffError on a refusal."""
    from pxr import Sdf

    sub, refs, payloads = _extract(layer)
    if layer.identifier != str(root) and layer.inner is None:
        _no_own_variables(layer)
    found: list[_Layer] = []
    for kind, names in (("sublayer", sub), ("reference", refs), ("payload", payloads)):
        for name in names:
            if not name:
                continue
            file_name = (Sdf.Layer.SplitIdentifier(name)[0] if ":SDF_FORMAT_ARGS:" in name
                         else name)
            ext = file_name.rsplit(".", 1)[-1].lower() if "." in file_name else ""
            is_layer = kind != "reference" or Sdf.FileFormat.FindByExtension(ext) is not None
            said = kind if is_layer else "asset"
            if _EXPRESSION.search(name):
                raise DiffError(f"{layer.shown}: refers to {printable(name)!r} ({said}): an "
                                "expression USD evaluates from variables; diff does not "
                                "follow computed paths")
            target = _judge(layer, file_name, root, policy, said, must_exist=is_layer)
            if target is not None and is_layer:
                found.append(target)
    return found


def _judge(layer: _Layer, name: str, root: Path, policy: ReferencePolicy, kind: str,
           must_exist: bool) -> _Layer | None:
    """The layer ``name`` (written in ``layer``) opens, after the policy; None for an
    asset that is absent (diff reports it as missing content)."""
    via = f"{layer.shown}: refers to {printable(name)!r} ({kind})"
    probe = name.replace(_UDIM, "1001")
    if layer.inner is not None and not os.path.isabs(probe) and ":" not in probe:
        joined = posixpath.normpath(posixpath.join(posixpath.dirname(layer.inner), probe))
        if joined in layer.members:
            return _Layer(layer.file, joined, layer.members, via)
        if must_exist:
            raise DiffError(f"{via}: not a file of the package {printable(layer.file.name)}")
        return None
    anchor = layer.file
    try:
        policy.resolve(anchor, probe, within=root, shown=layer.shown, kind=kind)
    except ReferenceRefused as exc:
        raise DiffError(str(exc)) from None
    except FileNotFoundError:
        if must_exist:
            raise DiffError(f"{via}: no such file (USD would compose the stage without "
                            "it)") from None
        return None
    if name != probe:  # UDIM tiles: each is judged when read
        return None
    target = Path(os.path.normpath(anchor.parent / name))
    if target.suffix.lower() == ".usdz":
        return _package(target, via)
    return _Layer(target, via=via)


def _no_own_variables(layer: _Layer) -> None:
    """Refuse a layer below the root that defines expression variables: USD evaluates
    paths with the root's variables only, so what the layer names cannot be judged."""
    from pxr import Sdf

    opened = Sdf.Layer.FindOrOpen(layer.identifier)
    if opened is not None and dict(opened.expressionVariables):
        raise DiffError(f"{layer.shown}: defines expressionVariables below the root layer; "
                        "diff does not follow computed paths")
