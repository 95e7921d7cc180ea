"""Tiling textures against the same textures baked at UVs in [0, 1]: two glbs of one
furnished room, identical in geometry and (up to texel-edge rounding) in every sensor image, one
sampling 64 px tiles with UVs from -2 to 10 under REPEAT / MIRRORED_REPEAT samplers, one with each
surface's tiling baked into its own large texture (CLAMP_TO_EDGE, UVs in [0, 1]). Explores both with
the same policy and seed, runs render-eval on both and prints the test PSNR of each map (target:
within 2 dB), after the pixel agreement of a few simulator frames.

    python benchmarks/tiling.py [--steps 1000] [--out runs/tiling] [--frames-only]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from activesplat.errors import InvalidInputError, check_output_folder
from activesplat.sim import Simulator, load_scene
from activesplat.sim.gltf import write_glb
from activesplat.sim.materials import CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT, Material, Surface

TILE_PX = 64
TILE_M = 0.5
"""One tile covers 0.5 m of surface: 128 texels per metre, as the built-in houses."""


def _boxes() -> list[tuple[np.ndarray, np.ndarray, int]]:
    """(lo, hi, material) of the room shell (inward faces come from the quad list) and furniture."""
    # sizes are multiples of 1/128 m, so every surface holds a whole number of texels
    return [(np.array([1.0, 0.0, 1.0]), np.array([2.25, 0.75, 1.75]), 3),
            (np.array([4.0, 0.0, 3.25]), np.array([4.625, 1.875, 4.875]), 4),
            (np.array([2.75, 0.0, 3.5]), np.array([3.375, 0.5, 4.125]), 3)]


def _quads(size=(6.0, 2.75, 5.0)):
    """(corner, edge_a, edge_b, material) of the room: floor, ceiling and walls facing inward, then
    the furniture boxes' faces facing outward."""
    w, h, d = size
    quads = [((0, 0, 0), (0, 0, d), (w, 0, 0), 0), ((0, h, 0), (w, 0, 0), (0, 0, d), 1),
             ((0, 0, 0), (w, 0, 0), (0, h, 0), 2), ((0, 0, d), (0, h, 0), (w, 0, 0), 2),
             ((0, 0, 0), (0, h, 0), (0, 0, d), 2), ((w, 0, 0), (0, 0, d), (0, h, 0), 2)]
    for lo, hi, m in _boxes():
        x, y, z = hi - lo
        quads += [((lo[0], hi[1], lo[2]), (0, 0, z), (x, 0, 0), m),
                  ((lo[0], lo[1], lo[2]), (x, 0, 0), (0, y, 0), m),
                  ((lo[0], lo[1], hi[2]), (0, y, 0), (x, 0, 0), m),
                  ((lo[0], lo[1], lo[2]), (0, y, 0), (0, 0, z), m),
                  ((hi[0], lo[1], lo[2]), (0, 0, z), (0, y, 0), m)]
    return [(np.asarray(c, float), np.asarray(a, float), np.asarray(b, float), m) for c, a, b, m in quads]


def _tiles(seed: int = 0) -> list[np.ndarray]:
    """Five 64 x 64 noisy, patterned tiles (floor, ceiling, walls, wood, fabric)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:TILE_PX, 0:TILE_PX] / TILE_PX
    tiles = []
    bases = [(0.6, 0.45, 0.3), (0.92, 0.92, 0.9), (0.75, 0.78, 0.7), (0.55, 0.35, 0.2), (0.3, 0.4, 0.6)]
    for k, base in enumerate(bases):
        stripes = 0.1 * np.sin(2 * np.pi * (k + 2) * (xx + 0.3 * yy))
        pattern = 0.85 + stripes + 0.08 * rng.standard_normal(xx.shape)
        tiles.append(np.clip(pattern[..., None] * base, 0, 1))
    return [np.round(t * 255).astype(np.uint8) for t in tiles]


def room_glbs(folder: Path) -> tuple[Path, Path]:
    """Write tiling.glb and baked.glb into folder."""
    tiles = _tiles()
    wraps = [REPEAT, REPEAT, MIRRORED_REPEAT, REPEAT, MIRRORED_REPEAT]
    verts, tiled_uv, baked_uv, face_mat, baked_mats, tiled_mats = [], [], [], [], [], []
    for k, tile in enumerate(tiles):
        tiled_mats.append(Material(f"tile{k}", np.ones(3), tile, wraps[k], wraps[k]))
    for q, (corner, ea, eb, m) in enumerate(_quads()):
        na, nb = np.linalg.norm(ea) / TILE_M, np.linalg.norm(eb) / TILE_M  # tiles along each edge
        s = np.array([0.0, 1.0, 1.0, 0.0])
        t = np.array([0.0, 0.0, 1.0, 1.0])
        pos = corner + s[:, None] * ea + t[:, None] * eb
        idx = [0, 1, 2, 0, 2, 3]
        verts.append(pos[idx])
        start = -2.0  # UVs from -2 to -2 + tiles: negative and > 1, as designed furniture has
        tiled_uv.append(np.stack([start + s * na, start + t * nb], axis=1)[idx])
        baked_uv.append(np.stack([s, t], axis=1)[idx])
        # bake: texel (row, col) of the big texture = the tiled lookup at the same surface point
        cols, rows = int(round(na * TILE_PX)), int(round(nb * TILE_PX))
        sc = start * TILE_PX + np.arange(cols)
        tr = start * TILE_PX + np.arange(rows)
        ci, ri = (_wrapped(sc, wraps[m]), _wrapped(tr, wraps[m]))
        baked_mats.append(Material(f"baked{q}", np.ones(3), tiles[m][ri[:, None], ci[None, :]],
                                   CLAMP_TO_EDGE, CLAMP_TO_EDGE))
        face_mat.append(np.full(2, m))
    vertices = np.concatenate(verts)
    faces = np.arange(len(vertices)).reshape(-1, 3)
    tiled = Surface(tiled_mats, np.concatenate(face_mat), np.concatenate(tiled_uv).reshape(-1, 3, 2))
    baked = Surface(baked_mats, np.repeat(np.arange(len(baked_mats)), 2),
                    np.concatenate(baked_uv).reshape(-1, 3, 2))
    folder.mkdir(parents=True, exist_ok=True)
    return (write_glb(folder / "tiling.glb", vertices, faces, tiled),
            write_glb(folder / "baked.glb", vertices, faces, baked))


def _wrapped(texel: np.ndarray, mode: int) -> np.ndarray:
    texel = texel.astype(np.int64)
    if mode == MIRRORED_REPEAT:
        m = np.mod(texel, 2 * TILE_PX)
        return np.where(m >= TILE_PX, 2 * TILE_PX - 1 - m, m)
    return np.mod(texel, TILE_PX)


def frame_agreement(tiling: Path, baked: Path, n: int = 20) -> float:
    """Fraction of identical pixels over n frames of a random walk in both rooms."""
    a = Simulator(load_scene(tiling), seed=0)
    b = Simulator(load_scene(baked), start=a.start_pose)
    rng = np.random.default_rng(0)
    same = total = 0
    for i in range(n):
        action = None if i == 0 else str(rng.choice(["turn_left", "move_forward", "look_down", "look_up"]))
        oa, ob = (a.reset(), b.reset()) if action is None else (a.step(action), b.step(action))
        same += int((oa.rgb == ob.rgb).all(axis=-1).sum())
        total += oa.rgb.shape[0] * oa.rgb.shape[1]
    return same / total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--out", default="runs/tiling")
    parser.add_argument("--frames-only", action="store_true", help="only compare simulator frames")
    args = parser.parse_args()
    out = Path(args.out)
    try:
        check_output_folder(out, "--out")  # before the scenes are written
    except InvalidInputError as exc:
        parser.error(str(exc))
    tiling, baked = room_glbs(out)
    print(f"identical pixels, tiling vs baked, 20 frames: {100 * frame_agreement(tiling, baked):.3f} %")
    if args.frames_only:
        return
    from activesplat.eval.render_eval import render_eval
    from activesplat.explore import run_exploration

    rows = []
    for path in (tiling, baked):
        episode = out / path.stem
        metrics = run_exploration(str(path), steps=args.steps, seed=0, out=episode, overwrite=True,
                                  progress=False)
        render = render_eval(episode, progress=False)
        rows.append((path.stem, metrics["completion_ratio_pct"], render["train"]["psnr"],
                     render["test"]["psnr"]))
    print("| room | completion % | train PSNR | test PSNR |\n|---|---:|---:|---:|")
    for name, completion, train, test in rows:
        print(f"| {name} | {completion:.2f} | {train:.2f} | {test:.2f} |")
    print(f"test PSNR difference: {abs(rows[0][3] - rows[1][3]):.2f} dB (target <= 2 dB)")
    (out / "tiling_vs_baked.json").write_text(json.dumps(rows))


if __name__ == "__main__":
    main()
