"""What the viewers draw, with viser: the Gaussian map as splats, the camera frustum, trajectories, the
plan (Voronoi graph by subregion, eq. 12 score bars, goal and path, the top-down grid), rotation
targets, and the RGB-D / panorama images, each in its own toggleable layer (`SceneDrawer`); and the
conversions they need (depth and panorama images, splat arrays). Shared by the live (`viz.live`) and
replay (`viz.replay`) viewers."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from activesplat.viz.server import ViewerConfig


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


def splat_count_text(n: int, max_splats: int) -> str:
    """How many Gaussians a map has and, above ``max_splats``, how many of them the browser is sent."""
    if n <= max_splats:
        return f"{n} gaussians"
    return f"{n} gaussians, the {max_splats} most opaque drawn"


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
        """A GUI image under "Images" (created on first use); None hides it until the next image (a view
        without one: nothing stale is left beside the others)."""
        handle = self.image_handles.get(label)
        if image is None:
            if handle is not None:
                handle.visible = False
            return
        if handle is None:
            with self.images_folder:
                self.image_handles[label] = self.server.gui.add_image(image, label=label, format="jpeg")
        else:
            handle.image = image
            handle.visible = True
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


__all__ = ["LAYERS", "SceneDrawer", "depth_image", "panorama_image", "splat_arrays", "splat_count_text"]
