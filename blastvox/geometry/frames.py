"""Up-axis frames: which axis points up, and the change of frame between Y-up and Z-up.

A VoxelModel keeps its input's coordinates and names its up axis
(``meta["up_axis"]``, "Y" as glTF or "Z" as most CAD/STL files); gravity acts
along minus that axis and the ground plane is perpendicular to it. An export
states its own up axis; :func:`frame_change` is the rotation between the two.
Axis names are upper-case "X", "Y", "Z"; indices 0, 1, 2; vectors (3,) float64.
"""

from __future__ import annotations

import numpy as np

AXES = ("X", "Y", "Z")
#: the up axes a model or an export may have
UP_AXES = ("Y", "Z")
#: m/s^2, standard gravity (the default of the scene's settings)
STANDARD_GRAVITY = 9.81

#: Z-up -> Y-up: (x, y, z) -> (x, z, -y), a -90 degree turn about x (Blender's
#: glTF/USD exporters' convention); its inverse (transpose) for Y-up -> Z-up
_Z_TO_Y = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
_Y_TO_Z = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


def up_index(up_axis: str) -> int:
    """Index 0, 1 or 2 of the axis named ``up_axis`` ("X", "Y" or "Z")."""
    if up_axis not in AXES:
        raise ValueError(f"unknown axis {up_axis!r}: use one of {', '.join(AXES)}")
    return AXES.index(up_axis)


def up_name(index: int) -> str:
    """Name "X", "Y" or "Z" of axis ``index`` (0, 1, 2)."""
    return AXES[index]


def up_vector(up_axis: str) -> np.ndarray:
    """Unit vector (3,) float64 along the axis named ``up_axis``."""
    up = np.zeros(3)
    up[up_index(up_axis)] = 1.0
    return up


def gravity_vector(up_axis: str, gravity: float = STANDARD_GRAVITY) -> np.ndarray:
    """Gravitational acceleration (3,) m/s^2: ``gravity`` (m/s^2) down the up axis."""
    return -float(gravity) * up_vector(up_axis)


def frame_change(model_up: str, export_up: str) -> np.ndarray:
    """Rotation (3, 3) from a frame whose up axis is ``model_up`` to one whose up axis is
    ``export_up`` (column vectors: ``x_export = C @ x_model``).

    Z-up -> Y-up maps (x, y, z) to (x, z, -y) (a -90 degree turn about x), the
    convention of Blender's glTF/USD exporters; the inverse for Y-up -> Z-up;
    the identity when the two agree. Returns a new array.
    """
    if model_up == export_up:
        return np.eye(3)
    if model_up == "Z" and export_up == "Y":
        return _Z_TO_Y.copy()
    if model_up == "Y" and export_up == "Z":
        return _Y_TO_Z.copy()
    raise ValueError(f"unsupported up axes {model_up!r} -> {export_up!r}")
