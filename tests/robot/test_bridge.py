"""The live-robot bridge end to end on loopback: a scripted fake robot served by our simulator speaks
rosbridge v2 on a local port; the exploration loop drives it through RosbridgeEnvironment and takes the
same actions, and sees the same poses, as when it drives the simulator directly."""

import numpy as np
import pytest

from activesplat.config import RunConfig
from activesplat.errors import InvalidInputError
from activesplat.explore import explore_environment
from activesplat.robot.bridge import RosbridgeEnvironment, serve_simulator
from activesplat.sim import SimConfig, Simulator, box_room

SIM = SimConfig(width=32, height=32)
TOPICS = ("/camera/color/image_raw", "/camera/depth/image_raw", "/camera/color/camera_info", "/camera_pose")


def test_explore_a_fake_robot_over_rosbridge(tmp_path):
    server, url = serve_simulator(Simulator(box_room(), seed=0, config=SIM))
    try:
        env = RosbridgeEnvironment(url, *TOPICS, timeout_s=20)
        assert (env.width, env.height) == (32, 32)
        run = RunConfig().replace(steps=8, sim=SIM, backend="numba")
        explore_environment(env, run, tmp_path / "robot", progress=False, name="fake-robot")
        env.close()
    finally:
        server.shutdown()
    explore_environment(Simulator(box_room(), seed=0, config=SIM), run, tmp_path / "sim", progress=False)
    robot, sim = (
        (tmp_path / "robot" / "actions.txt").read_text(),
        (tmp_path / "sim" / "actions.txt").read_text(),
    )
    assert robot == sim and len(robot.split()) == 8
    np.testing.assert_allclose(
        np.loadtxt(tmp_path / "robot" / "poses.txt"), np.loadtxt(tmp_path / "sim" / "poses.txt"), atol=1e-9
    )


def test_waypoints_go_to_the_robot_in_its_z_up_world():
    server, url = serve_simulator(Simulator(box_room(), seed=0, config=SIM))
    try:
        env = RosbridgeEnvironment(url, *TOPICS, timeout_s=20)
        obs = env.reset()
        env.waypoint(None)
        env.waypoint(np.array([1.5, -2.0]))
        env.waypoint(np.array([1.5, -2.0]))  # unchanged: not sent again
        env.step("turn_left")
        env.close()
    finally:
        server.shutdown()
    points = [op["msg"]["point"] for op in server.received if op["topic"] == "/activesplat/waypoint"]
    assert points == [{"x": 1.5, "y": 2.0, "z": pytest.approx(obs.pose[1, 3])}]


def test_no_robot_is_one_line():
    with pytest.raises(InvalidInputError, match="rosbridge ws://127.0.0.1:9: cannot connect"):
        RosbridgeEnvironment("ws://127.0.0.1:9", *TOPICS, timeout_s=2)


def test_a_url_that_is_not_a_websocket_is_one_line(tmp_path, capsys):
    from activesplat.cli import main

    for url in ("http://x", "notaurl", "ws://"):
        with pytest.raises(InvalidInputError, match=f"rosbridge URL {url!r}: expected a websocket address"):
            RosbridgeEnvironment(url, *TOPICS, timeout_s=2)
        assert main(["robot", url, "--steps", "3", "--out", str(tmp_path / "r")]) == 2
        err = capsys.readouterr().err
        assert err == (f"activesplat: error: rosbridge URL {url!r}: expected a websocket address "
                       f"ws://HOST:PORT (or wss://HOST:PORT), e.g. ws://robot.local:9090 "
                       f"(rosbridge_websocket's port)\n")
    assert not (tmp_path / "r").exists()


def test_a_server_that_is_not_rosbridge_is_one_line():
    import socket
    import threading

    server = socket.create_server(("127.0.0.1", 0))

    def answer():  # an HTTP server, not a websocket
        conn, _ = server.accept()
        conn.recv(4096)
        conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nhi")
        conn.close()

    threading.Thread(target=answer, daemon=True).start()
    url = f"ws://127.0.0.1:{server.getsockname()[1]}"
    try:
        with pytest.raises(InvalidInputError, match=f"rosbridge {url}: cannot connect"):
            RosbridgeEnvironment(url, *TOPICS, timeout_s=5)
    finally:
        server.close()


def test_robot_command_over_loopback(tmp_path, capsys):
    from activesplat.cli import main

    server, url = serve_simulator(Simulator(box_room(), seed=0, config=SimConfig(width=32, height=32)))
    try:
        assert main(["robot", url, "--steps", "3", "--out", str(tmp_path / "ep"), "--no-progress"]) == 0
    finally:
        server.shutdown()
    assert "explored 3 steps" in capsys.readouterr().out
    assert (
        main(["robot", "ws://127.0.0.1:9", "--steps", "3", "--out", str(tmp_path / "x"), "--timeout", "2"])
        == 2
    )
    assert "cannot connect" in capsys.readouterr().err


def test_ctrl_c_while_connecting_is_one_line(tmp_path, capsys, monkeypatch):
    from activesplat.cli import main

    def ctrl_c(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr("activesplat.robot.bridge.RosbridgeEnvironment", ctrl_c)
    out = tmp_path / "ep"
    assert main(["robot", "ws://127.0.0.1:9", "--steps", "3", "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip()
    assert err == f"interrupted while connecting to ws://127.0.0.1:9: nothing written to {out}"
    assert not out.exists()


def test_the_robot_s_action_sizes_reach_the_planner_and_the_bridge(tmp_path, capsys, monkeypatch):
    """`robot --sim.forward-step / --sim.turn-deg / --sim.look-deg`: the sizes the planner assumes (and the
    action-size check compares the poses with) and the bridge's collision test, as the warning says to set
    them; a bad one is refused before connecting."""
    from activesplat.cli import main

    seen = {}

    class Robot:
        def __init__(self, url, *topics, **options):
            seen["options"] = options

        def close(self):
            pass

    def explore(env, run, out, **options):
        seen["run"] = run
        return {"steps": 3, "path_length_m": 0.0, "n_gaussians": 0, "ms_per_step": 1.0}

    monkeypatch.setattr("activesplat.robot.bridge.RosbridgeEnvironment", Robot)
    monkeypatch.setattr("activesplat.explore.explore_environment", explore)
    argv = ["robot", "ws://127.0.0.1:9", "--steps", "3", "--out", str(tmp_path / "ep")]
    assert main([*argv, "--sim.forward-step", "0.1", "--sim.turn-deg", "15", "--sim.look-deg", "20"]) == 0
    run = seen["run"]
    assert (run.sim.forward_step, run.sim.turn_deg, run.sim.look_deg) == (0.1, 15.0, 20.0)
    assert (run.explorer.controller.forward_m, run.explorer.controller.turn_deg) == (0.1, 15.0)
    assert seen["options"]["forward_step"] == 0.1
    seen.clear()
    assert main([*argv, "--sim.forward-step", "-1"]) == 2
    assert capsys.readouterr().err == "activesplat: error: SimConfig.forward_step must be > 0, got -1.0\n"
    assert seen == {}
