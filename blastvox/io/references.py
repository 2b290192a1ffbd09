"""One reader policy for the files a file refers to (issue 36): an OBJ's ``mtllib`` and
the textures an MTL names, a .gltf's buffer and image URIs, a USD layer's sublayers,
references, payloads, clips and asset paths (:mod:`blastvox.diff.usd_refs`).

A reference is read only if it is a regular file (never a device, a FIFO, a socket
or a directory: /dev/zero is read forever, a FIFO blocks), inside the referring
file's folder (after symlinks: ``../../etc/passwd`` or a link to /dev/zero is
refused; for layers that bring in layers, the folder of the file the user named)
unless the user allows more (``--references-anywhere`` of voxelize, run and diff),
never a URL (``http://``, ``file://``: nothing is fetched), and at most
:data:`MAX_REFERENCE_BYTES` (checked before reading). A refusal is one line naming
the referring file, the reference and the rule, and the flag that allows it where
one does.
"""

from __future__ import annotations

import os
import re
import stat
import urllib.parse
from dataclasses import dataclass
from pathlib import Path

from blastvox.bounds import printable, shortened
from blastvox.errors import InputError

#: The largest file a reference may name (bytes): a texture or a buffer of a few
#: hundred MB is already a very large asset.
MAX_REFERENCE_BYTES = 1 << 30
#: A URI with a scheme (``http:``, ``https:``, ``file:``, ``ftp:``...); one-letter
#: schemes are Windows drive letters (``C:/...``), which the folder rule judges.
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]+:")
#: The flag that lifts the folder rule.
ANYWHERE_FLAG = "--references-anywhere"


class ReferenceRefused(InputError):
    """A file refers to something the reader policy does not read."""


@dataclass(frozen=True)
class ReferencePolicy:
    """What references may be read: anywhere, False: only inside the referring file's
    folder; max_bytes: the largest file."""

    anywhere: bool = False
    max_bytes: int = MAX_REFERENCE_BYTES

    def resolve(self, referrer: Path, name: str, *, within: Path | None = None,
                shown: str | None = None, kind: str | None = None) -> Path:
        """The file ``name`` (as written in ``referrer``) names, checked: see the module
        docstring. Raises :class:`ReferenceRefused`, or FileNotFoundError for a regular
        reference to a missing file (the loaders treat a missing texture as absent).

        within: the file whose folder bounds every reference (a USD layer's layers refer
        to more layers: all must stay in the folder of the file the user named; default
        ``referrer``); shown: how the refusal names the referrer (default its path);
        kind: what the reference is (``sublayer``, ``payload``...), said after it."""
        where = _where(shown if shown is not None else referrer, name, kind)
        within = referrer if within is None else within
        if name.startswith("data:"):
            raise ReferenceRefused(f"{where}: a data: URI is decoded by the loader, not read")
        if _SCHEME.match(name):
            raise ReferenceRefused(f"{where}: a URL; blastvox reads files only, nothing is "
                                   "fetched (download it beside the file that names it)")
        if "\0" in name:
            raise ReferenceRefused(f"{where}: a file name with a NUL character")
        try:
            folder = within.parent.resolve()
            target = (referrer.parent / name).resolve()
            info = os.stat(target)
        except FileNotFoundError:
            info = None
        except (OSError, RuntimeError, ValueError) as exc:  # a symlink loop, a name too long
            raise ReferenceRefused(f"{where}: cannot be followed ({_reason(exc)})") from None
        if info is not None and not stat.S_ISREG(info.st_mode):  # whatever the flag
            from blastvox.io.outputs import file_kind

            raise ReferenceRefused(f"{where}: {printable(target)} is {file_kind(info.st_mode)}"
                                   ", not a regular file")
        if not self.anywhere and not target.is_relative_to(folder):
            raise ReferenceRefused(f"{where}: outside the folder of {printable(within.name)}"
                                   f" ({printable(target)}); copy it beside the file, or "
                                   f"pass {ANYWHERE_FLAG}")
        if info is None:  # a missing file, for the loader to skip (and warn)
            raise FileNotFoundError(2, "no such file", str(target))
        if info.st_size > self.max_bytes:
            raise ReferenceRefused(f"{where}: {info.st_size:,} bytes, more than the "
                                   f"{self.max_bytes:,} a reference may be")
        return target

    def read(self, referrer: Path, name: str, *, within: Path | None = None,
             shown: str | None = None, kind: str | None = None) -> bytes:
        """The bytes of the file ``name`` names (see :meth:`resolve`, whose keywords it
        takes), opened without blocking and checked again once open (a file swapped for a
        FIFO after the check is refused, not waited on)."""
        target = self.resolve(referrer, name, within=within, shown=shown, kind=kind)
        where = _where(shown if shown is not None else referrer, name, kind)
        fd = os.open(target, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise ReferenceRefused(f"{where}: not a regular file")
            data = fh.read(self.max_bytes + 1)
        if len(data) > self.max_bytes:
            raise ReferenceRefused(f"{where}: more than the {self.max_bytes:,} bytes a "
                                   "reference may be")
        return data


def uri_paths(uri: str) -> list[str]:
    """The file names a glTF URI may mean, in the order to try them: its percent-decoded
    path (glTF URIs are RFC 3986: Blender writes ``my%20skin.png`` for ``my skin.png``),
    then the URI as written if that differs (an exporter that did not encode a literal
    ``%``)."""
    decoded = urllib.parse.unquote(uri)
    return [decoded] if decoded == uri else [decoded, uri]


def read_uri(policy: ReferencePolicy, referrer: Path, uri: str) -> bytes:
    """The bytes of the first file of :func:`uri_paths` (``uri`` as a glTF names it) that
    exists, read under ``policy`` (a refusal raises at once); FileNotFoundError if none
    does."""
    names = uri_paths(uri)
    for name in names[:-1]:
        try:
            return policy.read(referrer, name)
        except FileNotFoundError:
            continue
    return policy.read(referrer, names[-1])


def _reason(exc: BaseException) -> str:
    """Why a path could not be resolved, in a few words: the OS's reason (``Too many
    levels of symbolic links``, ``File name too long``), or a symlink loop."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return "a symlink loop" if isinstance(exc, RuntimeError) else str(exc)


def _where(referrer: Path | str, name: str, kind: str | None = None) -> str:
    """The start of a refusal: the referring file and the reference as written (and
    what it is)."""
    said = f" ({kind})" if kind else ""
    return f"{printable(referrer)}: refers to {shortened(printable(name))!r}{said}"
