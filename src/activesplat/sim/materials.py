"""Surface appearance as the scene file defines it: a list of materials (base colour factor, own
texture, own sampler wrap modes) and, per triangle, its material, corner UVs and corner colours.

Colour of a surface point (glTF 2.0, metallic-roughness base colour; lighting is the sensor's):

    albedo = texel(material texture, uv) * baseColorFactor * interpolated vertex colour (COLOR_0)

- Texel lookup is **nearest** (the texel whose square holds the UV; no filtering, no mipmaps), in
  the material's own texture, after its sampler's wrap mode per axis: REPEAT (glTF default),
  MIRRORED_REPEAT or CLAMP_TO_EDGE. Nothing is packed into an atlas, so tiling UVs stay tiling.
- UVs follow glTF: (0, 0) is the top-left corner of the image, t grows downward.
- Products are taken on the stored values divided by 255 (no sRGB-to-linear conversion), so a
  texture with factor 1 and no vertex colours renders its own texel values. Alpha is ignored
  (surfaces are opaque).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

REPEAT = 10497
"""glTF sampler wrap mode REPEAT (the default when a texture has no sampler or no wrapS/wrapT)."""
MIRRORED_REPEAT = 33648
"""glTF sampler wrap mode MIRRORED_REPEAT."""
CLAMP_TO_EDGE = 33071
"""glTF sampler wrap mode CLAMP_TO_EDGE."""
WRAP_MODES = {REPEAT: "repeat", MIRRORED_REPEAT: "mirrored repeat", CLAMP_TO_EDGE: "clamp"}
UNTEXTURED_GREY = 0.7
"""Albedo of meshes that carry no colour at all (plain .ply/.obj without materials)."""


@dataclass
class Material:
    """One material: base colour factor (RGB in [0, 1]), optional RGB uint8 texture (row 0 = top)
    and the wrap mode of its sampler along s (columns) and t (rows)."""

    name: str
    base_colour: np.ndarray
    texture: np.ndarray | None = None
    wrap_s: int = REPEAT
    wrap_t: int = REPEAT

    def __post_init__(self):
        self.base_colour = np.asarray(self.base_colour, dtype=np.float32).reshape(3)
        if self.texture is not None:
            self.texture = np.ascontiguousarray(self.texture, dtype=np.uint8)
        for mode in (self.wrap_s, self.wrap_t):
            if mode not in WRAP_MODES:
                raise ValueError(f"material {self.name!r}: unknown wrap mode {mode}")


@dataclass
class Surface:
    """Per-triangle appearance of a mesh with F faces: `face_material` (F,) int32 into `materials`,
    `face_uv` (F, 3, 2) float32 glTF UVs of the three corners (None: no face is textured) and
    `face_colour` (F, 3, 3) float32 vertex colours of the corners (None: all white)."""

    materials: list[Material]
    face_material: np.ndarray
    face_uv: np.ndarray | None = None
    face_colour: np.ndarray | None = None

    def __post_init__(self):
        self.face_material = np.ascontiguousarray(self.face_material, dtype=np.int32)
        if self.face_uv is not None:
            self.face_uv = np.ascontiguousarray(self.face_uv, dtype=np.float32)
        if self.face_colour is not None:
            self.face_colour = np.ascontiguousarray(self.face_colour, dtype=np.float32)

    def __len__(self) -> int:
        return len(self.face_material)

    @classmethod
    def concatenate(cls, parts: list[Surface]) -> Surface:
        """One surface of several meshes' faces in order; materials are renumbered, not merged."""
        materials, ids, offset = [], [], 0
        for part in parts:
            ids.append(part.face_material + offset)
            materials += part.materials
            offset += len(part.materials)
        n = [len(p) for p in parts]
        uv = None
        if any(p.face_uv is not None for p in parts):
            uv = np.concatenate([p.face_uv if p.face_uv is not None else np.zeros((k, 3, 2), np.float32)
                                 for p, k in zip(parts, n, strict=True)])
        colour = None
        if any(p.face_colour is not None for p in parts):
            white = [np.ones((k, 3, 3), np.float32) for k in n]
            colour = np.concatenate([w if p.face_colour is None else p.face_colour
                                     for p, w in zip(parts, white, strict=True)])
        face_material = np.concatenate(ids) if ids else np.zeros(0, np.int32)
        return cls(materials, face_material, uv, colour)

    def drop_texture(self, faces: np.ndarray) -> None:
        """Let `faces` (bool mask) show their material's base colour only (bad UVs): each affected
        textured material gets an untextured twin that those faces use."""
        twins: dict[int, int] = {}
        for m in np.unique(self.face_material[faces]):
            material = self.materials[m]
            if material.texture is None:
                continue
            twins[int(m)] = len(self.materials)
            self.materials.append(Material(f"{material.name} (base colour)", material.base_colour))
        for m, twin in twins.items():
            self.face_material[faces & (self.face_material == m)] = twin
        if self.face_uv is not None:
            self.face_uv[faces] = 0.0


def image_rgb(image) -> np.ndarray:
    """RGB uint8 array of a PIL image of any mode (grey, palette, RGBA, 16 bit, ...)."""
    if image.mode in ("I;16", "I;16B", "I;16L", "I"):
        data = np.asarray(image, dtype=np.float64)
        data = np.round(data / max(data.max(), 1.0) * 255.0) if image.mode == "I" else np.round(data / 257.0)
        return np.repeat(data.astype(np.uint8)[..., None], 3, axis=2)
    return np.asarray(image.convert("RGB"), dtype=np.uint8)


def _trimesh_material(material, name: str) -> Material:
    """A Material from a trimesh PBR or simple material (texture, colour factor; REPEAT wrap)."""
    factor, image = np.ones(3), None
    if isinstance(material, trimesh.visual.material.PBRMaterial):
        image = material.baseColorTexture
        if material.baseColorFactor is not None:
            factor = np.asarray(material.baseColorFactor[:3], dtype=np.float64) / 255.0
    elif isinstance(material, trimesh.visual.material.SimpleMaterial):
        image = material.image
        factor = np.asarray(material.diffuse[:3], dtype=np.float64) / 255.0
    name = getattr(material, "name", None) or name
    return Material(name, factor, None if image is None else image_rgb(image))


def surface_from_trimesh(mesh: trimesh.Trimesh, name: str = "material") -> Surface:
    """The Surface of a trimesh mesh: a TextureVisuals material (with vertex colours kept in its
    `color` attribute), per-vertex or per-face colours, or UNTEXTURED_GREY."""
    visual, faces = mesh.visual, mesh.faces
    n = len(faces)
    ids = np.zeros(n, np.int32)
    if isinstance(visual, trimesh.visual.TextureVisuals):
        material = _trimesh_material(visual.material, name)
        colour = None
        vc = visual.vertex_attributes.get("color") if hasattr(visual, "vertex_attributes") else None
        if vc is not None and len(vc) == len(mesh.vertices):
            vc = np.asarray(vc, dtype=np.float32)
            colour = (vc[:, :3] / (255.0 if vc.max() > 1.0 else 1.0))[faces]
        if material.texture is not None and visual.uv is not None and len(visual.uv) == len(mesh.vertices):
            uv = np.asarray(visual.uv, dtype=np.float64)[faces]
            uv[..., 1] = 1.0 - uv[..., 1]  # trimesh's v points up; glTF's t points down
            return Surface([material], ids, uv.astype(np.float32), colour)
        return Surface([Material(material.name, material.base_colour)], ids, None, colour)
    kind = getattr(visual, "kind", None)
    white = Material(name, np.ones(3))
    if kind == "vertex":
        colours = np.asarray(visual.vertex_colors[:, :3], np.float32) / 255.0
        return Surface([white], ids, None, colours[faces])
    if kind == "face":
        colours = np.asarray(visual.face_colors[:, :3], np.float32) / 255.0
        return Surface([white], ids, None, np.repeat(colours[:, None, :], 3, axis=1))
    return Surface([Material(name, np.full(3, UNTEXTURED_GREY))], ids)
