"""A .usdz package: the crate (.usdc) export and its textures in one file.

The export is written as ``<stem>.usdc`` with its textures in ``<stem>_textures/``
in a private temporary directory, then packaged by OpenUSD itself
(``UsdUtils.CreateNewUsdzPackage``: an uncompressed zip, the root layer first,
every file 64-byte aligned, as the USDZ specification requires) and moved onto
the output atomically. Every packaged file is dated 1980-01-01 (zip headers
record times): the same cache and options give the same bytes. One file for a
shot that travels (a review tool, an asset library, Apple's Quick Look), where a
.usdc needs its texture directory beside it.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from blastvox.cache import SimCache
from blastvox.errors import OutputError
from blastvox.export.options import ExportOptions
from blastvox.io.atomic import atomic_path

#: 1980-01-01 00:00 UTC, the earliest time a zip header holds: every packaged file's
#: time, so that the package's bytes depend on the shot only.
ZIP_EPOCH = 315532800


def write_usdz(cache: SimCache, path: Path, options: ExportOptions) -> None:
    """Write ``cache`` to ``path`` (.usdz) atomically: the .usdc export and its
    textures packaged with ``UsdUtils.CreateNewUsdzPackage``."""
    from pxr import Sdf, UsdUtils

    from blastvox.export.usd import write_usd

    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="blastvox-usdz-") as staging:
        root = Path(staging) / f"{path.stem}.usdc"
        write_usd(cache, root, options)
        for file in Path(staging).rglob("*"):  # the zip records each file's time
            os.utime(file, (ZIP_EPOCH, ZIP_EPOCH))
        with atomic_path(path) as tmp:
            # USD writes a package only to a name that ends in .usdz
            package = tmp.with_name(tmp.name + ".usdz")
            try:
                if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(root)), str(package)):
                    raise OutputError(f"{path}: USD could not write the package")
                os.replace(package, tmp)
            finally:
                with contextlib.suppress(FileNotFoundError):
                    package.unlink()
