"""Collisions: seeded random walks never bring the agent's axis (hence the camera) closer than the
agent radius to any geometry between the floor step margin and the agent height. Checked against the
mesh itself with horizontal rays (trimesh's ray caster), not against the navigability map."""

import numpy as np
import pytest
import trimesh
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from activesplat.sim import SimConfig, Simulator

CFG = SimConfig()
N_DIRECTIONS = 360
HEIGHTS = np.arange(CFG.step_margin + 0.01, CFG.agent_height + 1e-9, 0.02)


def _random_walk(sim: Simulator, n_steps: int, seed: int) -> np.ndarray:
    """Forward until blocked, then a random number of turns; returns the distinct camera positions."""
    rng = np.random.default_rng(seed)
    positions = [sim.reset().pose[:3, 3]]
    moved, turns = 0, []
    for _ in range(n_steps):
        action = turns.pop() if turns else ("move_forward" if rng.random() < 0.9 else "turn_left")
        obs = sim.step(action)
        if obs.collided:
            turns = [str(rng.choice(["turn_left", "turn_right"]))] * int(rng.integers(2, 12))
        moved += action == "move_forward" and not obs.collided
        positions.append(obs.pose[:3, 3])
    assert moved > n_steps // 3, "the walk hardly moved; the test would prove nothing"
    return np.unique(np.round(np.array(positions), 9), axis=0)


def _horizontal_clearance(mesh: trimesh.Trimesh, positions: np.ndarray, floor: float) -> np.ndarray:
    """Per position: the nearest hit of horizontal rays (1 deg apart) from the agent axis at heights
    floor + 0.11 ... floor + 1.5 m, cast with a separate Embree scene of the mesh."""
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32))
    angles = np.deg2rad(np.arange(N_DIRECTIONS))
    dirs = np.stack([np.cos(angles), np.zeros_like(angles), np.sin(angles)], axis=1)
    dirs = np.tile(dirs, (len(HEIGHTS), 1)).astype(np.float32)
    heights = floor + np.repeat(HEIGHTS, N_DIRECTIONS)
    out = np.empty(len(positions))
    for k, p in enumerate(positions):
        origins = np.stack([np.full_like(heights, p[0]), heights, np.full_like(heights, p[2])], axis=1)
        out[k] = scene.run(origins.astype(np.float32), dirs, query="DISTANCE").min()
    return out


WALKS = [("box", 0, 300), ("box", 1, 300), ("small0", 0, 600), ("small0", 5, 600)]


@pytest.mark.parametrize(("scene_name", "seed", "n_steps"), WALKS)
def test_random_walk_keeps_radius_from_geometry(request, scene_name, seed, n_steps):
    scene = request.getfixturevalue(scene_name)
    sim = Simulator(scene, seed=seed, config=SimConfig(width=8, height=8))  # images are not needed
    positions = _random_walk(sim, n_steps, seed)
    clearance = _horizontal_clearance(scene.mesh, positions, scene.floor_height)
    assert np.all(clearance < 100.0)  # closed rooms: every position sees walls (misses read 1e37)
    assert clearance.min() >= CFG.agent_radius, f"closest approach {clearance.min():.4f} m"
    np.testing.assert_allclose(positions[:, 1], scene.floor_height + CFG.sensor_height)


def test_clearance_check_detects_a_violation(box):
    """The independent check itself: a point 5 cm from the x = 0 wall reads 0.05 m."""
    clearance = _horizontal_clearance(box.mesh, np.array([[0.05, 1.25, 1.5]]), 0.0)
    assert clearance[0] == pytest.approx(0.05, abs=1e-4)
