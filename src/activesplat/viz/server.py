"""What both viser viewers share: their settings (`ViewerConfig`: what they draw, how often the live one
sends) and the server of their page (`start_server`: exactly the port asked for, or a one-line error
naming the command's port option). viser itself is imported only when a server starts."""

from __future__ import annotations

import math
import socket
from dataclasses import dataclass

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


def check_port(host: str, port: int, option: str = "--port") -> None:
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
    check_port(cfg.host, port, option)
    import viser

    server = viser.ViserServer(host=cfg.host, port=port, verbose=False)
    if server.get_port() != port:  # lost a race for the port
        server.stop()
        raise InvalidInputError(f"viewer port {port} on {cfg.host} is not available; pick another with "
                                f"{option}")
    server.scene.set_up_direction("+y")
    return server


def camera_fov(K: np.ndarray, width: int, height: int) -> tuple[float, float]:
    """(vertical fov in radians, aspect) of a pinhole K."""
    return 2.0 * math.atan(height / (2.0 * float(K[1][1]))), width / height


__all__ = ["ViewerConfig", "camera_fov", "check_port", "free_port", "start_server"]
