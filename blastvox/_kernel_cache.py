"""Where numba caches blastvox's compiled kernels: one directory per version of their source.

numba's on-disk cache (``cache=True``) checks only the source file of the
function it compiled, so editing a helper that a kernel in another module
inlines would leave the kernel's stale machine code in use. blastvox instead
keys the whole cache on a content hash of every module that holds numba code:
any edit to one of them starts a fresh cache directory, and everything is
compiled again (once). Old directories beyond the newest :data:`KEEP` are
removed.

The directory is ``$NUMBA_CACHE_DIR/blastvox-<hash>`` if the user set
NUMBA_CACHE_DIR, else ``$XDG_CACHE_HOME/blastvox/numba/<hash>`` (by default
``~/.cache/blastvox/numba/<hash>``). No numba import here: this runs when
``blastvox`` is imported, before any kernel is decorated.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import sys
from pathlib import Path

KEEP = 3
#: A module that compiles code imports numba or blastvox.jit (a mention in a docstring
#: does not count: it would key the cache on modules no kernel reads).
_KERNEL_MODULE = re.compile(rb"^[ \t]*(?:import|from)[ \t]+(?:numba|blastvox\.jit)\b", re.M)
#: ``from pkg.x.y import a, b`` or ``from pkg.x import (a,\n b)``: the module and the
#: names; ``import pkg.x.y``: the module. For the package's name ``pkg``.
_FROM = r"^[ \t]*from[ \t]+({0}(?:\.\w+)*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)"
_PLAIN = r"^[ \t]*import[ \t]+({0}(?:\.\w+)*)"


def source_hash(package: Path) -> str:
    """Hash (16 hex digits) of the contents of every module under ``package`` that
    holds or calls numba code, and of every package module those import (their
    constants, e.g. face tables, are frozen into the compiled code), in path order."""
    digest = hashlib.blake2b(digest_size=8)
    for path in sorted(_kernel_sources(package)):
        text = path.read_bytes()
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + text + b"\0")
    return digest.hexdigest()


def _kernel_sources(package: Path) -> set[Path]:
    """The numba modules of ``package`` and, transitively, the package modules they import."""
    texts = {path: path.read_bytes() for path in package.rglob("*.py")}
    name = re.escape(package.name)
    froms, plains = re.compile(_FROM.format(name), re.M), re.compile(_PLAIN.format(name), re.M)
    todo = [path for path, text in texts.items() if _KERNEL_MODULE.search(text)]
    found: set[Path] = set()
    while todo:
        path = todo.pop()
        if path in found:
            continue
        found.add(path)
        text = texts[path].decode("utf-8", "replace")
        modules = [m.split(".")[1:] for m in plains.findall(text)]
        for source, names in froms.findall(text):
            parts = source.split(".")[1:]
            modules.append(parts)
            modules += [parts + [n.split()[0]] for n in names.strip("()").split(",") if n.split()]
        for module in modules:
            for target in (package.joinpath(*module).with_suffix(".py"),
                           package.joinpath(*module, "__init__.py")):
                if target in texts and target not in found:
                    todo.append(target)
    return found


#: Set by :func:`configure` for child processes: the directory it pointed
#: NUMBA_CACHE_DIR at, and the user's own NUMBA_CACHE_DIR before that ("" = unset). A
#: child that inherits NUMBA_CACHE_DIR unchanged shares its parent's cache instead of
#: nesting a second one inside it (and compiling every kernel again).
_SET_BY_US = "BLASTVOX_KERNEL_CACHE"
_USERS_OWN = "BLASTVOX_USER_NUMBA_CACHE_DIR"


def cache_directory(package: Path, environ: dict[str, str] | None = None) -> Path:
    """The cache directory for the kernels of ``package`` as it is now (see module doc)."""
    environ = os.environ if environ is None else environ
    key = source_hash(package)
    user = environ.get("NUMBA_CACHE_DIR")
    if user and user == environ.get(_SET_BY_US):  # inherited from a blastvox process
        user = environ.get(_USERS_OWN) or None
    if user:
        return Path(user) / f"blastvox-{key}"
    base = Path(environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "blastvox" / "numba" / key


def configure(package: Path) -> Path:
    """Point numba's cache at :func:`cache_directory` (also if numba is imported already)
    and prune old siblings. Returns the directory."""
    directory = cache_directory(package)
    user = os.environ.get("NUMBA_CACHE_DIR")
    if not (user and user == os.environ.get(_SET_BY_US)):
        os.environ[_USERS_OWN] = user or ""
    os.environ["NUMBA_CACHE_DIR"] = str(directory)
    os.environ[_SET_BY_US] = str(directory)
    numba = sys.modules.get("numba")
    if numba is not None:
        numba.config.CACHE_DIR = str(directory)
    _prune(directory)
    return directory


def _prune(directory: Path) -> None:
    """Remove all but the newest KEEP sibling cache directories of ours."""
    parent = directory.parent
    if not parent.is_dir():
        return
    mine = [p for p in parent.iterdir() if p.is_dir() and p != directory and (
        p.name.startswith("blastvox-") if parent.name != "numba" else len(p.name) == 16)]
    if len(mine) < KEEP:
        return
    mine.sort(key=lambda p: p.stat().st_mtime, reverse=True)
    for old in mine[KEEP - 1:]:
        shutil.rmtree(old, ignore_errors=True)
