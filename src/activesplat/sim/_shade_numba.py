"""numba kernel of RGBDSensor.render after the Embree cast: per pixel z-depth, nearest texel of the
hit face's material (own texture, wrap modes), base colour / vertex colours, face shading, uint8.

One pass over the pixels in float32 with the operation order of the numpy reference
(`RGBDSensor.shade`), so both give the same images; tests compare them."""

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


@numba.njit(cache=True, nogil=True)
def shade_pixels(prim, tfar, u, v, max_depth, textured, planes, face_tex, texels, texel_divisor, face_rgb,
                 face_base, face_shade, rgb_out, depth_out):
    """Fill rgb_out (N, 3) uint8 and depth_out (N,) float32 from Embree hits (primID -1 = miss).
    face_rgb (F, 3, 3) or shape (0, 3, 3); face_base (F, 3) or (0, 3); texels float32 in [0, 1] or
    uint8 (texel_divisor 1 or 255); face_tex (F, 5) int: texel offset, width, height, wrap s, wrap t."""
    one, scale, half, zero = np.float32(1.0), np.float32(255.0), np.float32(0.5), np.float32(0.0)
    has_rgb = face_rgb.shape[0] > 0
    has_base = face_base.shape[0] > 0
    for i in range(prim.shape[0]):
        f = prim[i]
        if f < 0:
            depth_out[i] = zero
            rgb_out[i, 0] = rgb_out[i, 1] = rgb_out[i, 2] = 0
            continue
        depth_out[i] = tfar[i] if tfar[i] <= max_depth else zero
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
        if has_rgb:
            w0 = one - a - b
            r = r * (w0 * face_rgb[f, 0, 0] + a * face_rgb[f, 1, 0] + b * face_rgb[f, 2, 0])
            g = g * (w0 * face_rgb[f, 0, 1] + a * face_rgb[f, 1, 1] + b * face_rgb[f, 2, 1])
            bl = bl * (w0 * face_rgb[f, 0, 2] + a * face_rgb[f, 1, 2] + b * face_rgb[f, 2, 2])
        elif has_base:
            r, g, bl = r * face_base[f, 0], g * face_base[f, 1], bl * face_base[f, 2]
        s = face_shade[f]
        rgb_out[i, 0] = np.uint8(min(max((r * s) * scale + half, zero), scale))
        rgb_out[i, 1] = np.uint8(min(max((g * s) * scale + half, zero), scale))
        rgb_out[i, 2] = np.uint8(min(max((bl * s) * scale + half, zero), scale))
