"""The live viewer of `activesplat explore --viewer` (`LiveViewer`): the exploration loop calls
`LiveViewer.update` after every step, and the page follows the run: the map as splats, the agent's camera
frustum and trajectory, the plan of the last replan (Voronoi graph by subregion, eq. 12 score bars, goal
and path), the latest RGB-D images and panorama, and a status (step, policy, map size, graph).

`update` is rate-limited: the splats (the expensive part) are sent at most every
`ViewerConfig.map_interval_s`, only when the mapper took a frame since the last send, and never for more
than `max_map_share` of the wall time; the frustum, trajectory, plan and images follow at their own
bounded rates. An error while updating stops the page's updates, not the exploration. Without `--viewer`
nothing here is imported (the exploration loop checks `viewer is not None` and nothing else).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable

import numpy as np

from activesplat.viz.drawing import SceneDrawer, depth_image, panorama_image, splat_count_text
from activesplat.viz.server import ViewerConfig, camera_fov, start_server


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
        self.draw.draw_camera(pose, *camera_fov(mapper.K, mapper.width, mapper.height))
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


__all__ = ["LiveViewer"]
