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
from typing import Any

import numpy as np

from activesplat.errors import InvalidInputError


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
    """More Gaussians than this: only the most opaque are sent (a browser's budget)."""
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


def _check_port(host: str, port: int) -> None:
    if not 0 < port < 65536:
        raise InvalidInputError(f"viewer port must be in 1..65535, got {port}")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server itself binds
        try:
            s.bind((host, port))
        except OSError as exc:
            raise InvalidInputError(f"viewer port {port} on {host} is not available ({exc.strerror}); "
                                    "pick another with --port / --viewer-port") from None


def start_server(port: int, cfg: ViewerConfig):
    """A viser server on exactly `cfg.host:port` (viser itself would silently take the next free port)."""
    _check_port(cfg.host, port)
    import viser

    server = viser.ViserServer(host=cfg.host, port=port, verbose=False)
    if server.get_port() != port:  # lost a race for the port
        server.stop()
        raise InvalidInputError(f"viewer port {port} on {cfg.host} is not available")
    server.scene.set_up_direction("+y")
    return server


# --------------------------------------------------------------------------- conversions
def _rgb_u8(colormap: str, values: np.ndarray) -> np.ndarray:
    import matplotlib

    return (255 * matplotlib.colormaps[colormap](np.clip(values, 0.0, 1.0))[..., :3]).astype(np.uint8)


def depth_image(depth: np.ndarray, depth_max: float) -> np.ndarray:
    """(H, W) metres -> (H, W, 3) uint8, turbo over 0..depth_max, black where there is no depth."""
    d = np.asarray(depth, dtype=np.float32)
    img = _rgb_u8("turbo", d / depth_max)
    img[~(d > 0)] = 0
    return img


def panorama_image(pano, depth_max: float) -> np.ndarray:
    """Invisibility (white = not yet seen) above median depth: the panorama the rotations come from."""
    inv = (255 * np.clip(pano.invisibility, 0, 1)).astype(np.uint8)
    return np.vstack([np.repeat(inv[..., None], 3, axis=2), depth_image(pano.median_depth, depth_max)])


def splat_arrays(gaussians, max_splats: int) -> dict[str, np.ndarray]:
    """A GaussianMap as viser's splat arrays: centers, covariances R S S R^T, uint8 rgbs and opacities."""
    import torch

    from activesplat.splat.kernels import quat_to_rotmat

    with torch.no_grad():
        means = gaussians.means.detach().cpu().numpy()
        quats = gaussians.quats.detach().cpu().numpy()
        scales = gaussians.scales.detach().cpu().numpy()
        opac = gaussians.opacities.detach().cpu().numpy()
        rgbs = gaussians.colors.detach().clamp(0, 1).cpu().numpy()
    if len(means) > max_splats:
        keep = np.argpartition(-opac, max_splats - 1)[:max_splats]
        means, quats, scales, opac, rgbs = means[keep], quats[keep], scales[keep], opac[keep], rgbs[keep]
    rot = quat_to_rotmat(torch.from_numpy(quats.astype(np.float32))).numpy()
    m = rot * scales.astype(np.float32)[:, None, :]
    cov = np.empty_like(m)  # M M^T term by term: much faster than a batched 3x3 matmul
    for i in range(3):
        for j in range(i, 3):
            cov[:, i, j] = cov[:, j, i] = np.einsum("nk,nk->n", m[:, i], m[:, j])
    return {"centers": means.astype(np.float32), "covariances": cov,
            "rgbs": (255 * rgbs + 0.5).astype(np.uint8),
            "opacities": (255 * opac + 0.5).astype(np.uint8)[:, None]}


def _wxyz(rotation: np.ndarray) -> np.ndarray:
    from viser import transforms

    return transforms.SO3.from_matrix(np.asarray(rotation, dtype=np.float64)).wxyz


def _segments(points: np.ndarray) -> np.ndarray:
    """A polyline (N, 3) as line segments (N - 1, 2, 3)."""
    p = np.asarray(points, dtype=np.float32)
    return np.stack([p[:-1], p[1:]], axis=1)


def _on_floor(xz: np.ndarray, height: float) -> np.ndarray:
    xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
    return np.stack([xz[:, 0], np.full(len(xz), height), xz[:, 1]], axis=1)


# --------------------------------------------------------------------------- drawing
LAYERS = ("splats", "graph", "scores", "goal and path", "trajectory", "top-down grid")


class SceneDrawer:
    """The scene nodes and GUI shared by the live and the replay viewer. Re-adding a node under the same
    name replaces it (viser drops the old message), so every draw_* call sends only its own layer."""

    def __init__(self, server, cfg: ViewerConfig, title: str):
        self.server, self.cfg = server, cfg
        self.sent: dict[str, int] = {}
        """How many times each layer was sent (tests and measurements)."""
        gui = server.gui
        gui.set_panel_label(title)
        self.status = gui.add_markdown("starting ...")
        with gui.add_folder("Layers", expand_by_default=False):
            self.layers = {name: gui.add_checkbox(name, name != "top-down grid") for name in LAYERS}
        self.handles: dict[str, list] = {name: [] for name in LAYERS}
        for name, box in self.layers.items():
            box.on_update(lambda _e, name=name: self._set_visible(name))
        self.images_folder = gui.add_folder("Images")
        self.image_handles: dict[str, Any] = {}

    # ------------------------------------------------------------------ bookkeeping
    def _set_visible(self, layer: str) -> None:
        for h in self.handles[layer]:
            h.visible = self.layers[layer].value

    def _add(self, layer: str, fn: Callable, name: str, *args, **kwargs):
        """Add (or replace) a scene node of `layer`, visible as the layer's checkbox says."""
        handle = fn(name, *args, visible=self.layers[layer].value, **kwargs)
        self.handles[layer] = [h for h in self.handles[layer] if h.name != name] + [handle]
        self.sent[name] = self.sent.get(name, 0) + 1
        return handle

    def _remove(self, layer: str, name: str) -> None:
        for h in [h for h in self.handles[layer] if h.name == name]:
            h.remove()
        self.handles[layer] = [h for h in self.handles[layer] if h.name != name]

    def set_image(self, label: str, image: np.ndarray | None) -> None:
        """A GUI image under "Images" (created on first use); None leaves the last one in place."""
        if image is None:
            return
        handle = self.image_handles.get(label)
        if handle is None:
            with self.images_folder:
                self.image_handles[label] = self.server.gui.add_image(image, label=label, format="jpeg")
        else:
            handle.image = image
        self.sent[f"image:{label}"] = self.sent.get(f"image:{label}", 0) + 1

    # ------------------------------------------------------------------ layers
    def draw_map(self, gaussians) -> None:
        if len(gaussians) == 0:
            return
        a = splat_arrays(gaussians, self.cfg.max_splats)
        self._add("splats", self.server.scene.add_gaussian_splats, "/map/splats", a["centers"],
                  a["covariances"], a["rgbs"], a["opacities"])

    def draw_camera(self, pose: np.ndarray, fov_y: float, aspect: float) -> None:
        """The agent's frustum (a persistent node: only its pose message is sent after the first time)."""
        handle = getattr(self, "_frustum", None)
        if handle is None:
            handle = self._frustum = self.server.scene.add_camera_frustum(
                "/agent/frustum", fov=fov_y, aspect=aspect, scale=self.cfg.frustum_scale,
                color=(230, 80, 20), thickness=0.015)
        handle.wxyz = _wxyz(pose[:3, :3])
        handle.position = np.asarray(pose[:3, 3], dtype=np.float64)
        self.sent["/agent/frustum"] = self.sent.get("/agent/frustum", 0) + 1

    def draw_trajectory(self, positions: np.ndarray, name: str = "/agent/trajectory",
                        color=(40, 110, 220)) -> None:
        if len(positions) >= 2:
            self._add("trajectory", self.server.scene.add_line_segments, name, _segments(positions), color,
                      thickness=0.02)

    def draw_plan(self, plan, floor_height: float) -> None:
        """Top-down grid, Voronoi graph (nodes by subregion), score bars, goal and path of a `Plan`."""
        lift = floor_height + self.cfg.graph_lift_m
        if plan.grids is not None:
            self._draw_grid(plan, floor_height)
        graph = plan.graph
        nodes = sorted(graph.nodes)
        if nodes:
            pos = {n: np.asarray(graph.nodes[n]["pos"], dtype=np.float64) for n in nodes}
            if graph.number_of_edges():
                seg = np.stack([_on_floor(np.stack([pos[a], pos[b]]), lift) for a, b in graph.edges])
                self._add("graph", self.server.scene.add_line_segments, "/graph/edges",
                          seg.astype(np.float32), (110, 117, 125), thickness=0.015)
            labels = np.array([plan.subregions.get(n, graph.nodes[n].get("subregion", 0)) for n in nodes])
            self._add("graph", self.server.scene.add_point_cloud, "/graph/nodes",
                      _on_floor(np.stack([pos[n] for n in nodes]), lift).astype(np.float32),
                      _rgb_u8("tab10", (labels % 10 + 0.5) / 10), point_size=0.12, point_shape="circle")
        else:
            for name in ("/graph/edges", "/graph/nodes"):
                self._remove("graph", name)
        self._draw_scores(plan, floor_height)
        if plan.path is not None and len(plan.path) >= 2:
            self._add("goal and path", self.server.scene.add_line_segments, "/plan/path",
                      _segments(_on_floor(plan.path, lift + 0.01)), (220, 30, 40), thickness=0.04)
        else:
            self._remove("goal and path", "/plan/path")
        if plan.goal is not None:
            self._add("goal and path", self.server.scene.add_icosphere, "/plan/goal", radius=0.12,
                      color=(220, 30, 40), position=_on_floor(plan.goal, lift + 0.1)[0])
        else:
            self._remove("goal and path", "/plan/goal")

    def _draw_scores(self, plan, floor_height: float) -> None:
        scores = {n: s for n, s in plan.scores.items() if n in plan.graph.nodes and math.isfinite(s)}
        if not scores:
            self._remove("scores", "/graph/scores")
            return
        nodes = list(scores)
        values = np.array([scores[n] for n in nodes])
        top = max(float(values.max()), 1e-9)
        rel = np.clip(values / top, 0.02, 1.0)
        base = _on_floor(np.stack([np.asarray(plan.graph.nodes[n]["pos"]) for n in nodes]), floor_height)
        tip = base + np.outer(rel * self.cfg.score_bar_m, [0.0, 1.0, 0.0])
        colours = np.repeat(_rgb_u8("viridis", rel)[:, None, :], 2, axis=1)
        self._add("scores", self.server.scene.add_line_segments, "/graph/scores",
                  np.stack([base, tip], axis=1).astype(np.float32), colours, thickness=0.05)

    def _draw_grid(self, plan, floor_height: float) -> None:
        from activesplat.workspace.draw import grid_image
        from activesplat.workspace.topdown import TOPDOWN_ROTATION

        geom = plan.grids.geometry
        image = (255 * grid_image(plan.grids, plan.workspace)).astype(np.uint8)
        x0, x1, z0, z1 = geom.extent
        # image columns run along world x, rows along world z: the top-down camera's rotation
        self._add("top-down grid", self.server.scene.add_image, "/map/grid", image, x1 - x0, z1 - z0,
                  format="png", wxyz=_wxyz(TOPDOWN_ROTATION),
                  position=np.array([(x0 + x1) / 2, floor_height + 0.01, (z0 + z1) / 2]))

    def draw_targets(self, pose: np.ndarray, targets) -> None:
        """Remaining on-the-spot rotation targets as rays from the camera."""
        from activesplat.geometry import heading

        if not targets:
            self._remove("goal and path", "/agent/targets")
            return
        origin = np.asarray(pose[:3, 3], dtype=np.float64)
        seg = np.stack([np.stack([origin, origin + 0.8 * heading(t.yaw, t.pitch)]) for t in targets])
        self._add("goal and path", self.server.scene.add_line_segments, "/agent/targets",
                  seg.astype(np.float32), (250, 190, 20), thickness=0.02)

    def look_at(self, target: np.ndarray) -> None:
        """The initial camera of new clients: above and behind `target`, looking at it."""
        target = np.asarray(target, dtype=np.float64)
        self.server.initial_camera.look_at = target
        self.server.initial_camera.position = target + np.array([3.0, 6.0, 3.0])


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
        self.server = start_server(port, self.cfg)
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
        print(f"viewer: {self.url}", file=sys.stderr)

    @property
    def sent(self) -> dict[str, int]:
        return self.draw.sent

    def update(self, step: int, obs, mapper, explorer, final: bool = False) -> None:
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
        lines = [f"**step** {step}  ", f"**gaussians** {len(mapper.gaussians)}  "]
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
        print(f"viewer: {cost:.1f} ms/step spent updating it; the run is over, still serving {self.url} "
              "(Ctrl-C to quit)", file=sys.stderr)
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


class EpisodeViewer:
    """The `activesplat view DIR` page: the final map and graph, and a timeline over the trajectory."""

    def __init__(self, episode_dir: str | Path, port: int = 8080, config: ViewerConfig | None = None,
                 ground_truth: bool = True):
        from activesplat.episode import read_episode

        self.cfg = config or ViewerConfig()
        self.episode = read_episode(episode_dir)  # EpisodeError when it is not an episode folder
        _check_port(self.cfg.host, port)  # before the (slow) loading
        self._load(ground_truth)
        self.server = start_server(port, self.cfg)  # the page appears once everything is loaded
        self.port = self.server.get_port()
        self.url = f"http://{self.cfg.host}:{self.port}"
        self._pending: int | None = None
        self._wake = threading.Condition()
        self._stop = False
        self._worker = threading.Thread(target=self._render_loop, name="activesplat-view-render", daemon=True)
        try:
            self.draw = SceneDrawer(self.server, self.cfg, f"activesplat view {self.episode.dir.name}")
            self._draw_scene()
        except BaseException:
            self.server.stop()
            raise
        self._worker.start()
        self.show_step(int(self.slider.value))

    # ------------------------------------------------------------------ loading
    def _load(self, ground_truth: bool) -> None:
        """Map, camera model, ground-truth simulator and the workspace / graph of the final map."""
        from activesplat.planning.controller import floor_xz
        from activesplat.splat.ply import load_ply
        from activesplat.workspace.config import WorkspaceConfig
        from activesplat.workspace.plan import build_plan

        ep, meta = self.episode, self.episode.meta
        self.poses, self.positions = ep.poses, ep.poses[:, :3, 3]
        ply = ep.dir / "gaussians.ply"
        self.gaussians = load_ply(ply) if ply.is_file() else None
        has_map = self.gaussians is not None and len(self.gaussians) > 0
        sim_cfg = meta.get("config", {}).get("sim", {})
        self.floor_height = float(meta.get("floor_height",
                                           self.poses[0][1, 3] - sim_cfg.get("sensor_height", 1.25)))
        self.width, self.height = int(sim_cfg.get("width", 256)), int(sim_cfg.get("height", 256))
        hfov = math.radians(float(sim_cfg.get("hfov_deg", 90.0)))
        self.fov_y = 2.0 * math.atan(math.tan(hfov / 2) * self.height / self.width)
        self.sim = self._load_simulator(meta) if ground_truth else None
        self.renderer = self.plan = None
        if has_map:
            from activesplat.geometry import intrinsics
            from activesplat.splat.mapper import Mapper

            # a bare mapper renders the map (Mapper.load would also read every keyframe, which is slow)
            K = intrinsics(self.width, self.height, math.degrees(hfov))
            self.renderer = Mapper(K, self.width, self.height, backend="auto")
            self.renderer.gaussians = self.gaussians
            saved = meta.get("config", {}).get("explorer", {}).get("workspace")
            self.plan = build_plan(self.gaussians, self.floor_height, floor_xz(self.poses[-1]),
                                   _dataclass_from(WorkspaceConfig, saved))

    def _load_simulator(self, meta: dict):
        """The episode's simulator for ground-truth images, None when its scene cannot be loaded."""
        from activesplat.errors import ActiveSplatError
        from activesplat.sim import SimConfig, Simulator, load_scene

        try:
            scene = load_scene(meta["scene"], z_up=bool(meta.get("z_up", False)), floor=meta.get("floor"))
            cfg = _dataclass_from(SimConfig, meta.get("config", {}).get("sim"))
            return Simulator(scene, start=self.episode.start_pose, config=cfg)
        except (ActiveSplatError, KeyError) as exc:
            print(f"viewer: no ground-truth images ({exc})", file=sys.stderr)
            return None

    def _draw_scene(self) -> None:
        meta, n = self.episode.meta, len(self.poses) - 1
        if self.plan is not None:
            self.draw.draw_map(self.gaussians)
            self.draw.draw_plan(self.plan, self.floor_height)
        self.draw.draw_trajectory(self.positions, name="/agent/trajectory_all", color=(170, 190, 225))
        self.draw.look_at(self.positions[0])
        gui = self.server.gui
        with gui.add_folder("Timeline"):
            self.slider = gui.add_slider("step", min=0, max=max(n, 1), step=1, initial_value=n)
            self.play = gui.add_checkbox("play", False)
        self.slider.on_update(lambda _e: self.show_step(int(self.slider.value)))
        nodes = 0 if self.plan is None else self.plan.graph.number_of_nodes()
        count = 0 if self.gaussians is None else len(self.gaussians)
        partial = "" if self.episode.complete else " (partial)"
        self.summary = (f"**{meta.get('scene', '?')}** / {meta.get('policy', '?')} / seed "
                        f"{meta.get('seed', '?')}{partial}  \n**steps** {n}  \n**gaussians** {count}  \n"
                        f"**graph** {nodes} nodes  ")

    # ------------------------------------------------------------------ timeline
    def show_step(self, step: int) -> None:
        """Move the frustum to the pose after `step` actions; the images follow from the render worker."""
        step = int(np.clip(step, 0, len(self.poses) - 1))
        pose = self.poses[step]
        self.draw.draw_camera(pose, self.fov_y, self.width / self.height)
        self.draw.draw_trajectory(self.positions[: step + 1])
        action = self.episode.actions[step - 1] if step > 0 else "reset"
        self.draw.status.content = f"{self.summary}\n**step** {step}: {action}"
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
            self.render_images(step)

    def render_images(self, step: int) -> None:
        """Ground-truth RGB-D (simulator) and the map's rendering at the pose after `step` actions."""
        pose = self.poses[step]
        if self.sim is not None:
            rgb, depth = self.sim.render(pose, self.width, self.height)
            self.draw.set_image("ground truth RGB", rgb)
            self.draw.set_image("ground truth depth", depth_image(depth, self.cfg.depth_max_m))
        if self.renderer is not None:
            out = self.renderer.render(pose)
            self.draw.set_image("map RGB", (255 * out.rgb.clamp(0, 1).cpu().numpy()).astype(np.uint8))

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
        self.server.stop()
        if self._worker.is_alive():
            self._worker.join(timeout=5.0)


def view_from_args(args) -> int:
    viewer = EpisodeViewer(args.dir, port=args.port)
    try:
        viewer.serve_forever()
    finally:
        viewer.close()
    return 0


__all__ = ["EpisodeViewer", "LiveViewer", "SceneDrawer", "ViewerConfig", "depth_image", "free_port",
           "panorama_image", "splat_arrays", "start_server", "view_from_args"]
