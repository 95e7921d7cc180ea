"""The ``activesplat`` command: one entry point, one subcommand per job.

Every subcommand turns bad input (an :class:`~activesplat.errors.ActiveSplatError`) into a one-line
``activesplat: error: ...`` message on stderr and exit code 2, never a traceback. Heavy modules are
imported inside the command functions so that ``activesplat --help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from activesplat.errors import ActiveSplatError

Handler = Callable[[argparse.Namespace], int | None]


# --------------------------------------------------------------------------- scenes
FLOOR_HELP = ("storey of a multi-storey mesh: an index from the bottom (0, 1, ...) or a floor height in "
              "metres (3.0); needed when the mesh has several storeys under a ceiling")


def floor_arg(text: str) -> int | float:
    """--floor: an integer is a storey index, anything with a '.' (or a trailing 'm') a height."""
    value = text.strip().removesuffix("m")
    try:
        return float(value) if "." in value or "e" in value.lower() else int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a storey index (1) or a height in metres (3.0), "
                                         f"got {text!r}") from None


def _cmd_scenes_list(args: argparse.Namespace) -> int:
    from activesplat.sim import describe_builtin_scenes

    print(describe_builtin_scenes())
    return 0


def _cmd_scenes_export(args: argparse.Namespace) -> int:
    from pathlib import Path

    from activesplat.errors import InvalidInputError
    from activesplat.sim import load_scene

    if Path(args.file).suffix.lower() != ".glb":  # checked before the (slow) scene build
        raise InvalidInputError(f"export file must end in .glb: {args.file}")
    scene = load_scene(args.name, z_up=args.z_up, floor=args.floor)
    path = scene.export(args.file)
    print(f"wrote {path}")
    return 0


# --------------------------------------------------------------------------- explore
def _cmd_explore(args: argparse.Namespace) -> int:
    from activesplat.explore import explore_from_args

    return explore_from_args(args)


# --------------------------------------------------------------------------- evaluate
def _cmd_evaluate(args: argparse.Namespace) -> int:
    from activesplat.eval.evaluate import evaluate_episode

    m = evaluate_episode(args.dir)
    uncapped = m["completion_cm_uncapped"]
    print(f"completion ratio {m['completion_ratio_pct']:.2f} %  completion {m['completion_cm']:.2f} cm  "
          f"(uncapped {'n/a' if uncapped is None else f'{uncapped:.2f}'} cm)  "
          f"path length {m['path_length_m']:.2f} m  steps {m['steps']}  -> {args.dir}/metrics.json")
    return 0


# --------------------------------------------------------------------------- render-eval / refine
def _cmd_render_eval(args: argparse.Namespace) -> int:
    from activesplat.eval.render_eval import render_eval_from_args

    return render_eval_from_args(args)


def _cmd_refine(args: argparse.Namespace) -> int:
    from activesplat.refine import refine_from_args

    return refine_from_args(args)


# --------------------------------------------------------------------------- view / benchmark
def _cmd_view(args: argparse.Namespace) -> int:
    from activesplat.viz.viewer import view_from_args

    return view_from_args(args)


def _cmd_benchmark(args: argparse.Namespace) -> int:
    from activesplat.bench import benchmark_from_args

    return benchmark_from_args(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="activesplat",
        description="Autonomous exploration that builds a 3D Gaussian-splatting map "
        "(ActiveSplat, RA-L 2025).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    # scenes
    p_scenes = sub.add_parser("scenes", help="list built-in scenes or export one as a mesh")
    scenes_sub = p_scenes.add_subparsers(dest="scenes_command", metavar="ACTION")
    scenes_sub.required = True
    p_list = scenes_sub.add_parser("list", help="list the built-in procedural houses")
    p_list.set_defaults(func=_cmd_scenes_list)
    p_export = scenes_sub.add_parser(
        "export", help="write the exact mesh the simulator uses (world frame, y up) as .glb"
    )
    p_export.add_argument("name", help="built-in name (small-0, medium-3, ...) or a mesh file")
    p_export.add_argument("file", help="output file (.glb)")
    p_export.add_argument("--z-up", action="store_true", help="the input mesh file is z-up")
    p_export.add_argument("--floor", type=floor_arg, default=None, help=FLOOR_HELP)
    p_export.set_defaults(func=_cmd_scenes_export)

    # explore
    p_explore = sub.add_parser("explore", help="explore a scene and write an episode folder")
    p_explore.add_argument("--scene", default="small-0", help="built-in name or mesh file")
    p_explore.add_argument("--steps", type=int, default=None,
                           help="step budget (default: 1000 for small scenes, 2000 for medium)")
    p_explore.add_argument("--policy", default="activesplat",
                           help="exploration policy: activesplat (default), fbe, random, position, "
                                "viewpoint, no-hp, visibility-only, hull-only")
    p_explore.add_argument("--seed", type=int, default=0, help="seed of the random start")
    p_explore.add_argument("--out", default=None, help="episode folder (default: runs/SCENE-sSEED)")
    p_explore.add_argument("--overwrite", action="store_true",
                           help="replace an existing complete episode in --out")
    p_explore.add_argument("--z-up", action="store_true", help="the scene mesh file is z-up")
    p_explore.add_argument("--floor", type=floor_arg, default=None, help=FLOOR_HELP)
    p_explore.add_argument("--backend", default="auto", choices=("auto", "numba", "torch", "gsplat"),
                           help="rasterizer backend (auto: gsplat with CUDA, else numba)")
    p_explore.add_argument("--no-progress", action="store_true", help="no progress bar")
    p_explore.add_argument("--viewer", action="store_true",
                           help="serve a live viser web viewer of the run on localhost")
    p_explore.add_argument("--viewer-port", type=int, default=8080, help="port of --viewer (default 8080)")
    p_explore.set_defaults(func=_cmd_explore)

    # evaluate
    p_eval = sub.add_parser("evaluate", help="recompute completion metrics of an episode from its actions")
    p_eval.add_argument("dir", help="episode folder")
    p_eval.set_defaults(func=_cmd_evaluate)

    # render-eval
    p_reval = sub.add_parser("render-eval",
                             help="PSNR / SSIM / LPIPS / depth L1 of a map on train and test views")
    p_reval.add_argument("dir", help="episode folder (or a refined_<method> folder inside one)")
    p_reval.add_argument("--n-train", type=int, default=50, help="train views, spread over the trajectory")
    p_reval.add_argument("--n-test", type=int, default=50, help="test views, random poses in the free space")
    p_reval.add_argument("--seed", type=int, default=0, help="seed of the test poses")
    p_reval.add_argument("--backend", default="auto", choices=("auto", "numba", "torch", "gsplat"),
                         help="rasterizer backend")
    p_reval.add_argument("--no-progress", action="store_true", help="no progress bar")
    p_reval.set_defaults(func=_cmd_render_eval)

    # refine
    p_refine = sub.add_parser("refine", help="offline refinement of an episode's map from its keyframes")
    p_refine.add_argument("dir", help="episode folder")
    p_refine.add_argument("--method", default="3dgs", help="3dgs (default) or 2dgs")
    p_refine.add_argument("--iters", type=int, default=2000, help="optimisation iterations (default 2000)")
    p_refine.add_argument("--seed", type=int, default=0, help="seed of the view sampling")
    p_refine.add_argument("--restart", action="store_true",
                          help="ignore a checkpoint in DIR/refined_METHOD and start again")
    p_refine.add_argument("--backend", default="auto", choices=("auto", "numba", "torch", "gsplat"),
                          help="rasterizer backend")
    p_refine.add_argument("--no-progress", action="store_true", help="no progress bar")
    p_refine.set_defaults(func=_cmd_refine)

    # view
    p_view = sub.add_parser("view", help="serve a viser web viewer of a finished episode")
    p_view.add_argument("dir", help="episode folder")
    p_view.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    p_view.set_defaults(func=_cmd_view)

    # benchmark
    p_bench = sub.add_parser("benchmark", help="scenes x policies x trials -> CSV and paper-style tables")
    p_bench.add_argument("--scenes", nargs="+", default=["small-0", "small-1", "small-2", "small-3"],
                         help="scene names or mesh files")
    p_bench.add_argument("--policies", nargs="+", default=["activesplat", "fbe", "random"], help="policies")
    p_bench.add_argument("--trials", type=int, default=1, help="trials (seeds 0..trials-1) per scene")
    p_bench.add_argument("--steps", type=int, default=None, help="step budget (default: per scene size)")
    p_bench.add_argument("--root", default="runs/benchmark", help="folder of the episodes and tables")
    p_bench.add_argument("--workers", type=int, default=1, help="parallel processes (local executor)")
    p_bench.add_argument("--executor", default="local", choices=("local", "ray"),
                         help="local process pool (default) or a Ray cluster (pip install activesplat[ray])")
    p_bench.add_argument("--ray-address", default=None, help="Ray cluster address (default: auto / local)")
    p_bench.set_defaults(func=_cmd_benchmark)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = args.func(args)
    except ActiveSplatError as exc:
        print(f"activesplat: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("activesplat: interrupted", file=sys.stderr)
        return 130
    return int(code or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
