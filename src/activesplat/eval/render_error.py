"""Where a map's rendering error comes from: every pixel of the render-eval views gets one class, and the
budget says how many dB of PSNR each class costs (docs/protocol.md §6, "Error budget").

The views, ground truth and renders are exactly those of :func:`activesplat.eval.render_eval.render_eval`
(same train and test poses, same seed). Each pixel falls in the first class whose test it passes:

1. ``hole_unobserved``: the map renders it with opacity below 0.5 (render-eval's ``unmapped``), and no
   frame of the trajectory saw its ground-truth surface point (projected into every ``poses.txt`` camera:
   inside the image, in front of it, and within 5 cm of that camera's ground-truth depth). The mapper
   never had an observation of it: this error belongs to the explorer.
2. ``hole_grazing``: a hole whose surface point the trajectory saw, but only at a grazing angle: every
   frame that saw it looked at the surface more than ``grazing_deg`` (70) off its normal. Such a surface
   is a strip a few pixels wide in those frames, and the mapper's per-pixel Gaussians, each about a
   pixel's footprint across the ray, cover a sixth of it along the slant at 80 degrees, so seen face-on
   it is mostly gaps (the top of a counter a little below the camera's height).
3. ``hole_observed``: a hole whose surface point some frame saw less obliquely: the mapper's own failure.
4. ``translucent``: opacity in [0.5, 0.95): the background shows through gaps between Gaussians.
5. ``depth_front`` / ``depth_behind``: the rendered depth (sum w_i z_i / O) is more than 10 cm in front of
   / behind the ground truth: floaters, surfaces bleeding over silhouettes, missing objects.
6. ``depth_edge``: within 2 px of a depth jump of the ground truth (a kink of more than 5 % in the
   inverse depth, which is affine on a plane): silhouettes the map renders at the right depth.
7. ``floor`` / ``ceiling``: ground-truth surface facing up within 5 cm of the floor height / facing down
   above the camera; ``rest``: everything else (walls, furniture).

For each class the budget reports its share of the pixels, its share of the summed squared colour error
of the split, ``depth_l1_cm``: the class's part of render-eval's depth L1 (|sum w_i z_i - D_gt| summed
over the class's pixels with ground-truth depth, divided by the view's count of such pixels, averaged over
views; the parts add up to the split's depth L1), and ``gain_db``: how much the split's PSNR (the mean
over views of each view's PSNR, as render-eval computes it) would rise if that class's squared error were
halved in every view. Halving, not removing: a view whose error is nearly all one class would otherwise
jump to the 100 dB cap and swamp the mean. The gain of a view is at most 10 log10 2 = 3.01 dB (all its
error in the class); for a class holding a share s of a view's error it is -10 log10(1 - s / 2). Gains
of different classes do not add up, but they rank what to fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from activesplat.errors import EpisodeError
from activesplat.timing import progress_bar

PIXEL_CLASSES = ("hole_unobserved", "hole_grazing", "hole_observed", "translucent", "depth_front",
                 "depth_behind", "depth_edge", "floor", "ceiling", "rest")
"""Pixel classes in the order their tests are applied (module docstring)."""
_HOLE_UNOBSERVED = PIXEL_CLASSES.index("hole_unobserved")
_HOLE_GRAZING = PIXEL_CLASSES.index("hole_grazing")
_HOLE_OBSERVED = PIXEL_CLASSES.index("hole_observed")


@dataclass(frozen=True)
class ErrorBudgetConfig:
    """Thresholds of the pixel classes (ours; module docstring)."""

    hole_alpha: float = 0.5
    """Opacity below which a pixel is a hole (render-eval's ``unmapped_alpha``)."""
    translucent_alpha: float = 0.95
    """Opacity below which a mapped pixel is translucent."""
    depth_margin_m: float = 0.1
    """Rendered depth (sum w_i z_i / O) this far in front of / behind the ground truth is a depth error."""
    edge_jump: float = 0.05
    """A depth jump: the inverse depth's Laplacian above this fraction of the inverse depth."""
    edge_px: int = 2
    """Pixels within this distance of a depth jump are depth-edge pixels."""
    observed_tol_m: float = 0.05
    """A trajectory camera saw a surface point when its ground-truth depth there is within this of the
    point's depth (the completion metric's 5 cm)."""
    grazing_deg: float = 70.0
    """A hole the trajectory saw only more than this many degrees off the surface normal is
    ``hole_grazing``: at 70 degrees a pixel's footprint is three times longer along the slant than
    across it. On a live medium-house map the observed holes' best keyframe angle has a median of 80
    degrees, that of a sample of mapped pixels 32 (docs/mapping.md, "Holes seen edge-on")."""
    floor_tol_m: float = 0.05
    """Upward-facing surface within this of the floor height is floor."""
    horizontal_cos: float = 0.9
    """|n_y| above this makes a surface horizontal (floor or ceiling)."""


# --------------------------------------------------------------------------- per-pixel pieces
def surface_normals(points: np.ndarray) -> np.ndarray:
    """(H, W, 3) unit normals of an (H, W, 3) image of world points, from central differences (the border
    pixels copy their neighbours; pixels without neighbours get zero)."""
    dx = np.zeros_like(points)
    dy = np.zeros_like(points)
    dx[:, 1:-1] = points[:, 2:] - points[:, :-2]
    dy[1:-1] = points[2:] - points[:-2]
    dx[:, 0], dx[:, -1] = dx[:, 1], dx[:, -2]
    dy[0], dy[-1] = dy[1], dy[-2]
    n = np.cross(dx, dy)
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(norm > 1e-12, n / np.maximum(norm, 1e-12), 0.0)


def depth_jumps(gt_depth: np.ndarray, cfg: ErrorBudgetConfig) -> np.ndarray:
    """Pixels within ``edge_px`` of a kink in the ground truth's inverse depth (module docstring)."""
    from scipy import ndimage

    valid = gt_depth > 0
    inverse = np.where(valid, 1.0 / np.maximum(gt_depth, 1e-6), 0.0)
    kink = np.abs(ndimage.laplace(inverse)) > cfg.edge_jump * np.maximum(inverse, 1e-6)
    kink |= valid != ndimage.binary_erosion(valid, border_value=1)  # edges of missing depth
    if cfg.edge_px <= 0:
        return kink
    return ndimage.binary_dilation(kink, iterations=cfg.edge_px)


def observation_angle(points: np.ndarray, poses, depth_of, K: np.ndarray, width: int, height: int,
                      tol_m: float, normals: np.ndarray | None = None, enough_deg: float = 0.0) -> np.ndarray:
    """(N,) the smallest angle (degrees) between each world point's surface normal and the ray to a
    camera-to-world pose of ``poses`` that saw it: it projects inside the image, in front of the camera,
    within ``tol_m`` of that camera's ground-truth depth ``depth_of(pose)``. inf where no pose saw it;
    0 for every seen point when ``normals`` is None or a point's normal is zero (the sign of a normal does
    not matter). A point whose angle is already at most ``enough_deg`` is not looked at again (0: the
    first sighting with normals None, every pose otherwise)."""
    angle = np.full(len(points), np.inf)
    for pose in poses:
        todo = np.nonzero(angle > enough_deg)[0]
        if len(todo) == 0:
            break
        w2c = np.linalg.inv(pose)
        cam = points[todo] @ w2c[:3, :3].T + w2c[:3, 3]
        z = cam[:, 2]
        front = z > 1e-3
        zs = np.where(front, z, 1.0)
        u = np.floor(cam[:, 0] / zs * K[0, 0] + K[0, 2]).astype(np.int64)
        v = np.floor(cam[:, 1] / zs * K[1, 1] + K[1, 2]).astype(np.int64)
        inside = front & (u >= 0) & (u < width) & (v >= 0) & (v < height)
        if not inside.any():
            continue
        depth = depth_of(pose)
        idx = np.nonzero(inside)[0]
        d = depth[v[idx], u[idx]]
        hit = todo[idx[(d > 0) & (np.abs(d - z[idx]) < tol_m)]]
        if normals is None:
            angle[hit] = 0.0
            continue
        ray = pose[:3, 3] - points[hit]
        cos = np.abs(np.sum(ray * normals[hit], axis=1)) / np.maximum(np.linalg.norm(ray, axis=1), 1e-12)
        # a point without a normal (zero: no neighbours to take it from) counts as seen head-on
        cos = np.where(np.linalg.norm(normals[hit], axis=1) > 0.5, cos, 1.0)
        angle[hit] = np.minimum(angle[hit], np.degrees(np.arccos(np.clip(cos, 0.0, 1.0))))
    return angle


def classify_pixels(alpha: np.ndarray, depth: np.ndarray, gt_depth: np.ndarray, points: np.ndarray,
                    camera: np.ndarray, floor_y: float, observed=None,
                    cfg: ErrorBudgetConfig | None = None, normals: np.ndarray | None = None) -> np.ndarray:
    """(H, W) index into PIXEL_CLASSES of every pixel of one view (module docstring).

    ``alpha`` / ``depth``: the render's opacity and un-normalised depth sum w_i z_i; ``points``: (H, W, 3)
    world points of the ground-truth depth; ``camera``: the view's position; ``observed(points (N, 3),
    normals (N, 3))`` -> (N,) the smallest angle (degrees) off the normal at which the trajectory saw each
    point, inf where it never did (:func:`observation_angle`; only asked for holes; None: every hole stays
    ``hole_observed``, for the caller to split); ``normals``: :func:`surface_normals` of ``points`` when the
    caller has them already."""
    cfg = cfg or ErrorBudgetConfig()
    valid = gt_depth > 0
    shown = np.where(alpha > 1e-6, depth / np.maximum(alpha, 1e-6), 0.0)
    normals = surface_normals(points) if normals is None else normals
    up = normals[..., 1]
    # orient the normals toward the camera so that "faces up" means what the camera sees faces up
    toward = np.sum(normals * (camera[None, None, :] - points), axis=-1) < 0
    up = np.where(toward, -up, up)
    label = np.full(alpha.shape, PIXEL_CLASSES.index("rest"), dtype=np.int64)
    horizontal = valid & (np.abs(up) > cfg.horizontal_cos)
    floor = horizontal & (up > 0) & (np.abs(points[..., 1] - floor_y) < cfg.floor_tol_m)
    ceiling = horizontal & (up < 0) & (points[..., 1] > camera[1])
    label[ceiling] = PIXEL_CLASSES.index("ceiling")
    label[floor] = PIXEL_CLASSES.index("floor")
    label[depth_jumps(gt_depth, cfg)] = PIXEL_CLASSES.index("depth_edge")
    label[valid & (shown > gt_depth + cfg.depth_margin_m)] = PIXEL_CLASSES.index("depth_behind")
    label[valid & (shown < gt_depth - cfg.depth_margin_m)] = PIXEL_CLASSES.index("depth_front")
    label[alpha < cfg.translucent_alpha] = PIXEL_CLASSES.index("translucent")
    hole = alpha < cfg.hole_alpha
    label[hole] = PIXEL_CLASSES.index("hole_observed")
    ask = hole & valid
    if observed is not None and ask.any():
        rows, cols = np.nonzero(ask)
        label[rows, cols] = hole_labels(observed(points[ask], normals[ask]), cfg)
    return label


def hole_labels(angle: np.ndarray, cfg: ErrorBudgetConfig) -> np.ndarray:
    """The hole class of points the trajectory saw at best at ``angle`` degrees off their normal (inf:
    never): ``hole_unobserved``, ``hole_grazing`` beyond ``cfg.grazing_deg``, else ``hole_observed``."""
    label = np.full(angle.shape, _HOLE_OBSERVED, dtype=np.int64)
    label[angle > cfg.grazing_deg] = _HOLE_GRAZING
    label[~np.isfinite(angle)] = _HOLE_UNOBSERVED
    return label


def squared_error(rgb: np.ndarray, gt_rgb: np.ndarray) -> np.ndarray:
    """(H, W) squared colour error per pixel, averaged over the channels (colours in [0, 1]; uint8 ground
    truth divided by 255), as render-eval's PSNR sees it."""
    gt = gt_rgb.astype(np.float64) / 255.0 if gt_rgb.dtype == np.uint8 else gt_rgb.astype(np.float64)
    return np.mean((np.clip(rgb.astype(np.float64), 0.0, 1.0) - gt) ** 2, axis=-1)


def depth_error(depth: np.ndarray, gt_depth: np.ndarray) -> np.ndarray:
    """(H, W) |sum w_i z_i - D_gt| in metres where the ground truth has depth, NaN elsewhere: the pixels
    and the error of render-eval's depth L1."""
    gt = np.asarray(gt_depth, dtype=np.float64)
    err = np.abs(np.asarray(depth, dtype=np.float64) - gt)
    return np.where(gt > 0, err, np.nan)


def view_budget(se: np.ndarray, label: np.ndarray, psnr_max_db: float = 100.0,
                depth_err: np.ndarray | None = None) -> dict:
    """One view from its squared error image ``se`` and pixel classes: its PSNR, and per class the pixel
    count, summed squared error and the PSNR with that class's squared error halved. With ``depth_err``
    (:func:`depth_error`), also the view's depth L1 and each class's part of it (cm; the parts add up)."""
    se = se.astype(np.float64)
    floor = 10.0 ** (-psnr_max_db / 10.0)
    total = float(se.sum())
    n = se.size

    def to_db(sum_se: float) -> float:
        return -10.0 * math.log10(max(sum_se / n, floor))

    out = {"psnr": to_db(total), "pixels": {}, "squared_error": {}, "psnr_if_halved": {}}
    valid = None
    if depth_err is not None:
        valid = np.isfinite(depth_err)
        n_valid = int(valid.sum())
        out["depth_l1_cm"] = 100.0 * float(depth_err[valid].mean()) if n_valid else None
        out["depth_l1_part_cm"] = {}
    for k, name in enumerate(PIXEL_CLASSES):
        mask = label == k
        class_se = float(se[mask].sum())
        out["pixels"][name] = int(mask.sum())
        out["squared_error"][name] = class_se
        out["psnr_if_halved"][name] = to_db(total - 0.5 * class_se)
        if valid is not None and n_valid:
            out["depth_l1_part_cm"][name] = 100.0 * float(depth_err[mask & valid].sum()) / n_valid
    return out


def summarise_budget(views: list[dict]) -> dict:
    """Per class over the views of a split: % of pixels, % of squared error, mean PSNR gain (dB) if the
    class's error were halved."""
    if not views:
        return {"psnr": None, "n_views": 0, "classes": {}}
    base = float(np.mean([v["psnr"] for v in views]))
    pixels = sum(sum(v["pixels"].values()) for v in views)
    error = sum(sum(v["squared_error"].values()) for v in views)
    with_depth = [v for v in views if v.get("depth_l1_cm") is not None]
    classes = {}
    for name in PIXEL_CLASSES:
        classes[name] = {
            "pixels_pct": 100.0 * sum(v["pixels"][name] for v in views) / max(pixels, 1),
            "error_pct": 100.0 * sum(v["squared_error"][name] for v in views) / max(error, 1e-30),
            "gain_db": float(np.mean([v["psnr_if_halved"][name] for v in views])) - base,
        }
        if with_depth:
            classes[name]["depth_l1_cm"] = float(np.mean([v["depth_l1_part_cm"][name] for v in with_depth]))
    out = {"psnr": base, "n_views": len(views), "classes": classes}
    if with_depth:
        out["depth_l1_cm"] = float(np.mean([v["depth_l1_cm"] for v in with_depth]))
    return out


# --------------------------------------------------------------------------- an episode
def error_budget(episode_dir: str | Path, gaussians_path: str | Path | None = None, n_train: int = 50,
                 n_test: int = 50, seed: int = 0, splits: tuple[str, ...] = ("train", "test"),
                 backend: str = "auto", config: ErrorBudgetConfig | None = None,
                 progress: bool = True, sim_overrides: dict | None = None, renderer=None,
                 figure: str | Path | None = None, figure_views: int = 4) -> dict:
    """The error budget (module docstring) of an exploration episode's map on render-eval's views
    (``sim_overrides``, ``renderer``: as render-eval's; default renderer: the 3DGS rasterizer with the
    map's own depth, as render-eval's). With
    ``figure``, a PNG of the ``figure_views`` test views with the largest squared error: ground truth,
    render, and the pixel classes."""
    from activesplat.episode import is_recorded_map, read_episode
    from activesplat.eval.render_eval import (
        SPLITS,
        RenderEvalConfig,
        _simulated_setup,
        default_renderer,
        locate,
    )
    from activesplat.geometry import backproject
    from activesplat.splat.ply import load_ply

    cfg = config or ErrorBudgetConfig()
    for split in splits:
        if split not in SPLITS:
            raise EpisodeError(f"unknown split {split!r}: choose from {', '.join(SPLITS)}")
    episode_dir, gaussians_path, _ = locate(episode_dir, gaussians_path)
    episode = read_episode(episode_dir)
    if is_recorded_map(episode.meta):
        raise EpisodeError(f"{episode_dir} is a recording: the error budget needs the scene's ground truth")
    setup = _simulated_setup(episode_dir, RenderEvalConfig(n_train=n_train, n_test=n_test, seed=seed),
                             sim_overrides)
    gmap = load_ply(gaussians_path)
    if len(gmap) == 0:
        raise EpisodeError(f"{gaussians_path} holds no Gaussians: nothing to render")
    W, H, K = setup.width, setup.height, setup.K
    renderer = renderer or default_renderer(gaussians_path)
    rows, cols = np.mgrid[0:H, 0:W]
    bar = progress_bar(sum(len(setup.poses[s]) for s in splits) + len(episode.poses),
                       "error budget (views, then trajectory frames)", "frame", progress)
    # 1. every view: squared error and classes, holes provisionally "observed"; their surface points
    views: dict[str, list] = {s: [] for s in splits}
    shown: list[tuple] = []  # (mean squared error, split, view, ground truth, render) for the figure
    holes: list[tuple] = []  # (split, view, rows, cols, points)
    for split in splits:
        for i, pose in enumerate(setup.poses[split]):
            gt_rgb, gt_depth = setup.ground_truth(split, i, pose)
            rgb, depth, alpha = renderer(gmap, pose, K, W, H, backend)
            valid = gt_depth > 0
            points = backproject(np.where(valid, gt_depth, 1.0), pose, K, rows.ravel(), cols.ravel())
            points = points.reshape(H, W, 3)
            normals = surface_normals(points)
            label = classify_pixels(alpha, depth, gt_depth, points, pose[:3, 3], setup.floor_height,
                                    cfg=cfg, normals=normals)
            r, c = np.nonzero((label == _HOLE_OBSERVED) & valid)
            holes.append((split, i, r, c, points[r, c], normals[r, c]))
            views[split].append((squared_error(rgb, gt_rgb).astype(np.float32), label.astype(np.int8),
                                 depth_error(depth, gt_depth).astype(np.float32)))
            if figure is not None and split == splits[-1]:
                shown.append((float(views[split][-1][0].mean()), split, i, gt_rgb, np.clip(rgb, 0.0, 1.0)))
            if bar is not None:
                bar.update(1)

    # 2. one pass over the trajectory: did any frame see the hole points, and how obliquely at best?
    def depth_of(pose: np.ndarray) -> np.ndarray:
        if bar is not None:
            bar.update(1)
        return setup.ground_truth("train", 0, pose)[1]

    points = np.concatenate([h[4] for h in holes]) if holes else np.zeros((0, 3))
    normals = np.concatenate([h[5] for h in holes]) if holes else np.zeros((0, 3))
    angle = observation_angle(points, episode.poses, depth_of, K, W, H, cfg.observed_tol_m, normals,
                              enough_deg=cfg.grazing_deg)
    start = 0
    for split, i, r, c, p, _n in holes:
        views[split][i][1][r, c] = hole_labels(angle[start : start + len(p)], cfg)
        start += len(p)
    if bar is not None:
        bar.close()
    result = {"episode": str(episode_dir), "gaussians": str(gaussians_path), "scene": setup.name,
              "classes": list(PIXEL_CLASSES), "config": cfg.__dict__.copy()}
    for split in splits:
        result[split] = summarise_budget([view_budget(se, label, depth_err=err)
                                          for se, label, err in views[split]])
    if figure is not None:
        worst = sorted(shown, key=lambda v: -v[0])[:figure_views]
        rows = [(f"{s} view {i}, PSNR {-10 * math.log10(max(e, 1e-10)):.1f} dB", gt, rgb, views[s][i][1])
                for e, s, i, gt, rgb in worst]
        where = Path(gaussians_path)
        draw_budget_figure(Path(figure), rows, title=f"{setup.name}: {where.parent.name}/{where.name}")
    return result


CLASS_COLOURS = ("#000000", "#3f3f3f", "#7f7f7f", "#9467bd", "#d62728", "#ff7f0e", "#e377c2", "#8c564b",
                 "#17becf", "#f0f0f0")
"""Colours of PIXEL_CLASSES in figures: holes never observed black, seen only edge-on dark grey, observed
holes grey, rest near white."""


def draw_budget_figure(path: Path, rows: list[tuple], title: str = "") -> Path:
    """Rows of (label, ground truth, render, pixel classes): ground truth | render | classes, and a
    legend."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from activesplat.eval.render_eval import save_view_grid, view_grid

    fig, axes = view_grid(len(rows), ("ground truth", "render", "pixel class"), extra_height=1.0)
    cmap = ListedColormap(CLASS_COLOURS)
    for r, (label, gt, rgb, classes) in enumerate(rows):
        axes[r, 0].imshow(gt)
        axes[r, 1].imshow(rgb)
        axes[r, 2].imshow(classes, cmap=cmap, vmin=-0.5, vmax=len(PIXEL_CLASSES) - 0.5,
                          interpolation="nearest")
        axes[r, 0].set_ylabel(label, fontsize=8)
    fig.legend(handles=[Patch(facecolor=col, edgecolor="0.5", label=name.replace("_", " "))
                        for name, col in zip(PIXEL_CLASSES, CLASS_COLOURS, strict=True)],
               loc="outside lower center", ncol=5, fontsize=8)
    return save_view_grid(fig, path, title)


def format_budget(result: dict) -> str:
    """A markdown table per split: class, % pixels, % squared error, dB gained if its error were halved,
    and the class's part of the depth L1 (cm) where the budget has it."""
    lines = []
    for split in ("train", "test"):
        if split not in result:
            continue
        s = result[split]
        depth = s.get("depth_l1_cm") is not None
        head = f"{split}: {s['n_views']} views, PSNR {s['psnr']:.2f} dB"
        lines += [head + (f", depth L1 {s['depth_l1_cm']:.2f} cm" if depth else ""), "",
                  "| pixel class | pixels % | squared error % | PSNR gain if halved (dB) |"
                  + (" depth L1 part (cm) |" if depth else ""),
                  "|---|---|---|---|" + ("---|" if depth else "")]
        for name, c in s["classes"].items():
            row = f"| {name} | {c['pixels_pct']:.1f} | {c['error_pct']:.1f} | +{c['gain_db']:.2f} |"
            lines.append(row + (f" {c['depth_l1_cm']:.2f} |" if depth else ""))
        lines.append("")
    return "\n".join(lines)
