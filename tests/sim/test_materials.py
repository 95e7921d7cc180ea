"""Materials as glTF defines them: per-material textures and samplers (repeat, mirrored
repeat, clamp), two materials on one mesh, vertex colours times texture, node transforms, texture
transforms; bad textures warn and fall back to the base colour; KTX2 gives a clear error.

Each glb is written by hand here (JSON + one binary chunk), independent of the package's writer, and
the sensor's pixels are compared with texel colours computed from the glTF sampler definitions."""

import base64
import io
import json
import struct

import numpy as np
import pytest
from PIL import Image

from activesplat.errors import SceneError
from activesplat.geometry import intrinsics
from activesplat.sim import SimConfig, Simulator, load_scene
from activesplat.sim.gltf import GltfWarning, read_gltf, write_glb
from activesplat.sim.materials import CLAMP_TO_EDGE, MIRRORED_REPEAT, REPEAT
from activesplat.sim.scene import Scene
from activesplat.sim.sensor import RGBDSensor

RNG = np.random.default_rng(7)
CHECKER = RNG.integers(0, 256, size=(4, 4, 3), dtype=np.uint8)
"""A 4 x 4 texture of random colours: every texel distinct, so a wrong texel index shows."""
QUAD = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
"""Unit quad in the z = 0 plane facing +z: the sensor looks at it from z = 1."""
TRIS = np.array([[0, 1, 2], [0, 2, 3]], np.uint16)


def _png(image: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG")
    return buf.getvalue()


def make_gltf(primitives, materials, images=(), samplers=(), textures=(), nodes=None, glb=True):
    """bytes of a glTF: primitives = [(attributes {name: float32/uint16 array}, indices, material)];
    images = [bytes | {"uri": ...}]; materials, samplers, textures as glTF JSON dicts."""
    chunks, views, accessors = [], [], []

    def view(data: bytes) -> int:
        offset = sum(len(c) for c in chunks)
        chunks.append(data + b"\0" * (-len(data) % 4))
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(data)})
        return len(views) - 1

    def accessor(array) -> int:
        array = np.asarray(array)
        kind = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}[1 if array.ndim == 1 else array.shape[1]]
        ctype = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint8): 5121}[array.dtype]
        acc = {"bufferView": view(array.tobytes()), "componentType": ctype, "count": len(array), "type": kind}
        if array.dtype == np.uint8:
            acc["normalized"] = True
        accessors.append(acc)
        return len(accessors) - 1

    prims = []
    for attributes, indices, material in primitives:
        prim = {"attributes": {k: accessor(v) for k, v in attributes.items()},
                "indices": accessor(np.asarray(indices, np.uint16).ravel())}
        if material is not None:
            prim["material"] = material
        prims.append(prim)
    image_json = []
    for image in images:
        if isinstance(image, dict):
            image_json.append(image)
        else:
            image_json.append({"bufferView": view(image), "mimeType": "image/png"})
    binary = b"".join(chunks)
    header = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
              "nodes": nodes or [{"mesh": 0}], "meshes": [{"primitives": prims}],
              "materials": list(materials),
              "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(binary)}]}
    for key, value in (("images", image_json), ("samplers", samplers), ("textures", textures)):
        if value:
            header[key] = list(value)
    if not glb:
        encoded = base64.b64encode(binary).decode()
        header["buffers"][0]["uri"] = "data:application/octet-stream;base64," + encoded
        return json.dumps(header).encode()
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text
    body += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def textured_material(name="checker", factor=(1.0, 1.0, 1.0, 1.0), texture=0):
    return {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(factor),
                                                   "baseColorTexture": {"index": texture}}}


def quad_uv(lo: float, hi: float) -> np.ndarray:
    """glTF UVs of QUAD spanning [lo, hi] along s (x) and t (down the quad, so t = lo at the top)."""
    return np.array([[lo, hi], [hi, hi], [hi, lo], [lo, lo]], np.float32)


def view_quad(path, width=48):
    """Render the quad of `path` from (0.5, 0.5, 1) looking at -z with the nearest-texel filter (the one
    the numpy reference implements): (rgb, face shade, hit x, hit y)."""
    vertices, faces, surface = read_gltf(path)
    import trimesh

    sensor = RGBDSensor(trimesh.Trimesh(vertices, faces, process=False), surface=surface,
                        config=SimConfig(texture_filter="nearest"))
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])  # OpenCV camera: x right, y down, z forward = -z world
    pose[:3, 3] = [0.5, 0.5, 1.0]
    K = intrinsics(width, width, 90.0)
    rgb, depth = sensor.render(pose, K, width, width)
    reference = sensor.render_reference(pose, K, width, width)  # numpy shading of the numba kernel
    np.testing.assert_array_equal(rgb, reference[0])
    np.testing.assert_array_equal(depth, reference[1])
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(width) + 0.5)
    x = 0.5 + (cols - K[0, 2]) / K[0, 0]
    y = 0.5 - (rows - K[1, 2]) / K[1, 1]
    assert np.allclose(depth[(x > 0.01) & (x < 0.99) & (y > 0.01) & (y < 0.99)], 1.0, atol=1e-5)
    return rgb, sensor.face_shade[0], x, y


def reference_texel(s: np.ndarray, n: int, mode: int) -> np.ndarray:
    """Nearest texel index of continuous texture coordinate s (texture widths) under a wrap mode,
    written from the glTF / OpenGL definitions."""
    if mode == REPEAT:
        f = s - np.floor(s)
    elif mode == MIRRORED_REPEAT:
        k = np.floor(s)
        f = np.where(k % 2 == 1, 1.0 - (s - k), s - k)
    else:
        f = np.clip(s, 0.0, 1.0)
    return np.clip(np.floor(f * n), 0, n - 1).astype(int)


def away_from_texel_edges(*coords):
    """Pixels whose texture coordinate is not within 2 % of a texel edge (float rounding)."""
    keep = True
    for c in coords:
        frac = (c * 4) % 1.0
        keep = keep & (frac > 0.02) & (frac < 0.98)
    return keep


@pytest.mark.parametrize(("mode", "lo", "hi"), [(REPEAT, 0.0, 3.0), (MIRRORED_REPEAT, 0.0, 3.0),
                                                (CLAMP_TO_EDGE, -1.0, 2.0), (REPEAT, -2.0, 4.0)])
def test_sampler_wrap_modes(tmp_path, mode, lo, hi):
    path = tmp_path / "quad.glb"
    path.write_bytes(make_gltf([({"POSITION": QUAD, "TEXCOORD_0": quad_uv(lo, hi)}, TRIS, 0)],
                               [textured_material()], images=[_png(CHECKER)],
                               samplers=[{"wrapS": mode, "wrapT": mode, "magFilter": 9728}],
                               textures=[{"source": 0, "sampler": 0}]))
    rgb, shade, x, y = view_quad(path)
    s, t = lo + (hi - lo) * x, lo + (hi - lo) * (1.0 - y)
    inside = (x > 0.01) & (x < 0.99) & (y > 0.01) & (y < 0.99) & away_from_texel_edges(s, t)
    expected = CHECKER[reference_texel(t, 4, mode), reference_texel(s, 4, mode)]
    expected = np.clip(expected / np.float32(255) * shade * 255 + 0.5, 0, 255).astype(np.uint8)
    assert inside.sum() > 500
    np.testing.assert_array_equal(rgb[inside], expected[inside])


def test_no_sampler_means_repeat_and_two_materials_on_one_mesh(tmp_path):
    """Triangle 0 uses the checker (no sampler: REPEAT) with a colour factor, triangle 1 a plain
    material; each keeps its own colour, with no atlas bleeding between them."""
    path = tmp_path / "two.glb"
    uv = quad_uv(0.0, 3.0)
    prims = [({"POSITION": QUAD, "TEXCOORD_0": uv}, TRIS[:1], 0), ({"POSITION": QUAD}, TRIS[1:], 1)]
    materials = [textured_material(factor=(0.5, 1.0, 0.25, 1.0)),
                 {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1.0]}}]
    path.write_bytes(make_gltf(prims, materials, images=[_png(CHECKER)], textures=[{"source": 0}]))
    rgb, shade, x, y = view_quad(path)
    s, t = 3.0 * x, 3.0 * (1.0 - y)
    inside = (x > 0.01) & (x < 0.99) & (y > 0.01) & (y < 0.99) & away_from_texel_edges(s, t)
    first = inside & (x - y > 0.02)  # triangle 0 (corners 0, 1, 2) lies below the diagonal y = x
    second = inside & (y - x > 0.02)
    texel = CHECKER[reference_texel(t, 4, REPEAT), reference_texel(s, 4, REPEAT)] / 255.0
    expected = texel * np.float32([0.5, 1.0, 0.25]) * shade * 255
    np.testing.assert_allclose(rgb[first], expected[first], atol=1.0)
    np.testing.assert_allclose(rgb[second], np.broadcast_to(np.float32([0.8, 0.1, 0.1]) * shade * 255,
                                                            (second.sum(), 3)), atol=1.0)


def test_vertex_colours_multiply_the_texture(tmp_path):
    """COLOR_0 (normalized uint8 RGBA) varies linearly in x; pixel = texel * colour(x) * shade."""
    colours = np.array([[255, 255, 255, 255], [128, 64, 255, 255], [128, 64, 255, 255], [255, 255, 255, 255]],
                       np.uint8)
    path = tmp_path / "vc.gltf"
    path.write_bytes(make_gltf([({"POSITION": QUAD, "TEXCOORD_0": quad_uv(0.0, 1.0), "COLOR_0": colours},
                                 TRIS, 0)], [textured_material()], images=[_png(CHECKER)],
                               textures=[{"source": 0}], glb=False))
    rgb, shade, x, y = view_quad(path)
    inside = (x > 0.01) & (x < 0.99) & (y > 0.01) & (y < 0.99) & away_from_texel_edges(x, 1.0 - y)
    c = colours[:2, :3] / 255.0
    vertex = (1.0 - x)[..., None] * c[0] + x[..., None] * c[1]
    texel = CHECKER[reference_texel(1.0 - y, 4, REPEAT), reference_texel(x, 4, REPEAT)] / 255.0
    np.testing.assert_allclose(rgb[inside], (texel * vertex * shade * 255)[inside], atol=1.0)


def test_node_transforms_texcoord_sets_and_texture_transform(tmp_path):
    """A node's TRS is applied; the material samples TEXCOORD_1 through KHR_texture_transform."""
    path = tmp_path / "node.glb"
    info = {"index": 0, "texCoord": 1,
            "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "scale": [2.0, 2.0]}}}
    material = {"name": "t", "pbrMetallicRoughness": {"baseColorTexture": info}}
    nodes = [{"children": [1], "translation": [10.0, 0.0, 0.0]},
             {"mesh": 0, "scale": [2.0, 2.0, 2.0], "rotation": [0.0, 0.0, 0.0, 1.0]}]
    path.write_bytes(make_gltf([({"POSITION": QUAD, "TEXCOORD_0": np.zeros((4, 2), np.float32),
                                  "TEXCOORD_1": quad_uv(0.0, 1.0)}, TRIS, 0)], [material],
                               images=[_png(CHECKER)], textures=[{"source": 0}], nodes=nodes))
    vertices, _, surface = read_gltf(path)
    np.testing.assert_allclose(vertices, QUAD * 2.0 + [10.0, 0.0, 0.0])
    np.testing.assert_allclose(surface.face_uv[0], quad_uv(0.0, 1.0)[TRIS[0]] * 2.0 + [0.5, 0.0])


def _room(tmp_path, material, images=(), textures=(), uv=None, name="room.glb", glb=True, drop_uv=False):
    """A 4 x 4 m floor (walkable) with one material; UVs 0..2 unless given (none with drop_uv)."""
    floor = np.array([[0, 0, 0], [0, 0, 4], [4, 0, 4], [4, 0, 0]], np.float32)
    attrs = {"POSITION": floor, "TEXCOORD_0": quad_uv(0.0, 2.0) if uv is None else uv}
    if drop_uv:
        del attrs["TEXCOORD_0"]
    path = tmp_path / name
    path.write_bytes(make_gltf([(attrs, TRIS, 0)], [material], images=images, textures=textures, glb=glb))
    return path


def _floor_colour(scene: Scene) -> np.ndarray:
    sim = Simulator(scene, seed=0)
    sim.reset()
    for _ in range(3):
        obs = sim.step("look_down")
    return obs.rgb[obs.depth > 0].reshape(-1, 3)


@pytest.mark.parametrize("problem", ["missing_file", "not_an_image", "nan_uv", "no_uv"])
def test_bad_textures_warn_and_show_the_base_colour(tmp_path, problem):
    material = textured_material("oak floor", factor=(0.2, 0.6, 0.4, 1.0))
    uv = None
    if problem == "missing_file":
        images = [{"uri": "textures/oak.png"}]
    elif problem == "not_an_image":
        images = [b"GIF89a but not really an image at all"]
    else:
        images = [_png(CHECKER)]
        uv = quad_uv(0.0, 2.0)
        uv[0] = np.nan  # a corner of both triangles
    path = _room(tmp_path, material, images=images, textures=[{"source": 0}], uv=uv,
                 name="room.gltf" if problem == "missing_file" else "room.glb",
                 glb=problem != "missing_file", drop_uv=problem == "no_uv")
    with pytest.warns(GltfWarning, match="material 'oak floor'.*base colour"):
        scene = load_scene(path)
    colours = _floor_colour(scene)
    shade = scene.sensor_for(Simulator(scene, seed=0).config).face_shade[0]
    assert len(colours) > 100
    expected = np.broadcast_to(np.float32([0.2, 0.6, 0.4]) * shade * 255, colours.shape)
    np.testing.assert_allclose(colours, expected, atol=1.0)


def test_ktx2_textures_give_a_clear_error(tmp_path):
    material = textured_material("scan")
    textures = [{"extensions": {"KHR_texture_basisu": {"source": 0}}}]
    ktx2 = {"uri": "scan.ktx2", "mimeType": "image/ktx2"}
    path = _room(tmp_path, material, images=[ktx2], textures=textures)
    with pytest.raises(SceneError, match="KHR_texture_basisu.*PNG"):
        load_scene(path)
    with_fallback = [{"source": 1, "extensions": {"KHR_texture_basisu": {"source": 0}}}]
    path = _room(tmp_path, material, images=[{"uri": "scan.ktx2", "mimeType": "image/ktx2"}, _png(CHECKER)],
                 textures=with_fallback, name="fallback.glb")
    scene = load_scene(path)  # the PNG fallback source is used
    np.testing.assert_array_equal(scene.surface.materials[0].texture, CHECKER)


def test_obj_with_missing_texture_warns(tmp_path):
    (tmp_path / "room.mtl").write_text("newmtl carpet\nKd 0.5 0.2 0.1\nmap_Kd carpet.jpg\n")
    lines = ["mtllib room.mtl", "v 0 0 0", "v 0 0 4", "v 4 0 4", "v 4 0 0", "usemtl carpet",
             "f 1 2 3", "f 1 3 4"]
    (tmp_path / "room.obj").write_text("\n".join(lines) + "\n")
    with pytest.warns(GltfWarning, match="material 'carpet'.*carpet.jpg"):
        scene = load_scene(tmp_path / "room.obj")
    colours = _floor_colour(scene)
    assert len(colours) > 100 and np.ptp(colours, axis=0).max() == 0  # one flat colour, no confetti


def test_writer_round_trip_keeps_materials_and_samplers(tmp_path):
    path = tmp_path / "quad.glb"
    path.write_bytes(make_gltf([({"POSITION": QUAD, "TEXCOORD_0": quad_uv(0.0, 3.0)}, TRIS[:1], 0),
                                ({"POSITION": QUAD, "TEXCOORD_0": quad_uv(-1.0, 2.0)}, TRIS[1:], 1)],
                               [textured_material("a"), textured_material("b", texture=1)],
                               images=[_png(CHECKER)],
                               samplers=[{"wrapS": MIRRORED_REPEAT, "wrapT": CLAMP_TO_EDGE}],
                               textures=[{"source": 0, "sampler": 0}, {"source": 0}]))
    vertices, faces, surface = read_gltf(path)
    again = write_glb(tmp_path / "again.glb", vertices, faces, surface)
    rgb_a, *_ = view_quad(path)
    rgb_b, *_ = view_quad(again)
    np.testing.assert_array_equal(rgb_a, rgb_b)
    _, _, back = read_gltf(again)
    assert [(m.name, m.wrap_s, m.wrap_t) for m in back.materials] == [("a", MIRRORED_REPEAT, CLAMP_TO_EDGE),
                                                                       ("b", REPEAT, REPEAT)]
