"""Texture filtering of the simulated camera (SimConfig.texture_filter): the "area" filter against
supersampled nearest-texel renders, the atlas split into tiles, and bad settings."""

import dataclasses
import math

import numpy as np
import pytest

from activesplat.errors import InvalidInputError
from activesplat.geometry import camera_pose, intrinsics
from activesplat.sim import SimConfig, Simulator
from activesplat.sim.materials import Surface
from activesplat.sim.sensor import RGBDSensor
from activesplat.sim.textures import ATLAS_MATERIAL, TILE_PX, tile_surface

NEAREST = SimConfig(texture_filter="nearest")


def _psnr(a, b) -> float:
    mse = np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2) / 255.0**2
    return -10.0 * math.log10(max(mse, 1e-10))


def _views(scene, n=4):
    """Level and tilted-down views from the middle of the house (floors at grazing angles)."""
    sim = Simulator(scene, seed=3, config=NEAREST)
    start = sim.reset().pose[:3, 3]
    return [camera_pose(start, math.radians(yaw), math.radians(pitch))
            for yaw, pitch in ((0, 0), (90, -30), (180, -15), (270, 0))[:n]]


def _supersampled(sensor, pose, size, factor):
    K = intrinsics(size * factor, size * factor, 90.0)
    rgb, _ = sensor.render(pose, K, size * factor, size * factor)
    return rgb.reshape(size, factor, size, factor, 3).astype(np.float64).mean(axis=(1, 3))


def test_area_filter_is_close_to_a_supersampled_camera(small0):
    """Each pixel of a real camera integrates the light over its area: 8 x 8 nearest-texel rays per pixel,
    averaged, stand for it. The area filter is much closer to that than one nearest texel per pixel."""
    size = 48
    K = intrinsics(size, size, 90.0)
    nearest = small0.sensor_for(NEAREST)
    area = small0.sensor_for(SimConfig())
    gain = []
    for pose in _views(small0):
        reference = _supersampled(nearest, pose, size, 8)
        a, depth_a = area.render(pose, K, size, size)
        n, depth_n = nearest.render(pose, K, size, size)
        np.testing.assert_array_equal(depth_a, depth_n)  # the filter changes colours only
        gain.append(_psnr(a, reference) - _psnr(n, reference))
    assert np.mean(gain) > 2.0, gain
    assert min(gain) > 0.0, gain


def test_atlas_tiles_keep_the_nearest_texels(small0):
    """The atlas split into one texture per tile reads the same nearest texel under every pixel."""
    surface = small0.surface
    assert surface.materials[0].name == ATLAS_MATERIAL
    tiled = tile_surface(surface)
    assert len(tiled.materials) > 1
    assert all(m.texture.shape == (TILE_PX, TILE_PX, 3) for m in tiled.materials)
    renamed = dataclasses.replace(surface.materials[0], name="not the atlas")
    untiled = Surface([renamed], surface.face_material, surface.face_uv, surface.face_colour)
    assert tile_surface(untiled) is untiled  # only the named atlas is split
    K = intrinsics(64, 64, 90.0)
    a = RGBDSensor(small0.mesh, NEAREST, surface=surface)
    b = RGBDSensor(small0.mesh, NEAREST, surface=untiled)
    for pose in _views(small0, 2):
        np.testing.assert_array_equal(a.render(pose, K, 64, 64)[0], b.render(pose, K, 64, 64)[0])


def test_untextured_scene_is_the_same_with_either_filter():
    from activesplat.sim import load_scene

    scene = load_scene("small-0-plain")
    K = intrinsics(48, 48, 90.0)
    for pose in _views(scene, 2):
        a = scene.sensor_for(SimConfig()).render(pose, K, 48, 48)
        n = scene.sensor_for(NEAREST).render(pose, K, 48, 48)
        np.testing.assert_array_equal(a[0], n[0])


@pytest.mark.parametrize("bad", [{"texture_filter": "bilinear"}, {"texture_max_anisotropy": 0}])
def test_bad_filter_settings_are_refused(bad):
    with pytest.raises(InvalidInputError, match=next(iter(bad))):
        SimConfig(**bad)


def _tiling_room():
    """A 4 m box room seen from inside, its faces cycling through three 16 x 16 / 8 x 32 / 32 x 4 textures
    with every wrap mode, UVs from about -3 to 5 (negative texel indices on every axis)."""
    import trimesh

    from activesplat.sim.materials import CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT, Material

    room = trimesh.creation.box(extents=[4.0, 3.0, 4.0])
    room.apply_translation([2.0, 1.5, 2.0])
    room.invert()
    room = room.subdivide().subdivide()
    rng = np.random.default_rng(0)
    modes = (REPEAT, MIRRORED_REPEAT, CLAMP_TO_EDGE)
    materials = [Material(f"m{k}", np.ones(3), rng.integers(0, 256, (h, w, 3)).astype(np.uint8),
                          modes[k % 3], modes[(k + 1) % 3])
                 for k, (h, w) in enumerate([(16, 16), (8, 32), (32, 4)] * 2)]
    tri = room.vertices[room.faces]
    uv = np.stack([tri[..., 0] + 0.5 * tri[..., 1], tri[..., 2] - tri[..., 1]], axis=-1) * 2.0 - 3.0
    surface = Surface(materials, np.arange(len(room.faces)) % len(materials), uv.astype(np.float32))
    return room, surface


@pytest.mark.parametrize("config", [SimConfig(), NEAREST])
def test_power_of_two_wrap_is_the_modulo(config):
    """With every texture side a power of two the kernels wrap texel indices with a bitwise and; the
    general modulo gives the same bytes (every wrap mode, negative indices, both filters)."""
    mesh, surface = _tiling_room()
    sensor = RGBDSensor(mesh, config, surface=surface)
    assert sensor._pow2
    K = intrinsics(64, 48, 90.0)
    poses = [camera_pose(np.array([2.0, 1.2, 2.0]), math.radians(yaw), math.radians(pitch))
             for yaw, pitch in ((0, 0), (120, -40), (240, 35))]
    fast = [sensor.render(pose, K, 64, 48) for pose in poses]
    sensor._pow2 = False
    for pose, (rgb, depth) in zip(poses, fast, strict=True):
        ref_rgb, ref_depth = sensor.render(pose, K, 64, 48)
        assert rgb.std() > 10  # textured, not a flat colour
        np.testing.assert_array_equal(rgb, ref_rgb)
        np.testing.assert_array_equal(depth, ref_depth)
