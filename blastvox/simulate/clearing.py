"""The size of each piece across the wave, for clearing (UFC 3-340-02 §2-15.3.2).

A reflected pressure relieves from the edges of the loaded surface: the
clearing time grows with the surface's smaller half-extent S and the ratio
S/G to the larger one (:func:`blastvox.blast.face_load.face_load_nb`). Here the
surface is the piece's silhouette seen from the charge: its rest bounding box,
turned with the piece, measured along the up direction and the horizontal,
both perpendicular to the line from the charge. A free piece clears over all
four edges (S = half the smaller extent); a founded one does not clear at its
foot (S = the smaller of its height and half its width, as UFC's front wall).
"""

from __future__ import annotations

import math

import numpy as np

from blastvox.jit import kernel
from blastvox.simulate.model import CONFORM_FACES
from blastvox.simulate.state import Exposure


@kernel
def body_boxes(geometry, voxels, n_bodies):
    """Rest bounding boxes (B, 2, 3) of each body's alive voxels' corners, m, relative to
    nothing (rest frame); empty bodies get lo > hi."""
    vertices, corners = geometry.vertices, geometry.corners
    out = np.empty((n_bodies, 2, 3))
    out[:, 0, :] = np.inf
    out[:, 1, :] = -np.inf
    for v in range(corners.shape[0]):
        if not voxels.alive[v]:
            continue
        b = voxels.body[v]
        for c in range(8):
            for a in range(3):
                x = vertices[corners[v, c], a]
                if x < out[b, 0, a]:
                    out[b, 0, a] = x
                if x > out[b, 1, a]:
                    out[b, 1, a] = x
    return out


@kernel
def clearing_sizes(boxes, bodies, active, charge_pos, up):
    """(B, C, 2) the smaller and larger half-extent S, G (m) of each active body's
    silhouette from each charge (0 for inactive or empty bodies); up (3,) unit."""
    n_bodies, n_charges = boxes.shape[0], charge_pos.shape[0]
    out = np.zeros((n_bodies, n_charges, 2))
    corner = np.empty(3)
    for b in range(n_bodies):
        if not active[b] or boxes[b, 0, 0] > boxes[b, 1, 0]:
            continue
        for c in range(n_charges):
            u = bodies.pos[b] - charge_pos[c]
            norm = math.sqrt(u[0] ** 2 + u[1] ** 2 + u[2] ** 2)
            if norm <= 0.0:
                continue
            u /= norm
            e_h = up - (up[0] * u[0] + up[1] * u[1] + up[2] * u[2]) * u
            h_norm = math.sqrt(e_h[0] ** 2 + e_h[1] ** 2 + e_h[2] ** 2)
            if h_norm < 1e-6:  # seen from straight above or below: any horizontal
                e_h = np.array([u[1], -u[0], 0.0]) if abs(u[2]) < 0.9 else np.array(
                    [0.0, u[2], -u[1]])
                h_norm = math.sqrt(e_h[0] ** 2 + e_h[1] ** 2 + e_h[2] ** 2)
            e_h /= h_norm
            e_w = np.array([u[1] * e_h[2] - u[2] * e_h[1], u[2] * e_h[0] - u[0] * e_h[2],
                            u[0] * e_h[1] - u[1] * e_h[0]])
            h_lo, h_hi, w_lo, w_hi = np.inf, -np.inf, np.inf, -np.inf
            for k in range(8):
                for a in range(3):
                    corner[a] = boxes[b, (k >> (2 - a)) & 1, a] - bodies.com[b, a]
                h = 0.0
                w = 0.0
                for a in range(3):
                    world = (bodies.rot[b, a, 0] * corner[0] + bodies.rot[b, a, 1] * corner[1]
                             + bodies.rot[b, a, 2] * corner[2])
                    h += world * e_h[a]
                    w += world * e_w[a]
                h_lo, h_hi = min(h_lo, h), max(h_hi, h)
                w_lo, w_hi = min(w_lo, w), max(w_hi, w)
            height, width = h_hi - h_lo, w_hi - w_lo
            if bodies.fixed[b]:
                s, g = min(height, 0.5 * width), max(height, 0.5 * width)
            else:
                s, g = 0.5 * min(height, width), 0.5 * max(height, width)
            out[b, c, 0], out[b, c, 1] = s, g
    return out


def clearing_of(model, state, charge_pos: np.ndarray, active: np.ndarray) -> np.ndarray:
    """(B, C, 2) :func:`clearing_sizes` of the state's bodies as they stood when the
    current wave arrived: sizes are kept from the step a wave first reaches a body
    (state.caches.clearing, reset by :func:`reset_clearing`), and a piece split off
    during the wave keeps its parent's, so what a wave does does not depend on how
    many steps it took to cross a structure."""
    caches = state.caches
    n = state.n_bodies
    known = caches.clearing
    if known is None or known.shape[1] != len(charge_pos):
        known = caches.clearing = np.full((len(state.bodies.mass), len(charge_pos), 2), np.nan)
    missing = active[:n] & np.isnan(known[:n, 0, 0])
    if missing.any():
        inherit = missing & (state.bodies.parent[:n] >= 0)
        for b in np.flatnonzero(inherit):  # a split's pieces are born in parent order
            parent = state.bodies.parent[b]
            if not np.isnan(known[parent, 0, 0]):
                known[b] = known[parent]
        missing = active[:n] & np.isnan(known[:n, 0, 0])
    if missing.any():
        version = state.counters.topology_version
        if caches.boxes is None or caches.boxes_version != version:
            caches.boxes = body_boxes(model.voxels, state.voxels, n)
            caches.boxes_version = version
        sizes = clearing_sizes(caches.boxes, state.bodies, missing, charge_pos, model.up)
        known[:n][missing] = sizes[missing]
    return known


def reset_clearing(state) -> None:
    """Forget the clearing sizes and the lines of sight: a new wave arrives."""
    if state.caches.clearing is not None:
        state.caches.clearing[:] = np.nan
    if state.caches.sight is not None:
        state.caches.sight[:] = 0
    state.caches.reach = None
    state.caches.detour = None


def exposure_of(model, state, charge_pos: np.ndarray, active: np.ndarray,
                gas: np.ndarray | None) -> Exposure:
    """The :class:`~blastvox.simulate.state.Exposure` of the current wave: the shielding
    grid, :func:`clearing_of`, the charges' gas (zeros if None), the faces' sight
    cache, the air the waves reach and their detours round solid
    (:mod:`blastvox.simulate.diffraction`; kept in state.caches, reset with the
    clearing by :func:`reset_clearing`: a new wave)."""
    caches = state.caches
    n_charges = len(charge_pos)
    if caches.sight is None or caches.sight.shape[1] != n_charges:
        caches.sight = np.zeros((state.shielding.member.shape[0], n_charges, CONFORM_FACES),
                                dtype=np.int8)
    if caches.reach is None or caches.reach.shape[0] != n_charges:
        from blastvox.simulate.confinement import wave_reach

        caches.reach = wave_reach(state.shielding, charge_pos)
        if caches.leaky is not None:  # rooms fill through their openings, not by the wave
            caches.reach[:, caches.leaky] = False
    if caches.detour is None or caches.detour.extra.shape[0] != n_charges:
        from blastvox.simulate.diffraction import detour_field

        caches.detour = detour_field(state.shielding, charge_pos, caches.ground)
    return Exposure(state.shielding, clearing_of(model, state, charge_pos, active),
                    np.zeros((n_charges, 2)) if gas is None else gas, caches.sight,
                    caches.reach, caches.detour)
