"""Textured mesh assembly from axis-aligned boxes and quads (tiles of the texture atlas)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import trimesh
from PIL import Image

from activesplat.sim.textures import ATLAS_MATERIAL, TILE_METRES, Atlas

# Box faces: (outward normal, in-plane edge a, in-plane edge b) as axis indices with signs, chosen
# so that a x b = outward normal (counter-clockwise winding seen from outside).
_FACES = {
    "+x": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    "-x": ((-1, 0, 0), (0, 0, 1), (0, 1, 0)),
    "+y": ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
    "-y": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
    "+z": ((0, 0, 1), (1, 0, 0), (0, 1, 0)),
    "-z": ((0, 0, -1), (-1, 0, 0), (0, 1, 0)),
}
ALL_FACES = tuple(_FACES)

MaterialChooser = str | Callable[[np.ndarray, np.ndarray], str | None]
"""A material name, or f(face_centre, outward_normal) -> name (None drops the face)."""


class MeshBuilder:
    """Collects quads split into at most one-tile pieces, each mapped to a corner-anchored part of
    its material's atlas tile so that the periodic textures continue across pieces."""

    def __init__(self, atlas: Atlas):
        self.atlas = atlas
        self._verts: list[np.ndarray] = []
        self._uvs: list[np.ndarray] = []
        self._materials: list[str] = []

    def add_quad(self, origin, edge_a, edge_b, material: str) -> None:
        """Quad origin + s*edge_a + t*edge_b, s, t in [0, 1]; normal = edge_a x edge_b."""
        origin, edge_a, edge_b = (np.asarray(v, dtype=np.float64) for v in (origin, edge_a, edge_b))
        len_a, len_b = np.linalg.norm(edge_a), np.linalg.norm(edge_b)
        cuts_a = _tile_cuts(len_a)
        cuts_b = _tile_cuts(len_b)
        for a0, a1 in zip(cuts_a[:-1], cuts_a[1:], strict=True):
            for b0, b1 in zip(cuts_b[:-1], cuts_b[1:], strict=True):
                corners_st = np.array([[a0, b0], [a1, b0], [a1, b1], [a0, b1]])
                pos = origin + corners_st[:, :1] / len_a * edge_a + corners_st[:, 1:] / len_b * edge_b
                local = (corners_st - [a0, b0]) / TILE_METRES
                uv = self.atlas.tile_uv(material, local[:, 0], local[:, 1])
                self._verts.append(pos[[0, 1, 2, 0, 2, 3]])
                self._uvs.append(uv[[0, 1, 2, 0, 2, 3]])
                self._materials.append(material)

    def add_box(self, lo, hi, material: MaterialChooser, faces=ALL_FACES) -> None:
        """Axis-aligned box [lo, hi]; `faces` picks which of the six sides to emit."""
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        size = hi - lo
        centre = 0.5 * (lo + hi)
        for key in faces:
            normal, axis_a, axis_b = (np.asarray(v, dtype=np.float64) for v in _FACES[key])
            edge_a, edge_b = axis_a * size, axis_b * size
            face_centre = centre + 0.5 * normal * size
            name = material if isinstance(material, str) else material(face_centre, normal)
            if name is None:
                continue
            self.add_quad(face_centre - 0.5 * edge_a - 0.5 * edge_b, edge_a, edge_b, name)

    def build(self, plain: bool = False) -> trimesh.Trimesh:
        """One unmerged triangle soup with TextureVisuals (PBR base colour = the atlas), or with
        plain=True the same triangles with one flat colour per material (face colours, no texture)."""
        # Rounded to float32 (what glTF stores), so an exported scene is bit-identical to this one.
        verts = np.concatenate(self._verts).astype(np.float32).astype(np.float64)
        faces = np.arange(len(verts)).reshape(-1, 3)
        if plain:
            flat = {name: self.atlas.flat_colour(name) for name in set(self._materials)}
            colours = np.repeat([flat[name] for name in self._materials], 2, axis=0)  # 2 triangles a quad
            return trimesh.Trimesh(vertices=verts, faces=faces, face_colors=colours, process=False)
        uvs = np.concatenate(self._uvs).astype(np.float32).astype(np.float64)
        material = trimesh.visual.material.PBRMaterial(
            name=ATLAS_MATERIAL, baseColorTexture=Image.fromarray(self.atlas.image), metallicFactor=0.0,
            roughnessFactor=1.0, doubleSided=True,
        )
        visual = trimesh.visual.TextureVisuals(uv=uvs, material=material)
        return trimesh.Trimesh(vertices=verts, faces=faces, visual=visual, process=False)


def _tile_cuts(length: float) -> np.ndarray:
    """0, T, 2T, ..., length: full tiles then one remainder (no sliver below 1 mm)."""
    cuts = list(np.arange(0.0, length, TILE_METRES))
    if length - cuts[-1] < 1e-3 and len(cuts) > 1:
        cuts.pop()
    return np.array([*cuts, length])
