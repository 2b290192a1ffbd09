"""The simulator's mutable state: everything a step changes, as flat arrays.

Like MuJoCo's mjData or Warp's State. The arrays are grouped into a few
NamedTuples that numba kernels take as single arguments (a kernel reads the
fields it needs; see ``benchmarks/containers.py`` for why NamedTuples rather
than jitclasses or structrefs). :class:`State` holds the containers and the
few Python-side values of a run (counters, cached hashes) that no kernel
reads. Capacities: N voxels, L links, B body slots (2 N + 2: every split adds
bodies, none is ever reused).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from blastvox.simulate.shielding import Occupancy


class Bodies(NamedTuple):
    """Rigid bodies, by slot (B,). A body's rest frame is the VoxelModel's frame:
    ``x_world = pos + rot (x_rest - com)``.

    mass (B,) kg; com (B, 3) rest centre of mass, m; inertia, inv_inertia
    (B, 3, 3) rest-frame tensor about com (kg m^2) and its inverse; radius (B,)
    m, a sphere about com holding every voxel; pos (B, 3) world position of
    com, m; quat (B, 4) orientation (w, x, y, z); rot (B, 3, 3) its matrix,
    refreshed by :func:`blastvox.simulate.kernels.body_rotations`; lin (B, 3)
    linear momentum, N s; ang (B, 3) world angular momentum about com, N m s;
    fixed (has a live foundation voxel), live (exists now), dust (a destroyed
    voxel), asleep (B,) bool; parent (B,) the body it split from or -1;
    born, died (B,) step numbers (died = -1 while live); still (B,) steps in a
    row below the sleep speed; count (1,) slots in use.
    """

    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray
    inv_inertia: np.ndarray
    radius: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    rot: np.ndarray
    lin: np.ndarray
    ang: np.ndarray
    fixed: np.ndarray
    live: np.ndarray
    dust: np.ndarray
    asleep: np.ndarray
    parent: np.ndarray
    born: np.ndarray
    died: np.ndarray
    still: np.ndarray
    count: np.ndarray


class Voxels(NamedTuple):
    """Per-voxel state (N,).

    body: body slot; alive; link_mask (uint8): bit f set iff an alive link
    leaves across face f; yield_pa: current voxel yield, Pa; foundation and
    foundation_pa: foundation flag and its remaining yield, Pa; damage:
    Davison-Stevens damage (links' worth, 0..6); combust: combustibility left
    (inf = cannot burn; the model's array, read only, in a run without fire); burning.
    """

    body: np.ndarray
    alive: np.ndarray
    link_mask: np.ndarray
    yield_pa: np.ndarray
    foundation: np.ndarray
    foundation_pa: np.ndarray
    damage: np.ndarray
    combust: np.ndarray
    burning: np.ndarray


class Links(NamedTuple):
    """Per-link state (L,): alive; yield_pa, current yield limit, Pa."""

    alive: np.ndarray
    yield_pa: np.ndarray


class Marks(NamedTuple):
    """What the current phase changed, for the phases after it (cleared by whoever
    starts a new round): broken (L,) links broken; destroyed (N,) voxels dusted;
    crossed (N,) voxels a front crossed; dirty (B,) bodies to search for a
    split; active (B,) bodies a front's shell can touch this step."""

    broken: np.ndarray
    destroyed: np.ndarray
    crossed: np.ndarray
    dirty: np.ndarray
    active: np.ndarray


class Loads(NamedTuple):
    """Blast loads. impulse (B, 3) N s and angular (B, 3) N m s about the centre of
    mass: this step's, per body. What voxels of fixed bodies took during the current
    wave, handed to their piece if it breaks free (see
    :func:`blastvox.simulate.kernels.release_held`), by the voxels that hold some:
    held_slot (N,) int32, each voxel's row or -1 (none: nothing held); held_p (K, 3) N
    s and held_l (K, 3) N m s about the voxel centroid, the rows, held_count[0] of them
    in use (the others zero), held_voxel (K,) int32 the voxel of each
    (:func:`blastvox.simulate.kernels.hold` gives a voxel a row, :func:`hold_room`
    makes room; only the voxels the wave loads hold a row, a block's faces: the (N,
    3) columns took 46 MiB at a million voxels). shadow (N,) uint8: bit f set
    when the neighbour across face f turned to dust in the current waves: that dust
    left with the wave's impulse through the face, which then loads it no more
    (see :func:`blastvox.simulate.fracture.fracture_voxels`)."""

    impulse: np.ndarray
    angular: np.ndarray
    held_slot: np.ndarray
    held_p: np.ndarray
    held_l: np.ndarray
    held_count: np.ndarray
    held_voxel: np.ndarray
    shadow: np.ndarray


def held_loads(n: int, capacity: int) -> Loads:
    """The blast loads of ``capacity`` bodies and N voxels, none held."""
    return Loads(impulse=np.zeros((capacity, 3)), angular=np.zeros((capacity, 3)),
                 held_slot=np.full(n, -1, dtype=np.int32), held_p=np.zeros((0, 3)),
                 held_l=np.zeros((0, 3)), held_count=np.zeros(1, dtype=np.int64),
                 held_voxel=np.zeros(0, dtype=np.int32), shadow=np.zeros(n, dtype=np.uint8))


def hold_room(state: State, more: int) -> None:
    """Room in the held impulses (:class:`Loads`) for ``more`` voxels beyond those that
    hold now: a kernel that may give that many a row (:func:`~blastvox.simulate.kernels.hold`)
    cannot grow them."""
    loads = state.loads
    need = int(loads.held_count[0]) + more
    if need <= len(loads.held_p):
        return
    new = max(need, 2 * len(loads.held_p), 1024)
    state.loads = loads._replace(held_p=padded(loads.held_p, new, 0.0),
                                 held_l=padded(loads.held_l, new, 0.0),
                                 held_voxel=padded(loads.held_voxel, new, 0))


def clear_held(loads: Loads) -> None:
    """Every voxel's held impulses spent: none holds a row any more."""
    count = int(loads.held_count[0])
    loads.held_slot[loads.held_voxel[:count]] = -1
    loads.held_p[:count] = 0.0
    loads.held_l[:count] = 0.0
    loads.held_count[0] = 0


class Contacts(NamedTuple):
    """Contact scratch and flags. resting (B,): a gentle contact this step;
    supported, supported_next (B,): resting on the ground or on something at
    rest, last step and this one; hits (H, 4): this step's contact points (m)
    and approach speeds (m/s), for dust; points (K, 3): ground contact points
    of one body (grows with the largest body); vertex_stamp (V,): body that
    last listed a corner (-1 none), int32; memory: the contact solver's rows and what they
    carry from step to step (:class:`~blastvox.simulate.contact.ground.ContactMemory`),
    made by the first contact phase."""

    resting: np.ndarray
    supported: np.ndarray
    supported_next: np.ndarray
    hits: np.ndarray
    points: np.ndarray
    vertex_stamp: np.ndarray
    memory: tuple | None = None


class Front(NamedTuple):
    """The C charges' shock fronts over one step: position (C, 3) m, time (C,)
    detonation s, scale (C,) W^(1/3) in kg^(1/3), table: the face tables of
    both bursts (:func:`blastvox.blast.face_load.face_tables`, (2, G, 12)),
    burst (C,) int64: each charge's row of it; inner (C,) radius at
    the step's start (-1: nothing passed yet), outer (C,) radius at its end
    (<= 0: not detonated), m."""

    position: np.ndarray
    time: np.ndarray
    scale: np.ndarray
    table: np.ndarray
    burst: np.ndarray
    inner: np.ndarray
    outer: np.ndarray


class Exposure(NamedTuple):
    """What decides a face's or element's load besides the wave: grid, the shielding
    :class:`~blastvox.simulate.shielding.Occupancy`; clearing (B, C, 2), each
    body's silhouette half-extents S, G from each charge, m; gas (C, 2), each
    charge's room gas pressure (Pa) and vent time (s), zeros if it is not confined
    (:mod:`blastvox.simulate.confinement`); sight (N, C, CONFORM_FACES) int8, each voxel face's
    line of sight to each charge in the current wave: 0 not yet known, 1 clear,
    2 shadowed, 3 sealed off (faces 0-5, and a conform voxel's surface by facing,
    6-11); reach (C, X*Y*Z) bool, the grid cells each charge's wave reaches through
    air (:func:`blastvox.simulate.confinement.wave_reach`), at the wave's start;
    detour: how much farther each charge's wave travels round solid to each cell
    (:class:`~blastvox.simulate.diffraction.Detour`), at the wave's start."""

    grid: Occupancy
    clearing: np.ndarray
    gas: np.ndarray
    sight: np.ndarray
    reach: np.ndarray
    detour: tuple


class WaveViews(NamedTuple):
    """What each wave put on each voxel's element when its front crossed it (see
    :func:`blastvox.simulate.fracture.fracture_wave`), (N, C): known bool, the
    (voxel, charge) was judged; peak Pa and impulse Pa s of its face load; blocked
    bool, shielded from the charge; thickness m, the member thickness that resisted
    it; squeezed bool, the wave swept along the member (edge-on to it)."""

    known: np.ndarray
    peak: np.ndarray
    impulse: np.ndarray
    blocked: np.ndarray
    thickness: np.ndarray
    squeezed: np.ndarray


@dataclass
class Caches:
    """Derived lookups, rebuilt only when what they derive from changes.

    boundary: (offsets (B+1,), voxels) each body's alive boundary voxels, or
    None after a topology change; version counts rebuilds. rest: the rest-grid
    hash of the boundary (version rest_version). static: the hash of resting
    bodies' voxels, for ``static_key``. boxes: each body's rest bounding box
    (:func:`blastvox.simulate.clearing.body_boxes`) at topology boxes_version;
    clearing: each body's clearing sizes for the current wave (see
    :func:`blastvox.simulate.clearing.clearing_of`); sight: the faces' lines of
    sight in the current wave (see :class:`Exposure`); holds: work of
    :func:`blastvox.simulate.contact.fragments.mute_member_rows`; balanced: (B,) bool, the
    bodies that stood balanced on the step's contacts
    (:func:`blastvox.simulate.contact.balance.balance`); fragment_rows: how many of the
    step's solved contact rows are between fragments, and how many in all (the
    ground's follow them). views: the waves' element views (see
    :func:`blastvox.simulate.fracture.fracture_wave`). leaky: (X*Y*Z,) bool, the
    shielding grid's cells in rooms the waves enter only through openings
    (:mod:`blastvox.simulate.leakage`), which no wave reaches directly. detour: the
    current wave's :class:`~blastvox.simulate.diffraction.Detour`; ground: (up (3,),
    height m) of the ground plane, or None without one (solid under the detours)."""

    boundary: tuple | None = None
    version: int = 0
    rest: tuple | None = None
    rest_version: int = -1
    static: tuple | None = None
    static_key: tuple | None = None
    boxes: np.ndarray | None = None
    boxes_version: int = -1
    clearing: np.ndarray | None = None
    sight: np.ndarray | None = None
    reach: np.ndarray | None = None
    holds: np.ndarray | None = None
    balanced: np.ndarray | None = None
    fragment_rows: tuple = (0, 0)
    views: WaveViews | None = None
    leaky: np.ndarray | None = None
    detour: tuple | None = None
    ground: tuple | None = None


@dataclass
class Counters:
    """Run totals stored in the SimCache meta, and change counters."""

    broken_links: int = 0
    ground_contacts: int = 0
    collisions: int = 0
    topology_version: int = 0  # counts topology changes (the only place links die)


@dataclass
class Scratch:
    """Work arrays of the phases, allocated once. component, order (N,) int32: for
    splits; voxel_owner (N,) int32: the voxel each fracture candidate moves with;
    voxel_candidate (N,): fracture candidates."""

    component: np.ndarray
    order: np.ndarray
    voxel_owner: np.ndarray
    voxel_candidate: np.ndarray

    @classmethod
    def for_model(cls, model) -> Scratch:
        n = model.n_voxels
        return cls(component=np.zeros(n, dtype=np.int32), order=np.zeros(n, dtype=np.int32),
                   voxel_owner=np.arange(n, dtype=np.int32),
                   voxel_candidate=np.zeros(n, dtype=bool))


@dataclass
class State:
    """Everything a run changes (see the module docstring)."""

    bodies: Bodies
    voxels: Voxels
    links: Links
    marks: Marks
    loads: Loads
    contacts: Contacts
    scratch: Scratch
    shielding: Occupancy
    caches: Caches = field(default_factory=Caches)
    counters: Counters = field(default_factory=Counters)
    holding: bool = False  # do voxels hold blast impulse (Loads.held_*) now?
    hold_since: int = 0  # the step the current holding began

    @property
    def n_bodies(self) -> int:
        return int(self.bodies.count[0])


def padded(array: np.ndarray, length: int, fill) -> np.ndarray:
    """``array`` with its first axis grown to ``length`` rows, the new ones ``fill``."""
    if len(array) >= length:
        return array
    out = np.full((length, *array.shape[1:]), fill, dtype=array.dtype)
    out[:len(array)] = array
    return out


#: Body slots a run starts with beyond its objects; they double whenever a split needs
#: more (:func:`grow_bodies`). Every split retires its parent, so a model of N voxels
#: can use up to 2 N + objects slots, but a shot uses a few per broken piece: sized for
#: the worst case, a million-voxel block reserved 1.1 GB of body arrays and touched
#: about 100 MB of them (its peak RSS fell 1,842 -> 1,741 MB).
SPARE_BODIES = 1024


def grow_bodies(state: State, needed: int) -> None:
    """Make room for ``needed`` bodies in all: double the capacity (or more) of the body
    arrays and of every array of the state indexed by body (marks, loads, contact
    flags and the solver's scratch, the clearing and holding caches), new slots unused.
    Outside the state: the stress solver's ``solved`` is padded after each split
    (:func:`blastvox.simulate.engine.split`); the contact punch's ``net`` and the limit
    monitor's rotations size themselves from ``len(state.bodies.mass)``."""
    capacity = len(state.bodies.mass)
    if needed <= capacity:
        return
    new = max(needed, 2 * capacity)
    old, grown = state.bodies, empty_bodies(new)
    for name in Bodies._fields:
        if name != "count":
            getattr(grown, name)[:capacity] = getattr(old, name)
    grown.count[0] = old.count[0]
    state.bodies = grown
    marks, loads, contacts, caches = state.marks, state.loads, state.contacts, state.caches
    state.marks = marks._replace(dirty=padded(marks.dirty, new, False),
                                 active=padded(marks.active, new, False))
    state.loads = loads._replace(impulse=padded(loads.impulse, new, 0.0),
                                 angular=padded(loads.angular, new, 0.0))
    memory = contacts.memory
    if memory is not None:
        memory = memory._replace(local=padded(memory.local, new, -1))
    state.contacts = contacts._replace(
        resting=padded(contacts.resting, new, False),
        supported=padded(contacts.supported, new, False),
        supported_next=padded(contacts.supported_next, new, False), memory=memory)
    if caches.clearing is not None:
        caches.clearing = padded(caches.clearing, new, np.nan)
    if caches.holds is not None:
        caches.holds = padded(caches.holds, new, False)


def empty_bodies(capacity: int) -> Bodies:
    """``capacity`` unused body slots."""
    return Bodies(
        mass=np.zeros(capacity), com=np.zeros((capacity, 3)),
        inertia=np.zeros((capacity, 3, 3)), inv_inertia=np.zeros((capacity, 3, 3)),
        radius=np.zeros(capacity), pos=np.zeros((capacity, 3)), quat=np.zeros((capacity, 4)),
        rot=np.zeros((capacity, 3, 3)), lin=np.zeros((capacity, 3)),
        ang=np.zeros((capacity, 3)), fixed=np.zeros(capacity, dtype=bool),
        live=np.zeros(capacity, dtype=bool), dust=np.zeros(capacity, dtype=bool),
        asleep=np.zeros(capacity, dtype=bool), parent=np.full(capacity, -1, dtype=np.int64),
        born=np.zeros(capacity, dtype=np.int64), died=np.full(capacity, -1, dtype=np.int64),
        still=np.zeros(capacity, dtype=np.int64), count=np.zeros(1, dtype=np.int64))
