"""Atomic file writes: a failed or interrupted stage never leaves a partial output.

A temporary file is named ``.<output>.<host>-<pid>.<random>.partial`` beside its
output: the writer's host and process are in its name, so a write cut short by
SIGKILL (which no handler sees) is cleaned by the next write of the same output
(:func:`clean_stale`) once its process is gone, and never while it lives: two
wedges writing into one folder at once do not delete each other's files mid-write.
:func:`staged_directory` does the same for a folder of files written together (an
export and its textures), moved into place only when all of them are written.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import shutil
import socket
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from blastvox.errors import OutputError
from blastvox.io.outputs import refuse_special

#: A temporary file or folder of another host, or of a version that did not name its
#: writer, is taken as abandoned once it has not changed for this long (seconds).
STALE_AFTER_S = 3600.0
#: ``.<output>.<host>-<pid>.<random>.partial``
_PARTIAL = re.compile(r"^\.(?P<output>.+)\.(?P<host>[A-Za-z0-9]+)-(?P<pid>\d+)\.[^.]+\.partial$")
#: The name of a temporary from before writers were named: ``.<output>.<random>.partial``.
_UNNAMED = re.compile(r"^\.(?P<output>.+)\.[a-z0-9_]{8}\.partial$")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def writer_tag() -> str:
    """``<host>-<pid>``: who writes a temporary file (the host's name, letters and
    digits only)."""
    host = re.sub(r"[^A-Za-z0-9]", "", socket.gethostname().split(".")[0])[:32] or "host"
    return f"{host}-{os.getpid()}"


def _pid_alive(pid: int) -> bool:
    """Is process ``pid`` of this host (maybe) still running?"""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def clean_stale(directory: Path, output: str | None = None) -> list[Path]:
    """Remove the temporary files and folders in ``directory`` (of ``output`` only, if
    given) that a killed writer left: of this host, when their process is gone; of
    another host (whose processes cannot be asked) or unnamed, when untouched for
    :data:`STALE_AFTER_S`. Those of a running writer are never touched. Returns what
    was removed."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    here, now = writer_tag().rsplit("-", 1)[0], time.time()
    for entry in entries:
        if not entry.name.endswith(".partial"):
            continue
        named = _PARTIAL.match(entry.name)
        match = named or _UNNAMED.match(entry.name)
        if match is None or (output is not None and match["output"] != output):
            continue
        if named is not None and named["host"] == here:
            if _pid_alive(int(named["pid"])):
                continue
        else:
            try:
                if now - entry.stat(follow_symlinks=False).st_mtime < STALE_AFTER_S:
                    continue
            except OSError:
                continue
        path = Path(entry.path)
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()
        removed.append(path)
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it onto ``path`` only on success.

    The temporary file lives in the destination directory (created if missing)
    so the final ``os.replace`` is atomic on POSIX. On any exception (including
    an interrupt) the temporary file is removed and ``path`` is untouched. An
    existing ``path`` that is not a regular file (a device, a pipe, a directory)
    is never replaced, and an OS error while writing (read-only directory, full
    disk) becomes one :class:`~blastvox.errors.OutputError` line naming ``path``.
    Temporaries of ``path`` left by a killed writer are removed first.
    """
    final = Path(path)
    refuse_special(final, "output")
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        clean_stale(final.parent, final.name)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{final.name}.{writer_tag()}.",
                                        suffix=".partial", dir=final.parent)
    except OSError as exc:
        raise OutputError(f"{final}: cannot write ({exc.strerror or exc})") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs follow the umask
        refuse_special(final, "output")  # it may have become a device while we worked
        os.replace(tmp, final)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise OutputError(f"{final}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


@contextlib.contextmanager
def staged_directory(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a private empty folder beside ``path`` (named like an atomic temporary) in
    which to write ``path``'s name and its side files; removed, whatever is in it, when
    the block ends (the caller moves what it keeps out first, see :func:`swap_in`)."""
    final = Path(path)
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        clean_stale(final.parent, final.name)
        staging = Path(tempfile.mkdtemp(prefix=f".{final.name}.{writer_tag()}.",
                                        suffix=".partial", dir=final.parent))
    except OSError as exc:
        raise OutputError(f"{final}: cannot write ({exc.strerror or exc})") from None
    try:
        yield staging
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def exchange(a: Path, b: Path) -> bool:
    """Swap the names of ``a`` and ``b`` (both exist) in one atomic step (Linux
    renameat2 RENAME_EXCHANGE); False where the system cannot (nothing was done)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                          ctypes.c_uint]
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    error = ctypes.get_errno()
    if error in (38, 22, 95):  # ENOSYS, EINVAL, EOPNOTSUPP: the file system cannot
        return False
    raise OSError(error, os.strerror(error), str(a))


@contextlib.contextmanager
def swapped_in(new: Path, final: Path) -> Iterator[None]:
    """Put the folder ``new`` at ``final`` for the block, and back where it was if the
    block raises. An existing ``final`` is exchanged with ``new`` (in one atomic step
    where the system can; else moved aside first), so it ends at ``new``'s name for the
    caller to remove; files it held that ``new`` does not are kept (linked into
    ``new`` first): the folder may hold more than one export's files."""
    if not final.exists():
        os.rename(new, final)
        try:
            yield
        except BaseException:
            shutil.rmtree(final, ignore_errors=True)
            raise
        return
    _keep_others(final, new)
    if exchange(new, final):
        def undo() -> None:
            if not exchange(new, final):
                raise OSError(f"{final}: cannot put the previous folder back")
    else:
        aside = new.with_name(new.name + ".old")
        os.rename(final, aside)
        try:
            os.rename(new, final)
        except BaseException:
            os.rename(aside, final)
            raise

        def undo() -> None:
            os.rename(final, new)
            os.rename(aside, final)
    try:
        yield
    except BaseException:
        undo()
        raise


def _keep_others(old: Path, new: Path) -> None:
    """Link (or copy) into ``new`` each entry of ``old`` that ``new`` does not have."""
    def link(src: str, dst: str) -> None:
        try:
            os.link(src, dst)
        except OSError:
            shutil.copy2(src, dst)

    for entry in os.scandir(old):
        target = new / entry.name
        if os.path.lexists(target):
            continue
        if entry.is_dir(follow_symlinks=False):
            shutil.copytree(entry.path, target, symlinks=True, copy_function=link)
        elif entry.is_symlink():
            os.symlink(os.readlink(entry.path), target)
        else:
            link(entry.path, str(target))
