"""Embree RGB-D sensor: one ray per pixel centre, z-depth in metres, colour from each face's
material (own texture and sampler, base colour factor, vertex colours; see sim/materials.py) with
view-independent shading (fixed directional light, |n . l|).

Texture filtering (``SimConfig.texture_filter``): "area" (default) integrates the texture over the
pixel's footprint on the hit face (anisotropic mip-mapping, as a GPU or the paper's Habitat renderer
filters textures, and as a camera pixel integrates light), "nearest" reads the one texel under the
pixel centre (the project's renderer before; its numpy reference is ``render_reference``). With
"nearest", textures finer than the pixels alias: the image changes from one frame to the next in a way
no 3D map can reproduce (docs/protocol.md §1, "Texture filtering")."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from functools import cached_property

import numba
import numpy as np
import trimesh
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from activesplat.sim._shade_numba import shade_pixels, shade_pixels_area, world_rays
from activesplat.sim.config import SimConfig
from activesplat.sim.materials import CLAMP_TO_EDGE, MIRRORED_REPEAT, Surface, surface_from_trimesh
from activesplat.sim.textures import tile_surface

FLOAT_TEXELS = 4_000_000
"""Scenes with at most this many texels keep them as float32 (48 MB); larger ones as uint8."""


BLOCK_PIXELS = 8192
"""Fewest pixels per thread of a render (smaller images stay on the calling thread)."""
_POOL: tuple[int, ThreadPoolExecutor] | None = None
_THREAD = threading.local()


def render_on_this_thread() -> None:
    """Renders asked from the calling thread from now on run on it alone, not on the shared pool: for a
    background thread whose work should not take the pool's threads (the live evaluation's worker of
    `activesplat explore`)."""
    _THREAD.serial = True


def _in_blocks(fn, n: int) -> None:
    """``fn(lo, hi)`` over [0, n) split into contiguous blocks, one per thread (at most numba's thread
    count, at least BLOCK_PIXELS each); on this thread when that is one block, or when this thread asked
    for it (:func:`render_on_this_thread`)."""
    global _POOL
    threads = 1 if getattr(_THREAD, "serial", False) else min(numba.get_num_threads(), n // BLOCK_PIXELS)
    if threads <= 1:
        fn(0, n)
        return
    if _POOL is None or _POOL[0] < threads:
        if _POOL is not None:  # a larger pool replaces it: its idle threads end
            _POOL[1].shutdown(wait=False)
        _POOL = (threads, ThreadPoolExecutor(threads, thread_name_prefix="sensor"))
    bounds = np.linspace(0, n, threads + 1).astype(int)
    for job in [_POOL[1].submit(fn, lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)]:
        job.result()


def camera_rays(K: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H*W, 3) camera-frame directions through pixel centres with z = 1, so the ray parameter of
    a hit is its z-depth."""
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    x = (cols - K[0, 2]) / K[0, 0]
    y = (rows - K[1, 2]) / K[1, 1]
    return np.stack([x, y, np.ones_like(x)], axis=-1).reshape(-1, 3)


def hit_distance(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray,
                 directions: np.ndarray) -> np.ndarray:
    """Embree ray parameter of the closest hit of each ray on a bare triangle mesh (1e37 on a miss)."""
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(vertices, dtype=np.float32),
                 np.ascontiguousarray(faces, dtype=np.int32))
    return scene.run(np.ascontiguousarray(origins, dtype=np.float32),
                     np.ascontiguousarray(directions, dtype=np.float32), query="DISTANCE")


class RGBDSensor:
    """Ray casts a mesh with Embree; shared by the agent's camera and arbitrary evaluation poses."""

    def __init__(self, mesh: trimesh.Trimesh, config: SimConfig | None = None,
                 surface: Surface | None = None):
        self.config = config = config or SimConfig()
        self.vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
        self.faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, self.vertices, self.faces)
        surface = surface if surface is not None else surface_from_trimesh(mesh)
        if len(surface) != len(self.faces):
            raise ValueError(f"surface has {len(surface)} faces, mesh {len(self.faces)}")
        # the built-in houses' atlas as one texture per tile: same nearest texels, no bleeding when filtered
        self.surface = surface = tile_surface(surface)
        tri = self.vertices[self.faces].astype(np.float64)
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        self.face_normal = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        self._store_textures(surface)
        self.face_shade = self._face_shading()
        self._rays: dict[tuple, np.ndarray] = {}

    def _store_textures(self, surface: Surface) -> None:
        """Every material's texture, unchanged, in one flat texel array (entry 0: a white texel for
        untextured materials) with per-material offset, size and wrap modes; per face the texel
        column and row as affine functions of Embree's (u, v): an (F, 6) array [column at corner 0,
        d/du, d/dv, row at corner 0, d/du, d/dv], so shading gathers one row per pixel."""
        mats = surface.materials
        textured = [m.texture is not None for m in mats]
        self.face_material = surface.face_material
        self.textured = surface.face_uv is not None and any(textured)
        base = np.stack([m.base_colour for m in mats]).astype(np.float32)
        corner = surface.face_colour
        if corner is not None:
            self.face_rgb = corner * base[self.face_material][:, None, :]
            self.face_base = None
        else:
            self.face_rgb = None
            self.face_base = None if np.all(base == 1.0) else base[self.face_material]
        if not self.textured:
            return
        blocks, offsets, sizes, offset = [np.full((1, 3), 255, np.uint8)], [], [], 1
        for m in mats:
            if m.texture is None:
                offsets.append(0)
                sizes.append((1, 1))
                continue
            offsets.append(offset)
            sizes.append(m.texture.shape[:2])
            blocks.append(m.texture.reshape(-1, 3))
            offset += blocks[-1].shape[0]
        tex_offset = np.asarray(offsets, np.int64)
        tex_h, tex_w = (np.asarray(v, np.int64) for v in zip(*sizes, strict=True))
        if self.config.texture_filter == "area":
            pyramids, self._levels, self._nlevels = mip_pyramids(mats, tex_offset, offset)
            blocks += pyramids
            # each level's width and height over level 0's, as the kernel's float32 division gives them
            sizes = self._levels[:, :, 1:].astype(np.float32)
            self._level_scale = np.ascontiguousarray(sizes / sizes[:, :1])
        texels = np.concatenate(blocks)
        # float32 texels (the values texel / 255 the shading uses) when small: one gather, no convert
        self.texels = texels.astype(np.float32) / np.float32(255.0) if len(texels) <= FLOAT_TEXELS else texels
        wrap = np.asarray([(m.wrap_s, m.wrap_t) for m in mats], np.int32)
        used = np.unique(self.face_material)
        sizes = np.concatenate([tex_w[used], tex_h[used]])
        self._pow2 = bool(np.all((sizes & (sizes - 1)) == 0))
        # [texel offset, width, height]: scalars when one material covers every face, else per face
        # (one row gather per pixel). Wrap modes likewise per face only when the materials disagree.
        uniform = len(np.unique(wrap[used], axis=0)) == 1
        self._wrap = tuple(int(w) for w in wrap[used[0]]) if uniform else None
        table = np.concatenate([np.stack([tex_offset, tex_w, tex_h], axis=1), wrap], axis=1)
        self._tex = tuple(int(x) for x in table[used[0], :3]) if len(used) == 1 else None
        index_type = np.int32 if len(texels) < 2**31 else np.int64
        # the numba kernel reads all five columns per face; the numpy reference the first three
        self._face_tex = table.astype(index_type)[self.face_material]
        uv = surface.face_uv.astype(np.float64)
        c = uv[:, :, 0] * tex_w[self.face_material, None]
        r = uv[:, :, 1] * tex_h[self.face_material, None]
        planes = [x for t in (c, r) for x in (t[:, 0], t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])]
        self._texel_planes = np.stack(planes, axis=1).astype(np.float32)
        if self.config.texture_filter == "area":
            self._texel_jacobian = texel_jacobians(self.vertices[self.faces].astype(np.float64),
                                                   self.face_normal, np.stack(planes, axis=1))

    def _face_shading(self) -> np.ndarray:
        """ambient + (1 - ambient) * |n . l| per face: fixed world light, view-independent."""
        n = self.face_normal
        light = np.asarray(self.config.light_dir, dtype=np.float64)
        light /= np.linalg.norm(light)
        a = self.config.ambient
        return (a + (1.0 - a) * np.abs(n @ light)).astype(np.float32)

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> dict:
        """Embree closest hits: tfar (in units of |direction|), primID (-1 = miss), u, v."""
        return self._scene.run(np.ascontiguousarray(origins, dtype=np.float32),
                               np.ascontiguousarray(directions, dtype=np.float32), output=1)

    def distance(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Bare Embree ray parameter of the closest hit (1e37 on a miss); used by benchmarks."""
        return self._scene.run(np.ascontiguousarray(origins, dtype=np.float32),
                               np.ascontiguousarray(directions, dtype=np.float32), query="DISTANCE")

    def _camera_rays(self, K: np.ndarray, width: int, height: int) -> np.ndarray:
        """`camera_rays` as float32, cached per image size and intrinsics."""
        key = (width, height, *np.round(K.ravel(), 9))
        if key not in self._rays:
            self._rays[key] = camera_rays(K, width, height).astype(np.float32)
        return self._rays[key]

    def world_rays(self, pose: np.ndarray, K: np.ndarray, width: int, height: int, lo: int = 0,
                   hi: int | None = None):
        """Origins and world directions (camera z component 1) of the pixels [lo, hi) (row-major; default:
        every pixel) for a 4x4 pose."""
        rays = self._camera_rays(K, width, height)[lo:hi]
        origins, dirs = np.empty_like(rays), np.empty_like(rays)
        # one compiled pass, not a (N, 3) @ (3, 3) BLAS call (thread start-up) nor numpy temporaries
        world_rays(rays, np.ascontiguousarray(pose[:3, :3], dtype=np.float32),
                   np.ascontiguousarray(pose[:3, 3], dtype=np.float32), origins, dirs)
        return origins, dirs

    def depth(self, pose: np.ndarray, K: np.ndarray, width: int, height: int) -> np.ndarray:
        """The depth of `render` alone (float32 (H, W) z-depth metres, 0 past max_depth or no hit): one Embree
        distance query, no shading and no compiled kernel (the live evaluation's renders)."""
        t = self.distance(*self.world_rays(pose, K, width, height))
        return np.where(t <= np.float32(self.config.max_depth), t, np.float32(0.0)).reshape(height, width)

    def render(self, pose: np.ndarray, K: np.ndarray, width: int, height: int):
        """(rgb uint8 (H, W, 3), depth float32 (H, W) z-depth metres, 0 past max_depth or no hit);
        the colour of each hit as `shade` computes it, in one compiled pass over the pixels. Embree and
        the shading kernel release the GIL, so the pixels go out in row blocks to threads (as many as
        numba may use, ``NUMBA_NUM_THREADS``); every pixel is computed alone, so the image is the same."""
        rgb = np.empty((width * height, 3), dtype=np.uint8)
        depth = np.empty(width * height, dtype=np.float32)
        rot = np.asarray(pose[:3, :3], dtype=np.float32)
        steps = rot[:, 0] / np.float32(K[0, 0]), rot[:, 1] / np.float32(K[1, 1])
        self._camera_rays(K, width, height)  # filled before the threads read it

        def block(lo: int, hi: int) -> None:  # each block's rays on its own thread (elementwise: the same)
            origins, dirs = self.world_rays(pose, K, width, height, lo, hi)
            self._shade(self.cast(origins, dirs), dirs, steps, rgb[lo:hi], depth[lo:hi])

        _in_blocks(block, width * height)
        return rgb.reshape(height, width, 3), depth.reshape(height, width)

    def _shade(self, hit: dict, dirs: np.ndarray, steps, rgb: np.ndarray, depth: np.ndarray) -> None:
        """Colour and depth of Embree hits into `rgb` (N, 3) and `depth` (N,)."""
        max_depth = np.float32(self.config.max_depth)
        if self.textured and self.config.texture_filter == "area":
            shade_pixels_area(hit["primID"], hit["tfar"], hit["u"], hit["v"], dirs, *steps,
                              max_depth, self._pow2, *self._kernel_arrays,
                              self.face_shade, self._face_normal32, self._texel_jacobian, self.face_material,
                              self._levels, self._level_scale, self._nlevels,
                              np.int64(self.config.texture_max_anisotropy), rgb, depth)
        else:
            shade_pixels(hit["primID"], hit["tfar"], hit["u"], hit["v"], max_depth, self.textured,
                         self.textured and self._pow2, *self._kernel_arrays, self.face_shade, rgb, depth)

    @cached_property
    def _face_normal32(self) -> np.ndarray:
        return self.face_normal.astype(np.float32)

    @cached_property
    def _kernel_arrays(self) -> tuple:
        """Texel planes, per-face texture table, texels, corner colours, base colours for
        shade_pixels; empty arrays stand for the absent ones."""
        def present(array, shape, dtype=np.float32):
            return array if array is not None else np.zeros(shape, dtype)

        if self.textured:
            planes, table, texels = self._texel_planes, self._face_tex, self.texels
        else:
            planes, table = np.zeros((0, 6), np.float32), np.zeros((0, 5), np.int32)
            texels = np.zeros((0, 3), np.float32)
        divisor = np.float32(255.0 if texels.dtype == np.uint8 else 1.0)
        return (planes, table, texels, divisor, present(self.face_rgb, (0, 3, 3)),
                present(self.face_base, (0, 3)))

    def render_reference(self, pose: np.ndarray, K: np.ndarray, width: int, height: int):
        """`render` in plain numpy (`shade` on the hits): the slow, readable reference of the kernel with
        texture_filter "nearest" (the nearest texel under each pixel centre, whatever the config says)."""
        origins, dirs = self.world_rays(pose, K, width, height)
        hit = self.cast(origins, dirs)
        prim = hit["primID"]
        valid = prim >= 0
        depth = np.where(valid & (hit["tfar"] <= self.config.max_depth), hit["tfar"], np.float32(0.0))
        rgb = np.zeros((width * height, 3), dtype=np.float32)
        face = prim[valid]
        rgb[valid] = self.shade(face, hit["u"][valid], hit["v"][valid])
        rgb_u8 = np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return rgb_u8.reshape(height, width, 3), depth.astype(np.float32).reshape(height, width)

    def shade(self, face: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Colour of surface points given by face index and Embree barycentrics (u, v): the nearest
        texel of the face's material texture (after its sampler's wrap modes) times its base colour
        and the interpolated vertex colours, times the face shading."""
        colour = np.ones((len(face), 3), dtype=np.float32)
        if self.textured:
            c0, cu, cv, r0, ru, rv = self._texel_planes[face].T
            if self._tex is not None:
                offset, width, height = self._tex
                wrap_s, wrap_t = self._wrap
            else:
                offset, width, height, wrap_s, wrap_t = self._face_tex[face].T
                if self._wrap is not None:
                    wrap_s, wrap_t = self._wrap
            col = _wrap(np.floor(c0 + u * cu + v * cv).astype(np.int64), width, wrap_s, self._pow2)
            row = _wrap(np.floor(r0 + u * ru + v * rv).astype(np.int64), height, wrap_t, self._pow2)
            colour = self.texels[offset + row * width + col]
            if colour.dtype == np.uint8:
                colour = colour.astype(np.float32) / np.float32(255.0)
        if self.face_rgb is not None:
            w = np.stack([1.0 - u - v, u, v], axis=1).astype(np.float32)
            colour = colour * np.einsum("nk,nkd->nd", w, self.face_rgb[face])
        elif self.face_base is not None:
            colour = colour * self.face_base[face]
        return colour * self.face_shade[face, None]


def mip_pyramids(materials, tex_offset: np.ndarray, start: int) -> tuple[list, np.ndarray, np.ndarray]:
    """Mip levels 1, 2, ... of every material's texture (each half the size of the one before, box
    filtered with cv2's INTER_AREA, down to 1 x 1), as uint8 texel blocks to append to the texel array at
    ``start``; with the table of every level (M, L, 3) [texel offset, width, height] (level 0: the
    texture itself at ``tex_offset``; untextured materials: the white texel 0) and the level counts (M,)."""
    import cv2

    blocks, tables, offset = [], [], start
    for m, base in zip(materials, tex_offset, strict=True):
        if m.texture is None:
            tables.append([(0, 1, 1)])
            continue
        image = m.texture.astype(np.float32)
        h, w = image.shape[:2]
        table = [(int(base), w, h)]
        while w > 1 or h > 1:
            w, h = max(1, w // 2), max(1, h // 2)
            image = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA).reshape(h, w, 3)
            blocks.append(np.clip(np.rint(image), 0, 255).astype(np.uint8).reshape(-1, 3))
            table.append((offset, w, h))
            offset += w * h
        tables.append(table)
    n = max(len(t) for t in tables)
    levels = np.zeros((len(tables), n, 3), np.int64)
    for i, table in enumerate(tables):
        levels[i, :len(table)] = table
        levels[i, len(table):] = table[-1]
    return blocks, levels, np.asarray([len(t) for t in tables], np.int64)


def texel_jacobians(triangles: np.ndarray, normals: np.ndarray, planes: np.ndarray) -> np.ndarray:
    """(F, 6) float32 d(texel column, texel row) / d(world point) of each face, rows flattened: the
    texel coordinates are affine in Embree's barycentrics (u, v) (``planes`` (F, 6): column at corner 0,
    d/du, d/dv, row at corner 0, d/du, d/dv), and (u, v) are the coordinates of the point along the
    edges V1 - V0 and V2 - V0; nothing changes along the normal. Degenerate faces get zeros."""
    edges = np.stack([triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0], normals], axis=2)
    ok = np.abs(np.linalg.det(edges)) > 1e-18
    tex = np.zeros((len(triangles), 2, 3))
    tex[:, 0, :2] = planes[:, 1:3]
    tex[:, 1, :2] = planes[:, 4:6]
    jac = np.zeros((len(triangles), 2, 3))
    jac[ok] = tex[ok] @ np.linalg.inv(edges[ok])
    return jac.reshape(-1, 6).astype(np.float32)


def _wrap(index: np.ndarray, size: np.ndarray, mode, pow2: bool) -> np.ndarray:
    """Texel index along one axis after the glTF wrap mode (one for all points, or one per point):
    REPEAT, MIRRORED_REPEAT, CLAMP_TO_EDGE, with OpenGL semantics on whole texels. `pow2`: every
    size is a power of two, so the modulo is a bitwise and (also right for negative indices)."""
    if np.isscalar(mode):
        if mode == CLAMP_TO_EDGE:
            return np.clip(index, 0, size - 1)
        if mode == MIRRORED_REPEAT:
            m = index & (2 * size - 1) if pow2 else np.mod(index, 2 * size)
            return np.where(m >= size, 2 * size - 1 - m, m)
        return index & (size - 1) if pow2 else np.mod(index, size)
    out = index & (size - 1) if pow2 else np.mod(index, size)
    mirrored = mode == MIRRORED_REPEAT
    if mirrored.any():
        m = index & (2 * size - 1) if pow2 else np.mod(index, 2 * size)
        out = np.where(mirrored, np.where(m >= size, 2 * size - 1 - m, m), out)
    clamped = mode == CLAMP_TO_EDGE
    if clamped.any():
        out = np.where(clamped, np.clip(index, 0, size - 1), out)
    return out
