"""What ``activesplat refine`` prints: the run's summary (iterations, Gaussians, density control, the
training PSNR) and the refined map's render-eval, beside the online map's on the same views when the
episode folder has its render_metrics.json (`format_metrics`). The refinement itself is
:func:`activesplat.refine.trainer.refine`."""

from __future__ import annotations

import json
from pathlib import Path

from activesplat.refine.episode_map import check_arguments
from activesplat.refine.trainer import refine


def refine_from_command(cmd) -> int:
    """``activesplat refine DIR [--method 3dgs|2dgs] [--iters N] [--seed S] [--restart] [--backend B]
    [--image-size PX] [--no-lpips] [--refine.FIELD VALUE ...]`` (an `activesplat.config.RefineCommand`)."""
    check_arguments(cmd.dir, cmd.method, cmd.iters)
    if cmd.lpips:  # the evaluation after training needs the weights: say so before training, not after
        from activesplat.eval.lpips import find_weights

        find_weights()
    res = refine(cmd.dir, cmd.method, cmd.iters, config=cmd.refine, seed=cmd.seed, backend=cmd.backend,
                 restart=cmd.restart, progress=cmd.progress, image_size=cmd.image_size,
                 eval_kwargs={"lpips": cmd.lpips})
    rate = res.iterations / res.train_seconds if res.train_seconds else float("nan")
    print(f"refined {res.method}: {res.iterations} iterations ({rate:.2f} it/s), "
          f"{res.n_gaussians_initial} -> {res.n_gaussians} Gaussians "
          f"(cloned {res.densify.get('cloned', 0)}, split {res.densify.get('split', 0)}, "
          f"pruned {res.densify.get('pruned', 0)}) -> {res.out_dir}")
    window = round(1.0 / (1.0 - cmd.refine.psnr_ema)) if cmd.refine.psnr_ema < 1 else res.iterations
    print(f"training PSNR {res.psnr:.2f} dB (running mean over about the last {window} iterations' "
          f"keyframes, pixels with depth, the map still changing: not the render-eval numbers below)")
    if res.metrics:
        online_path = Path(cmd.dir) / "render_metrics.json"
        online = json.loads(online_path.read_text()) if online_path.is_file() else None
        print(format_metrics(res.metrics, online, online_path, same_size=cmd.image_size is None))
    elif res.not_evaluated:
        print(f"not evaluated: {res.not_evaluated}")
    return 0


VIEW_KEYS = ("step", "position", "yaw_deg")  # what names a view in render_metrics.json (train / test)


def other_views(before: dict, after: dict) -> str | None:
    """None when two render_metrics.json measured the same views the same way (image size, field of view,
    render-eval settings, metric definitions, every view's step or pose), else what differs. LPIPS
    measured in one of them only does not count (it is then left out of the comparison)."""
    def protocol(m: dict) -> dict:
        return {k: v for k, v in (m.get("protocol") or {}).items() if k != "lpips"}

    if (before.get("width"), before.get("height")) != (after.get("width"), after.get("height")):
        return (f"image size {before.get('width')}x{before.get('height')}, not "
                f"{after.get('width')}x{after.get('height')}")
    for what, a, b in (("field of view", before.get("hfov_deg"), after.get("hfov_deg")),
                       ("render-eval settings", before.get("config"), after.get("config")),
                       ("metric definitions", protocol(before), protocol(after))):
        if a != b:
            return f"other {what}"
    for split in ("train", "test"):
        views = [[{k: v.get(k) for k in VIEW_KEYS} for v in (m.get(split) or {}).get("views", [])]
                 for m in (before, after)]
        if views[0] != views[1]:
            return f"other {split} views"
    return None


def format_metrics(metrics: dict, online: dict | None = None, online_path: Path | None = None,
                   same_size: bool = True) -> str:
    """The refined map's render-eval: a heading naming the views, then one line per split (PSNR / SSIM /
    LPIPS / depth L1). With the online map's render_metrics.json of the same views (:func:`other_views`),
    every number as online -> refined; otherwise a last line says why the online map is not shown
    (``same_size``: the map was refined at the keyframes' own size, so that render-eval of the episode
    measures the same views)."""
    differs = other_views(online, metrics) if online is not None else None
    before = online if online is not None and differs is None else None
    n = {split: (metrics.get(split) or {}).get("n_views") or 0 for split in ("train", "test")}
    lines = [f"render-eval, online map -> refined on the same {n['train']} train / {n['test']} test views "
             f"(whole image):" if before else
             f"render-eval of the refined map ({n['train']} train / {n['test']} test views, whole image):"]

    def value(split: str, key: str, spec: str) -> str:
        after = format(metrics[split][key], spec)
        old = (before or {}).get(split, {}).get(key)
        return after if old is None else f"{format(old, spec)} -> {after}"

    for split in ("train", "test"):
        m = metrics.get(split)
        if not m or m.get("psnr") is None:  # no views (a recorded map has no test split)
            continue
        parts = [f"PSNR {value(split, 'psnr', '.2f')} dB", f"SSIM {value(split, 'ssim', '.3f')}"]
        if m.get("lpips") is not None:
            parts.append(f"LPIPS {value(split, 'lpips', '.3f')}")
        parts.append(f"depth L1 {value(split, 'depth_l1_cm', '.2f')} cm")
        lines.append(f"{split:5s} " + "  ".join(parts))
    if online is None and online_path is not None and same_size:
        lines.append(f"(the online map on the same views: `activesplat render-eval {online_path.parent}`, "
                     f"then this command again)")
    elif online is None and online_path is not None:
        lines.append("(the online map is not compared: render-eval measures it at the episode's own image "
                     "size, not the one refined at)")
    elif differs is not None:
        lines.append(f"(the online map is not compared: {online_path} has {differs})")
    return "\n".join(lines)



__all__ = ["format_metrics", "other_views", "refine_from_command"]
