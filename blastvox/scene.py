"""Scene files: the TOML configuration shared by every stage.

A scene names the meshes to voxelize (``[[objects]]``), the charges (``[[charges]]``),
the simulation settings, which effects to model, an optional camera and output paths,
plus optional extra materials (``materials_file`` and inline ``[materials.<name>]``
tables in the format of :mod:`blastvox.materials`).

Conventions (all SI: metres, seconds, kilograms, pascals):

* Every coordinate in the scene (transforms, rule regions, charge positions, camera,
  ``ground`` height) is in the scene's world frame, whose up axis is ``up_axis`` -- the
  same axis that points up in the input meshes. Rule regions are tested against voxel
  centres *after* the object's transform.
* ``transform`` maps mesh coordinates to world: scale, then rotate, then translate.
  ``rotate_deg`` is XYZ Euler in degrees, extrinsic (rotate about X, then Y, then Z: R =
  Rz @ Ry @ Rx), as Blender's ``XYZ`` mode.
* Paths are relative to the scene file and are stored resolved (absolute). Mesh files
  are not checked here: the voxelize stage reads them, and records each mesh path as the
  scene wrote it (``SceneObject.mesh_as_written``), so a build is byte-identical
  wherever the scene and its meshes are.
* Every number is finite and within a documented range (:mod:`blastvox.bounds`;
  docs/user-guide.md, Limits and exit codes): coordinates within 1e6 m of the origin,
  seeds 0 .. 2**63 - 1, and so on. ``charges[i].explosive`` must be a known explosive.

Loading never raises anything but :class:`~blastvox.errors.SceneError`, whose message is
one line: ``<file>: <key.path>: <what is wrong>``.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    StringConstraints,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from blastvox import bounds as limits
from blastvox.bounds import Bound, printable
from blastvox.errors import BlastvoxError, MaterialError, SceneError
from blastvox.materials import MaterialLibrary, read_toml
from blastvox.scene_errors import At, format_validation_error, shown, toml_key

_UNKNOWN_SOURCE = "<scene>"


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _in_bound(bound: Bound, vec: Any, value: Any) -> tuple[float, float, float]:
    try:
        checked = [bound.check(v) for v in vec]
    except ValueError as exc:
        problem = str(exc).split(" (got ")[0]
        each = "" if _is_number(value) else "each component "
        raise ValueError(f"{each}{problem} (got {shown(value)})") from None
    return (checked[0], checked[1], checked[2])


def _vector(bound: Bound) -> BeforeValidator:
    """3 finite numbers, each within ``bound`` (shared with the CLI: blastvox.bounds)."""

    def _vec3(value: Any) -> tuple[float, float, float]:
        if (not isinstance(value, list | tuple) or len(value) != 3
                or not all(_is_number(v) and math.isfinite(v) for v in value)):
            raise ValueError(f"must be a list of 3 finite numbers (got {shown(value)})")
        return _in_bound(bound, value, value)

    _vec3.bound = bound  # type: ignore[attr-defined]  # for tools/scene_reference.py
    return BeforeValidator(_vec3)


def _sizes(bound: Bound) -> BeforeValidator:
    """One number for all three axes or 3 numbers, each within ``bound``."""

    def _size3(value: Any) -> tuple[float, float, float]:
        vec3 = [value] * 3 if _is_number(value) else value
        if (not isinstance(vec3, list | tuple) or len(vec3) != 3
                or not all(_is_number(v) for v in vec3)):
            raise ValueError(f"must be a number or a list of 3 numbers (got {shown(value)})")
        if not all(math.isfinite(v) for v in vec3):
            raise ValueError(f"must be finite (got {shown(value)})")
        return _in_bound(bound, vec3, value)

    _size3.bound = bound  # type: ignore[attr-defined]
    return BeforeValidator(_size3)


def _path(value: Any, info: ValidationInfo) -> Path:
    if not isinstance(value, str | Path) or not str(value).strip():
        raise ValueError(f"must be a non-empty path string (got {shown(value)})")
    path = Path(value).expanduser()
    base = (info.context or {}).get("base_dir")
    if base is not None and not path.is_absolute():
        path = Path(os.path.normpath(Path(base).absolute() / path))
    return path


def _material_name(value: Any) -> Any:
    return value.strip().lower() if isinstance(value, str) else value


def _case(fold: str) -> BeforeValidator:
    """Fold strings to ``fold`` ("lower"/"upper") case before validation."""

    def convert(value: Any) -> Any:
        return getattr(value, fold)() if isinstance(value, str) else value
    return BeforeValidator(convert)


def _ground(value: Any) -> Any:
    if isinstance(value, str) and value.strip().lower() in ("auto", "none"):
        return value.strip().lower()
    if _is_number(value) and math.isfinite(value):
        return limits.COORDINATE.check(value)
    raise ValueError(f"must be 'auto', 'none' or a finite height in metres (got {shown(value)})")


_ground.bound = limits.COORDINATE  # type: ignore[attr-defined]


Vec3 = Annotated[tuple[float, float, float], _vector(limits.COORDINATE)]
Direction3 = Annotated[tuple[float, float, float], _vector(limits.DIRECTION)]
Angles3 = Annotated[tuple[float, float, float], _vector(limits.ANGLE_DEG)]
Size3 = Annotated[tuple[float, float, float], _sizes(limits.VOXEL_SIZE)]
Scale3 = Annotated[tuple[float, float, float], _sizes(limits.SCALE)]
# numbers within a documented bound (blastvox.bounds), as pydantic constraints
Resolution = Annotated[int, limits.RESOLUTION.constraints()]
ContactSubsteps = Annotated[int, limits.CONTACT_SUBSTEPS.constraints()]
FocalLength = Annotated[float, limits.FOCAL_LENGTH_MM.constraints()]
Seed = Annotated[int, limits.SEED.constraints()]
Jitter = Annotated[float, limits.JITTER.constraints()]
Length = Annotated[float, limits.LENGTH.constraints()]
StrengthScale = Annotated[float, limits.STRENGTH_SCALE.constraints()]
ChunkSize = Annotated[float, limits.CHUNK_SIZE.constraints()]
PartBond = Annotated[float, limits.PART_BOND.constraints()]
SheetThickness = Annotated[float, limits.SHEET_THICKNESS.constraints()]
_CHUNK = "Chunk size instead of the material's: 0 (no chunks) or one voxel to the object's size."
# The simulation's settings and budgets (simulation.*, particles.*, charges' mass and
# time) are bounded where they are used: blastvox.simulate.settings.check_settings names
# the scene file and key; here they need only be finite and of the right sign.
Positive = Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
NonNegative = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0)]
FilePath = Annotated[Path, BeforeValidator(_path)]
Name = Annotated[str, StringConstraints(strict=True, strip_whitespace=True, min_length=1)]
MaterialName = Annotated[Name, BeforeValidator(_material_name)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, ser_json_inf_nan="constants")

    def __eq__(self, other: object) -> bool:
        """Equal fields (private notes such as the path as written do not count)."""
        if not isinstance(other, BaseModel):
            return NotImplemented
        return type(self) is type(other) and self.__dict__ == other.__dict__

    def __hash__(self) -> int:
        return hash((type(self), *self.__dict__.values()))


class Transform(_Model):
    """Mesh-to-world transform: scale, then rotate (XYZ Euler, degrees), then translate (m)."""

    translate: Vec3 = Field((0.0, 0.0, 0.0), description=(
        "Translation applied last, after scale and rotation."))
    rotate_deg: Angles3 = Field((0.0, 0.0, 0.0), description=(
        "Rotation as XYZ Euler angles, extrinsic (about X, then Y, then Z: "
        "R = Rz Ry Rx), as Blender's XYZ mode; applied after scale."))
    scale: Scale3 = Field((1.0, 1.0, 1.0), description=(
        "Scale factor, one number for all axes or one per axis; applied first."))


class Box(_Model):
    """Axis-aligned box (m), boundary inclusive."""

    min: Vec3 = Field(description="Lowest corner (world frame).")
    max: Vec3 = Field(description="Highest corner (world frame); >= min on every axis.")

    @model_validator(mode="after")
    def _ordered(self) -> Box:
        if any(lo > hi for lo, hi in zip(self.min, self.max, strict=True)):
            raise At(("max",), f"must be >= min on every axis (min {list(self.min)})")
        return self

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask of the (N, 3) ``points`` inside the box."""
        pts = np.asarray(points, dtype=np.float64)
        return np.all((pts >= self.min) & (pts <= self.max), axis=-1)


class Sphere(_Model):
    """Ball with ``center`` (m) and ``radius`` (m > 0), boundary inclusive."""

    center: Vec3 = Field(description="Centre (world frame).")
    radius: Length = Field(description="Radius.")

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask of the (N, 3) ``points`` inside the ball."""
        d = np.asarray(points, dtype=np.float64) - self.center
        return np.einsum("...i,...i->...", d, d) <= self.radius**2


class Halfspace(_Model):
    """Points x with (x - point) . normal >= 0; ``normal`` need not be unit length."""

    point: Vec3 = Field(description="A point on the bounding plane (world frame).")
    normal: Direction3 = Field(description=(
        "Direction into the half-space (need not be unit length, must not be zero)."))

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, normal: tuple[float, float, float]) -> tuple[float, float, float]:
        if not any(normal):
            raise ValueError("must not be the zero vector")
        return normal

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask of the (N, 3) ``points`` in the half-space."""
        return (np.asarray(points, dtype=np.float64) - self.point) @ np.asarray(self.normal) >= 0


class Rule(_Model):
    """A region (exactly one of box/sphere/halfspace) that sets material and/or scales strength.

    ``strength_scale`` multiplies the link, voxel and foundation yields inside.
    Rules apply in order; a later rule wins where regions overlap.
    """

    box: Box | None = Field(None, description="Axis-aligned box region.")
    sphere: Sphere | None = Field(None, description="Ball region.")
    halfspace: Halfspace | None = Field(None, description="Half-space region.")
    material: MaterialName | None = Field(None, description=(
        "Material of the voxels whose centre is inside the region."))
    strength_scale: StrengthScale | None = Field(None, description=(
        "Factor on the link, voxel and foundation yields inside the region "
        "(a link takes the smaller factor of its two voxels)."))
    chunk_size: ChunkSize | None = Field(None, description=_CHUNK + " Inside the region.")

    @model_validator(mode="after")
    def _complete(self) -> Rule:
        given = [k for k in ("box", "sphere", "halfspace") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"needs exactly one of box, sphere, halfspace (got {given or 'none'})")
        if self.material is None and self.strength_scale is None and self.chunk_size is None:
            raise ValueError("needs material, strength_scale or chunk_size (else it does nothing)")
        return self

    @property
    def region(self) -> Box | Sphere | Halfspace:
        """The rule's region."""
        return self.box or self.sphere or self.halfspace  # type: ignore[return-value]


class SceneObject(_Model):
    """One mesh to voxelize. Exactly one of ``voxel_size`` (m) and ``resolution`` is set."""

    mesh: FilePath = Field(description=(
        "Mesh file: OBJ, STL, PLY, OFF, glTF/GLB, or a volume mesh meshio reads "
        "(.vtu, .msh, ...)."))
    name: Name = Field(description=(
        "Object name, unique in the scene; default: the mesh file's stem. Parts that are "
        "not connected become the objects NAME.000, NAME.001, ..."))
    voxel_size: Size3 | None = Field(None, description=(
        "Voxel edge, one number or one per axis. Give voxel_size or resolution, not both."))
    resolution: Resolution | None = Field(None, description=(
        "Voxels along the longest axis of the transformed mesh; 32 if neither "
        "voxel_size nor resolution is given."))
    shape: Annotated[Literal["cube", "conform"], _case("lower")] = Field("cube", description=(
        "cube: every voxel a (jittered) hexahedron; conform: voxels the surface crosses "
        "are the exact cell-and-mesh intersection (needs a closed mesh)."))
    jitter: Jitter = Field(0.0, description=(
        "Moves each lattice vertex by a seeded random fraction of the voxel size; "
        "neighbouring voxels share vertices, so faces stay shared."))
    chunk_size: ChunkSize | None = Field(None, description=_CHUNK)
    part_bond: PartBond = Field(1.0, description=(
        "Factor on the strength of the links between two parts of the mesh that touch "
        "(a glTF's nodes and primitives, an OBJ's objects): 1 welds them like one solid; "
        "0.2 holds a tyre or a window in place by contact and lets it break off first."))
    sheet_thickness: SheetThickness = Field(limits.DEFAULT_SHEET_THICKNESS_M, description=(
        "Thickness in metres of the mesh's parts that are open surfaces (a window pane, "
        "a sign) beside closed ones: each becomes a sheet one voxel deep whose mass and "
        "link strength are those of a pane this thick."))
    anchored: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Voxels touching the ground are foundations that hold the object until the "
        "blast tears them off; false lets the object stand on the ground as a free "
        "body (a vehicle, furniture, a crate)."))
    material: MaterialName = Field("concrete", description=(
        "Material of the object's voxels where neither material_map nor a rule sets one."))
    material_map: dict[str, MaterialName] = Field({}, description=(
        "Mesh material name -> library material, for meshes that name their materials "
        "(case-insensitive)."))
    transform: Transform = Field(Transform(), description="Mesh-to-world transform.")
    rules: list[Rule] = Field([], description=(
        "Region rules, applied in order after material and material_map; a later rule "
        "wins where regions overlap."))

    _mesh_as_written: str | None = PrivateAttr(default=None)

    @model_validator(mode="wrap")
    @classmethod
    def _keep_written_path(cls, data: Any, handler: Any) -> SceneObject:
        obj = handler(data)
        if isinstance(data, dict) and isinstance(data.get("mesh"), str | Path):
            obj._mesh_as_written = str(data["mesh"])
        return obj

    @property
    def mesh_as_written(self) -> str | None:
        """``mesh`` as the scene file wrote it (relative to the scene, unless absolute):
        what a model records, so that the same build elsewhere gives the same bytes."""
        return self._mesh_as_written

    @model_validator(mode="before")
    @classmethod
    def _defaults(cls, data: Any) -> Any:
        if isinstance(data, dict):
            data = dict(data)
            if "name" not in data and isinstance(data.get("mesh"), str | Path):
                data["name"] = Path(data["mesh"]).stem
            if "voxel_size" not in data and "resolution" not in data:
                data["resolution"] = 32
        return data

    @field_validator("resolution")
    @classmethod
    def _one_size(cls, resolution: int | None, info: ValidationInfo) -> int | None:
        if resolution is not None and info.data.get("voxel_size") is not None:
            raise ValueError("give either voxel_size or resolution, not both")
        return resolution

    @model_validator(mode="after")
    def _has_size(self) -> SceneObject:
        if self.voxel_size is None and self.resolution is None:
            raise At(("resolution",), "give voxel_size or resolution")
        return self


class Charge(_Model):
    """``mass_kg`` (kg) of ``explosive`` at ``position`` (m), detonated at ``time_s`` (s)."""

    position: Vec3 = Field(description="Centre of the charge (world frame).")
    mass_kg: Positive = Field(description="Mass of explosive.")
    explosive: Name = Field("TNT", description=(
        "Explosive, converted to a TNT-equivalent mass (see Explosives)."))
    time_s: NonNegative = Field(0.0, description="Detonation time after the start of the shot.")
    burst: Literal["auto", "air", "surface"] = Field("auto", description=(
        "air: a spherical free-air burst; surface: a hemispherical burst on the ground "
        "(stronger); auto: surface when the charge's centre is within 0.2 W^(1/3) m "
        "(W in kg TNT) of the ground, else air."))

    @field_validator("explosive")
    @classmethod
    def _known_explosive(cls, explosive: str) -> str:
        from blastvox.blast.explosives import known_explosives, tnt_equivalent

        try:
            tnt_equivalent(explosive)
        except BlastvoxError:
            raise ValueError(f"unknown explosive {explosive!r} (known: "
                             f"{', '.join(known_explosives())})") from None
        return explosive


class Simulation(_Model):
    """Integrator and physics settings.

    dt, duration: s; fps: 1/s; gravity: m/s^2 along -up; drags: 1/s.
    weakening: fraction of a wave's peak overpressure taken off the yield of a
    link or voxel it did not break. orientation_factor k: a link parallel to
    the wave's radius holds only (1 - k) of its yield. damage_b (-) and
    damage_c (1/(Pa s)): Davison-Stevens constants for ``fracture = "damage"``.
    friction: Coulomb mu at the ground. Fire: fire_pressure_scale (-) times a
    wave's peak erodes combustibility; fire_spread (Pa/s) erodes a burning
    voxel's neighbours (full rate straight above); burn_rate (1/s) is the
    fraction of its initial yield a burning voxel or link loses per second.
    """

    dt: Positive = Field(1.0 / 240.0, description=(
        "Fixed time step; shortened if needed so that a whole number of steps fills "
        "a frame interval."))
    fps: Positive = Field(24.0, description="Output frames per second.")
    duration: Positive = Field(5.0, description=(
        "Length of the shot; frames run from t = 0 to the last frame at or before it."))
    fracture: Annotated[Literal["pressure-impulse", "yield", "damage"], _case("lower")] = Field(
        "pressure-impulse", description=(
            "pressure-impulse: a link or voxel breaks when the face load's peak and impulse "
            "pass its material's pressure-impulse curve (reflection, clearing and "
            "shielding included); yield: the papers' model, the incident peak "
            "overpressure against the yield (Martins 2001); damage: Davison-Stevens "
            "damage accumulation (Mazarak 1999)."))
    gravity: NonNegative = Field(9.81, description=(
        "Gravitational acceleration along -up_axis; 0 switches gravity off."))
    linear_drag: NonNegative = Field(0.0, description=(
        "Exponential decay rate of every body's linear momentum."))
    angular_drag: NonNegative = Field(0.0, description=(
        "Exponential decay rate of every body's angular momentum."))
    weakening: Annotated[float, Field(strict=True, ge=0, le=1)] = Field(0.5, description=(
        "Fraction of a wave's peak overpressure taken off the yield of a link or voxel "
        "that the wave did not break (yield fracture)."))
    orientation_factor: Annotated[float, Field(strict=True, ge=0, lt=1)] = Field(
        0.5, description=(
            "k: a link's yield is scaled by (1 - k |R.l|), R the wave's direction and l "
            "the link's, so a link along the wave's radius holds only (1 - k) of it."))
    damage_b: NonNegative = Field(0.1, description=(
        "Davison-Stevens constant B (fracture = \"damage\")."))
    damage_c: NonNegative = Field(0.05, description=(
        "Davison-Stevens constant C, per Pa s of overpressure above yield "
        "(fracture = \"damage\")."))
    friction: NonNegative = Field(0.6, description=(
        "Coulomb friction coefficient at the ground and between pieces."))
    contact_substeps: ContactSubsteps = Field(4, description=(
        "Sub-steps of the contact solver a step (a soft step: each sub-step one sweep "
        "with a soft push-out and one rigid sweep): more hold tall stacks and deep piles "
        "stiffer and cost more (measure a shot's trade with benchmarks/pile.py "
        "--contact-substeps N)."))
    fire_pressure_scale: NonNegative = Field(1.0, description=(
        "A wave's peak overpressure times this is taken off a voxel's combustibility; "
        "below zero the voxel burns."))
    fire_spread: NonNegative = Field(20_000.0, description=(
        "Rate at which a burning voxel lowers the combustibility of its linked "
        "neighbours (full rate straight above, 20 % beside or below)."))
    burn_rate: NonNegative = Field(0.05, description=(
        "Fraction of its initial yield that a burning voxel and its links lose per second."))


class Effects(_Model):
    """Which effects to model; an effect that is off costs nothing."""

    collisions: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Pieces collide with each other."))
    ground: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "The ground plane and foundations; false: foundations are ignored and the "
        "model floats free."))
    fire: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Ignition, burning and spread, with flame and smoke particles (only where a "
        "material can burn)."))
    stress: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Load paths: founded structures carry their weight through their links to the "
        "ground, and a link stressed past its material's strength breaks (the stress "
        "solver; only where something is founded)."))
    dust: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Dust particles from destroyed voxels, impacts, the passing shock and the "
        "shock's ring on the ground."))
    fireball: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Fireball particles at each charge."))
    shock_sphere: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Shock-front sphere opacity in the cache (false: opacity 0, the sphere is hidden)."))
    camera_shake: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Shake the scene's [camera] when a wave reaches it."))


class Particles(_Model):
    """Particle budgets per system (most particles kept over the whole shot)."""

    dust: Annotated[int, Field(strict=True, ge=0)] = Field(20_000, description=(
        "Most dust particles kept; later emission is dropped."))
    fire: Annotated[int, Field(strict=True, ge=0)] = Field(10_000, description=(
        "Most flame particles kept."))
    smoke: Annotated[int, Field(strict=True, ge=0)] = Field(10_000, description=(
        "Most smoke particles kept."))
    fireball: Annotated[int, Field(strict=True, ge=0)] = Field(2_000, description=(
        "Most fireball particles kept."))


class Camera(_Model):
    """Shot camera: ``position`` and ``look_at`` in m, focal length in mm (35 mm film back)."""

    position: Vec3 = Field(description="Camera position (world frame).")
    look_at: Vec3 = Field(description="Point the camera looks at (world frame).")
    focal_length_mm: FocalLength = Field(35.0, description=(
        "Focal length on a 36 x 24 mm film back, 1 to 10,000 mm."))

    @model_validator(mode="after")
    def _distinct(self) -> Camera:
        if self.position == self.look_at:
            raise At(("look_at",), "must differ from position")
        return self


class Output(_Model):
    """Default output paths of the stages (absolute once loaded), and export options.

    ``export`` may be one path or a list (e.g. a .usdc and a .glb of the same shot).
    """

    model: FilePath | None = Field(None, description=(
        "VoxelModel (.npz) that voxelize writes and simulate reads."))
    cache: FilePath | None = Field(None, description=(
        "SimCache (.npz) that simulate writes and export reads."))
    export: FilePath | list[FilePath] | None = Field(None, description=(
        "Export file(s): .usda, .usdc, .usd, .usdz, .gltf or .glb; the suffix picks the "
        "format."))
    up_axis: Annotated[Literal["Y", "Z"], _case("upper")] = Field("Y", description=(
        "Up axis of the exported files."))
    layout: Literal["xforms", "instancer", "skinned"] = Field("xforms", description=(
        "xforms: an Xform and a Mesh per piece (USD), a node per piece (glTF); "
        "instancer: one USD PointInstancer; skinned: one glTF mesh with a joint per "
        "piece, which imports into Blender as one object (thousands of pieces)."))
    shock: bool = Field(False, description=(
        "Also export each charge's shock front as a growing sphere (a viewport aid: a "
        "guide prim in USD, skipped by renderers; a translucent sphere in glTF)."))
    damage_textures: bool = Field(True, description=(
        "Fracture faces show their material's damage texture (its damage_pattern, "
        "tinted to its damage_color; USD: PNGs in <stem>_textures/ beside the file); "
        "false keeps the flat damage_color."))
    fracture_faces: Literal["rough", "voxel"] = Field("rough", description=(
        "rough: fracture faces drawn as broken rubble (the voxels' steps smoothed and "
        "their corners roughened; pieces still fit together at rest; collision stays "
        "voxel-based); voxel: the voxels' cell faces."))
    particles: Literal["auto", "volumes", "spheres"] = Field("auto", description=(
        "How USD exports dust, fire, smoke and the fireball: volumes (OpenVDB density "
        "and, for fire, temperature grids per frame in <stem>_volumes/ beside the file, "
        "a UsdVolVolume per system: renders as soft clouds), spheres (a PointInstancer "
        "of spheres per system) or auto (volumes for .usd/.usda/.usdc, spheres for "
        ".usdz, which cannot carry .vdb files). glTF: spheres writes a translucent "
        "sphere node per particle (at most 256 per system), else no particles."))
    volume_voxel_m: Annotated[float, Field(ge=0.001, le=100.0)] = Field(0.1, description=(
        "Cell size of the particle volumes (m): smaller is finer and costs about the "
        "cube of the ratio in time and disk."))
    key_tolerance_m: Annotated[float, Field(ge=0.0, le=1.0)] = Field(1e-4, description=(
        "Keyframe reduction: a piece's translation is keyed only where interpolating "
        "the kept keys would miss it by more than this (m); 0 with key_tolerance_deg = 0 "
        "keys every frame where it changes."))
    key_tolerance_deg: Annotated[float, Field(ge=0.0, le=90.0)] = Field(0.1, description=(
        "Keyframe reduction: a piece's rotation is keyed only where interpolating the "
        "kept keys would miss it by more than this angle (degrees)."))
    velocity_primvars: bool = Field(True, description=(
        "USD: each piece's time-sampled velocity and angularVelocity primvars (false: "
        "left out, a smaller file and faster frame changes in Blender)."))
    damage_samples: bool = Field(False, description=(
        "USD: time-sample each piece's per-face damage primvar at every change (Blender "
        "then reads every mesh again at each frame change); false writes its final value "
        "and the frame each face is first damaged."))


class Wedge(_Model):
    """A wedge of the scene (``blastvox wedge``): the keys to vary and where shots go."""

    vary: dict[str, list[Any] | str] = Field({}, description=(
        "KEY = values to run the scene over: a TOML array, or a 'START:STOP:COUNT' "
        "(':log') range string; KEY is a dotted path into this file, e.g. "
        "\"charges.0.mass_kg\" = [10, 50]. The grid is every combination; "
        "--vary options add keys or replace these."))
    sample: Annotated[int, Field(strict=True, ge=1)] | None = Field(None, description=(
        "Run a seeded random sample of this many shots of the grid instead of all."))
    sample_seed: Seed = Field(0, description="Seed of the random sample.")
    out: FilePath | None = Field(None, description=(
        "Directory of the wedge's shots, summary and contact sheet; default: wedge/ "
        "beside output.cache, else <scene stem>_wedge/ beside the scene."))
    preview: Annotated[bool, Field(strict=True)] = Field(True, description=(
        "Render a preview strip of each shot and a contact sheet of all of them."))


class Scene(_Model):
    """A validated scene. Build with :func:`load_scene` or :func:`scene_from_dict`.

    ``Scene.model_validate(data)`` also works; pass
    ``context={"base_dir": dir, "source": name}`` to resolve paths and name the
    source in errors. Material references are checked against
    :meth:`material_library` during validation.
    """

    seed: Seed = Field(0, description=(
        "Seed of every random choice (jitter, yield perturbation, particles): the same "
        "inputs and seed give byte-identical files."))
    up_axis: Annotated[Literal["Y", "Z"], _case("upper")] = Field("Y", description=(
        "Axis that points up in the meshes and in every coordinate of the scene; "
        "gravity acts along -up."))
    ground: Annotated[Literal["auto", "none"] | float, BeforeValidator(_ground)] = Field(
        "auto", description=(
            "Ground height along up_axis: auto (the lowest point of all voxels), none "
            "(no ground, no foundations) or a height. Voxels touching it are foundations."))
    materials_file: FilePath | None = Field(None, description=(
        "TOML material library that extends or overrides the built-in materials "
        "(see Materials)."))
    materials: dict[str, dict[str, Any]] = Field({}, description=(
        "Inline [materials.NAME] tables, applied after materials_file (see Materials)."))
    objects: Annotated[list[SceneObject], Field(min_length=1, description=(
        "Meshes to voxelize, at least one."))]
    charges: list[Charge] = Field([], description="Explosive charges (none: no blast).")
    simulation: Simulation = Field(Simulation(), description="Integrator and physics settings.")
    effects: Effects = Field(Effects(), description=(
        "Which effects to model; an effect that is off costs nothing."))
    particles: Particles = Field(Particles(), description="Particle budgets per system.")
    camera: Camera | None = Field(None, description=(
        "Shot camera for the exports, previews and camera shake (none: no camera)."))
    output: Output = Field(Output(), description="Output paths of the stages, export options.")
    wedge: Wedge | None = Field(None, description=(
        "Parameter sweep for `blastvox wedge` (ignored by the other commands)."))

    _library: MaterialLibrary | None = PrivateAttr(default=None)
    _source: str | None = PrivateAttr(default=None)

    @field_validator("objects")
    @classmethod
    def _unique_names(cls, objects: list[SceneObject]) -> list[SceneObject]:
        seen: dict[str, int] = {}
        for i, obj in enumerate(objects):
            if obj.name in seen:
                raise At((i, "name"), f"duplicate object name {obj.name!r} "
                                       f"(also objects[{seen[obj.name]}])")
            seen[obj.name] = i
        return objects

    @model_validator(mode="after")
    def _check_materials(self, info: ValidationInfo) -> Scene:
        source = (info.context or {}).get("source", _UNKNOWN_SOURCE)
        self._source = (info.context or {}).get("source")
        self._library = library = _build_library(self, source)
        for key, name in self._material_refs():
            try:
                library[name]
            except MaterialError as exc:
                raise SceneError(f"{source}: {key}: {exc}") from None
        return self

    def _material_refs(self) -> list[tuple[str, str]]:
        refs = []
        for i, obj in enumerate(self.objects):
            refs.append((f"objects[{i}].material", obj.material))
            refs += [(f"objects[{i}].material_map{toml_key(k)}", v)
                     for k, v in obj.material_map.items()]
            refs += [(f"objects[{i}].rules[{j}].material", r.material)
                     for j, r in enumerate(obj.rules) if r.material is not None]
        return refs

    @property
    def source(self) -> str | None:
        """How messages name the scene file (as given to :func:`load_scene`), if known."""
        return self._source

    def material_library(self) -> MaterialLibrary:
        """Built-in materials, extended by ``materials_file``, then by inline ``materials``."""
        if self._library is None:
            self._library = _build_library(self, _UNKNOWN_SOURCE)
        return self._library

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-compatible dict (paths as strings; ``inf`` kept as float) for metadata."""
        return self.model_dump(mode="json")


def _build_library(scene: Scene, source: str) -> MaterialLibrary:
    library = MaterialLibrary.builtin()
    if scene.materials_file is not None:
        try:
            library = MaterialLibrary.load(scene.materials_file)
        except MaterialError as exc:
            raise SceneError(f"{source}: materials_file: {exc}") from None
    try:
        return library.extended(scene.materials, source, prefix="materials.")
    except MaterialError as exc:
        raise SceneError(str(exc)) from None


def load_scene(path: Path) -> Scene:
    """Read, validate and resolve the scene file at ``path``; errors are :class:`SceneError`."""
    path = Path(path)
    return scene_from_dict(read_toml(path, SceneError), printable(path), path.parent)


def scene_from_dict(data: dict[str, Any], source: str, base_dir: Path) -> Scene:
    """Validate ``data`` (a parsed scene file, named ``source`` in error messages) with
    relative paths resolved against ``base_dir``."""
    context = {"source": source, "base_dir": Path(base_dir).absolute()}
    try:
        return Scene.model_validate(data, context=context)
    except ValidationError as exc:
        raise SceneError(format_validation_error(exc, source, Scene)) from None
