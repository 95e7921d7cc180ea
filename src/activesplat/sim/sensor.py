"""Embree RGB-D sensor: one ray per pixel centre, z-depth in metres, colour from texture and/or
vertex colours with view-independent shading (fixed directional light, |n . l|)."""

from __future__ import annotations

import numpy as np
import trimesh
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from activesplat.sim.config import SimConfig


def camera_rays(K: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H*W, 3) camera-frame directions through pixel centres with z = 1, so the ray parameter of
    a hit is its z-depth."""
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    x = (cols - K[0, 2]) / K[0, 0]
    y = (rows - K[1, 2]) / K[1, 1]
    return np.stack([x, y, np.ones_like(x)], axis=-1).reshape(-1, 3)


def _material_image(material) -> tuple[np.ndarray | None, np.ndarray]:
    """(texture RGB float image or None, base colour factor RGB) of a trimesh material."""
    factor = np.ones(3)
    image = None
    if isinstance(material, trimesh.visual.material.PBRMaterial):
        image = material.baseColorTexture
        if material.baseColorFactor is not None:
            factor = np.asarray(material.baseColorFactor[:3], dtype=np.float64) / 255.0
    elif isinstance(material, trimesh.visual.material.SimpleMaterial):
        image = material.image
        factor = np.asarray(material.diffuse[:3], dtype=np.float64) / 255.0
    if image is not None:
        image = np.asarray(image.convert("RGB"), dtype=np.float32) / 255.0
    return image, factor


def surface_colours(mesh: trimesh.Trimesh):
    """Colour sources of a mesh: texture (H, W, 3) float or None, per-face corner UVs (F, 3, 2)
    float32 or None, per-face corner colours (F, 3, 3) float32 or None (None = white)."""
    visual = mesh.visual
    faces = mesh.faces
    if isinstance(visual, trimesh.visual.TextureVisuals):
        image, factor = _material_image(visual.material)
        corner = None if np.allclose(factor, 1.0) else np.broadcast_to(factor, (len(faces), 3, 3))
        if image is not None and visual.uv is not None and len(visual.uv) == len(mesh.vertices):
            uv = np.asarray(visual.uv, dtype=np.float32)[faces]
            return image, uv, None if corner is None else corner.astype(np.float32)
        return None, None, np.broadcast_to(factor, (len(faces), 3, 3)).astype(np.float32)
    kind = getattr(visual, "kind", None)
    if kind == "vertex":
        return None, None, (np.asarray(visual.vertex_colors[:, :3], np.float32) / 255.0)[faces]
    if kind == "face":
        colours = np.asarray(visual.face_colors[:, :3], np.float32) / 255.0
        return None, None, np.repeat(colours[:, None, :], 3, axis=1)
    return None, None, np.full((len(faces), 3, 3), 0.7, dtype=np.float32)


class RGBDSensor:
    """Ray casts a mesh with Embree; shared by the agent's camera and arbitrary evaluation poses."""

    def __init__(self, mesh: trimesh.Trimesh, config: SimConfig | None = None):
        self.config = config = config or SimConfig()
        self.vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
        self.faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self._scene, self.vertices, self.faces)
        self.texture, self.face_uv, self.face_rgb = surface_colours(mesh)
        self.face_shade = self._face_shading()
        self._texel_planes = self._texel_coordinates()
        self._rays: dict[tuple, np.ndarray] = {}

    def _texel_coordinates(self):
        """Per face, texel column and row as affine functions of Embree's (u, v): (F, 3) arrays
        [at corner 0, d/du, d/dv], so shading gathers 6 scalars per pixel instead of 3 UV pairs."""
        if self.texture is None:
            return None
        th, tw = self.texture.shape[:2]
        uv = self.face_uv.astype(np.float64)
        col = uv[:, :, 0] * tw
        row = (1.0 - uv[:, :, 1]) * th
        planes = [np.stack([c[:, 0], c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]], axis=1) for c in (col, row)]
        return [p.astype(np.float32) for p in planes]

    def _face_shading(self) -> np.ndarray:
        """ambient + (1 - ambient) * |n . l| per face: fixed world light, view-independent."""
        tri = self.vertices[self.faces].astype(np.float64)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
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

    def world_rays(self, pose: np.ndarray, K: np.ndarray, width: int, height: int):
        """Origins and world directions (camera z component 1) of every pixel for a 4x4 pose."""
        key = (width, height, *np.round(K.ravel(), 9))
        if key not in self._rays:
            self._rays[key] = camera_rays(K, width, height).astype(np.float32)
        rays, rot = self._rays[key], np.asarray(pose[:3, :3], dtype=np.float32)
        # Broadcast sums instead of a (N, 3) @ (3, 3) BLAS call: no thread start-up, ~10x faster here.
        dirs = rays[:, :1] * rot[:, 0] + rays[:, 1:2] * rot[:, 1] + rays[:, 2:] * rot[:, 2]
        origins = np.empty_like(dirs)
        origins[:] = np.asarray(pose[:3, 3], dtype=np.float32)
        return origins, dirs

    def render(self, pose: np.ndarray, K: np.ndarray, width: int, height: int):
        """(rgb uint8 (H, W, 3), depth float32 (H, W) z-depth metres, 0 past max_depth or no hit)."""
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
        """Colour of surface points given by face index and Embree barycentrics (u, v): albedo from
        the nearest texel and/or interpolated corner colours, times the face shading."""
        colour = np.ones((len(face), 3), dtype=np.float32)
        if self.texture is not None:
            th, tw = self.texture.shape[:2]
            (c0, cu, cv), (r0, ru, rv) = (p[face].T for p in self._texel_planes)
            col = np.clip((c0 + u * cu + v * cv).astype(np.int64), 0, tw - 1)
            row = np.clip((r0 + u * ru + v * rv).astype(np.int64), 0, th - 1)
            colour = self.texture.reshape(-1, 3)[row * tw + col]
        if self.face_rgb is not None:
            w = np.stack([1.0 - u - v, u, v], axis=1).astype(np.float32)
            colour = colour * np.einsum("nk,nkd->nd", w, self.face_rgb[face])
        return colour * self.face_shade[face, None]
