"""Choices shared by several commands."""

from __future__ import annotations

from enum import StrEnum


class UpAxis(StrEnum):
    """Which axis points up: Y (glTF, USD's default) or Z (most CAD files)."""

    Y = "Y"
    Z = "Z"
