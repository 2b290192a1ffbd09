"""Contact loads on founded structures: what free pieces push into a founded body is
carried by its links, and a chunk whose links cannot carry it is punched out.

A founded body is an immovable (infinite-mass) body in the contact solve
(:mod:`~blastvox.simulate.contact.solver`). What its contacts strike it with in a step
(the pushes of resting pieces left out: :class:`SustainedLoads` carries those), J (N s)
on a voxel, is a force F = J / max(dt, strike time) on its support, as NVIDIA Blast's stress
solver turns the impulses applied to an actor into bond stress. The first link of
that load path is the struck chunk's own boundary: its alive links to the rest of
the body carry F in compression where they lie ahead of it (the link's outward
direction within 45 degrees of F) and in shear or tension elsewhere (the weaker of
the two). When F exceeds what those links can carry together (each link's area
times its strength: a rigid-plastic limit, the chunk sheared out as a plug), they
all break in the same step, and the step's contacts are solved again with the chunk
free: the striking pieces share their momentum with the piece they broke out, as
with any free body, where the immovable body stopped them dead. Otherwise the
foundation takes what they pushed.

So a wall that the wave throws into the end of a side wall (the corner of a house)
shears that end off and goes on, where an immovable side wall stopped it dead.
Foundation voxels are anchored to the ground (their own yield decides them) and are
never punched.

What resting pieces push in over time is also a static load on the founded body's
load paths (:class:`SustainedLoads`): rubble heaped on a floor, or a block on a
cantilever's tip, weighs on it. Only weight, bounded by the resting pieces' statics:
the squeeze of a jammed piece and the thrust of wedged rubble are not determined by
the contact solve, and are not loads.
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.geometry import exact
from blastvox.jit import helper, kernel
from blastvox.simulate.stress import voxel_links

#: A link carries a chunk's load in compression when its outward direction is within
#: this angle's cosine (45 degrees) of the load.
AHEAD = math.cos(math.radians(45.0))


@helper
def row_impulse(rows, r, side, out) -> None:
    """out (3,): the impulse (N s, normal and friction) row r gave its side (0: a, 1: b)."""
    sign = 1.0 if side == 1 else -1.0
    for a in range(3):
        out[a] = sign * (rows.impulse[r] * rows.frame[r, 0, a] + rows.friction[r, a])


@helper
def _lost(net, k, out) -> None:
    """out (3,): the load (N s) piece k put into fixed bodies this step: what they took
    from it, net[k, :3] being their impulse on it, less, axis by axis, what the ground
    pushed back against them (net[k, 3:6], the ground's impulse on it): between two
    immovable bodies the solve fixes only the sum of their pushes, not how much of it
    each gives and takes."""
    for a in range(3):
        f, g = net[k, a], net[k, 3 + a]
        if f * g < 0.0:
            f = math.copysign(max(0.0, abs(f) - abs(g)), f)
        out[a] = -f


@helper
def _at_rest(bodies, k, slow) -> bool:
    """Does body k move no faster than ``slow`` m/s?"""
    return (bodies.lin[k, 0] ** 2 + bodies.lin[k, 1] ** 2 + bodies.lin[k, 2] ** 2
            <= (slow * bodies.mass[k]) ** 2)


@kernel
def fixed_contact_impulses(rows, count, end, bodies, impulse, touched, net, slow,
                           resting, up, support) -> int:
    """Sum into impulse (N, 3) (N s; zero where nothing touched, the caller zeroes what
    it read) what free pieces pushed into each fixed body's voxel through the first
    ``count`` solved rows, and list those voxels in touched (N,); returns how many.
    resting (N, 3): the same through the rows whose points approached no faster than
    ``slow`` m/s before the solve, of pieces moving no faster than that after it (what
    rests on, leans on or is wedged against the body, not what strikes it or is still
    being slowed down on it). support (2,): adds the mass (kg) of the resting pieces
    (no faster than ``slow``) in the rows, and the ground's impulse (N s) on them along
    ``up`` (3,): how much of their weight the ground carried.

    A piece squeezed between the ground and a founded body is pushed by both in
    amounts the solve does not determine, only their sum; that cancelling part loads
    nothing. What a piece pushes into fixed bodies is what they took from it less
    that part, D (:func:`_lost`; the ground's rows are count..end), shared among its
    rows with fixed bodies in proportion to how hard each pushed along D. A piece
    pressed between a striking piece and a founded body passes the strike on.
    net (B, 7): work."""
    j = np.empty(3)
    d = np.empty(3)
    for r in range(end):
        for side in range(2):
            k = rows.body[r, side]
            if k >= 0 and not bodies.fixed[k]:
                net[k, :] = 0.0
    for r in range(end):
        for side in range(2):
            k = rows.body[r, side]
            if k < 0 or bodies.fixed[k]:
                continue
            o = rows.body[r, 1 - side]
            if r < count and (o < 0 or not bodies.fixed[o]):
                continue  # a free piece's push: a load that passes on
            row_impulse(rows, r, side, j)
            for a in range(3):
                net[k, a if r < count else 3 + a] += j[a]
    for r in range(end):  # each resting piece once: net[k, 6] is still 0 before the shares
        for side in range(2):
            k = rows.body[r, side]
            if k < 0 or bodies.fixed[k] or net[k, 6] != 0.0 or not _at_rest(bodies, k, slow):
                continue
            net[k, 6] = 1.0
            support[0] += bodies.mass[k]
            support[1] += net[k, 3] * up[0] + net[k, 4] * up[1] + net[k, 5] * up[2]
    for r in range(end):  # the flags off: net[k, 6] sums the shares' weights below
        for side in range(2):
            k = rows.body[r, side]
            if k >= 0 and not bodies.fixed[k]:
                net[k, 6] = 0.0
    for sweep in range(2):  # the weights' sums, then the shares
        n = 0
        for r in range(count):
            a_, b_ = rows.body[r, 0], rows.body[r, 1]
            if a_ < 0 or b_ < 0 or bodies.fixed[a_] == bodies.fixed[b_]:
                continue
            side = 0 if bodies.fixed[a_] else 1  # the fixed side
            k = rows.body[r, 1 - side]
            row_impulse(rows, r, side, j)  # on the fixed voxel
            _lost(net, k, d)
            size = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
            if size == 0.0:
                continue
            w = max(0.0, (j[0] * d[0] + j[1] * d[1] + j[2] * d[2]) / size)
            if sweep == 0:
                net[k, 6] += w
                continue
            if w == 0.0:
                continue
            v = rows.voxel[r, side]
            if impulse[v, 0] == 0.0 and impulse[v, 1] == 0.0 and impulse[v, 2] == 0.0:
                touched[n] = v
                n += 1
            rests = rows.approach[r] >= -slow and _at_rest(bodies, k, slow)
            for a in range(3):
                impulse[v, a] += d[a] * w / net[k, 6]
                if rests:
                    resting[v, a] += d[a] * w / net[k, 6]
    return n


#: The window (s) over which what contacts push into a founded body is averaged into a
#: static load on its links (:class:`SustainedLoads`): long against a step and the
#: contact solver's jitter, short against a collapse.
LOAD_WINDOW = 0.05
#: A founded body is solved again under its contacts' load when that load changed, summed
#: over its voxels, by more than this fraction of the load (before or after), and by
#: more than :data:`LOAD_FLOOR` of its weight.
LOAD_CHANGE = 0.1
#: Changes of a founded body's contact load smaller than this fraction of its weight
#: are not solved for (dust settling on a building).
LOAD_FLOOR = 1e-3


def _weight_only(force: np.ndarray, gravity: np.ndarray, carried: float) -> None:
    """Keep of each force (N, 3) N only its part along gravity (3,) m/s^2, and only
    where it pushes down, at most ``carried`` N in all: what rests on a body weighs on
    it, and the resting pieces' statics bound it (their weight less what the ground
    carries of it; the forces are scaled down together to that sum). A piece jammed
    between a founded overhang and the pile under it, or wedged between two founded
    parts, is squeezed by forces the contact solve does not determine (only their sum,
    through the soft push-out's overlap): an edge-on wall's own broken end, jammed under
    it, pushed it up with 230 kN, more than the wall weighs, and broke it; squeezed
    pieces pushed another 154 kN down on it (the whole wall weighs 56 kN)."""
    size = float(exact.norm(gravity))
    if size == 0.0:
        force[:] = 0.0
        return
    down = gravity / size
    along = np.maximum(force[:, 0] * down[0] + force[:, 1] * down[1] + force[:, 2] * down[2],
                       0.0)
    total = float(along.sum())
    if total > carried:
        along *= carried / total
    np.multiply(along[:, None], down[None, :], out=force)


class SustainedLoads:
    """What free pieces push into founded bodies, as forces on their voxels.

    The impulses of the resting contacts (that approached no faster than the contacts'
    line between resting and striking, :func:`~blastvox.simulate.contact.ground.rest_speed`,
    of pieces no faster than that: a strike is the punch's and the impact phase's) on
    each founded voxel (:func:`fixed_contact_impulses`) are summed
    over a window of :data:`LOAD_WINDOW` s; at its end their mean, ``force``
    (N, 3) N, is the voxels' load in the stress solve
    (:func:`~blastvox.simulate.stress.stress_phase`), and a body whose load changed by
    more than :data:`LOAD_CHANGE` since its last solve is solved again. Arrays are made
    on the first push (a scene whose pieces never touch a founded body needs none)."""

    def __init__(self, count: int, window: float = LOAD_WINDOW) -> None:
        self.count, self.window = count, window
        self.impulse: np.ndarray | None = None  # (N, 3) N s, this window's
        self.force: np.ndarray | None = None  # (N, 3) N, the last window's mean
        self.under: np.ndarray | None = None  # (N, 3) N, each body's at its last solve
        self.elapsed = 0.0
        self.carried = 0.0  # N s: this window's weight of resting pieces less the ground's

    def add(self, voxels: np.ndarray, impulse: np.ndarray, support: np.ndarray,
            weight_impulse: float) -> None:
        """The step's impulses (K, 3) N s on the founded ``voxels`` (K,); support (2,):
        the resting pieces' mass (kg) and the ground's impulse on them along up (N s)
        (:func:`fixed_contact_impulses`); weight_impulse: |g| dt, N s per kg."""
        if self.impulse is None:
            self.impulse = np.zeros((self.count, 3))
            self.force = np.zeros((self.count, 3))
            self.under = np.zeros((self.count, 3))
        self.impulse[voxels] += impulse
        self.carried += support[0] * weight_impulse - support[1]

    def close(self, state, stress, gravity: np.ndarray, mass: np.ndarray, dt: float) -> None:
        """After a step of dt s: at the window's end its mean force replaces ``force``,
        and the founded bodies whose load changed are marked unsolved (stress.solved).
        gravity (3,) m/s^2; mass (N,) kg, the voxels'."""
        if self.impulse is None:
            return
        self.elapsed += dt
        if self.elapsed < self.window * (1.0 - 1e-9):
            return
        np.divide(self.impulse, self.elapsed, out=self.force)
        _weight_only(self.force, gravity, max(self.carried, 0.0) / self.elapsed)
        self.impulse[:] = 0.0
        self.carried = 0.0
        self.elapsed = 0.0
        voxels, bodies = state.voxels, state.bodies
        founded = voxels.alive & bodies.fixed[voxels.body] & bodies.live[voxels.body]
        on = np.flatnonzero(founded & ((self.force != 0.0) | (self.under != 0.0)).any(axis=1))
        if not on.size:
            return
        body = voxels.body[on]
        size = len(bodies.mass)
        change = np.bincount(body, weights=exact.norm(self.force[on] - self.under[on]),
                             minlength=size)
        load = np.maximum(np.bincount(body, weights=exact.norm(self.force[on]), minlength=size),
                          np.bincount(body, weights=exact.norm(self.under[on]), minlength=size))
        weight = np.bincount(voxels.body[founded], weights=mass[founded], minlength=size
                             ) * float(exact.norm(gravity))
        stress.solved[(change > LOAD_CHANGE * load) & (change > LOAD_FLOOR * weight)] = False

    def solved(self, voxel_in: np.ndarray) -> None:
        """The voxels flagged in voxel_in (N,) were solved under ``force``."""
        if self.under is not None:
            self.under[voxel_in] = self.force[voxel_in]


class Punch:
    """The run's memory of :func:`punch_phase`: group (N,) each voxel's chunk (or the
    voxel itself), group_offsets (G+1,) and group_voxels (N,) the voxels of each group
    (CSR); impulse (N, 3) and touched (N,) work arrays; punched: chunks punched out;
    floor and version: see :func:`punch_phase`."""

    def __init__(self, group: np.ndarray) -> None:
        self.group = group
        # made when a contact first pushes a founded body (:meth:`ready`): a run whose
        # pieces never strike one (a founded million-voxel block) keeps 76 MB less
        self.group_voxels: np.ndarray | None = None
        self.group_offsets: np.ndarray | None = None
        self.impulse: np.ndarray | None = None
        self.resting: np.ndarray | None = None
        self.touched: np.ndarray | None = None
        self.net: np.ndarray | None = None
        # the least each (body, group) carries whichever way it is pushed (N), while the
        # links stand as at topology version ``version``: smaller pushes skip the links
        self.floor: dict[tuple[int, int], float] = {}
        self.version = -1
        self.punched = 0
        self.sustained = SustainedLoads(len(group))
        # the last phase's resting pushes: (voxels, impulses, support), see punch_phase
        self.last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def ready(self) -> None:
        """Make the groups' CSR and the work arrays, once."""
        if self.impulse is not None:
            return
        group = self.group
        order = np.argsort(group, kind="stable")
        self.group_voxels = order
        self.group_offsets = np.searchsorted(group[order], np.arange(int(group.max(
            initial=-1)) + 2))
        self.impulse = np.zeros((len(group), 3))
        self.resting = np.zeros((len(group), 3))
        self.touched = np.zeros(len(group), dtype=np.int64)

    @classmethod
    def of(cls, chunk: np.ndarray | None, count: int) -> Punch:
        """For a model of ``count`` voxels: groups by chunk (N,) (the stress solver's
        :attr:`~blastvox.simulate.stress.Stress.chunk`), or one per voxel."""
        return cls(np.arange(count, dtype=np.int64) if chunk is None
                   else np.ascontiguousarray(chunk, dtype=np.int64))


def punch_phase(model, state, stress, punch: Punch, rows, count: int, end: int,
                dt: float, resting: float = 0.0, up: np.ndarray | None = None) -> bool:
    """Phase: the chunks of founded bodies that this step's contacts (the first
    ``count`` solved rows between fragments, then the ground's up to ``end``) pushed
    harder than their links can carry are punched out (see the module docstring).
    Writes links.alive, marks.broken and marks.dirty and counters.broken_links (the
    caller splits, and solves the step's contacts again with the punched chunks
    free: :func:`blastvox.simulate.engine.step`). stress: the run's
    :class:`~blastvox.simulate.stress.Stress` (the links' areas and strengths);
    resting: the approach speed (m/s) below which a row rests (its push is kept in
    punch.last for :class:`SustainedLoads`, with the resting pieces' support: see
    :func:`fixed_contact_impulses`); up (3,): the unit vector against gravity (None: no
    gravity). Returns whether any link broke."""
    bodies, voxels = state.bodies, state.voxels
    punch.last = None
    if end == 0:  # no contact this step
        return False
    punch.ready()
    if punch.net is None or len(punch.net) != len(bodies.mass):
        punch.net = np.zeros((len(bodies.mass), 7))
    support = np.zeros(2)
    k = fixed_contact_impulses(rows, count, end, bodies, punch.impulse, punch.touched,
                               punch.net, resting, punch.resting,
                               np.zeros(3) if up is None else up, support)
    punch.last = None
    if k == 0:
        return False
    touched = np.unique(punch.touched[:k])  # a voxel whose sum passed through zero repeats
    # strikes punch; what rests weighs (SustainedLoads): a piece at rest pressed between
    # two parts of a wall is squeezed by the soft push-out, J ~ overlap / dt, a force
    # that grows as 1 / dt^2 and is not a load
    pushed = punch.impulse[touched] - punch.resting[touched]
    punch.last = (touched, punch.resting[touched].copy(), support)
    punch.impulse[touched] = 0.0
    punch.resting[touched] = 0.0
    span = len(punch.group_offsets) - 1  # (body, group) as one key: body * span + group
    keys, which = np.unique(voxels.body[touched] * span + punch.group[touched],
                            return_inverse=True)
    total = np.zeros((len(keys), 3))
    np.add.at(total, which.ravel(), pushed)
    force = np.linalg.norm(total, axis=1) / np.maximum(
        dt, _strike_times(model, state, rows, count, keys, punch.group, span))
    springs = stress.springs
    if punch.version != state.counters.topology_version:  # links changed: floors too
        punch.floor.clear()
        punch.version = state.counters.topology_version
    broke = False
    for i in np.flatnonzero(force > 0.0):
        b, g = divmod(int(keys[i]), span)
        if force[i] <= punch.floor.get((b, g), 0.0):
            continue  # carried whichever way it pushes: rubble resting on a floor
        members = punch.group_voxels[punch.group_offsets[g]:punch.group_offsets[g + 1]]
        members = members[voxels.alive[members] & (voxels.body[members] == b)]
        if not members.size or voxels.foundation[members].any():
            punch.floor[(b, g)] = math.inf  # held by the ground: never punched
            continue
        links, outward = _boundary_links(model, state, members)
        if not links.size:
            continue
        punch.floor[(b, g)] = float(np.sum(springs.area[links] * np.minimum(
            springs.compressive[links], np.minimum(springs.tensile[links], springs.shear[links]))))
        along = exact.dot(outward, total[i] / exact.norm(total[i]))
        strength = np.where(along > AHEAD, springs.compressive[links],
                            np.minimum(springs.tensile[links], springs.shear[links]))
        capacity = float(np.sum(springs.area[links] * strength))
        if not force[i] > capacity:
            continue
        state.links.alive[links] = False
        state.marks.broken[links] = True
        state.marks.dirty[b] = True
        state.counters.broken_links += int(links.size)
        punch.punched += 1
        broke = True
    return broke


def _strike_times(model, state, rows, count: int, keys: np.ndarray, group: np.ndarray,
                  span: int) -> np.ndarray:
    """(K,) s: for each (founded body, group) key, the longest elastic contact time of
    the free pieces whose rows (the first ``count``) touch it: 2 L / c, L the piece's
    size (twice its bounding radius, m) and c its material's bar wave speed (Goldsmith
    1960, *Impact*, ch. 2: a rod's strike lasts two transits of its length). The
    solve's impulse over a shorter step read as a force grew as 1/dt: the debris
    settling against an edge-on wall punched 32 chunks out of it at 1/4000 s and 2 at
    1/960 s."""
    times = np.zeros(len(keys))
    body, voxel = rows.body[:count], rows.voxel[:count]
    fixed = np.where(body >= 0, state.bodies.fixed[np.maximum(body, 0)], True)
    one = fixed[:, 0] != fixed[:, 1]
    if not one.any():
        return times
    side = np.where(fixed[one, 0], 0, 1)  # the founded side
    struck = voxel[one][np.arange(one.sum()), side]
    striker = body[one][np.arange(one.sum()), 1 - side]
    hitting = voxel[one][np.arange(one.sum()), 1 - side]
    key = state.voxels.body[struck] * span + group[struck]
    place = np.searchsorted(keys, key)
    known = (place < len(keys)) & (keys[np.minimum(place, len(keys) - 1)] == key)
    speed = model.wave_speed[model.material[hitting]]
    tau = np.where(speed > 0.0, 4.0 * state.bodies.radius[striker] / np.where(
        speed > 0.0, speed, 1.0), 0.0)
    np.maximum.at(times, place[known], tau[known])
    return times


def _boundary_links(model, state, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The alive links from ``members`` (voxel ids, one body) to the rest of their body,
    and each one's outward direction (K, 3), from the member to its neighbour, in the
    world frame (the links' rest directions turned by the body's rotation)."""
    links = model.links
    candidates, owner = voxel_links(model, members)
    alive = state.links.alive[candidates]
    candidates, owner = candidates[alive], owner[alive]
    ends = links.voxels[candidates]
    first = ends[:, 0] == owner
    outside = ~np.isin(np.where(first, ends[:, 1], ends[:, 0]), members)
    candidates, first = candidates[outside], first[outside]
    sign = np.where(first, 1.0, -1.0)
    body = int(state.voxels.body[members[0]])
    rest = links.direction[candidates] * sign[:, None]
    return candidates, exact.matvec(state.bodies.rot[body], rest)
