"""User-facing errors.

Every error a user can cause by bad input is a :class:`BlastvoxError`. The CLI
prints it as one line (``blastvox: error: <message>``) and exits non-zero, so
messages must name the file (and key, where there is one) and the problem.
"""

from __future__ import annotations


class BlastvoxError(Exception):
    """Base class for errors caused by user input; the message is shown as is."""

    exit_code = 1


class InputError(BlastvoxError):
    """An input file is missing, unreadable, or not what it claims to be."""


class MeshError(InputError):
    """A mesh cannot be turned into a solid (open, degenerate, empty, NaN...)."""


class MaterialError(BlastvoxError):
    """A material is unknown or its definition is invalid."""


class SceneError(BlastvoxError):
    """A scene file does not match the schema."""


class ContractError(InputError):
    """A stage file (VoxelModel, SimCache) is foreign, truncated or of another version."""


class OutputError(BlastvoxError):
    """An output path cannot or must not be written (a device, an input, a missing or
    read-only directory, a full disk)."""


class BudgetError(BlastvoxError):
    """A configured resource budget (voxel count, memory) would be exceeded."""


class WedgeError(BlastvoxError):
    """A wedge cannot run: an unknown or unsettable KEY, bad VALUES, a grid over its
    budget, or a Dask scheduler that cannot be reached."""


class BlastvoxWarning(UserWarning):
    """A warning the CLI prints as one ``blastvox: warning: <message>`` line."""


class ExportWarning(BlastvoxWarning):
    """An export that is valid but that its client will handle badly (Blender's glTF
    import of thousands of nodes)."""


class HostDependenceWarning(BlastvoxWarning):
    """A run whose bytes may depend on the CPU it runs on (see blastvox/__init__.py)."""


class SimulationLimitWarning(BlastvoxWarning):
    """A run's settings go beyond what the simulator can honour (see blastvox.simulate.limits).

    Issued once per limit and run; the CLI prints it as ``blastvox: warning: <message>``.
    """
