"""Validate a USD file with OpenUSD's own validation framework (``UsdValidation``).

Every registered validator runs (core, UsdGeom, UsdShade, UsdUtils, ...), at
every authored time sample, and each error becomes one line
``<validator>.<error>: <message> [<site paths>]``.
"""

from __future__ import annotations

from pathlib import Path


def _validators():
    from pxr import UsdValidation

    return UsdValidation.ValidationRegistry().GetOrLoadAllValidators()


def validate_usd(path: str | Path, warnings: bool = False) -> list[str]:
    """Error messages (and warnings if asked) from running all USD validators on ``path``."""
    from pxr import Usd, UsdValidation

    stage = Usd.Stage.Open(str(path))
    if stage is None:
        return [f"{path}: cannot be opened as a USD stage"]
    context = UsdValidation.ValidationContext(_validators())
    wanted = {UsdValidation.ValidationErrorType.Error}
    if warnings:
        wanted.add(UsdValidation.ValidationErrorType.Warn)
    messages = []
    for error in context.Validate(stage, UsdValidation.ValidationTimeRange()):
        if error.GetType() not in wanted:
            continue
        sites = sorted({str(site.GetPrim().GetPath()) if site.IsPrim() else
                        str(site.GetProperty().GetPath()) if site.IsProperty() else
                        str(site.GetLayer().identifier) for site in error.GetSites()
                        if site.IsValid()})
        suffix = f" [{', '.join(sites)}]" if sites else ""
        messages.append(f"{error.GetIdentifier()}: {error.GetMessage()}{suffix}")
    return messages
