"""Validate a USD file with OpenUSD's own validation framework (``UsdValidation``).

Every registered validator runs (core, UsdGeom, UsdShade, UsdUtils, ...), over
all authored time samples, and each finding becomes one line
``<validator>.<error>: <message> [<sites>]``. The framework is the
``pxr.UsdValidation`` module from OpenUSD 25.02 on (it lived in ``pxr.Usd`` as
``Usd.Validation*`` in 24.x, used as a fallback).
"""

from __future__ import annotations

from pathlib import Path


def _framework():
    """(registry, context class, error-type enum, time-range class or None)."""
    try:
        from pxr import UsdValidation as v

        return (v.ValidationRegistry(), v.ValidationContext, v.ValidationErrorType,
                getattr(v, "ValidationTimeRange", None))
    except ImportError:
        from pxr import Usd as v

        if not hasattr(v, "ValidationRegistry"):
            raise RuntimeError("USD validation needs usd-core >= 24.11 "
                               "(the UsdValidation framework)") from None
        return (v.ValidationRegistry(), v.ValidationContext, v.ValidationErrorType,
                getattr(v, "ValidationTimeRange", None))


def _site(site) -> str:
    if site.IsPrim():
        return str(site.GetPrim().GetPath())
    if site.IsProperty():
        return str(site.GetProperty().GetPath())
    return str(site.GetLayer().identifier)


def validate_usd(path: str | Path, warnings: bool = False) -> list[str]:
    """Errors (and warnings if asked) from running every USD validator on ``path``;
    an empty list means the file is valid."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    if stage is None:
        return [f"{path}: cannot be opened as a USD stage"]
    registry, context_class, error_type, time_range = _framework()
    context = context_class(registry.GetOrLoadAllValidators())
    errors = (context.Validate(stage, time_range()) if time_range is not None
              else context.Validate(stage))
    wanted = {error_type.Error} | ({error_type.Warn} if warnings else set())
    messages = []
    for error in errors:
        if error.GetType() not in wanted:
            continue
        sites = sorted({_site(s) for s in error.GetSites() if s.IsValid()})
        suffix = f" [{', '.join(sites)}]" if sites else ""
        messages.append(f"{error.GetIdentifier()}: {error.GetMessage()}{suffix}")
    return messages
