"""Web viewers built on viser: `activesplat explore --viewer` (live) and `activesplat view DIR` (replay).

Both serve a page on localhost showing the Gaussian map as splats, the agent's camera frustum and
trajectory, the Voronoi graph with its nodes coloured by subregion (and the eq. 12 scores of the last
replan as bars), the current goal and path, the top-down workspace grid, and the latest RGB-D images and
panorama. The world frame is used as is: y up (`set_up_direction("+y")`), cameras in OpenCV axes, which is
also viser's frustum convention, so no conversion is needed anywhere.

Live (`LiveViewer.update` after every step) is rate-limited: the splats (the expensive part) are sent at
most every `ViewerConfig.map_interval_s`, only when the mapper took a frame since the last send, and never
for more than `max_map_share` of the wall time; the frustum, trajectory, plan and images follow at their
own bounded rates. Without `--viewer` nothing here
is imported (the exploration loop checks `viewer is not None` and nothing else).

Replay (`EpisodeViewer`) loads gaussians.ply and poses.txt, rebuilds the workspace and Voronoi graph from
the final map (`workspace.plan.build_plan`), and adds a timeline slider: the frustum moves along the
trajectory and a background worker re-renders the ground truth RGB-D (simulator) and the map at that pose,
always the latest slider position (intermediate ones are dropped, so dragging never queues up renders).
The maps of `activesplat refine` (``DIR/refined_<method>/gaussians.ply``) are offered beside the online
one in a `map` dropdown, each rendered with its method's rasterizer. A map of a recording
(`activesplat map`, ``"source": "recording"``) has no simulator: the slider runs over the frames of
poses.txt and the ground truth is the recorded RGB-D of its held-out frames (heldout.npz).
"""

from __future__ import annotations

import math
import socket
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
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
from activesplat.viz.drawing import SceneDrawer, depth_image, panorama_image, splat_arrays, splat_count_text


@dataclass
class ViewerConfig:
    """How the viewers draw and how often the live one sends."""

    host: str = "127.0.0.1"
    """Interface the page is served on (localhost only by default)."""
    map_interval_s: float = 0.5
    """Live: the splats are sent at most this often (2 Hz), and only when the map took a new frame."""
    max_map_share: float = 0.05
    """Live: after a map send that took t seconds the next waits at least t / this, so sending the splats
    never takes more than this share of the run's wall time, however large the map or slow the machine
    (a 250k-Gaussian map takes ~110 ms of CPU to send: then about one send every 2 s)."""
    state_interval_s: float = 0.2
    """Live: frustum, trajectory, status and plan (graph, scores, goal, path) at most this often (5 Hz)."""
    image_interval_s: float = 0.5
    """Live: RGB-D and panorama images at most this often (2 Hz)."""
    max_splats: int = 400_000
    """More Gaussians than this: only the most opaque are sent (a browser's budget; `--max-splats` of
    `explore --viewer` and `view`)."""
    depth_max_m: float = 8.0
    """Depth images are coloured over 0 .. this many metres."""
    graph_lift_m: float = 0.05
    """The graph, path and goal are drawn this far above the floor (over the floor splats)."""
    score_bar_m: float = 1.0
    """Height of the best node's score bar; the others scale with their score."""
    frustum_scale: float = 0.3
    """Size of the agent's camera frustum in the scene (m)."""
    play_fps: float = 10.0
    """Replay: steps per second of the play checkbox."""


def free_port(host: str = "127.0.0.1") -> int:
    """A port that is free right now (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _check_port(host: str, port: int, option: str = "--port") -> None:
    """InvalidInputError naming `option` (the command's port option) when `host:port` cannot be served."""
    if not 0 < port < 65536:
        raise InvalidInputError(f"{option} must be in 1..65535, got {port}")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server itself binds
        try:
            s.bind((host, port))
        except OSError as exc:
            raise InvalidInputError(f"viewer port {port} on {host} is not available ({exc.strerror}); "
                                    f"pick another with {option}") from None


def start_server(port: int, cfg: ViewerConfig, option: str = "--port"):
    """A viser server on exactly `cfg.host:port` (viser itself would silently take the next free port);
    `option` is the command's port option, named when the port is taken."""
    _check_port(cfg.host, port, option)
    import viser

    server = viser.ViserServer(host=cfg.host, port=port, verbose=False)
    if server.get_port() != port:  # lost a race for the port
        server.stop()
        raise InvalidInputError(f"viewer port {port} on {cfg.host} is not available; pick another with "
                                f"{option}")
    server.scene.set_up_direction("+y")
    return server


def _camera_fov(K: np.ndarray, width: int, height: int) -> tuple[float, float]:
    """(vertical fov in radians, aspect) of a pinhole K."""
    return 2.0 * math.atan(height / (2.0 * float(K[1][1]))), width / height


# --------------------------------------------------------------------------- live
class LiveViewer:
    """The `explore --viewer` page. `update(step, obs, mapper, explorer)` after every step; cheap when the
    rate limits say nothing is due (a list append and three clock comparisons)."""

    def __init__(self, port: int = 8080, config: ViewerConfig | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.cfg = config or ViewerConfig()
        self.server = start_server(port, self.cfg, "--viewer-port")
        self.port = self.server.get_port()
        self.url = f"http://{self.cfg.host}:{self.port}"
        self.draw = SceneDrawer(self.server, self.cfg, "activesplat explore (live)")
        self._clock = clock
        self._last = {"state": -math.inf, "images": -math.inf}
        self._next_map = -math.inf
        self._map_frames = -1
        self._plan = None
        self._panorama = None
        self._positions: list[np.ndarray] = []
        self.time_ms = 0.0
        """Wall time spent in update() so far (what the viewer costs the run)."""
        self.updates = 0
        self.failed: str | None = None
        """Why the page stopped updating (the first error of `update`), None while it updates."""
        self._said_cut = False
        print(f"viewer: {self.url}", file=sys.stderr)

    @property
    def sent(self) -> dict[str, int]:
        return self.draw.sent

    def update(self, step: int, obs, mapper, explorer, final: bool = False) -> None:
        """Send what is due. An error here stops the page's updates, not the exploration: one line says so
        and the run goes on (it may have minutes of work behind it)."""
        if self.failed is not None:
            return
        try:
            self._update(step, obs, mapper, explorer, final)
        except Exception as exc:
            self.failed = f"step {step}: {type(exc).__name__}: {exc}"
            print(f"viewer: the page stopped updating at {self.failed}; the exploration goes on",
                  file=sys.stderr)

    def _update(self, step: int, obs, mapper, explorer, final: bool) -> None:
        t0 = time.perf_counter()
        self._positions.append(np.asarray(obs.pose, dtype=np.float64)[:3, 3].copy())
        now = self._clock()
        if final or now - self._last["state"] >= self.cfg.state_interval_s:
            self._last["state"] = now
            self._send_state(step, obs, mapper, explorer)
        if final or now - self._last["images"] >= self.cfg.image_interval_s:
            self._last["images"] = now
            self._send_images(obs, explorer)
        frames = getattr(mapper, "frames", step)
        if frames != self._map_frames and (final or now >= self._next_map):
            t_map = time.perf_counter()
            self._map_frames = frames
            self.draw.draw_map(mapper.gaussians)
            # over the budget: the terminal says so once (the page's status at every send)
            if len(mapper.gaussians) > self.cfg.max_splats and not self._said_cut:
                self._said_cut = True
                budget = self.cfg.max_splats
                print(f"viewer: the map has grown past {budget} Gaussians; the browser is sent the {budget} "
                      f"most opaque (--max-splats to change)", file=sys.stderr)
            spent = time.perf_counter() - t_map
            self._next_map = now + max(self.cfg.map_interval_s, spent / self.cfg.max_map_share)
        self.time_ms += 1000.0 * (time.perf_counter() - t0)
        self.updates += 1

    def _send_state(self, step: int, obs, mapper, explorer) -> None:
        pose = np.asarray(obs.pose, dtype=np.float64)
        if len(self._positions) == 1:
            self.draw.look_at(pose[:3, 3])
        self.draw.draw_camera(pose, *_camera_fov(mapper.K, mapper.width, mapper.height))
        self.draw.draw_trajectory(np.stack(self._positions))
        view = explorer.view_state() if hasattr(explorer, "view_state") else None
        count = splat_count_text(len(mapper.gaussians), self.cfg.max_splats)
        lines = [f"**step** {step}  ", f"**map** {count}  "]
        if view is not None:
            if view.plan is not self._plan:
                self._plan = view.plan
                self.draw.draw_plan(view.plan, view.floor_height)
            self.draw.draw_targets(pose, view.rotation_targets)
            plan = view.plan
            lines.insert(0, f"**policy** {view.name}  ")
            lines.append(f"**graph** {plan.graph.number_of_nodes()} nodes, "
                         f"{len(set(plan.subregions.values()))} subregions  ")
            if plan.scores:
                lines.append(f"**best score** {max(plan.scores.values()):.1f}  ")
            if plan.goal is not None:
                lines.append(f"**goal** ({plan.goal[0]:.2f}, {plan.goal[1]:.2f})  ")
        self.draw.status.content = "\n".join(lines)

    def _send_images(self, obs, explorer) -> None:
        self.draw.set_image("RGB", np.asarray(obs.rgb))
        self.draw.set_image("depth", depth_image(obs.depth, self.cfg.depth_max_m))
        view = explorer.view_state() if hasattr(explorer, "view_state") else None
        if view is not None and view.panorama is not None and view.panorama is not self._panorama:
            self._panorama = view.panorama
            self.draw.set_image("panorama (invisibility / depth)", panorama_image(view.panorama,
                                                                                  self.cfg.depth_max_m))

    def hold(self) -> None:
        """Keep serving the final state until Ctrl-C."""
        cost = self.time_ms / max(self.updates, 1)
        stopped = "" if self.failed is None else f" (its updates stopped at {self.failed})"
        print(f"viewer: {cost:.1f} ms/step spent updating it; the run is over, still serving {self.url}"
              f"{stopped} (Ctrl-C to quit)", file=sys.stderr)
        try:
            while True:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass

    def close(self) -> None:
        self.server.stop()


# --------------------------------------------------------------------------- replay
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
        _check_port(self.cfg.host, port)  # before the (slow) loading
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
        self.fov_y, _ = _camera_fov(self.K, self.width, self.height)
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


__all__ = ["ONLINE", "EpisodeViewer", "LiveViewer", "SceneDrawer", "ViewerConfig", "depth_image", "free_port",
           "map_files", "panorama_image", "splat_arrays", "start_server", "view_folder", "view_from_args"]
