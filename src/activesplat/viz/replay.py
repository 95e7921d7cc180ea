"""The replay viewer of `activesplat view DIR` (`EpisodeViewer`): a finished exploration episode, a map of
a recording (`activesplat map`) or a refined map (``DIR/refined_<method>/``) with its episode.

It loads gaussians.ply and poses.txt, rebuilds the workspace and Voronoi graph from the final map
(`workspace.plan.build_plan`), and adds a timeline slider: the frustum moves along the trajectory and a
background worker re-renders the ground truth RGB-D (simulator) and the map at that pose, always the latest
slider position (intermediate ones are dropped, so dragging never queues up renders). The maps of
`activesplat refine` are offered beside the online one in a `map` dropdown (`map_files`), each rendered with
its method's rasterizer. A map of a recording (``"source": "recording"``) has no simulator: the slider runs
over the frames of poses.txt and the ground truth is the recorded RGB-D of its held-out frames
(heldout.npz).
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

from activesplat.episode import (
    DERIVED_DIRS,
    episode_and_map,
    is_complete,
    is_recorded_map,
    read_episode,
    read_meta,
    read_poses,
)
from activesplat.errors import EpisodeError, InvalidInputError
from activesplat.viz.drawing import SceneDrawer, depth_image, splat_count_text
from activesplat.viz.server import ViewerConfig, camera_fov, check_port, start_server


def _dataclass_from(cls, saved: dict | None):
    """A config dataclass from its saved dict (unknown keys ignored, lists back to tuples)."""
    names = {f.name for f in fields(cls)}
    return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in (saved or {}).items() if k in names})


ONLINE = "online"
"""The name of an episode's own map (DIR/gaussians.ply) in the replay's map choice."""


def view_folder(path: str | Path) -> tuple[Path, str]:
    """(episode folder, name of the map to show first) of `activesplat view DIR`: DIR an episode or a
    recorded map's folder (its online map), or a map folder inside one (``DIR/refined_<method>/``: that
    map). EpisodeError otherwise."""
    episode_dir, map_dir = episode_and_map(path)
    return episode_dir, ONLINE if map_dir is None else map_dir.name


def map_files(episode_dir: Path) -> dict[str, Path]:
    """The maps of an episode folder by name: ``online`` (its gaussians.ply) and every ``refined_<method>``
    folder holding a gaussians.ply (`activesplat refine`)."""
    maps = {ONLINE: episode_dir / "gaussians.ply"} if (episode_dir / "gaussians.ply").is_file() else {}
    for folder in sorted(episode_dir.glob(DERIVED_DIRS)):
        if (folder / "gaussians.ply").is_file():
            maps[folder.name] = folder / "gaussians.ply"
    return maps


def _map_renderer(ply: Path):
    """How a map renders: its refinement method's rasterizer (2dgs: surfels), else the 3DGS one."""
    from activesplat.eval.render_eval import default_renderer
    from activesplat.refine.maps import render_options

    return render_options(ply.parent).get("renderer") or default_renderer(ply)


class EpisodeViewer:
    """The `activesplat view DIR` page: the map (the online one or a refined one, switchable) and the graph,
    and a timeline over the trajectory. DIR is an exploration episode (ground truth from its simulator), a
    map of a recording (`activesplat map`: the recorded RGB-D at its held-out frames), or a
    ``refined_<method>/`` folder inside either (that map first)."""

    def __init__(self, episode_dir: str | Path, port: int = 8080, config: ViewerConfig | None = None,
                 ground_truth: bool = True):
        self.cfg = config or ViewerConfig()
        self.dir, first_map = view_folder(episode_dir)
        self.recorded = is_recorded_map(read_meta(self.dir))
        if self.recorded:
            self.meta, self.complete = read_meta(self.dir), is_complete(self.dir)
            self.poses, self.actions = np.stack(read_poses(self.dir / "poses.txt")), None
        else:  # EpisodeError when it is not an episode folder
            ep = read_episode(self.dir)
            self.meta, self.complete, self.poses, self.actions = ep.meta, ep.complete, ep.poses, ep.actions
        self.positions = self.poses[:, :3, 3]
        self.maps = map_files(self.dir)
        check_port(self.cfg.host, port)  # before the (slow) loading
        self._loaded: dict[str, tuple] = {}
        self.map_name = first_map if first_map in self.maps else next(iter(self.maps), None)
        self._load(ground_truth)
        self.server = start_server(port, self.cfg)  # the page appears once everything is loaded
        self.port = self.server.get_port()
        self.url = f"http://{self.cfg.host}:{self.port}"
        self._pending: int | None = None
        self.rendered_step: int | None = None
        """The step whose images the page shows (the render worker's last finished render)."""
        self._wake = threading.Condition()
        self._stop = False
        self._worker = threading.Thread(target=self._render_loop, name="activesplat-view-render", daemon=True)
        try:
            self.draw = SceneDrawer(self.server, self.cfg, f"activesplat view {self.dir.name}")
            self._draw_scene()
        except BaseException:
            self.server.stop()
            raise
        self._worker.start()
        self.show_step(int(self.slider.value))

    # ------------------------------------------------------------------ loading
    def _load(self, ground_truth: bool) -> None:
        """Camera model, ground truth (simulator or held-out frames), the first map and the workspace / graph
        of the online map."""
        from activesplat.geometry import intrinsics
        from activesplat.planning.controller import floor_xz
        from activesplat.workspace.config import WorkspaceConfig
        from activesplat.workspace.plan import build_plan

        meta = self.meta
        if self.recorded:
            try:
                self.K = np.asarray(meta["K"], dtype=np.float64).reshape(3, 3)
                self.width, self.height = int(meta["width"]), int(meta["height"])
            except (KeyError, TypeError, ValueError) as exc:
                raise EpisodeError(f"{self.dir / 'episode.json'}: no camera of the recording (K, width, "
                                   f"height): {type(exc).__name__}: {exc}") from None
            self.floor_height = float(meta.get("floor_height", self.positions[:, 1].min() - 1.25))
        else:
            sim_cfg = meta.get("config", {}).get("sim", {})
            camera = meta.get("camera")  # the camera the run saw (a robot's is not the simulator's)
            if isinstance(camera, dict) and {"width", "height", "K"} <= set(camera):
                self.width, self.height = int(camera["width"]), int(camera["height"])
                self.K = np.asarray(camera["K"], dtype=np.float64).reshape(3, 3)
            else:  # an episode from before episode.json recorded the camera
                self.width, self.height = int(sim_cfg.get("width", 256)), int(sim_cfg.get("height", 256))
                self.K = intrinsics(self.width, self.height, float(sim_cfg.get("hfov_deg", 90.0)))
            self.floor_height = float(meta.get("floor_height",
                                               self.poses[0][1, 3] - sim_cfg.get("sensor_height", 1.25)))
        self.fov_y, _ = camera_fov(self.K, self.width, self.height)
        self.sim = self.heldout = None
        if ground_truth:
            if self.recorded:
                self.heldout = self._load_heldout()
            else:
                self.sim = self._load_simulator(meta)
        if self.map_name is None:
            print(f"viewer: {self.dir} has no map (no gaussians.ply): showing the trajectory only",
                  file=sys.stderr)
        else:
            self._say_subsampled()
        self.plan = None
        graph_map = ONLINE if ONLINE in self.maps else self.map_name
        if graph_map is not None and len(self._map(graph_map)[0]) > 0:
            saved = meta.get("config", {}).get("explorer", {}).get("workspace")
            try:
                self.plan = build_plan(self._map(graph_map)[0], self.floor_height, floor_xz(self.poses[-1]),
                                       _dataclass_from(WorkspaceConfig, saved))
            except Exception as exc:  # a map the workspace cannot be built from (tiny, flat): show the rest
                print(f"viewer: no graph ({type(exc).__name__}: {exc})", file=sys.stderr)

    def _map(self, name: str) -> tuple:
        """(GaussianMap, renderer) of map `name`, read once."""
        from activesplat.splat.ply import load_ply

        if name not in self._loaded:
            self._loaded[name] = (load_ply(self.maps[name]), _map_renderer(self.maps[name]))
        return self._loaded[name]

    def _say_subsampled(self) -> None:
        n = len(self._map(self.map_name)[0])
        if n > self.cfg.max_splats:
            print(f"viewer: {self.map_name} map: {n} Gaussians; the browser is sent the "
                  f"{self.cfg.max_splats} most opaque (--max-splats to change)", file=sys.stderr)

    def _load_simulator(self, meta: dict):
        """The episode's simulator for ground-truth images, None when its scene cannot be loaded."""
        from activesplat.errors import ActiveSplatError
        from activesplat.eval.evaluate import simulated_scene
        from activesplat.sim import SimConfig, Simulator

        try:
            scene = simulated_scene(meta, self.dir)
            cfg = _dataclass_from(SimConfig, meta.get("config", {}).get("sim"))
            return Simulator(scene, start=np.asarray(meta["start_pose"], dtype=np.float64), config=cfg)
        except (ActiveSplatError, KeyError) as exc:
            print(f"viewer: no ground-truth images ({exc})", file=sys.stderr)
            return None

    def _load_heldout(self) -> dict[int, tuple[np.ndarray, np.ndarray]] | None:
        """A recorded map's held-out frames (frame index -> recorded rgb, depth), None without any."""
        from activesplat.eval.render_eval import HELDOUT_FILE

        path = self.dir / HELDOUT_FILE
        try:
            with np.load(path) as data:
                frames = zip(data["index"], data["rgb"], data["depth"], strict=True)
                held = {int(k): (rgb, depth) for k, rgb, depth in frames}
        except (OSError, KeyError, ValueError) as exc:
            print(f"viewer: no recorded images beside the map ({path.name}: {exc})", file=sys.stderr)
            return None
        if not held:
            print("viewer: no recorded images beside the map (mapped with --holdout-every 0: every frame is "
                  "in the map, none kept out)", file=sys.stderr)
            return None
        return held

    def _summary(self) -> str:
        meta, n = self.meta, len(self.poses) - 1
        partial = "" if self.complete else " (partial)"
        if self.recorded:
            held = 0 if self.heldout is None else len(self.heldout)
            head = (f"**{Path(str(meta.get('recording', self.dir))).name}** (recording){partial}  \n"
                    f"**frames** {len(self.poses)}, {meta.get('mapped_frames', '?')} mapped, {held} held "
                    f"out  ")
        else:
            head = (f"**{meta.get('scene', '?')}** / {meta.get('policy', '?')} / seed "
                    f"{meta.get('seed', '?')}{partial}  \n**steps** {n}  ")
        nodes = 0 if self.plan is None else self.plan.graph.number_of_nodes()
        return f"{head}\n{self._map_text()}  \n**graph** {nodes} nodes  "

    def _map_text(self) -> str:
        if self.map_name is None:
            return "**map** none (no gaussians.ply)"
        count = splat_count_text(len(self._map(self.map_name)[0]), self.cfg.max_splats)
        return f"**map** {self.map_name}: {count}"

    def _draw_scene(self) -> None:
        n = len(self.poses) - 1
        if self.map_name is not None:
            self.draw.draw_map(self._map(self.map_name)[0])
        if self.plan is not None:
            self.draw.draw_plan(self.plan, self.floor_height)
        self.draw.draw_trajectory(self.positions, name="/agent/trajectory_all", color=(170, 190, 225))
        self.draw.look_at(self.positions[0])
        gui = self.server.gui
        if len(self.maps) > 1:
            self.map_choice = gui.add_dropdown("map", list(self.maps), initial_value=self.map_name)
            self.map_choice.on_update(lambda _e: self.show_map(str(self.map_choice.value)))
        with gui.add_folder("Timeline"):
            self.slider = gui.add_slider("frame" if self.recorded else "step", min=0, max=max(n, 1), step=1,
                                         initial_value=n)
            self.play = gui.add_checkbox("play", False)
        self.slider.on_update(lambda _e: self.show_step(int(self.slider.value)))
        self.summary = self._summary()

    # ------------------------------------------------------------------ timeline
    def show_map(self, name: str) -> None:
        """Show map `name` (of `self.maps`) in the scene and in the map images; one that cannot be read
        leaves the current one and says why (page and terminal)."""
        from activesplat.errors import ActiveSplatError

        if name == self.map_name:  # also the menu set back below
            return
        try:
            self._map(name)
        except ActiveSplatError as exc:
            print(f"viewer: map {name} not shown: {exc}", file=sys.stderr)
            self.draw.status.content = f"{self.summary}\n**map {name} not shown**: {exc}"
            self.map_choice.value = self.map_name
            return
        self.map_name = name
        self._say_subsampled()
        self.draw.draw_map(self._map(name)[0])
        self.summary = self._summary()
        self.show_step(int(self.slider.value))

    def _step_text(self, step: int) -> str:
        if not self.recorded:
            return f"**step** {step}: {self.actions[step - 1] if step > 0 else 'reset'}"
        if self.heldout is not None and step in self.heldout:
            return f"**frame** {step}: held out of the map; the recorded RGB-D beside the map's rendering"
        why = "no recorded images kept" if self.heldout is None else "only held-out frames keep theirs"
        return f"**frame** {step}: map rendering ({why})"

    def show_step(self, step: int) -> None:
        """Move the frustum to the pose after `step` actions (a recording: of frame `step`); the images
        follow from the render worker."""
        step = int(np.clip(step, 0, len(self.poses) - 1))
        pose = self.poses[step]
        self.draw.draw_camera(pose, self.fov_y, self.width / self.height)
        self.draw.draw_trajectory(self.positions[: step + 1])
        self.draw.status.content = f"{self.summary}\n{self._step_text(step)}"
        with self._wake:
            self._pending = step
            self._wake.notify()

    def _render_loop(self) -> None:
        while True:
            with self._wake:
                while self._pending is None and not self._stop:
                    self._wake.wait()
                if self._stop:
                    return
                step, self._pending = self._pending, None
            try:
                self.render_images(step)
                self.rendered_step = step
            except Exception as exc:  # the worker lives on: the next slider position renders again
                print(f"viewer: no images at step {step} ({type(exc).__name__}: {exc})", file=sys.stderr)

    def render_images(self, step: int) -> None:
        """Ground-truth RGB-D (simulator, or a recording's held-out frame) and the map's rendering at the
        pose after `step` actions (a recording: of frame `step`)."""
        pose = self.poses[step]
        if self.sim is not None:
            rgb, depth = self.sim.render(pose, self.width, self.height)
            self._show("ground truth RGB", rgb)
            self._show("ground truth depth", depth_image(depth, self.cfg.depth_max_m))
        if self.heldout is not None:
            rgb, depth = self.heldout.get(step, (None, None))
            self._show("recorded RGB (held out)", rgb)
            self._show("recorded depth (held out)",
                       None if depth is None else depth_image(depth, self.cfg.depth_max_m))
        if self.map_name is not None:
            gmap, renderer = self._map(self.map_name)
            rgb = renderer(gmap, pose, self.K, self.width, self.height, "auto")[0]
            self._show("map RGB", (255 * np.clip(rgb, 0, 1) + 0.5).astype(np.uint8))

    def _show(self, label: str, image: np.ndarray | None) -> None:
        """An image of the render worker, unless the viewer is closing (a render that ends after Ctrl-C
        would be queued on a stopped server, which warns that it will never be delivered)."""
        if not self._stop:
            self.draw.set_image(label, image)

    def serve_forever(self) -> None:
        """Serve until Ctrl-C; the play checkbox advances the slider at `play_fps`."""
        print(f"viewer: {self.url} (Ctrl-C to quit)", file=sys.stderr)
        try:
            while True:
                time.sleep(1.0 / self.cfg.play_fps)
                if self.play.value:
                    self.slider.value = (int(self.slider.value) + 1) % (len(self.poses))
        except KeyboardInterrupt:
            pass

    def close(self) -> None:
        with self._wake:
            self._stop = True
            self._wake.notify()
        if self._worker.is_alive():  # its last render ends before the server does
            self._worker.join(timeout=5.0)
        self.server.stop()


def view_from_args(args) -> int:
    max_splats = getattr(args, "max_splats", ViewerConfig.max_splats)
    if max_splats < 1:
        raise InvalidInputError(f"--max-splats must be a positive number of Gaussians, got {max_splats}")
    viewer = EpisodeViewer(args.dir, port=args.port, config=ViewerConfig(max_splats=max_splats))
    try:
        viewer.serve_forever()
    finally:
        viewer.close()
    return 0


__all__ = ["ONLINE", "EpisodeViewer", "map_files", "view_folder", "view_from_args"]
