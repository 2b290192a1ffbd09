"""The output-path policy every command applies before it does any work.

An output must be a regular file or not exist yet; it must not be, or resolve
to, any file the command (or the shot) reads; and its directory must exist
(commands given ``-o``) or is created (a scene's ``[output]`` paths, which the
scene author chose). Checked up front, so a long simulation never ends in a
refused write; :func:`blastvox.io.atomic.atomic_path` checks the file kind again
at the moment it replaces it.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable
from pathlib import Path

from blastvox.bounds import printable
from blastvox.errors import OutputError

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
          (stat.S_ISSOCK, "a socket"))


def file_kind(mode: int) -> str:
    """'a directory', 'a character device', ... for a ``st_mode`` that is not a regular file."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def not_a_file(path: str | os.PathLike, what: str = "file") -> str:
    """Why an input ``path`` that is not a regular file cannot be read, as an error line:
    ``no such file``, or ``is a directory, not a file`` for one that exists."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return f"{path}: no such {what}"
    return f"{path}: is {file_kind(mode)}, not a {what}"


def refuse_special(path: Path, label: str) -> None:
    """OutputError if ``path`` exists and is not a regular file (following symlinks)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputError(f"{path}: {label}: cannot be written ({exc.strerror})") from None
    except ValueError:  # a NUL in the name, or one the file system cannot encode
        raise OutputError(f"{printable(path)!r}: {label}: not a valid file name") from None
    if not stat.S_ISREG(mode):
        raise OutputError(f"{path}: {label}: is {file_kind(mode)}; outputs are regular files")


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """True if ``a`` and ``b`` are the same file: same inode when both exist (hard links,
    symlinks), else the same resolved path."""
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):  # missing; a NUL, or a name the file system cannot encode
        pass
    try:
        return os.path.realpath(a) == os.path.realpath(b)
    except (OSError, ValueError):
        return os.path.abspath(a) == os.path.abspath(b)


def check_npz_output(path: str | os.PathLike, label: str, what: str) -> None:
    """OutputError unless ``path`` ends in .npz: a VoxelModel or SimCache (``what``)
    written under another suffix (``-o wall.obj``, a typo) would replace that file."""
    suffix = Path(path).suffix
    if suffix.lower() != ".npz":
        got = repr(suffix) if suffix else "no suffix"
        raise OutputError(f"{path}: {label}: a {what} is an .npz file (got {got}); "
                          f"name it .npz")


def check_output(path: str | os.PathLike, inputs: Iterable[str | os.PathLike | None] = (),
                 label: str = "-o", make_dirs: bool = False) -> Path:
    """Apply the output policy to ``path``; return it as a Path.

    ``inputs`` are every file the command reads (None entries are skipped);
    ``label`` names where the path came from in messages (``-o``,
    ``output.cache``...). With ``make_dirs`` a missing directory is created
    later by the writer instead of being refused.
    """
    out = Path(path)
    if not out.name or out.name in (".", ".."):
        raise OutputError(f"{out}: {label}: is a directory; give a file name")
    refuse_special(out, label)
    for source in inputs:
        if source is not None and same_file(out, source):
            raise OutputError(f"{out}: {label}: is also an input of this command ({source}); "
                              f"write the output elsewhere")
    parent = out.parent
    if not parent.exists():
        if make_dirs:
            return out
        raise OutputError(f"{out}: {label}: directory {parent} does not exist")
    if not parent.is_dir():
        raise OutputError(f"{out}: {label}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{out}: {label}: directory {parent} is not writable")
    return out


def check_distinct(outputs: Iterable[tuple[str, str | os.PathLike]]) -> None:
    """OutputError if two of ``outputs`` ((label, path) pairs) are the same file."""
    seen: list[tuple[str, str | os.PathLike]] = []
    for label, path in outputs:
        for other_label, other in seen:
            if same_file(path, other):
                raise OutputError(f"{path}: {label} is the same file as {other_label}; "
                                  f"each output needs its own path")
        seen.append((label, path))


def _what(folder: Path) -> str:
    """What an export writes into ``folder``: "volumes" (``<stem>_volumes/``) or
    "textures"."""
    return "volumes" if folder.name.endswith("_volumes") else "textures"


def check_side_directory(directory: str | os.PathLike,
                         inputs: Iterable[str | os.PathLike | None] = (),
                         label: str = "-o") -> Path:
    """The output policy for a directory an output writes files into (a USD export's
    ``<stem>_textures/`` and ``<stem>_volumes/``): it is a directory or does not exist
    yet, and holds none of the command's ``inputs`` (its files would be overwritten).
    Returns it as a Path."""
    folder = Path(directory)
    try:
        mode = os.stat(folder).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        raise OutputError(f"{folder}: {label}: cannot be written ({exc.strerror})") from None
    if mode is not None and not stat.S_ISDIR(mode):
        kind = "a file" if stat.S_ISREG(mode) else file_kind(mode)
        raise OutputError(f"{folder}: {label}: is {kind}, where the export "
                          f"writes its {_what(folder)} (a directory); move it away")
    inside = os.path.realpath(folder)
    for source in inputs:
        if source is not None and os.path.realpath(source).startswith(inside + os.sep):
            raise OutputError(f"{folder}: {label}: holds an input of this command ({source}), "
                              f"and the export writes its {_what(folder)} there; write the "
                              f"output elsewhere")
    return folder
