"""`activesplat render-eval DIR`: which renderer evaluates a map folder. An episode's online map holds 3D
Gaussians (the default rasterizer of `eval.render_eval`); a `refined_<method>/` folder holds the map of its
refinement method (named in its refine.json), which says how it renders (2dgs: the surfel rasterizer)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from activesplat.eval.render_eval import format_table, locate, render_eval
from activesplat.refine.config import METHODS, RefineConfig
from activesplat.refine.methods import make_method


def render_options(folder: Path) -> dict:
    """`render_eval` arguments a map folder asks for: its refinement method's renderer and the image size it
    was refined at (refine.json; `refine --image-size 512` evaluates at 512, and so does render-eval of its
    folder), or none for an episode's online map."""
    meta = Path(folder) / "refine.json"
    info = json.loads(meta.read_text()) if meta.is_file() else {}
    method = info.get("method") if isinstance(info, dict) else None
    if method not in METHODS:
        return {}
    options = make_method(method, RefineConfig(), iters=1).eval_kwargs()
    size = info.get("image_size")
    if isinstance(size, list) and len(size) == 2:  # [width, height] of the keyframes it was refined on
        options["sim_overrides"] = {"width": int(size[0]), "height": int(size[1])}
    return options


def render_eval_from_args(args: argparse.Namespace) -> int:
    """The `render-eval` command: evaluate the map of `args.dir` with its renderer and print a table."""
    from activesplat.errors import check_output_file, interrupted

    _, _, out = locate(args.dir)
    if getattr(args, "budget", False):  # before the evaluation (render_eval checks its own files)
        for name in ("render_budget.json", "render_budget.png"):
            check_output_file(Path(out) / name)
    options = {"renderer": None, **render_options(Path(out))}
    metrics_file = Path(out) / "render_metrics.json"
    try:
        result = render_eval(args.dir, n_train=args.n_train, n_test=args.n_test, seed=args.seed,
                             backend=args.backend, progress=not args.no_progress,
                             lpips=not getattr(args, "no_lpips", False), **options)
    except KeyboardInterrupt:
        raise interrupted(f"render-eval interrupted: nothing measured is kept ({metrics_file} as it was); "
                          f"run the same command again") from None
    print(format_table(result, out))
    if getattr(args, "budget", False):
        from activesplat.episode import write_json_atomic
        from activesplat.eval.render_error import error_budget, format_budget

        try:
            budget = error_budget(args.dir, n_train=args.n_train, n_test=args.n_test, seed=args.seed,
                                  backend=args.backend, progress=not args.no_progress,
                                  renderer=options["renderer"], sim_overrides=options.get("sim_overrides"),
                                  figure=Path(out) / "render_budget.png")
        except KeyboardInterrupt:
            raise interrupted(f"render-eval interrupted in the error budget: {metrics_file} is written, "
                              f"render_budget.json is not; run the same command again for it") from None
        write_json_atomic(Path(out) / "render_budget.json", budget)
        print(f"\nerror budget ({Path(out) / 'render_budget.json'}, {Path(out) / 'render_budget.png'}):\n")
        print(format_budget(budget))
    return 0


__all__ = ["render_eval_from_args", "render_options"]
