"""First-run compilation on two cores: a forked child compiles the phases a run needs last.

numba compiles a kernel on its first call, one after another (its compiler
lock), so a first run pays the sum of every kernel's compile time: about a
minute for a shot with every effect on two busy cores. The kernels a step
needs last (contacts, ground, sleeping, integration, fire) do not depend on
what the first (fracture, splits, blast loading) compute, only on the types
of the run's arrays, which the run itself fixes.

So when the kernel cache is cold, :func:`compile_ahead` forks the process
just after the run is built: the child calls those late phases once on its
own copy of the run (compiling them into numba's on-disk cache) while the
parent starts stepping and compiles the early ones; when the parent reaches
a late phase, numba loads it from the cache instead of compiling it. Nothing
here is recorded or listed by hand: the child calls the phases themselves,
with the run's own arrays, so a new kernel or a changed signature is covered
by the same calls. The child writes only the cache; the parent waits for it
at the end of the run. Forking is used only on Linux, with a single thread
alive (no progress bar yet), as numba's documentation requires of fork.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable

import numpy as np

from blastvox.simulate import fire, integrate, kernels
from blastvox.simulate.contact import fragments as collide
from blastvox.simulate.contact import ground
from blastvox.simulate.contact import solver as contact_solver


def compile_ahead(run) -> Callable[[bool], None]:
    """Fork a child that compiles ``run``'s late phases (see the module docstring).

    Returns ``finish(cancel)``: it waits for the child, after stopping it (SIGTERM)
    if ``cancel`` (the run was interrupted: Ctrl-C must not wait for compilation;
    numba replaces cache files whole, so a stopped child leaves none half
    written). A no-op where no child was started. Call only when the kernel
    cache is cold: with a warm one the child would only load what the parent
    loads anyway.
    """
    if not _can_fork():
        return lambda cancel=False: None
    pid = os.fork()
    if pid == 0:  # the child: compile, never return into the caller's code
        code = 1
        try:
            for signum in (signal.SIGINT, signal.SIGTERM):  # not the parent's handlers:
                signal.signal(signum, signal.SIG_DFL)  # finish(cancel) must stop it at once
            compile_late_phases(run)
            code = 0
        finally:
            os._exit(code)

    def finish(cancel: bool = False) -> None:
        if cancel:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)
        with contextlib.suppress(ChildProcessError):
            os.waitpid(pid, 0)

    return finish


def compile_late_phases(run) -> None:
    """Call, once each, the phases after the blast loading that ``run``'s settings switch
    on, the ones a step needs soonest first, but the contact solver before them all
    (its compile is the longest; see :func:`_compile_solver`). Changes ``run``'s
    state: call it on a copy (the forked child's)."""
    model, state, s, dt = run.model, run.state, run.settings, run.dt
    integrate.integrate_velocities(dt, run.gravity, s.linear_drag, s.angular_drag,
                                   state.loads, state.bodies)
    if s.collisions or run.ground is not None:
        _compile_solver(state, s, dt, model.up)
    if s.collisions:
        collide.begin_contacts(state)
        collide.collide_phase(model, state, s, dt)
        collide.strike_phase(model, state, s)
    if run.ground is not None:
        ground.ground_phase(model, state, s, dt, run.ground)
    if s.collisions or run.ground is not None:
        kernels.settle(state.bodies, s.sleep_speed, run.still_steps,
                       np.ones(len(state.bodies.mass), dtype=bool))
    integrate.integrate_positions(dt, state.bodies)
    if run.fire is not None:
        fire.burn_phase(model, state, run.fire, s, dt, 0)


def _compile_solver(state, settings, dt: float, up) -> None:
    """The contact solver on no rows, with a memory of the run's types: it compiles
    first, the longest of the contact phases (about 6 s on 2 cores), so that it is in
    the cache when the run's first contact reaches it (called through the phases, it
    came after collision detection and the run compiled it too). The child's state
    keeps the memory it had (none yet: the first contact phase makes the real one)."""
    contacts = state.contacts
    memory = ground.new_memory(state, 1.0, np.zeros((0, 3)), np.zeros(0))
    contact_solver.solve_contacts(state.bodies, memory, 0,
                                  ground.solver_params(memory, settings, dt, up),
                                  state.loads)
    state.contacts = contacts


def _can_fork() -> bool:
    return (sys.platform.startswith("linux") and hasattr(os, "fork")
            and threading.active_count() == 1
            and os.environ.get("BLASTVOX_COMPILE_AHEAD", "1") != "0")
