"""RGB-D sensor: z-depth against an independent ray/plane computation, the 10 m range, view-independent
shading, textures, determinism of images and poses per seed."""

import numpy as np
import pytest

from activesplat.geometry import camera_pose, intrinsics
from activesplat.sim import SimConfig, Simulator, box_room


def _sensor_pose(floor_position, yaw, pitch):
    """The camera 1.25 m above a floor position, at (yaw, pitch) (`geometry.camera_pose` conventions)."""
    return camera_pose(np.add(floor_position, [0.0, 1.25, 0.0]), yaw, pitch)


def _box_depth(pose, K, width, height, size):
    """Analytic z-depth inside the box [0, size]: for rays with camera-z 1 the ray parameter of the
    first wall plane hit is the z-depth."""
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    cam = np.stack([(cols - K[0, 2]) / K[0, 0], (rows - K[1, 2]) / K[1, 1], np.ones_like(cols)], axis=-1)
    d = cam @ pose[:3, :3].T
    o = pose[:3, 3]
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, (np.asarray(size) - o) / d, np.where(d < 0, -o / d, np.inf))
    return t.min(axis=-1)


@pytest.mark.parametrize(("position", "yaw_deg", "pitch_deg"), [((1.5, 0.0, 1.2), 30.0, -15.0),
                                                                ((3.1, 0.0, 0.4), -125.0, 45.0),
                                                                ((2.0, 0.0, 2.0), 200.0, -45.0)])
def test_depth_equals_ray_plane_intersection(flat_box, position, yaw_deg, pitch_deg):
    sim = Simulator(flat_box, seed=0)
    pose = _sensor_pose(position, np.deg2rad(yaw_deg), np.deg2rad(pitch_deg))
    _, depth = sim.render(pose)
    expected = _box_depth(pose, sim.K, 256, 256, (4.0, 2.6, 3.0))
    np.testing.assert_allclose(depth, expected, atol=2e-4, rtol=1e-5)


def test_depth_beyond_10_m_reads_zero():
    long_room = box_room(width=14.0, depth=3.0, textured=False)
    sim = Simulator(long_room, seed=0, config=SimConfig(width=64, height=48, hfov_deg=70.0))
    pose = _sensor_pose([0.5, 0.0, 1.5], np.pi / 2, 0.0)  # looking along +x
    _, depth = sim.render(pose)
    expected = _box_depth(pose, sim.K, 64, 48, (14.0, 2.6, 3.0))
    assert (expected > 10.0).sum() > 100 and (expected < 10.0).sum() > 100
    np.testing.assert_array_equal(depth[expected > 10.0 + 1e-3], 0.0)
    near = expected < 10.0 - 1e-3
    np.testing.assert_allclose(depth[near], expected[near], rtol=1e-5, atol=2e-4)
    np.testing.assert_allclose(sim.K[0, 0], 32.0 / np.tan(np.deg2rad(35.0)))


def test_shading_is_view_independent(flat_box):
    """A flat-coloured face reads one colour from every viewpoint and at every pixel."""
    sim = Simulator(flat_box, seed=0)
    colours = []
    for position, yaw in (((1.0, 0.0, 2.5), 0.0), ((3.5, 0.0, 0.5), 0.7), ((2.0, 0.0, 1.5), 2.5)):
        rgb, depth = sim.render(_sensor_pose(position, yaw, np.deg2rad(-30.0)))
        pose = _sensor_pose(position, yaw, np.deg2rad(-30.0))
        floor_y = _floor_mask(pose, sim.K, depth)
        floor = rgb[floor_y]
        assert len(floor) > 1000
        assert (floor == floor[0]).all()
        colours.append(floor[0])
    np.testing.assert_array_equal(colours[0], colours[1])
    np.testing.assert_array_equal(colours[0], colours[2])


def _floor_mask(pose, K, depth):
    """Pixels whose back-projected point lies on the floor (y < 1 mm), away from the walls."""
    rows, cols = np.indices(depth.shape) + 0.5
    cam = np.stack([(cols - K[0, 2]) / K[0, 0], (rows - K[1, 2]) / K[1, 1], np.ones_like(cols)], -1)
    world = (cam * depth[..., None]) @ pose[:3, :3].T + pose[:3, 3]
    inner = (world[..., 0] > 0.05) & (world[..., 0] < 3.95) & (world[..., 2] > 0.05) & (world[..., 2] < 2.95)
    return (depth > 0) & (np.abs(world[..., 1]) < 1e-3) & inner


def test_textured_surfaces_are_not_flat(box, flat_box, small0):
    pose = _sensor_pose([2.0, 0.0, 2.6], np.pi, np.deg2rad(-30.0))  # looking along -z
    textured, _ = Simulator(box, seed=0).render(pose)
    flat, _ = Simulator(flat_box, seed=0).render(pose)
    assert textured[128:, 64:192].reshape(-1, 3).std(axis=0).min() > 5.0  # wood floor and plaster wall
    assert len(np.unique(flat.reshape(-1, 3), axis=0)) <= 6
    obs = Simulator(small0, seed=0).reset()
    assert len(np.unique(obs.rgb.reshape(-1, 3), axis=0)) > 50
    gradient = np.abs(np.diff(obs.rgb.astype(np.int16), axis=1)).mean()
    assert gradient > 0.5  # texture detail between neighbouring pixels, not only face edges


def test_determinism_per_seed(small0):
    def run(seed):
        sim = Simulator(small0, seed=seed)
        frames = [sim.reset()]
        for action in ("turn_left", "move_forward", "look_down", "move_forward", "turn_right"):
            frames.append(sim.step(action))
        return frames

    a, b, c = run(3), run(3), run(4)
    for fa, fb in zip(a, b, strict=True):
        np.testing.assert_array_equal(fa.rgb, fb.rgb)
        np.testing.assert_array_equal(fa.depth, fb.depth)
        np.testing.assert_array_equal(fa.pose, fb.pose)
        assert fa.step == fb.step and fa.collided == fb.collided
    assert not np.allclose(a[0].pose, c[0].pose)
    sim = Simulator(small0, seed=3)
    start = sim.reset()
    sim.step("move_forward")
    np.testing.assert_array_equal(sim.reset().pose, start.pose)  # reset returns to the same start
    assert sim.reset().step == 0


def test_explicit_start_pose_is_kept(box):
    pose = _sensor_pose([1.0, 0.0, 2.0], 0.4, 0.0)
    sim = Simulator(box, start=pose)
    np.testing.assert_allclose(sim.reset().pose, pose, atol=1e-12)
    np.testing.assert_allclose(sim.start_pose, pose, atol=1e-12)


@pytest.mark.parametrize("name", ["small0", "plain"])
def test_compiled_render_equals_numpy_reference(small0, name):
    """The numba kernel of RGBDSensor.render gives the same bytes as `shade` in numpy (nearest texels)."""
    from activesplat.sim import load_scene

    scene = small0 if name == "small0" else load_scene("small-0-plain")
    sim = Simulator(scene, seed=1, config=SimConfig(texture_filter="nearest"))
    sim.reset()
    for action in ("turn_left", "look_down", "turn_left", "turn_left", "look_up", "look_up"):
        sim.act(action)
        rgb, depth = sim.sensor.render(sim.pose, sim.K, 96, 64)
        ref_rgb, ref_depth = sim.sensor.render_reference(sim.pose, sim.K, 96, 64)
        np.testing.assert_array_equal(rgb, ref_rgb)
        np.testing.assert_array_equal(depth, ref_depth)


def test_threaded_blocks_and_depth_alone_give_the_same_images(small0, monkeypatch):
    """A render split into row blocks over threads is the single-thread render, byte for byte (area filter,
    textured house), and `depth` alone is the depth of `render`."""
    import numba

    from activesplat.sim import sensor

    sim = Simulator(small0, seed=0)
    sim.reset()
    poses = []
    for action in ("turn_left", "look_down", "move_forward", "turn_right"):
        sim.act(action)
        poses.append(sim.pose)
    monkeypatch.setattr(sensor, "BLOCK_PIXELS", 1000)  # 96 x 64 = 6144 pixels: up to 6 blocks
    monkeypatch.setattr(numba, "get_num_threads", lambda: 4)
    blocks = [sim.sensor.render(p, sim.K, 96, 64) for p in poses]
    monkeypatch.setattr(numba, "get_num_threads", lambda: 1)
    for pose, (rgb, depth) in zip(poses, blocks, strict=True):
        ref_rgb, ref_depth = sim.sensor.render(pose, sim.K, 96, 64)
        np.testing.assert_array_equal(rgb, ref_rgb)
        np.testing.assert_array_equal(depth, ref_depth)
        np.testing.assert_array_equal(sim.depth(pose, 96, 64), sim.render(pose, 96, 64)[1])


def test_world_rays_are_the_rotated_camera_rays(small0):
    """The compiled world rays are the float32 sums of the numpy expression, bit for bit, for any pixel
    range."""
    sensor = small0.sensor_for(SimConfig())
    pose = _sensor_pose([1.0, 0.3, 2.0], 0.7, -0.4)
    K = intrinsics(40, 30, 90.0)
    rays, rot = sensor._camera_rays(K, 40, 30), pose[:3, :3].astype(np.float32)
    expected = rays[:, :1] * rot[:, 0] + rays[:, 1:2] * rot[:, 1] + rays[:, 2:] * rot[:, 2]
    origins, dirs = sensor.world_rays(pose, K, 40, 30)
    np.testing.assert_array_equal(dirs, expected)
    np.testing.assert_array_equal(origins, np.broadcast_to(pose[:3, 3].astype(np.float32), (1200, 3)))
    origins, dirs = sensor.world_rays(pose, K, 40, 30, 100, 250)
    np.testing.assert_array_equal(dirs, expected[100:250])
    assert origins.shape == (150, 3)
