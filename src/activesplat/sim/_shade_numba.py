"""numba kernels of RGBDSensor.render after the Embree cast: per pixel z-depth, the texture of the hit
face's material (own texture, wrap modes) read at the nearest texel (`shade_pixels`) or integrated over
the pixel's footprint (`shade_pixels_area`), base colour / vertex colours, face shading, uint8.

One pass over the pixels in float32. `shade_pixels` keeps the operation order of the numpy reference
(`RGBDSensor.shade`), so both give the same images; tests compare them. `shade_pixels_area` is tested
against supersampled renders of the nearest texels."""

from __future__ import annotations

import numba
import numpy as np

_REPEAT, _MIRRORED, _CLAMP = 10497, 33648, 33071


@numba.njit(cache=True, nogil=True, inline="always")
def _wrap(i, n, mode):
    if mode == _CLAMP:
        return min(max(i, 0), n - 1)
    if mode == _MIRRORED:
        m = i % (2 * n)  # Python semantics: non-negative for n > 0
        return 2 * n - 1 - m if m >= n else m
    return i % n


@numba.njit(cache=True, nogil=True, inline="always")
def _depth_or_miss(i, f, t, max_depth, rgb_out, depth_out):
    """Pixel i's z-depth (0 past max_depth); a miss (primID f < 0) gets depth 0 and black, and True."""
    if f < 0:
        depth_out[i] = np.float32(0.0)
        rgb_out[i, 0] = rgb_out[i, 1] = rgb_out[i, 2] = 0
        return True
    depth_out[i] = t if t <= max_depth else np.float32(0.0)
    return False


@numba.njit(cache=True, nogil=True, inline="always")
def _finish(i, f, a, b, r, g, bl, face_rgb, face_base, face_shade, rgb_out):
    """Pixel i: texture colour (r, g, bl) times the interpolated vertex colours (or the base colour) of
    face f at barycentrics (a, b), times its shading, rounded to uint8."""
    one, scale, half, zero = np.float32(1.0), np.float32(255.0), np.float32(0.5), np.float32(0.0)
    if face_rgb.shape[0] > 0:
        w0 = one - a - b
        r = r * (w0 * face_rgb[f, 0, 0] + a * face_rgb[f, 1, 0] + b * face_rgb[f, 2, 0])
        g = g * (w0 * face_rgb[f, 0, 1] + a * face_rgb[f, 1, 1] + b * face_rgb[f, 2, 1])
        bl = bl * (w0 * face_rgb[f, 0, 2] + a * face_rgb[f, 1, 2] + b * face_rgb[f, 2, 2])
    elif face_base.shape[0] > 0:
        r, g, bl = r * face_base[f, 0], g * face_base[f, 1], bl * face_base[f, 2]
    s = face_shade[f]
    rgb_out[i, 0] = np.uint8(min(max((r * s) * scale + half, zero), scale))
    rgb_out[i, 1] = np.uint8(min(max((g * s) * scale + half, zero), scale))
    rgb_out[i, 2] = np.uint8(min(max((bl * s) * scale + half, zero), scale))


@numba.njit(cache=True, nogil=True)
def shade_pixels(prim, tfar, u, v, max_depth, textured, planes, face_tex, texels, texel_divisor, face_rgb,
                 face_base, face_shade, rgb_out, depth_out):
    """Fill rgb_out (N, 3) uint8 and depth_out (N,) float32 from Embree hits (primID -1 = miss).
    face_rgb (F, 3, 3) or shape (0, 3, 3); face_base (F, 3) or (0, 3); texels float32 in [0, 1] or
    uint8 (texel_divisor 1 or 255); face_tex (F, 5) int: texel offset, width, height, wrap s, wrap t."""
    one = np.float32(1.0)
    for i in range(prim.shape[0]):
        f = prim[i]
        if _depth_or_miss(i, f, tfar[i], max_depth, rgb_out, depth_out):
            continue
        a, b = u[i], v[i]
        r = g = bl = one
        if textured:
            cf = planes[f, 0] + a * planes[f, 1] + b * planes[f, 2]
            rf = planes[f, 3] + a * planes[f, 4] + b * planes[f, 5]
            w, h = face_tex[f, 1], face_tex[f, 2]
            col = _wrap(np.int64(np.floor(cf)), w, face_tex[f, 3])
            row = _wrap(np.int64(np.floor(rf)), h, face_tex[f, 4])
            k = face_tex[f, 0] + row * w + col
            # uint8 texels are divided by 255 here, float32 ones (already / 255) by 1: exact
            r, g, bl = np.float32(texels[k, 0]) / texel_divisor, np.float32(texels[k, 1]) / texel_divisor, \
                np.float32(texels[k, 2]) / texel_divisor
        _finish(i, f, a, b, r, g, bl, face_rgb, face_base, face_shade, rgb_out)


@numba.njit(cache=True, nogil=True, inline="always")
def _bilinear(texels, divisor, level, w0, h0, ws, wt, x, y):
    """Bilinear texel colour of one mip level (offset, width, height) at level-0 texel coordinates (x, y),
    texel centres at integer + 0.5, after the wrap modes."""
    off, w, h = level[0], level[1], level[2]
    x = x * (np.float32(w) / np.float32(w0)) - np.float32(0.5)
    y = y * (np.float32(h) / np.float32(h0)) - np.float32(0.5)
    xf, yf = np.floor(x), np.floor(y)
    fx, fy = x - xf, y - yf
    x0, y0 = np.int64(xf), np.int64(yf)
    c0, r0 = _wrap(x0, w, ws), _wrap(y0, h, wt)
    if ws == _REPEAT:  # the next texel without a second modulo
        c1 = c0 + 1 if c0 + 1 < w else 0
    else:
        c1 = _wrap(x0 + 1, w, ws)
    if wt == _REPEAT:
        r1 = r0 + 1 if r0 + 1 < h else 0
    else:
        r1 = _wrap(y0 + 1, h, wt)
    k00, k01, k10, k11 = off + r0 * w + c0, off + r0 * w + c1, off + r1 * w + c0, off + r1 * w + c1
    one = np.float32(1.0)
    w00, w01, w10, w11 = (one - fx) * (one - fy), fx * (one - fy), (one - fx) * fy, fx * fy
    return ((w00 * np.float32(texels[k00, 0]) + w01 * np.float32(texels[k01, 0])
             + w10 * np.float32(texels[k10, 0]) + w11 * np.float32(texels[k11, 0])) / divisor,
            (w00 * np.float32(texels[k00, 1]) + w01 * np.float32(texels[k01, 1])
             + w10 * np.float32(texels[k10, 1]) + w11 * np.float32(texels[k11, 1])) / divisor,
            (w00 * np.float32(texels[k00, 2]) + w01 * np.float32(texels[k01, 2])
             + w10 * np.float32(texels[k10, 2]) + w11 * np.float32(texels[k11, 2])) / divisor)


@numba.njit(cache=True, nogil=True)
def shade_pixels_area(prim, tfar, u, v, dirs, dx, dy, max_depth, planes, face_tex, texels,
                      texel_divisor, face_rgb, face_base, face_shade, face_normal, face_jacobian,
                      face_material, levels, nlevels, max_aniso, rgb_out, depth_out):
    """`shade_pixels` for a textured scene, with the texture integrated over each pixel's footprint
    instead of read at its centre (SimConfig.texture_filter = "area"). The footprint is the pixel's
    square cast onto the hit face's plane by ray differentials (dirs (N, 3): world ray directions with
    camera z = 1; dx / dy: the world step of the direction per pixel column / row), mapped to texels by
    the face's Jacobian face_jacobian (F, 6) = d(column, row) / d(world point). Up to max_aniso
    trilinear taps along the footprint's long axis, at the mip level of its short axis (or of long /
    max_aniso): anisotropic mip-mapping as GPUs do it. levels (M, L, 3): [texel offset, width, height]
    of each mip level of material m's texture (level 0 = face_tex's), nlevels (M,) how many;
    face_material (F,) the material of each face."""
    one, half, zero = np.float32(1.0), np.float32(0.5), np.float32(0.0)
    for i in range(prim.shape[0]):
        f = prim[i]
        t = tfar[i]
        if _depth_or_miss(i, f, t, max_depth, rgb_out, depth_out):
            continue
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
        J = face_jacobian[f]
        gx0 = J[0] * px0 + J[1] * px1 + J[2] * px2
        gx1 = J[3] * px0 + J[4] * px1 + J[5] * px2
        gy0 = J[0] * py0 + J[1] * py1 + J[2] * py2
        gy1 = J[3] * py0 + J[4] * py1 + J[5] * py2
        lx = np.sqrt(gx0 * gx0 + gx1 * gx1)
        ly = np.sqrt(gy0 * gy0 + gy1 * gy1)
        if lx >= ly:
            major, minor, ax, ay = lx, ly, gx0, gx1
        else:
            major, minor, ax, ay = ly, lx, gy0, gy1
        n = 1
        if major > minor:
            n = min(max_aniso, max(1, np.int64(np.ceil(major / max(minor, np.float32(1e-6))))))
        width = max(major / np.float32(n), minor)
        mat = face_material[f]
        nlev = nlevels[mat]
        lod = np.float32(0.0)
        if width > one:
            lod = min(np.float32(np.log2(width)), np.float32(nlev - 1))
        l0 = np.int64(np.floor(lod))
        fl = lod - np.float32(l0)
        l1 = min(l0 + 1, nlev - 1)
        w0, h0 = face_tex[f, 1], face_tex[f, 2]
        ws, wt = face_tex[f, 3], face_tex[f, 4]
        r = g = bl = zero
        wk = one / np.float32(n)
        for k in range(n):
            s = (np.float32(k) + half) * wk - half
            x, y = cf + ax * s, rf + ay * s
            c0, c1, c2 = _bilinear(texels, texel_divisor, levels[mat, l0], w0, h0, ws, wt, x, y)
            if fl > zero:
                e0, e1, e2 = _bilinear(texels, texel_divisor, levels[mat, l1], w0, h0, ws, wt, x, y)
                keep = one - fl
                c0, c1, c2 = keep * c0 + fl * e0, keep * c1 + fl * e1, keep * c2 + fl * e2
            r += wk * c0
            g += wk * c1
            bl += wk * c2
        _finish(i, f, a, b, r, g, bl, face_rgb, face_base, face_shade, rgb_out)
