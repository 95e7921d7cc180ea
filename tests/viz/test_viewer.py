"""The viser viewers, headless: a live viewer attached to a tiny exploration and a replay viewer of the
episode it wrote are started on free ports; the page is fetched over HTTP and the scene is read back the
way a browser gets it (a websocket client decoding viser's wire format). No display needed."""

from __future__ import annotations

import json
import socket
import sys
import time
import urllib.request
from pathlib import Path
from types import SimpleNamespace

import msgspec
import networkx as nx
import numpy as np
import pytest
import torch
import viser
import zstandard
from websockets.sync.client import connect

from activesplat.cli import main
from activesplat.config import ExploreCommand
from activesplat.errors import EpisodeError, InvalidInputError
from activesplat.eval.coverage import CoverageConfig
from activesplat.explore import run_exploration
from activesplat.planning.explorer import ExplorerView
from activesplat.planning.viewpoints import RotationTarget
from activesplat.sim import SimConfig
from activesplat.splat.gaussians import GaussianMap
from activesplat.splat.ply import load_ply, save_ply
from activesplat.viz.viewer import (
    EpisodeViewer,
    LiveViewer,
    SceneDrawer,
    ViewerConfig,
    free_port,
    splat_arrays,
    start_server,
)
from activesplat.workspace.plan import Plan

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



def rendered(viewer, step: int, timeout: float = 10.0) -> None:
    """Wait until the render worker has shown the images of `step` and has nothing else queued."""
    deadline = time.monotonic() + timeout
    while (viewer.rendered_step != step or viewer._pending is not None) and time.monotonic() < deadline:
        time.sleep(0.02)
    assert viewer.rendered_step == step, f"the viewer shows step {viewer.rendered_step}, not {step}"


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


def test_splat_arrays_are_the_rasterizer_covariances_and_keep_the_most_opaque():
    gen = torch.Generator().manual_seed(0)
    raw = {"means": torch.randn(50, 3, generator=gen), "quats": torch.randn(50, 4, generator=gen),
           "log_scales": torch.randn(50, 3, generator=gen) - 3,
           "opacity_logits": torch.randn(50, generator=gen), "f_dc": torch.randn(50, 3, generator=gen)}
    gmap = GaussianMap(raw)
    a = splat_arrays(gmap, max_splats=50)
    q = gmap.quats.detach().double()
    w, x, y, z = q.unbind(1)  # independent rotation formula (torch, float64)
    R = torch.stack([torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], 1),
                     torch.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], 1),
                     torch.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], 1)], 1)
    cov = R @ torch.diag_embed(gmap.scales.detach().double() ** 2) @ R.transpose(1, 2)
    assert np.allclose(a["covariances"], cov.numpy(), rtol=1e-4, atol=1e-10)
    assert np.allclose(a["centers"], raw["means"].numpy())
    assert np.abs(a["opacities"][:, 0] / 255 - gmap.opacities.detach().numpy()).max() <= 0.5 / 255 + 1e-6
    top = splat_arrays(gmap, max_splats=10)
    assert len(top["centers"]) == 10
    assert top["opacities"].min() >= np.sort(a["opacities"][:, 0])[-10]


def fake_mapper_and_obs():
    gmap = GaussianMap.from_points(torch.rand(20, 3), torch.rand(20, 3), torch.full((20,), 0.05))
    mapper = SimpleNamespace(gaussians=gmap, K=np.array([[32.0, 0, 32], [0, 32, 32], [0, 0, 1]]), width=64,
                             height=64, frames=0)
    obs = SimpleNamespace(pose=np.eye(4), rgb=np.zeros((64, 64, 3), np.uint8),
                          depth=np.ones((64, 64), np.float32))
    return mapper, obs


def test_map_sends_keep_to_the_interval_and_the_cost_budget():
    """Fake loop: a map send is due every other update by the interval, but a budget of 1e-9 of the wall time
    allows only the first one, plus the final update's."""
    mapper, obs = fake_mapper_and_obs()
    # due at updates 1, 3, 5, 7 by the interval; no frame is mapped since update 3 when 5 comes, so 6 goes
    # instead; 8 is final
    for share, expected in ((1.0, 4), (1e-9, 2)):
        viewer = LiveViewer(port=free_port(), config=ViewerConfig(max_map_share=share), clock=FakeClock())
        try:
            for step in range(1, 9):
                mapper.frames += step not in (4, 5)  # skipped frames: nothing new to send at update 5
                viewer.update(step, obs, mapper, object(), final=step == 8)
            assert viewer.sent["/map/splats"] == expected
            assert viewer.sent["/agent/frustum"] == 8  # light state: every update at 0.25 s > 0.2 s
        finally:
            viewer.close()


def hand_made_plan() -> Plan:
    """Two subregions of two nodes each, two scored nodes, a goal and a path."""
    graph = nx.Graph()
    for n, (x, z, sub) in enumerate([(0, 0, 0), (1, 0, 0), (4, 0, 1), (5, 0, 1)]):
        graph.add_node(n, pos=np.array([x, z], float), subregion=sub)
    graph.add_edges_from([(0, 1), (1, 2), (2, 3)])
    return Plan(graph=graph, subregions={0: 0, 1: 0, 2: 1, 3: 1}, scores={0: 2.0, 3: 8.0},
                goal=np.array([5.0, 0.0]), path=np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0]]))


def test_live_viewer_shows_the_explorer_state():
    """What `view_state()` exposes reaches the page: plan layers once per new plan, the panorama once per new
    panorama, rotation targets as rays from the camera."""
    mapper, obs = fake_mapper_and_obs()
    pano = SimpleNamespace(invisibility=np.linspace(0, 1, 150 * 360).reshape(150, 360),
                           median_depth=np.full((150, 360), 2.0))
    state = ExplorerView("activesplat", 0.0, hand_made_plan(), pano,
                         (RotationTarget(0.0, 0.0, 1.0), RotationTarget(np.pi / 2, 0.2, 1.0)))
    explorer = SimpleNamespace(view_state=lambda: state)
    viewer = LiveViewer(port=free_port(), config=ViewerConfig(state_interval_s=0, image_interval_s=0),
                        clock=FakeClock())
    try:
        for step in (1, 2, 3):
            mapper.frames += 1
            viewer.update(step, obs, mapper, explorer)
        assert viewer.sent["/graph/nodes"] == viewer.sent["/plan/goal"] == 1  # the plan did not change
        assert viewer.sent["image:panorama (invisibility / depth)"] == 1
        assert viewer.draw.image_handles["panorama (invisibility / depth)"].image.shape == (300, 360, 3)
        targets = {h.name: h for h in viewer.draw.handles["goal and path"]}["/agent/targets"]
        assert targets.points.shape == (2, 2, 3)
        assert "**policy** activesplat" in viewer.draw.status.content
        state = ExplorerView("activesplat", 0.0, hand_made_plan(), pano, ())  # a replan, targets done
        viewer.update(4, obs, mapper, explorer)
        assert viewer.sent["/graph/nodes"] == 2
        assert "/agent/targets" not in {h.name for h in viewer.draw.handles["goal and path"]}
    finally:
        viewer.close()


def test_plan_layers_graph_by_subregion_scores_goal_and_path():
    """A hand-made plan: two subregions, scored nodes, a goal and a path -> the scene nodes that show them."""
    plan = hand_made_plan()
    graph = plan.graph
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
        with pytest.raises(InvalidInputError, match="not available .*; pick another with --viewer-port$"):
            LiveViewer(port=port)
        assert main(["view", str(out), "--port", str(port)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("activesplat: error:") and "not available" in err[-1]
    assert err[-1].endswith("pick another with --port")  # the option of `view`, not also explore's


def test_without_a_viewer_viser_is_never_imported(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "viser", None)  # any `import viser` now raises ImportError
    metrics = run_exploration("small-0", steps=2, seed=0, out=tmp_path / "ep", **TINY)
    assert metrics["steps"] == 2


def copy_episode(src, dst):
    """A copy of the fixture's episode (the tests below change it)."""
    import shutil

    shutil.copytree(src, dst)
    return dst


def splats_sent(port: int) -> int:
    (splats, buffers), = named(scene_messages(port), "GaussianSplatsMessage", "/map/splats")
    return len(splat_centers(splats, buffers))


def test_a_refined_map_opens_with_its_episode_and_the_online_one_a_click_away(live, tmp_path, capsys):
    """`view DIR/refined_3dgs`: the refined map with the episode's trajectory, graph and timeline; the map
    dropdown switches to the online map (and `view DIR` offers the refined one)."""
    _, out, metrics = live
    ep = copy_episode(out, tmp_path / "ep")
    online = load_ply(ep / "gaussians.ply")
    (ep / "refined_3dgs").mkdir()
    save_ply(GaussianMap(online.rows(torch.arange(len(online) // 2))), ep / "refined_3dgs" / "gaussians.ply")
    (ep / "refined_3dgs" / "refine.json").write_text('{"method": "3dgs"}')
    viewer = EpisodeViewer(ep / "refined_3dgs", port=free_port(), ground_truth=False)
    try:
        assert splats_sent(viewer.port) == len(online) // 2
        assert viewer.slider.max == STEPS and len(viewer.positions) == STEPS + 1
        assert viewer.map_choice.options == ("online", "refined_3dgs")
        assert viewer.map_choice.value == "refined_3dgs"
        assert "**map** refined_3dgs" in viewer.draw.status.content
        viewer.map_choice.value = "online"  # what a click in the dropdown does
        assert splats_sent(viewer.port) == metrics["n_gaussians"]
        assert "**map** online" in viewer.draw.status.content
        deadline = time.monotonic() + 10
        while viewer.draw.sent.get("image:map RGB", 0) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert viewer.draw.sent["image:map RGB"] >= 2
    finally:
        viewer.close()
    viewer = EpisodeViewer(ep, port=free_port(), ground_truth=False)
    try:
        assert viewer.map_choice.value == "online" and splats_sent(viewer.port) == metrics["n_gaussians"]
    finally:
        viewer.close()
    (ep / "refined_2dgs").mkdir()  # an interrupted refinement: no map yet
    with pytest.raises(EpisodeError, match="nor a map folder inside one"):
        EpisodeViewer(ep / "refined_2dgs", port=free_port())


@pytest.fixture(scope="module")
def recorded_map(tmp_path_factory):
    """A map of a recording (`activesplat map` of a TUM RGB-D folder, every 3rd frame held out)."""
    pytest.importorskip("cv2")
    sys.path.insert(0, str(Path(__file__).parents[1] / "robot"))
    from _bags import ros_intrinsics, sim_frames, write_tum

    K, frames = sim_frames(9, 32)
    root = tmp_path_factory.mktemp("recorded")
    tum = write_tum(root / "tum", K, frames)
    out = root / "map"
    assert main(["map", str(tum), "--intrinsics", *(str(v) for v in ros_intrinsics(K)),
                 "--holdout-every", "3", "--backend", "numba", "--out", str(out), "--no-progress"]) == 0
    return out, frames


def test_a_recorded_map_shows_its_trajectory_and_the_held_out_frames_beside_the_map(recorded_map, capsys):
    """`view` of an `activesplat map` folder: the map, the camera trajectory of poses.txt with a frame
    slider, and at the held-out frames (the only recorded images kept) the recording beside the map's
    rendering; at the mapped frames no stale recorded image stays on the page."""
    out, frames = recorded_map
    viewer = EpisodeViewer(out, port=free_port())
    try:
        assert splats_sent(viewer.port) == len(load_ply(out / "gaussians.ply")) > 0
        assert viewer.slider.max == len(frames) - 1 and viewer.slider.label == "frame"
        assert np.allclose(viewer.positions, [pose[:3, 3] for _, _, pose in frames], atol=1e-6)
        held = np.load(out / "heldout.npz")["index"]
        assert list(held) == [2, 5, 8] and "6 mapped, 3 held out" in viewer.draw.status.content

        def images_at(frame: int) -> dict:
            viewer.slider.value = frame
            rendered(viewer, frame)
            return {k: h for k, h in viewer.draw.image_handles.items() if h.visible}

        shown = images_at(5)
        assert "held out of the map" in viewer.draw.status.content
        assert np.array_equal(shown["recorded RGB (held out)"].image, frames[5][0])
        assert set(shown) == {"recorded RGB (held out)", "recorded depth (held out)", "map RGB"}
        assert set(images_at(4)) == {"map RGB"} and "**frame** 4: map rendering" in viewer.draw.status.content
    finally:
        viewer.close()
    broken = copy_episode(out, out.parent / "broken")
    meta = json.loads((broken / "episode.json").read_text())
    del meta["K"]
    (broken / "episode.json").write_text(json.dumps(meta))
    assert main(["view", str(broken), "--port", str(free_port())]) == 2
    assert "episode.json: no camera of the recording (K, width, height): KeyError" in capsys.readouterr().err


def test_a_map_too_large_for_the_browser_says_what_it_sends(live, tmp_path, capsys):
    """Above `max_splats` only the most opaque Gaussians go to the browser: the page and the terminal say
    so (the page showed the full count as if all were drawn), and `--max-splats` sets the budget."""
    _, out, metrics = live
    viewer = EpisodeViewer(out, port=free_port(), config=ViewerConfig(max_splats=100), ground_truth=False)
    try:
        assert splats_sent(viewer.port) == 100
        assert f"{metrics['n_gaussians']} gaussians, the 100 most opaque drawn" in viewer.draw.status.content
    finally:
        viewer.close()
    assert "the browser is sent the 100 most opaque (--max-splats to change)" in capsys.readouterr().err
    mapper, obs = fake_mapper_and_obs()  # the live page too: 20 Gaussians, 5 drawn
    live_viewer = LiveViewer(port=free_port(), config=ViewerConfig(max_splats=5), clock=FakeClock())
    try:
        live_viewer.update(1, obs, mapper, object())
        assert "20 gaussians, the 5 most opaque drawn" in live_viewer.draw.status.content
    finally:
        live_viewer.close()
    assert main(["view", str(out), "--max-splats", "0", "--port", str(free_port())]) == 2
    assert "--max-splats must be a positive number" in capsys.readouterr().err


@pytest.mark.filterwarnings("ignore:a budget of 6 actions")
def test_explore_viewer_takes_the_browser_budget_from_max_splats(tmp_path, capsys, monkeypatch):
    """`explore --viewer --max-splats N`: the live page gets at most N Gaussians of the growing map and says
    so, and the terminal says it once (explore had no such option: the live page always took 400 000). A
    budget below 1 is a one-line error before the run."""
    seen = {}

    def hold(viewer):  # instead of serving until Ctrl-C: what the page shows at the end of the run
        seen.update(budget=viewer.cfg.max_splats, sent=splats_sent(viewer.port),
                    status=viewer.draw.status.content)

    monkeypatch.setattr(LiveViewer, "hold", hold)
    tiny = ["explore", "--steps", "6", "--sim.width", "48", "--sim.height", "48", "--coverage.n-gt-points",
            "1000", "--coverage.resolution", "32", "--coverage.batch-frames", "5", "--backend", "numba",
            "--no-progress"]
    assert main([*tiny, "--out", str(tmp_path / "ep"), "--viewer", "--viewer-port", str(free_port()),
                 "--max-splats", "7"]) == 0
    n = len(load_ply(tmp_path / "ep" / "gaussians.ply"))
    assert n > 7 and (seen["budget"], seen["sent"]) == (7, 7)
    assert f"**map** {n} gaussians, the 7 most opaque drawn" in seen["status"]
    err = capsys.readouterr().err
    assert err.count("the browser is sent the 7 most opaque (--max-splats to change)") == 1
    assert main([*tiny, "--out", str(tmp_path / "never"), "--viewer", "--max-splats", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "activesplat: error: --max-splats must be a positive number of Gaussians, got 0"
    assert not (tmp_path / "never").exists()
    assert ExploreCommand().max_splats == ViewerConfig().max_splats  # the same default as the viewers'


def test_an_episode_without_a_map_or_graph_shows_what_it_has(live, tmp_path, capsys, monkeypatch):
    """No gaussians.ply (an episode cut before its map was written): the trajectory and timeline, and a line
    saying why there is no map. A map the workspace cannot be built from: the map without the graph."""
    _, out, _ = live
    ep = copy_episode(out, tmp_path / "ep")
    (ep / "gaussians.ply").unlink()
    viewer = EpisodeViewer(ep, port=free_port(), ground_truth=False)
    try:
        messages = scene_messages(viewer.port)
        assert not named(messages, "GaussianSplatsMessage") and named(messages, "LineSegmentsMessage",
                                                                      "/agent/trajectory_all")
        assert "**map** none (no gaussians.ply)" in viewer.draw.status.content
    finally:
        viewer.close()
    assert "has no map (no gaussians.ply): showing the trajectory only" in capsys.readouterr().err

    def no_workspace(*_args, **_kwargs):
        raise ValueError("no floor in the map")

    monkeypatch.setattr("activesplat.workspace.plan.build_plan", no_workspace)
    viewer = EpisodeViewer(out, port=free_port(), ground_truth=False)
    try:
        messages = scene_messages(viewer.port)
        assert named(messages, "GaussianSplatsMessage") and not named(messages, "PointCloudMessage")
        assert "**graph** 0 nodes" in viewer.draw.status.content
    finally:
        viewer.close()
    assert "viewer: no graph (ValueError: no floor in the map)" in capsys.readouterr().err


def test_an_episode_is_shown_with_the_camera_it_saw_not_the_simulators_settings(live, tmp_path):
    """An exploration in another environment (a robot) records its camera apart from config.sim, which
    keeps the simulator's defaults: the frustum and the map's renders take the recorded camera."""
    _, out, _ = live
    ep = copy_episode(out, tmp_path / "robot")
    meta = json.loads((ep / "episode.json").read_text())
    K = [[40.0, 0.0, 24.5], [0.0, 41.0, 15.5], [0.0, 0.0, 1.0]]
    meta["camera"] = {"width": 48, "height": 32, "K": K}
    (ep / "episode.json").write_text(json.dumps(meta))
    viewer = EpisodeViewer(ep, port=free_port(), ground_truth=False)
    try:
        assert (viewer.width, viewer.height) == (48, 32) and viewer.K.tolist() == K
    finally:
        viewer.close()


def test_ctrl_c_during_a_render_closes_without_a_warning(live):
    """Ctrl-C while the render worker draws the map: it finishes before the server stops, and nothing is
    queued on the stopped server (viser warned 'Queued a GuiImageMessage on a closed connection')."""
    import warnings

    _, out, _ = live
    viewer = EpisodeViewer(out, port=free_port(), ground_truth=False)
    gmap, render = viewer._map("online")

    def slow(*args):
        time.sleep(0.5)
        return render(*args)

    viewer._loaded["online"] = (gmap, slow)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        viewer.show_step(3)
        time.sleep(0.2)  # the worker is rendering
        viewer.close()
        time.sleep(0.5)
    assert not [w for w in caught if "closed connection" in str(w.message)]
    assert not viewer._worker.is_alive()


def test_an_error_in_the_live_viewer_stops_the_page_not_the_exploration(tmp_path, capsys):
    """A failing update (here: the explorer's state cannot be read) used to end the run with a traceback,
    after however many minutes of exploring; now the page stops updating and the run goes on."""
    mapper, obs = fake_mapper_and_obs()

    def broken():
        raise RuntimeError("no plan yet")

    viewer = LiveViewer(port=free_port(), clock=FakeClock())
    try:
        viewer.update(1, obs, mapper, SimpleNamespace(view_state=broken))
        viewer.update(2, obs, mapper, SimpleNamespace(view_state=broken))
        assert viewer.failed == "step 1: RuntimeError: no plan yet" and viewer.updates == 0
    finally:
        viewer.close()
    err = capsys.readouterr().err
    assert err.count("the page stopped updating at step 1: RuntimeError: no plan yet; the exploration goes "
                     "on") == 1


def test_a_broken_map_or_render_leaves_the_viewer_working(live, tmp_path, capsys):
    """A refined map that cannot be read, chosen in the map menu: the current map stays and a line says why
    (it raised in viser's callback thread). A render that fails: one line, and the next step renders (the
    worker thread died and the images froze). A 2dgs map renders with the surfel rasterizer."""
    from activesplat.refine.surfels import render_surfel_view

    _, out, _ = live
    ep = copy_episode(out, tmp_path / "ep")
    for method in ("2dgs", "3dgs"):
        (ep / f"refined_{method}").mkdir()
        (ep / f"refined_{method}" / "refine.json").write_text(f'{{"method": "{method}"}}')
    (ep / "refined_2dgs" / "gaussians.ply").symlink_to(ep / "gaussians.ply")
    (ep / "refined_3dgs" / "gaussians.ply").write_bytes((ep / "gaussians.ply").read_bytes()[:5000])  # cut
    viewer = EpisodeViewer(ep, port=free_port(), ground_truth=False)
    try:
        assert viewer._map("refined_2dgs")[1] is render_surfel_view
        viewer.map_choice.value = "refined_3dgs"
        assert viewer.map_name == viewer.map_choice.value == "online"
        assert "**map refined_3dgs not shown**: " in viewer.draw.status.content
        assert "viewer: map refined_3dgs not shown: " in capsys.readouterr().err
        rendered(viewer, viewer.slider.value)  # the first render is done before the renderer is replaced
        gmap, render = viewer._map("online")
        calls = []

        def fails_once(*args):
            calls.append(1)
            if len(calls) == 1:
                raise RuntimeError("out of memory")
            return render(*args)

        viewer._loaded["online"] = (gmap, fails_once)
        viewer.slider.value = 2
        deadline = time.monotonic() + 10
        while not calls and time.monotonic() < deadline:  # the worker took step 2
            time.sleep(0.05)
        sent = viewer.draw.sent.get("image:map RGB", 0)
        viewer.slider.value = 3
        rendered(viewer, 3)
        assert viewer.draw.sent["image:map RGB"] > sent and viewer._worker.is_alive()
        assert "viewer: no images at step 2 (RuntimeError: out of memory)" in capsys.readouterr().err
    finally:
        viewer.close()
