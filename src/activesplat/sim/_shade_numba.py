"""numba kernels of RGBDSensor.render: the world rays before the Embree cast (`world_rays`), and after it
per pixel z-depth, the texture of the hit face's material (own texture, wrap modes) read at the nearest
texel (`shade_pixels`) or integrated over the pixel's footprint (`shade_pixels_area`), base colour /
vertex colours, face shading, uint8.

All in float32. `shade_pixels` keeps the operation order of the numpy reference (`RGBDSensor.shade`), so
both give the same images; tests compare them. `shade_pixels_area` is tested against supersampled renders
of the nearest texels.

Speed: the loops hand arrays to no helper (an inlined helper that takes an array, or a view such as
``a[f]``, costs two atomic reference-count updates per pixel) and index them in place; the helpers take
and return numbers only. `shade_pixels_area` makes three passes over the pixels (footprint, mip level,
texture taps): short loops with independent iterations run faster than one long chain per pixel.
Every value is computed by the same float32 operations in the same order either way."""

from __future__ import annotations

import numba
import numpy as np

_REPEAT, _MIRRORED, _CLAMP = 10497, 33648, 33071


@numba.njit(cache=True, nogil=True)
def world_rays(rays, rot, position, origins_out, dirs_out):
    """World ray directions dirs_out (N, 3) = rot @ rays[i] (summed in the order of the numpy expression
    rays[:, :1] * rot[:, 0] + rays[:, 1:2] * rot[:, 1] + rays[:, 2:] * rot[:, 2], so the same floats)
    and origins_out (N, 3) = position, all float32."""
    for i in range(rays.shape[0]):
        x, y, z = rays[i, 0], rays[i, 1], rays[i, 2]
        for j in range(3):
            dirs_out[i, j] = x * rot[j, 0] + y * rot[j, 1] + z * rot[j, 2]
            origins_out[i, j] = position[j]


@numba.njit(cache=True, nogil=True, inline="always")
def _wrap(i, n, mode, pow2):
    """Texel index i along an axis of n texels after the wrap mode; pow2 (n a power of two): the modulo
    as a bitwise and, the same number for every i (negative ones too)."""
    if mode == _CLAMP:
        return min(max(i, 0), n - 1)
    if mode == _MIRRORED:
        m = i & (2 * n - 1) if pow2 else i % (2 * n)  # Python semantics: non-negative for n > 0
        return 2 * n - 1 - m if m >= n else m
    return i & (n - 1) if pow2 else i % n


@numba.njit(cache=True, nogil=True, inline="always")
def _mix3(w0, a, b, x0, x1, x2):
    """Corner values x0, x1, x2 interpolated at barycentrics (1 - a - b = w0, a, b)."""
    return w0 * x0 + a * x1 + b * x2


@numba.njit(cache=True, nogil=True, inline="always")
def _to_u8(x, shade):
    """Colour channel x times the face shading, to uint8 (rounded, clipped)."""
    scale, half, zero = np.float32(255.0), np.float32(0.5), np.float32(0.0)
    return np.uint8(min(max((x * shade) * scale + half, zero), scale))


@numba.njit(cache=True, nogil=True, inline="always")
def _store_rgb(i, f, r, g, bl, a, b, has_rgb, has_base, face_rgb, face_base, face_shade, rgb_out):
    """Pixel i's colour (r, g, bl) of face f, times the vertex colours interpolated at barycentrics (a, b)
    (or the face's base colour), times the face shading, stored to rgb_out[i] as uint8."""
    if has_rgb:
        w0 = np.float32(1.0) - a - b
        r = r * _mix3(w0, a, b, face_rgb[f, 0, 0], face_rgb[f, 1, 0], face_rgb[f, 2, 0])
        g = g * _mix3(w0, a, b, face_rgb[f, 0, 1], face_rgb[f, 1, 1], face_rgb[f, 2, 1])
        bl = bl * _mix3(w0, a, b, face_rgb[f, 0, 2], face_rgb[f, 1, 2], face_rgb[f, 2, 2])
    elif has_base:
        r, g, bl = r * face_base[f, 0], g * face_base[f, 1], bl * face_base[f, 2]
    s = face_shade[f]
    rgb_out[i, 0], rgb_out[i, 1], rgb_out[i, 2] = _to_u8(r, s), _to_u8(g, s), _to_u8(bl, s)


@numba.njit(cache=True, nogil=True)
def shade_pixels(prim, tfar, u, v, max_depth, textured, pow2, planes, face_tex, texels, texel_divisor,
                 face_rgb, face_base, face_shade, rgb_out, depth_out):
    """Fill rgb_out (N, 3) uint8 and depth_out (N,) float32 from Embree hits (primID -1 = miss).
    face_rgb (F, 3, 3) or shape (0, 3, 3); face_base (F, 3) or (0, 3); texels float32 in [0, 1] or
    uint8 (texel_divisor 1 or 255); face_tex (F, 5) int: texel offset, width, height, wrap s, wrap t;
    pow2: every texture's sides are powers of two."""
    one, zero = np.float32(1.0), np.float32(0.0)
    has_rgb, has_base = face_rgb.shape[0] > 0, face_base.shape[0] > 0
    for i in range(prim.shape[0]):
        f = prim[i]
        if f < 0:  # a miss: depth 0, black
            depth_out[i] = zero
            rgb_out[i, 0] = rgb_out[i, 1] = rgb_out[i, 2] = 0
            continue
        t = tfar[i]
        depth_out[i] = t if t <= max_depth else zero
        a, b = u[i], v[i]
        r = g = bl = one
        if textured:
            cf = planes[f, 0] + a * planes[f, 1] + b * planes[f, 2]
            rf = planes[f, 3] + a * planes[f, 4] + b * planes[f, 5]
            w, h = face_tex[f, 1], face_tex[f, 2]
            col = _wrap(np.int64(np.floor(cf)), w, face_tex[f, 3], pow2)
            row = _wrap(np.int64(np.floor(rf)), h, face_tex[f, 4], pow2)
            k = face_tex[f, 0] + row * w + col
            # uint8 texels are divided by 255 here, float32 ones (already / 255) by 1: exact
            r, g, bl = np.float32(texels[k, 0]) / texel_divisor, np.float32(texels[k, 1]) / texel_divisor, \
                np.float32(texels[k, 2]) / texel_divisor
        _store_rgb(i, f, r, g, bl, a, b, has_rgb, has_base, face_rgb, face_base, face_shade, rgb_out)


@numba.njit(cache=True, nogil=True, inline="always")
def _bilinear_taps(off, w, h, sx, sy, ws, wt, pow2, x, y):
    """The four texels (flat indices) and weights of a bilinear lookup in one mip level (texel offset,
    width, height; sx, sy: its size over level 0's) at level-0 texel coordinates (x, y), texel centres at
    integer + 0.5, after the wrap modes."""
    x = x * sx - np.float32(0.5)
    y = y * sy - np.float32(0.5)
    xf, yf = np.floor(x), np.floor(y)
    fx, fy = x - xf, y - yf
    x0, y0 = np.int64(xf), np.int64(yf)
    c0, r0 = _wrap(x0, w, ws, pow2), _wrap(y0, h, wt, pow2)
    if ws == _REPEAT:  # the next texel without a second modulo
        c1 = c0 + 1 if c0 + 1 < w else 0
    else:
        c1 = _wrap(x0 + 1, w, ws, pow2)
    if wt == _REPEAT:
        r1 = r0 + 1 if r0 + 1 < h else 0
    else:
        r1 = _wrap(y0 + 1, h, wt, pow2)
    one = np.float32(1.0)
    return (off + r0 * w + c0, off + r0 * w + c1, off + r1 * w + c0, off + r1 * w + c1,
            (one - fx) * (one - fy), fx * (one - fy), (one - fx) * fy, fx * fy)


@numba.njit(cache=True, nogil=True)
def shade_pixels_area(prim, tfar, u, v, dirs, dx, dy, max_depth, pow2, planes, face_tex, texels,
                      texel_divisor, face_rgb, face_base, face_shade, face_normal, face_jacobian,
                      face_material, levels, level_scale, nlevels, max_aniso, rgb_out, depth_out):
    """`shade_pixels` for a textured scene, with the texture integrated over each pixel's footprint
    instead of read at its centre (SimConfig.texture_filter = "area"). The footprint is the pixel's
    square cast onto the hit face's plane by ray differentials (dirs (N, 3): world ray directions with
    camera z = 1; dx / dy: the world step of the direction per pixel column / row), mapped to texels by
    the face's Jacobian face_jacobian (F, 6) = d(column, row) / d(world point). Up to max_aniso
    trilinear taps along the footprint's long axis, at the mip level of its short axis (or of long /
    max_aniso): anisotropic mip-mapping as GPUs do it. levels (M, L, 3): [texel offset, width, height]
    of each mip level of material m's texture (level 0 = face_tex's), level_scale (M, L, 2) float32 its
    width and height over level 0's, nlevels (M,) how many; face_material (F,) the material of each face."""
    one, half, zero = np.float32(1.0), np.float32(0.5), np.float32(0.0)
    n_pixels = prim.shape[0]
    # per pixel: texel column and row of the centre, the long axis in texels, the filter width (then the
    # fraction of the second mip level); the number of taps and the two mip levels
    foot = np.empty((n_pixels, 5), np.float32)
    taps = np.empty((n_pixels, 3), np.int64)
    for i in range(n_pixels):  # depth and footprint
        f = prim[i]
        if f < 0:
            depth_out[i] = zero
            continue
        t = tfar[i]
        depth_out[i] = t if t <= max_depth else zero
        a, b = u[i], v[i]
        cf = planes[f, 0] + a * planes[f, 1] + b * planes[f, 2]
        rf = planes[f, 3] + a * planes[f, 4] + b * planes[f, 5]
        nx, ny, nz = face_normal[f, 0], face_normal[f, 1], face_normal[f, 2]
        ddx, ddy, ddz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        nd = nx * ddx + ny * ddy + nz * ddz
        if abs(nd) < np.float32(1e-6):
            nd = np.float32(1e-6) if nd >= zero else np.float32(-1e-6)
        kx = (nx * dx[0] + ny * dx[1] + nz * dx[2]) / nd
        ky = (nx * dy[0] + ny * dy[1] + nz * dy[2]) / nd
        # footprint of one pixel step on the face's plane (world), then in texels
        px0, px1, px2 = t * (dx[0] - ddx * kx), t * (dx[1] - ddy * kx), t * (dx[2] - ddz * kx)
        py0, py1, py2 = t * (dy[0] - ddx * ky), t * (dy[1] - ddy * ky), t * (dy[2] - ddz * ky)
        j0, j1, j2 = face_jacobian[f, 0], face_jacobian[f, 1], face_jacobian[f, 2]
        j3, j4, j5 = face_jacobian[f, 3], face_jacobian[f, 4], face_jacobian[f, 5]
        gx0 = j0 * px0 + j1 * px1 + j2 * px2
        gx1 = j3 * px0 + j4 * px1 + j5 * px2
        gy0 = j0 * py0 + j1 * py1 + j2 * py2
        gy1 = j3 * py0 + j4 * py1 + j5 * py2
        lx = np.sqrt(gx0 * gx0 + gx1 * gx1)
        ly = np.sqrt(gy0 * gy0 + gy1 * gy1)
        if lx >= ly:
            major, minor, ax, ay = lx, ly, gx0, gx1
        else:
            major, minor, ax, ay = ly, lx, gy0, gy1
        n = 1
        if major > minor:
            n = min(max_aniso, max(1, np.int64(np.ceil(major / max(minor, np.float32(1e-6))))))
        foot[i, 0], foot[i, 1], foot[i, 2], foot[i, 3] = cf, rf, ax, ay
        foot[i, 4] = max(major / np.float32(n), minor)
        taps[i, 0] = n
    for i in range(n_pixels):  # mip levels of the filter width
        f = prim[i]
        if f < 0:
            continue
        width = foot[i, 4]
        nlev = nlevels[face_material[f]]
        lod = np.float32(0.0)
        if width > one:
            lod = min(np.float32(np.log2(width)), np.float32(nlev - 1))
        l0 = np.int64(np.floor(lod))
        foot[i, 4] = lod - np.float32(l0)
        taps[i, 1], taps[i, 2] = l0, min(l0 + 1, nlev - 1)
    has_rgb, has_base = face_rgb.shape[0] > 0, face_base.shape[0] > 0
    scaled = texel_divisor != one
    for i in range(n_pixels):  # texture taps, colour
        f = prim[i]
        if f < 0:
            rgb_out[i, 0] = rgb_out[i, 1] = rgb_out[i, 2] = 0
            continue
        cf, rf, ax, ay, fl = foot[i, 0], foot[i, 1], foot[i, 2], foot[i, 3], foot[i, 4]
        n, l0, l1 = taps[i, 0], taps[i, 1], taps[i, 2]
        mat = face_material[f]
        ws, wt = face_tex[f, 3], face_tex[f, 4]
        o0, w0, h0 = levels[mat, l0, 0], levels[mat, l0, 1], levels[mat, l0, 2]
        sx0, sy0 = level_scale[mat, l0, 0], level_scale[mat, l0, 1]
        o1, w1, h1 = levels[mat, l1, 0], levels[mat, l1, 1], levels[mat, l1, 2]
        sx1, sy1 = level_scale[mat, l1, 0], level_scale[mat, l1, 1]
        r = g = bl = zero
        wk = one / np.float32(n)
        for k in range(n):
            s = (np.float32(k) + half) * wk - half
            x, y = cf + ax * s, rf + ay * s
            k00, k01, k10, k11, w00, w01, w10, w11 = _bilinear_taps(o0, w0, h0, sx0, sy0, ws, wt, pow2, x, y)
            c0 = (w00 * np.float32(texels[k00, 0]) + w01 * np.float32(texels[k01, 0])
                  + w10 * np.float32(texels[k10, 0]) + w11 * np.float32(texels[k11, 0]))
            c1 = (w00 * np.float32(texels[k00, 1]) + w01 * np.float32(texels[k01, 1])
                  + w10 * np.float32(texels[k10, 1]) + w11 * np.float32(texels[k11, 1]))
            c2 = (w00 * np.float32(texels[k00, 2]) + w01 * np.float32(texels[k01, 2])
                  + w10 * np.float32(texels[k10, 2]) + w11 * np.float32(texels[k11, 2]))
            if scaled:  # uint8 texels: the sums / 255 (float32 texels, already / 255: no division by 1)
                c0, c1, c2 = c0 / texel_divisor, c1 / texel_divisor, c2 / texel_divisor
            if fl > zero:  # trilinear: blend with the next coarser level
                k00, k01, k10, k11, w00, w01, w10, w11 = _bilinear_taps(o1, w1, h1, sx1, sy1, ws, wt, pow2,
                                                                        x, y)
                e0 = (w00 * np.float32(texels[k00, 0]) + w01 * np.float32(texels[k01, 0])
                      + w10 * np.float32(texels[k10, 0]) + w11 * np.float32(texels[k11, 0]))
                e1 = (w00 * np.float32(texels[k00, 1]) + w01 * np.float32(texels[k01, 1])
                      + w10 * np.float32(texels[k10, 1]) + w11 * np.float32(texels[k11, 1]))
                e2 = (w00 * np.float32(texels[k00, 2]) + w01 * np.float32(texels[k01, 2])
                      + w10 * np.float32(texels[k10, 2]) + w11 * np.float32(texels[k11, 2]))
                if scaled:
                    e0, e1, e2 = e0 / texel_divisor, e1 / texel_divisor, e2 / texel_divisor
                keep = one - fl
                c0, c1, c2 = keep * c0 + fl * e0, keep * c1 + fl * e1, keep * c2 + fl * e2
            r += wk * c0
            g += wk * c1
            bl += wk * c2
        _store_rgb(i, f, r, g, bl, u[i], v[i], has_rgb, has_base, face_rgb, face_base, face_shade, rgb_out)
