"""The viser viewers, headless: a live viewer attached to a tiny exploration and a replay viewer of the
episode it wrote are started on free ports; the page is fetched over HTTP and the scene is read back the
way a browser gets it (a websocket client decoding viser's wire format). No display needed."""

from __future__ import annotations

import socket
import sys
import time
import urllib.request

import msgspec
import networkx as nx
import numpy as np
import pytest
import viser
import zstandard
from websockets.sync.client import connect

from activesplat.cli import main
from activesplat.errors import EpisodeError, InvalidInputError
from activesplat.eval.coverage import CoverageConfig
from activesplat.explore import run_exploration
from activesplat.planning.explorer import Plan
from activesplat.sim import SimConfig
from activesplat.splat.ply import load_ply
from activesplat.viz.viewer import (
    EpisodeViewer,
    LiveViewer,
    SceneDrawer,
    ViewerConfig,
    free_port,
    start_server,
)

TINY = dict(sim_config=SimConfig(width=64, height=64), coverage_config=CoverageConfig(n_gt_points=2000,
                                                                                     batch_frames=10),
            progress=False, backend="numba")
STEPS = 12


class FakeClock:
    """0.25 s per call: exact in binary, so the rate limits give exact counts."""

    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 0.25
        return self.t


def scene_messages(port: int, timeout: float = 10.0) -> list[tuple[dict, list[bytes]]]:
    """Everything a new browser tab receives on connecting, up to viser's end-of-replay marker: each message
    (a dict with 'type', 'name', 'props', ...) with the binary buffers of its websocket frame."""
    out: list[tuple[dict, list[bytes]]] = []
    deadline = time.monotonic() + timeout
    with connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None,
                 open_timeout=timeout) as ws:
        while time.monotonic() < deadline:
            frame = ws.recv(timeout=max(0.1, deadline - time.monotonic()))
            n_inner, n_packed = (int.from_bytes(frame[i:i + 8], "little") for i in (0, 8))
            payload = msgspec.msgpack.decode(zstandard.ZstdDecompressor().decompress(
                frame[16:16 + n_packed], max_output_size=n_inner))
            buffers, offset = [], 16 + n_packed
            for length in payload["binaryBufferLengths"]:
                offset += (8 - offset % 8) % 8
                buffers.append(frame[offset:offset + length])
                offset += length
            out += [(m, buffers) for m in payload["messages"]]
            if any(m["type"] == "ReplayDoneMessage" for m in payload["messages"]):
                return out
    raise AssertionError("the scene replay did not finish")


def named(messages, kind: str, name: str | None = None) -> list[tuple[dict, list[bytes]]]:
    return [(m, b) for m, b in messages if m["type"] == kind and (name is None or m.get("name") == name)]


def splat_centers(message: dict, buffers: list[bytes]) -> np.ndarray:
    """Centres of the Gaussians in a GaussianSplatsMessage (8 uint32 per splat, xyz float32 first)."""
    raw = buffers[message["props"]["buffer"]["__binary_index"]]
    return np.frombuffer(raw, dtype=np.uint32).reshape(-1, 8)[:, :3].copy().view(np.float32)


def fetch_page(port: int) -> str:
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10) as response:
        assert response.status == 200
        return response.read().decode("utf-8", errors="replace")


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    """A tiny exploration watched by a live viewer (left open for the tests, closed at the end)."""
    out = tmp_path_factory.mktemp("viewer") / "ep"
    viewer = LiveViewer(port=free_port(), clock=FakeClock())
    try:
        metrics = run_exploration("small-0", steps=STEPS, seed=0, out=out, viewer=viewer, **TINY)
        yield viewer, out, metrics
    finally:
        viewer.close()


def test_live_viewer_serves_the_page_and_the_scene(live):
    viewer, out, metrics = live
    assert "<html" in fetch_page(viewer.port).lower()
    messages = scene_messages(viewer.port)
    (splats, buffers), = named(messages, "GaussianSplatsMessage", "/map/splats")  # replaced, not duplicated
    centers = splat_centers(splats, buffers)
    final_map = load_ply(out / "gaussians.ply")  # the run's final map: the last update sent it
    assert len(centers) == len(final_map) == metrics["n_gaussians"] > 0
    assert np.allclose(centers, final_map.means.detach().numpy())
    assert named(messages, "CameraFrustumMessage", "/agent/frustum")
    # the frustum sits at the final camera pose, world frame y up
    positions = named(messages, "SetPositionMessage", "/agent/frustum")
    final_pose = np.loadtxt(out / "poses.txt")[-1, 1:].reshape(4, 4)
    assert np.allclose(positions[-1][0]["position"], final_pose[:3, 3], atol=1e-6)
    (trajectory, buffers), = named(messages, "LineSegmentsMessage", "/agent/trajectory")
    assert len(buffers[trajectory["props"]["points"]["__binary_index"]]) == (STEPS - 1) * 2 * 3 * 4
    assert len(named(messages, "GuiImageMessage")) == 2  # RGB and depth
    # y is up: viser turns the scene root about the vertical only (z up would tilt it about x)
    w, x, y, z = named(messages, "SetOrientationMessage", "")[-1][0]["wxyz"]
    assert abs(x) < 1e-9 and abs(z) < 1e-9


def test_live_updates_are_rate_limited(live):
    viewer, _, _ = live
    # 12 updates, 0.25 s apart: state (0.2 s) every update, images and map (0.5 s) every other one plus the
    # final update, and the map only when the mapper took a frame
    assert viewer.sent["/agent/frustum"] == STEPS
    assert viewer.sent["image:RGB"] == viewer.sent["image:depth"] == STEPS // 2 + 1
    assert 1 <= viewer.sent["/map/splats"] <= STEPS // 2 + 1
    assert viewer.time_ms > 0


def test_replay_viewer_has_a_timeline_over_the_trajectory(live):
    _, out, metrics = live
    viewer = EpisodeViewer(out, port=free_port())
    try:
        assert "<html" in fetch_page(viewer.port).lower()
        messages = scene_messages(viewer.port)
        (splats, buffers), = named(messages, "GaussianSplatsMessage", "/map/splats")
        assert len(splat_centers(splats, buffers)) == metrics["n_gaussians"]
        (everything, _), = named(messages, "LineSegmentsMessage", "/agent/trajectory_all")
        sliders = [m for m, _ in named(messages, "GuiSliderMessage")]
        assert len(sliders) == 1 and sliders[0]["props"]["max"] == STEPS
        # moving the slider moves the frustum to that pose; the render worker follows with the images
        poses = np.loadtxt(out / "poses.txt")[:, 1:].reshape(-1, 4, 4)
        viewer.slider.value = 3
        assert np.allclose(viewer.draw._frustum.position, poses[3][:3, 3])
        deadline = time.monotonic() + 10
        while viewer.draw.sent.get("image:map RGB", 0) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert viewer.draw.sent["image:ground truth RGB"] >= 2 and viewer.draw.sent["image:map RGB"] >= 2
        assert viewer.draw.image_handles["ground truth RGB"].image.shape == (64, 64, 3)
    finally:
        viewer.close()


def test_plan_layers_graph_by_subregion_scores_goal_and_path():
    """A hand-made plan: two subregions, scored nodes, a goal and a path -> the scene nodes that show them."""
    graph = nx.Graph()
    for n, (x, z, sub) in enumerate([(0, 0, 0), (1, 0, 0), (4, 0, 1), (5, 0, 1)]):
        graph.add_node(n, pos=np.array([x, z], float), subregion=sub)
    graph.add_edges_from([(0, 1), (1, 2), (2, 3)])
    plan = Plan(graph=graph, subregions={0: 0, 1: 0, 2: 1, 3: 1}, scores={0: 2.0, 3: 8.0},
                goal=np.array([5.0, 0.0]), path=np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0]]))
    cfg = ViewerConfig()
    server = start_server(free_port(), cfg)
    try:
        drawer = SceneDrawer(server, cfg, "test")
        drawer.draw_plan(plan, floor_height=0.5)
        handle = {h.name: h for layer in drawer.handles.values() for h in layer}
        nodes = handle["/graph/nodes"]
        assert np.allclose(nodes.points[:, 1], 0.5 + cfg.graph_lift_m, atol=1e-3)  # on the floor, y up
        assert np.allclose(nodes.points[:, [0, 2]], [[0, 0], [1, 0], [4, 0], [5, 0]], atol=1e-2)
        assert (nodes.colors[0] == nodes.colors[1]).all() and (nodes.colors[2] == nodes.colors[3]).all()
        assert (nodes.colors[0] != nodes.colors[2]).any()  # one colour per subregion
        assert handle["/graph/edges"].points.shape == (3, 2, 3)
        bars = handle["/graph/scores"].points
        heights = bars[:, 1, 1] - bars[:, 0, 1]
        assert heights.shape == (2,) and heights[1] == pytest.approx(cfg.score_bar_m)  # best score: full bar
        assert heights[0] == pytest.approx(cfg.score_bar_m * 2.0 / 8.0)
        assert handle["/plan/path"].points.shape == (2, 2, 3)
        assert np.allclose(handle["/plan/goal"].position[[0, 2]], [5.0, 0.0])
        # the next plan has no goal: goal, path and scores disappear
        drawer.draw_plan(Plan(graph=graph, subregions=plan.subregions), floor_height=0.5)
        handle = {h.name: h for layer in drawer.handles.values() for h in layer}
        assert "/graph/nodes" in handle and not set(handle) & {"/plan/goal", "/plan/path", "/graph/scores"}
        # layer checkboxes hide and show
        drawer.layers["graph"].value = False
        assert not handle["/graph/nodes"].visible and not handle["/graph/edges"].visible
        drawer.layers["graph"].value = True
        assert handle["/graph/nodes"].visible
    finally:
        server.stop()


def test_bad_input_is_a_one_line_error(live, tmp_path, capsys):
    _, out, _ = live
    with pytest.raises(EpisodeError):
        EpisodeViewer(tmp_path, port=free_port())
    assert main(["view", str(tmp_path), "--port", str(free_port())]) == 2
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(InvalidInputError, match="not available"):
            LiveViewer(port=port)
        assert main(["view", str(out), "--port", str(port)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("activesplat: error:") and "not available" in err[-1]


def test_without_a_viewer_viser_is_never_imported(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "viser", None)  # any `import viser` now raises ImportError
    metrics = run_exploration("small-0", steps=2, seed=0, out=tmp_path / "ep", **TINY)
    assert metrics["steps"] == 2
