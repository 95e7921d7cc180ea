"""A hand-made episode for the rendering evaluations: a box room (exported to .glb), a look-around at
64 x 64, and a map built directly from the ground-truth RGB-D (one Gaussian per 2x2 pixels of every third
frame)."""

import dataclasses

import pytest
import torch

from activesplat.episode import EpisodeWriter
from activesplat.sim import SimConfig, Simulator, box_room, load_scene
from activesplat.splat.config import MapperConfig
from activesplat.splat.densify import gaussians_from_pixels
from activesplat.splat.gaussians import GaussianMap
from activesplat.splat.ply import save_ply

SIM = SimConfig(width=64, height=64)


def map_from_ground_truth(frames, K) -> GaussianMap:
    cfg = MapperConfig()
    parts = []
    for rgb, depth, pose in frames:
        obs_rgb = torch.from_numpy(rgb).float() / 255.0
        obs_depth = torch.from_numpy(depth)
        parts.append(gaussians_from_pixels(obs_depth > 0, obs_rgb, obs_depth, pose, K, cfg))
    return GaussianMap({k: torch.cat([p[k] for p in parts]) for k in parts[0]})


def look_around_episode(root, turns: int = 36):
    """(episode folder, map) of ``turns`` left turns of 10 degrees in a box room, the map made from every
    third frame."""
    scene_file = box_room().export(root / "box.glb")
    scene = load_scene(str(scene_file))
    sim = Simulator(scene, seed=0, config=SIM)
    out = root / "episode"
    writer = EpisodeWriter(out)
    obs = sim.reset()
    meta = {"scene": str(scene_file), "z_up": False, "seed": 0, "policy": "scripted",
            "start_pose": sim.start_pose.tolist(), "config": {"sim": dataclasses.asdict(SIM)}}
    writer.start(meta, obs.pose)
    frames = [(obs.rgb, obs.depth, obs.pose)]
    for step in range(1, turns + 1):
        obs = sim.step("turn_left")
        writer.record(step, "turn_left", obs.pose)
        frames.append((obs.rgb, obs.depth, obs.pose))
    writer.finish({"steps": turns})
    gmap = map_from_ground_truth(frames[::3], sim.K)
    save_ply(gmap, out / "gaussians.ply")
    return out, gmap


@pytest.fixture(scope="module")
def episode(tmp_path_factory):
    """A full 360 degree look-around and its map."""
    return look_around_episode(tmp_path_factory.mktemp("render_eval"))


@pytest.fixture(scope="module")
def quarter_episode(tmp_path_factory):
    """A 90 degree look-around and its map: most of the room was never seen."""
    return look_around_episode(tmp_path_factory.mktemp("quarter"), turns=9)
