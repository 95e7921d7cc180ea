"""Procedural, seeded, seamlessly tiling textures packed into one atlas per scene.

Every tile covers ``TILE_METRES`` of surface (128 px per metre). Scene quads are at most one tile
large and map to a corner-anchored part of one tile, so neighbouring quads continue the pattern.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter

TILE_PX = 64
"""Pixels per tile side."""
TILE_METRES = 0.5
"""Surface size one tile covers (TILE_PX / TILE_METRES = 128 px per metre)."""
ATLAS_TILES = 4
"""The atlas is ATLAS_TILES x ATLAS_TILES tiles."""
ATLAS_MATERIAL = "activesplat texture atlas"
"""Name of the material whose texture is the atlas (kept by glTF export, so a reloaded house is
recognised as one)."""
BRIGHTNESS_JITTER = (0.92, 1.08)
"""Per-scene brightness factor range of each material's base colour."""
CHANNEL_JITTER = (0.97, 1.03)
"""Per-channel factor range: small, so near-white materials (ceiling) stay neutral, not pink."""


def _noise(rng: np.random.Generator, sigma: float) -> np.ndarray:
    """Periodic smooth noise in [-1, 1] (wrap-around blur, so the tile is seamless)."""
    n = gaussian_filter(rng.standard_normal((TILE_PX, TILE_PX)), sigma, mode="wrap")
    return n / (np.abs(n).max() + 1e-9)


def _grid() -> tuple[np.ndarray, np.ndarray]:
    idx = np.arange(TILE_PX) / TILE_PX
    return np.meshgrid(idx, idx, indexing="ij")  # (row, col) in [0, 1)


def _tint(pattern: np.ndarray, colour: np.ndarray) -> np.ndarray:
    """Scale an intensity pattern around 1 by an RGB base colour, clipped to [0, 1]."""
    return np.clip(pattern[..., None] * colour[None, None, :], 0.0, 1.0)


def plaster(rng, colour) -> np.ndarray:
    """Painted plaster: low-frequency blotches plus fine grain."""
    return _tint(1.0 + 0.08 * _noise(rng, 6.0) + 0.06 * _noise(rng, 1.0), colour)


def wood(rng, colour) -> np.ndarray:
    """Wood planks: 4 planks per tile along the column axis, wavy grain, dark seams."""
    rows, cols = _grid()
    warp = 0.08 * _noise(rng, 8.0)
    grain = 0.5 + 0.5 * np.sin(2 * np.pi * (6 * cols + 2 * warp * 6 + 3 * np.sin(2 * np.pi * rows)))
    plank = np.floor(rows * 4).astype(int)
    plank_shade = rng.uniform(0.85, 1.1, size=4)[plank]
    seam = (np.mod(rows * 4, 1.0) < 0.06).astype(float)
    return _tint(plank_shade * (0.85 + 0.2 * grain) * (1.0 - 0.45 * seam), colour)


def tiles(rng, colour) -> np.ndarray:
    """Square ceramic tiles (2x2 per tile, 25 cm) with grout lines and per-tile variation."""
    rows, cols = _grid()
    cell = (np.floor(rows * 2) * 2 + np.floor(cols * 2)).astype(int)
    shade = rng.uniform(0.9, 1.08, size=4)[cell]
    grout = (np.minimum(np.mod(rows * 2, 1.0), np.mod(cols * 2, 1.0)) < 0.05).astype(float)
    return _tint(shade * (1.0 + 0.03 * _noise(rng, 1.5)) * (1.0 - 0.4 * grout), colour)


def fabric(rng, colour) -> np.ndarray:
    """Woven fabric: alternating warp/weft threads (a fine checker) with slight noise."""
    rows, cols = _grid()
    weave = np.sign(np.sin(2 * np.pi * 16 * rows)) * np.sign(np.sin(2 * np.pi * 16 * cols))
    return _tint(1.0 + 0.08 * weave + 0.05 * _noise(rng, 3.0), colour)


def carpet(rng, colour) -> np.ndarray:
    """Carpet: strong high-frequency pile noise plus a faint diamond pattern."""
    rows, cols = _grid()
    diamond = np.abs(np.sin(2 * np.pi * 2 * (rows + cols))) * np.abs(np.sin(2 * np.pi * 2 * (rows - cols)))
    return _tint(0.92 + 0.12 * _noise(rng, 0.7) + 0.1 * diamond, colour)


def cardboard(rng, colour) -> np.ndarray:
    """Cardboard / plain surfaces: fibre noise."""
    rows, _ = _grid()
    return _tint(1.0 + 0.05 * _noise(rng, 2.0) + 0.03 * np.sin(2 * np.pi * 8 * rows), colour)


# name -> (pattern, base RGB); each scene draws a colour jitter per tile.
MATERIALS: dict[str, tuple] = {
    "wall_a": (plaster, (0.86, 0.82, 0.74)),
    "wall_b": (plaster, (0.70, 0.78, 0.82)),
    "wall_c": (plaster, (0.85, 0.72, 0.66)),
    "wall_d": (plaster, (0.76, 0.80, 0.66)),
    "floor_wood": (wood, (0.62, 0.44, 0.28)),
    "floor_wood_dark": (wood, (0.42, 0.29, 0.20)),
    "floor_tiles": (tiles, (0.80, 0.80, 0.78)),
    "floor_carpet": (carpet, (0.45, 0.36, 0.42)),
    "ceiling": (plaster, (0.93, 0.93, 0.91)),
    "fabric_a": (fabric, (0.30, 0.42, 0.58)),
    "fabric_b": (fabric, (0.65, 0.35, 0.28)),
    "furniture_wood": (wood, (0.72, 0.55, 0.36)),
    "furniture_dark": (wood, (0.35, 0.25, 0.18)),
    "cardboard": (cardboard, (0.68, 0.53, 0.36)),
    "white_board": (cardboard, (0.90, 0.90, 0.88)),
    "metal": (cardboard, (0.55, 0.57, 0.60)),
}
WALL_MATERIALS = ("wall_a", "wall_b", "wall_c", "wall_d")
FLOOR_MATERIALS = ("floor_wood", "floor_wood_dark", "floor_tiles", "floor_carpet")


@dataclass(frozen=True)
class Atlas:
    """One RGB uint8 atlas image (row 0 = top) and the tile index of each material name."""

    image: np.ndarray
    tile_of: dict[str, int]

    def tile_uv(self, material: str, s: np.ndarray, t: np.ndarray) -> np.ndarray:
        """UV (glTF/trimesh convention: v up from the image bottom) of local tile coordinates s, t in
        [0, 1]. Inset by half a pixel so nearest sampling never reads a neighbouring tile."""
        k = self.tile_of[material]
        size = self.image.shape[0]
        col0, row0 = (k % ATLAS_TILES) * TILE_PX, (k // ATLAS_TILES) * TILE_PX
        # Rounded to half pixels: multiples of 1/512 survive float32 and glTF's v -> 1 - v exactly.
        px = col0 + 0.5 + np.round(np.asarray(s) * (TILE_PX - 1) * 2) / 2
        py = row0 + 0.5 + np.round(np.asarray(t) * (TILE_PX - 1) * 2) / 2
        return np.stack([px / size, 1.0 - py / size], axis=-1)

    def flat_colour(self, material: str) -> np.ndarray:
        """uint8 RGB of a material without its pattern: the mean of its tile (plain-material houses)."""
        k = self.tile_of[material]
        r, c = (k // ATLAS_TILES) * TILE_PX, (k % ATLAS_TILES) * TILE_PX
        tile = self.image[r : r + TILE_PX, c : c + TILE_PX].reshape(-1, 3).astype(np.float64)
        return np.round(tile.mean(axis=0)).astype(np.uint8)


def build_atlas(seed: int) -> Atlas:
    """Render every material of MATERIALS into one seeded atlas (deterministic per seed)."""
    rng = np.random.default_rng(seed)
    size = TILE_PX * ATLAS_TILES
    image = np.zeros((size, size, 3), dtype=np.uint8)
    tile_of = {}
    for k, (name, (pattern, base)) in enumerate(MATERIALS.items()):
        jitter = rng.uniform(*BRIGHTNESS_JITTER) * rng.uniform(*CHANNEL_JITTER, size=3)
        colour = np.clip(np.asarray(base) * jitter, 0, 1)
        r, c = (k // ATLAS_TILES) * TILE_PX, (k % ATLAS_TILES) * TILE_PX
        image[r : r + TILE_PX, c : c + TILE_PX] = np.round(pattern(rng, colour) * 255).astype(np.uint8)
        tile_of[name] = k
    return Atlas(image=image, tile_of=tile_of)


def tile_surface(surface):
    """The surface of a MeshBuilder mesh (one material named ATLAS_MATERIAL whose texture is the atlas,
    as built or reloaded from an exported .glb) as one material per atlas tile, each with its own
    TILE_PX x TILE_PX texture and REPEAT wrap, and UVs in tile units. Reading the nearest texel gives the
    same image as the atlas (the same texel under every pixel), but a filter that reads neighbouring
    texels or coarser mip levels (SimConfig.texture_filter "area") wraps around within the tile, which is
    seamless, instead of bleeding into the next tile of the atlas. Any other surface is returned unchanged."""
    from activesplat.sim.materials import REPEAT, Material, Surface

    size = TILE_PX * ATLAS_TILES
    atlas = surface.materials[0] if len(surface.materials) == 1 else None
    if (atlas is None or atlas.name != ATLAS_MATERIAL or surface.face_uv is None or atlas.texture is None
            or atlas.texture.shape[:2] != (size, size)):
        return surface
    px = surface.face_uv.astype(np.float64) * size  # (F, 3, 2) texel columns and rows, rows down
    tile = np.floor(px.mean(axis=1) / TILE_PX).astype(np.int64).clip(0, ATLAS_TILES - 1)
    index = tile[:, 1] * ATLAS_TILES + tile[:, 0]
    used, face_material = np.unique(index, return_inverse=True)
    materials = []
    for k in used:
        r, c = (k // ATLAS_TILES) * TILE_PX, (k % ATLAS_TILES) * TILE_PX
        materials.append(Material(f"{atlas.name} tile {k}", atlas.base_colour,
                                  atlas.texture[r : r + TILE_PX, c : c + TILE_PX], REPEAT, REPEAT))
    uv = (px - TILE_PX * tile[:, None, :]) / TILE_PX
    return Surface(materials, face_material, uv.astype(np.float32), surface.face_colour)
