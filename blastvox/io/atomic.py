"""Atomic file writes: a failed or interrupted stage never leaves a partial output."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from blastvox.errors import OutputError
from blastvox.io.outputs import refuse_special


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; move it onto ``path`` only on success.

    The temporary file lives in the destination directory (created if missing)
    so the final ``os.replace`` is atomic on POSIX. On any exception (including
    an interrupt) the temporary file is removed and ``path`` is untouched. An
    existing ``path`` that is not a regular file (a device, a pipe, a directory)
    is never replaced, and an OS error while writing (read-only directory, full
    disk) becomes one :class:`~blastvox.errors.OutputError` line naming ``path``.
    """
    final = Path(path)
    refuse_special(final, "output")
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".partial",
                                        dir=final.parent)
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
