"""A small z-buffer rasteriser in numba: background, ground, triangles, splats, spheres.

Every kernel draws into the same two buffers, a :class:`Target`, in *view
space* (the camera at the origin, x right, y up, z forward along the line of
sight, metres):

* ``color`` (H, W, 3) float32: linear RGB, 0..1 (emissive splats may exceed 1;
  :func:`resolve` clips);
* ``depth`` (H, W) float32: 1/z of the nearest opaque surface (1/m), 0 where
  nothing opaque has been drawn (infinitely far), so *greater is nearer* and
  1/z interpolates linearly in screen space (perspective-correct depth).

A pixel (px, py) is sampled at its centre; the pinhole (a :class:`Pinhole`)
maps a view-space point to ``sx = cx + f x / z``, ``sy = cy - f y / z`` with
``f`` the focal length in pixels. Opaque triangles are culled when they face
away, clipped against the near plane ``z = near`` and filled with the z-test;
splats (particles) and the translucent spheres (shock fronts) are z-tested
against the opaque surfaces but do not write depth, and are alpha-blended in
the order given.

Kernels are serial and use no fast-math, so the same input gives the same
pixels on every run (previews are byte-reproducible). They are compiled once
and cached by numba (``cache=True``, see blastvox._kernel_cache). Their arguments are grouped into
a few NamedTuples of arrays and scalars (as :mod:`blastvox.simulate.state`
does); a kernel unpacks the fields it uses at its top.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from blastvox.jit import kernel

EDGE_TOL_PX = 1e-3  #: a pixel centre this close outside a triangle edge is inside
EDGE_DEPTH_BIAS = 1.0 - 1e-6  #: and loses a depth tie against a triangle it is inside


class Target(NamedTuple):
    """The buffers every kernel draws into (H, W: the supersampled image's pixels).

    color (H, W, 3) float32 linear RGB; depth (H, W) float32 1/z of the nearest
    opaque surface, 1/m, 0 where nothing opaque has been drawn.
    """

    color: np.ndarray
    depth: np.ndarray


class Pinhole(NamedTuple):
    """The camera as the kernels see it.

    rotation (3, 3) world -> view (rows: right, up, forward); eye (3,) m, its
    position; fpx: focal length, pixels; cx, cy: the image centre, pixels;
    near: the near clipping plane, m. Only :func:`draw_ground` (which works in
    world space) reads rotation and eye.
    """

    rotation: np.ndarray
    eye: np.ndarray
    fpx: float
    cx: float
    cy: float
    near: float


class Ground(NamedTuple):
    """The infinite ground plane ``dot(up, x) = height`` and how it looks.

    up, axis_u, axis_v (3,): the plane's unit normal and two in-plane axes of
    its grid lines, one every ``grid_step`` m; height, m. ``shade`` scales
    ``albedo`` (3,) linear RGB (the lighting of the flat plane); beyond the
    camera the plane fades into ``fog_color`` (3,) as 1 - exp(-z / fog_distance)
    (z view depth, m).
    """

    up: np.ndarray
    height: float
    axis_u: np.ndarray
    axis_v: np.ndarray
    grid_step: float
    albedo: np.ndarray
    shade: float
    fog_distance: float
    fog_color: np.ndarray


class Triangles(NamedTuple):
    """Triangles (T) in their pieces' frames: local (T, 3, 3) corners, m; normals (T, 3)
    unit; piece (T,) the index of their piece; albedo (T, 3) linear RGB."""

    local: np.ndarray
    normals: np.ndarray
    piece: np.ndarray
    albedo: np.ndarray


class Poses(NamedTuple):
    """Pieces (P) at one frame: rotation (P, 3, 3) piece -> world; matrix (P, 3, 3)
    piece -> view (the camera's rotation times the piece's); offset (P, 3) m, the
    piece's origin in view space; alive (P,) bool."""

    rotation: np.ndarray
    matrix: np.ndarray
    offset: np.ndarray
    alive: np.ndarray


class Lighting(NamedTuple):
    """Flat shading: a face of world normal n gets ``ambient + sky (1 + n.up) / 2 +
    key max(0, n.light)`` times its albedo; up and light (3,) unit vectors."""

    up: np.ndarray
    light: np.ndarray
    ambient: float
    sky: float
    key: float


class Splats(NamedTuple):
    """Particles (K), in the order they are blended: centres (K, 3) view space, m;
    radius (K,) m; colors (K, 3) linear RGB; alpha (K,) 0..1."""

    centres: np.ndarray
    radius: np.ndarray
    colors: np.ndarray
    alpha: np.ndarray


@kernel
def fill_background(target, top, bottom) -> None:
    """Clear the ``target``'s depth to 0 and its colour to a vertical gradient from
    ``top`` (3,) at the first row to ``bottom`` (3,) at the last (linear RGB)."""
    color, depth = target.color, target.depth
    h, w = depth.shape
    for y in range(h):
        s = (y + 0.5) / h
        r = top[0] + (bottom[0] - top[0]) * s
        g = top[1] + (bottom[1] - top[1]) * s
        b = top[2] + (bottom[2] - top[2]) * s
        for x in range(w):
            color[y, x, 0] = r
            color[y, x, 1] = g
            color[y, x, 2] = b
            depth[y, x] = 0.0


@kernel
def draw_ground(target, camera, ground) -> None:
    """The infinite :class:`Ground` plane seen through ``camera`` (a :class:`Pinhole`),
    per pixel by ray casting. Writes depth."""
    color, depth = target.color, target.depth
    view_rot, eye = camera.rotation, camera.eye
    fpx, cx, cy, near = camera.fpx, camera.cx, camera.cy, camera.near
    up, height, axis_u, axis_v = ground.up, ground.height, ground.axis_u, ground.axis_v
    grid_step, albedo, shade = ground.grid_step, ground.albedo, ground.shade
    fog_distance, fog_color = ground.fog_distance, ground.fog_color
    h, w = depth.shape
    d_eye = height - (up[0] * eye[0] + up[1] * eye[1] + up[2] * eye[2])
    line = 0.03 * grid_step
    for y in range(h):
        vy = -(y + 0.5 - cy) / fpx
        for x in range(w):
            vx = (x + 0.5 - cx) / fpx
            # world direction of the ray whose view-space z component is 1
            dx = view_rot[0, 0] * vx + view_rot[1, 0] * vy + view_rot[2, 0]
            dy = view_rot[0, 1] * vx + view_rot[1, 1] * vy + view_rot[2, 1]
            dz = view_rot[0, 2] * vx + view_rot[1, 2] * vy + view_rot[2, 2]
            denom = up[0] * dx + up[1] * dy + up[2] * dz
            if denom == 0.0:
                continue
            t = d_eye / denom  # = view depth z, since the ray's view z is 1
            if t <= near:
                continue
            inv = 1.0 / t
            if inv <= depth[y, x]:
                continue
            px = eye[0] + t * dx
            py = eye[1] + t * dy
            pz = eye[2] + t * dz
            # grid lines: darken by the fraction of the pixel footprint they cover
            footprint = t / fpx
            half = 0.5 * max(line, footprint)
            cover = min(1.0, line / footprint)
            darken = 0.0
            for k in range(2):
                if k == 0:
                    c = px * axis_u[0] + py * axis_u[1] + pz * axis_u[2]
                else:
                    c = px * axis_v[0] + py * axis_v[1] + pz * axis_v[2]
                m = c / grid_step
                dist = abs(m - math.floor(m + 0.5)) * grid_step
                if dist < half:
                    darken = max(darken, cover)
            fog = 1.0 - math.exp(-t / fog_distance)
            k_lit = shade * (1.0 - 0.35 * darken)
            for ch in range(3):
                lit = albedo[ch] * k_lit
                color[y, x, ch] = lit + (fog_color[ch] - lit) * fog
            depth[y, x] = inv


@kernel
def _fill_triangle(target, corner0, corner1, corner2, rgb) -> None:
    """Fill one projected triangle with the z-test: each corner a tuple (sx, sy, 1/z) of
    pixel coordinates and inverse depth, ``rgb`` a tuple (r, g, b).

    Edge functions are stepped incrementally along each row. A pixel centre on
    an edge shared by two triangles (or a hair's breadth outside both, from
    rounding or a T-junction) must not be missed by both, so a centre within
    ``EDGE_TOL_PX`` of an edge counts as inside. There it takes the depth of the
    nearest point of the triangle (not an extrapolation, which for a face seen
    edge-on could come out nearer than the face in front of it), pushed back by
    ``EDGE_DEPTH_BIAS``, so that a triangle the centre is really inside wins.
    """
    color, depth = target.color, target.depth
    x0, y0, w0 = corner0
    x1, y1, w1 = corner1
    x2, y2, w2 = corner2
    r, g, b = rgb
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if area == 0.0 or not math.isfinite(area):
        return
    h, w = depth.shape
    xmin = max(0, int(math.floor(min(x0, min(x1, x2)))))
    xmax = min(w - 1, int(math.ceil(max(x0, max(x1, x2)))))
    ymin = max(0, int(math.floor(min(y0, min(y1, y2)))))
    ymax = min(h - 1, int(math.ceil(max(y0, max(y1, y2)))))
    if xmin > xmax or ymin > ymax:
        return
    sgn = 1.0 if area > 0.0 else -1.0
    inv_area = 1.0 / abs(area)
    # E_i(sx, sy) = c_i + a_i sx + b_i sy, positive inside (after the sign flip)
    a0, b0, c0 = sgn * (y1 - y2), sgn * (x2 - x1), sgn * (x1 * y2 - x2 * y1)
    a1, b1, c1 = sgn * (y2 - y0), sgn * (x0 - x2), sgn * (x2 * y0 - x0 * y2)
    a2, b2, c2 = sgn * (y0 - y1), sgn * (x1 - x0), sgn * (x0 * y1 - x1 * y0)
    t0 = -EDGE_TOL_PX * math.sqrt(a0 * a0 + b0 * b0)
    t1 = -EDGE_TOL_PX * math.sqrt(a1 * a1 + b1 * b1)
    t2 = -EDGE_TOL_PX * math.sqrt(a2 * a2 + b2 * b2)
    for py in range(ymin, ymax + 1):
        sy = py + 0.5
        # this row's span: where every edge function reaches its tolerance (widened by a
        # pixel against rounding; the edge tests below decide)
        lo, hi = float(xmin), float(xmax)
        for a, bc, tol in ((a0, c0 + b0 * sy, t0), (a1, c1 + b1 * sy, t1),
                           (a2, c2 + b2 * sy, t2)):
            if a > 0.0:
                lo = max(lo, (tol - bc) / a - 1.5)
            elif a < 0.0:
                hi = min(hi, (tol - bc) / a + 0.5)
            elif bc < tol:
                hi = lo - 1.0
        if hi < lo:
            continue
        x_start, x_stop = int(math.floor(lo)), int(math.ceil(hi))
        sx = x_start + 0.5
        e0 = c0 + a0 * sx + b0 * sy
        e1 = c1 + a1 * sx + b1 * sy
        e2 = c2 + a2 * sx + b2 * sy
        for px in range(x_start, x_stop + 1):
            if e0 >= t0 and e1 >= t1 and e2 >= t2:
                if e0 >= 0.0 and e1 >= 0.0 and e2 >= 0.0:
                    z = (e0 * w0 + e1 * w1 + e2 * w2) * inv_area
                else:  # only just outside: the edge's depth, pushed back a hair
                    k0, k1, k2 = max(e0, 0.0), max(e1, 0.0), max(e2, 0.0)
                    z = (k0 * w0 + k1 * w1 + k2 * w2) / (k0 + k1 + k2) * EDGE_DEPTH_BIAS
                if z > depth[py, px]:
                    depth[py, px] = z
                    color[py, px, 0] = r
                    color[py, px, 1] = g
                    color[py, px, 2] = b
            e0 += a0
            e1 += a1
            e2 += a2


@kernel
def transform_triangles(triangles, poses, lighting, out_view, out_color) -> int:
    """Rigidly moved, flat-shaded triangles of the alive pieces, in view space.

    ``triangles`` (:class:`Triangles`, T) are moved by their piece's pose
    (:class:`Poses`) and shaded by ``lighting`` (:class:`Lighting`, with n the
    world normal). Writes the first K rows of ``out_view`` (T, 3, 3) and
    ``out_color`` (T, 3) and returns K, the number of alive triangles.
    """
    local, normals = triangles.local, triangles.normals
    piece, albedo = triangles.piece, triangles.albedo
    rotation, matrix, offset, alive = poses.rotation, poses.matrix, poses.offset, poses.alive
    up, light = lighting.up, lighting.light
    ambient, sky, key = lighting.ambient, lighting.sky, lighting.key
    k = 0
    for t in range(local.shape[0]):
        p = piece[t]
        if not alive[p]:
            continue
        for v in range(3):
            for i in range(3):
                out_view[k, v, i] = (offset[p, i] + matrix[p, i, 0] * local[t, v, 0]
                                     + matrix[p, i, 1] * local[t, v, 1]
                                     + matrix[p, i, 2] * local[t, v, 2])
        n_up = 0.0
        n_light = 0.0
        for i in range(3):
            n = (rotation[p, i, 0] * normals[t, 0] + rotation[p, i, 1] * normals[t, 1]
                 + rotation[p, i, 2] * normals[t, 2])
            n_up += n * up[i]
            n_light += n * light[i]
        shade = ambient + sky * 0.5 * (1.0 + n_up) + key * max(n_light, 0.0)
        for i in range(3):
            out_color[k, i] = albedo[t, i] * shade
        k += 1
    return k


@kernel
def draw_triangles(target, camera, vertices, colors) -> int:
    """Opaque triangles ``vertices`` (T, 3, 3) in view space (m), flat ``colors`` (T, 3),
    seen through ``camera`` (a :class:`Pinhole`).

    Corners are counter-clockwise seen from outside (outward normals, as
    :func:`blastvox.export.pieces.piece_meshes` makes them); triangles seen from
    behind are culled. The view basis (right, up, forward) is left-handed, so a
    triangle faces the camera when ``dot(cross(b - a, c - a), a) > 0``. Parts in
    front of ``z = near`` are clipped away. Returns the number of triangles drawn.
    """
    fpx, cx, cy, near = camera.fpx, camera.cx, camera.cy, camera.near
    drawn = 0
    poly = np.empty((4, 3))
    for t in range(vertices.shape[0]):
        ax, ay, az = vertices[t, 0, 0], vertices[t, 0, 1], vertices[t, 0, 2]
        bx, by, bz = vertices[t, 1, 0], vertices[t, 1, 1], vertices[t, 1, 2]
        qx, qy, qz = vertices[t, 2, 0], vertices[t, 2, 1], vertices[t, 2, 2]
        ux, uy, uz = bx - ax, by - ay, bz - az
        vx, vy, vz = qx - ax, qy - ay, qz - az
        nx = uy * vz - uz * vy
        ny = uz * vx - ux * vz
        nz = ux * vy - uy * vx
        if nx * ax + ny * ay + nz * az <= 0.0:
            continue
        inside = (az >= near) + (bz >= near) + (qz >= near)
        if inside == 0:
            continue
        r, g, b = colors[t, 0], colors[t, 1], colors[t, 2]
        if inside == 3:
            _fill_triangle(target, (cx + fpx * ax / az, cy - fpx * ay / az, 1.0 / az),
                           (cx + fpx * bx / bz, cy - fpx * by / bz, 1.0 / bz),
                           (cx + fpx * qx / qz, cy - fpx * qy / qz, 1.0 / qz), (r, g, b))
            drawn += 1
            continue
        # Sutherland-Hodgman against z >= near: a triangle or a quad remains
        n = 0
        for i in range(3):
            j = (i + 1) % 3
            pz, sz = vertices[t, i, 2], vertices[t, j, 2]
            if pz >= near:
                poly[n, 0] = vertices[t, i, 0]
                poly[n, 1] = vertices[t, i, 1]
                poly[n, 2] = pz
                n += 1
            if (pz >= near) != (sz >= near):
                s = (near - pz) / (sz - pz)
                poly[n, 0] = vertices[t, i, 0] + s * (vertices[t, j, 0] - vertices[t, i, 0])
                poly[n, 1] = vertices[t, i, 1] + s * (vertices[t, j, 1] - vertices[t, i, 1])
                poly[n, 2] = near
                n += 1
        for k in range(1, n - 1):
            _fill_triangle(target,
                           (cx + fpx * poly[0, 0] / poly[0, 2], cy - fpx * poly[0, 1] / poly[0, 2],
                            1.0 / poly[0, 2]),
                           (cx + fpx * poly[k, 0] / poly[k, 2], cy - fpx * poly[k, 1] / poly[k, 2],
                            1.0 / poly[k, 2]),
                           (cx + fpx * poly[k + 1, 0] / poly[k + 1, 2],
                            cy - fpx * poly[k + 1, 1] / poly[k + 1, 2], 1.0 / poly[k + 1, 2]),
                           (r, g, b))
        drawn += 1
    return drawn


@kernel
def draw_splats(target, camera, splats, min_radius_px, max_radius_px) -> None:
    """Round, soft-edged particles (:class:`Splats`) seen through ``camera`` (a
    :class:`Pinhole`), blended in the given order (pass them far to near). The
    on-screen radius is clamped to [min_radius_px, max_radius_px]."""
    color, depth = target.color, target.depth
    fpx, cx, cy, near = camera.fpx, camera.cx, camera.cy, camera.near
    centres, radius, colors, alpha = splats.centres, splats.radius, splats.colors, splats.alpha
    h, w = depth.shape
    for k in range(centres.shape[0]):
        z = centres[k, 2]
        if z < near or alpha[k] <= 0.0:
            continue
        sx = cx + fpx * centres[k, 0] / z
        sy = cy - fpx * centres[k, 1] / z
        rad = min(max(fpx * radius[k] / z, min_radius_px), max_radius_px)
        xmin = max(0, int(math.floor(sx - rad)))
        xmax = min(w - 1, int(math.ceil(sx + rad)))
        ymin = max(0, int(math.floor(sy - rad)))
        ymax = min(h - 1, int(math.ceil(sy + rad)))
        inv_z = 1.0 / z
        inv_r2 = 1.0 / (rad * rad)
        for py in range(ymin, ymax + 1):
            dy = py + 0.5 - sy
            if dy * dy >= rad * rad:
                continue
            half = math.sqrt(rad * rad - dy * dy)  # the circle's span on this row
            x0 = max(xmin, int(math.floor(sx - half)))
            x1 = min(xmax, int(math.ceil(sx + half)))
            for px in range(x0, x1 + 1):
                dx = px + 0.5 - sx
                q = (dx * dx + dy * dy) * inv_r2
                if q >= 1.0 or inv_z <= depth[py, px]:
                    continue
                a = alpha[k] * (1.0 - q * q)  # soft edge
                for ch in range(3):
                    color[py, px, ch] += (colors[k, ch] - color[py, px, ch]) * a


@kernel
def draw_spheres(target, camera, centres, radius, opacity, tint) -> None:
    """Translucent spheres (shock fronts) seen through ``camera`` (a :class:`Pinhole`):
    centres (S, 3) view space (m), radius (S,) m, opacity (S,) 0..1, colour ``tint``
    (3,). Both the far and the near side are drawn where they are in front of the
    opaque surfaces; a surface's alpha grows towards the silhouette, so a front reads
    as a bright ring with a faint veil inside."""
    color, depth = target.color, target.depth
    fpx, cx, cy, near = camera.fpx, camera.cx, camera.cy, camera.near
    h, w = depth.shape
    for s in range(centres.shape[0]):
        if opacity[s] <= 0.0 or radius[s] <= 0.0:
            continue
        ox, oy, oz = centres[s, 0], centres[s, 1], centres[s, 2]
        rr = radius[s]
        # screen rectangle: the projection of the sphere's box when it is all in front
        x0, x1, y0, y1 = 0, w - 1, 0, h - 1
        if oz - rr > near:
            zn = oz - rr
            x0 = max(0, int(math.floor(cx + fpx * min((ox - rr) / zn, (ox - rr) / (oz + rr)))))
            x1 = min(w - 1, int(math.ceil(cx + fpx * max((ox + rr) / zn, (ox + rr) / (oz + rr)))))
            y0 = max(0, int(math.floor(cy - fpx * max((oy + rr) / zn, (oy + rr) / (oz + rr)))))
            y1 = min(h - 1, int(math.ceil(cy - fpx * min((oy - rr) / zn, (oy - rr) / (oz + rr)))))
        c = ox * ox + oy * oy + oz * oz - rr * rr
        inv_r = 1.0 / rr
        for y in range(y0, y1 + 1):
            vy = -(y + 0.5 - cy) / fpx
            for x in range(x0, x1 + 1):
                vx = (x + 0.5 - cx) / fpx
                dd = vx * vx + vy * vy + 1.0
                half_b = vx * ox + vy * oy + oz
                disc = half_b * half_b - dd * c
                if disc <= 0.0:
                    continue
                root = math.sqrt(disc)
                inv_len = 1.0 / math.sqrt(dd)
                for side in range(2):  # far side first, then the near side over it
                    t = (half_b + root) / dd if side == 0 else (half_b - root) / dd
                    if t <= near or 1.0 / t <= depth[y, x]:
                        continue
                    # |cos| between the ray and the normal: |(t d - o) . d| / (r |d|)
                    cos = abs(t * dd - half_b) * inv_r * inv_len
                    rim = 1.0 - min(cos, 1.0)
                    a = opacity[s] * min(1.0, 0.06 + 0.9 * rim * rim * rim * rim)
                    for ch in range(3):
                        color[y, x, ch] += (tint[ch] - color[y, x, ch]) * a


@kernel
def resolve(color, factor, lut, out) -> None:
    """Average ``factor`` x ``factor`` blocks of ``color`` (H*f, W*f, 3) linear RGB into
    ``out`` (H, W, 3) uint8 through ``lut`` (L,) uint8, the sRGB encoding of L even
    steps over 0..1 (values outside 0..1 are clipped)."""
    h, w = out.shape[0], out.shape[1]
    scale = 1.0 / (factor * factor)
    top = lut.shape[0] - 1
    for y in range(h):
        for x in range(w):
            for ch in range(3):
                acc = 0.0
                for j in range(factor):
                    for i in range(factor):
                        acc += color[y * factor + j, x * factor + i, ch]
                v = min(max(acc * scale, 0.0), 1.0)
                out[y, x, ch] = lut[int(v * top + 0.5)]


def srgb_lut(size: int = 8192) -> np.ndarray:
    """(size,) uint8: the sRGB transfer function of ``size`` even steps over linear 0..1."""
    x = np.linspace(0.0, 1.0, size)
    s = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.clip(np.round(s * 255.0), 0, 255).astype(np.uint8)


def srgb_to_linear(value: np.ndarray) -> np.ndarray:
    """Inverse sRGB transfer function, for 8-bit values 0..255 -> linear 0..1."""
    s = np.asarray(value, dtype=np.float64) / 255.0
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)
