"""glTF 2.0 (.glb / .gltf) reading and writing with materials as the file defines them.

`read_gltf` walks the default scene's node tree (matrix or TRS transforms applied) and returns one
triangle list with, per triangle, its material, corner UVs (the TEXCOORD set the material's base
colour texture names, after KHR_texture_transform) and corner vertex colours (COLOR_0). Each
material keeps its base colour factor, its own decoded texture and its sampler's wrap modes (see
sim/materials.py for how the sensor shades them). Supported: triangles, strips and fans; indexed or
not; interleaved (byteStride), normalized and sparse accessors; embedded, data-URI and external
buffers and images (PNG, JPEG and anything else Pillow reads, EXT_texture_webp);
KHR_materials_pbrSpecularGlossiness (diffuse) and KHR_materials_unlit.

Bad textures never stop a load: a missing or undecodable image, or non-finite UVs, give a warning
naming the material, and its faces show the base colour. Things that cannot be shown faithfully
stop it with a SceneError naming the extension: KTX2 / Basis Universal textures
(KHR_texture_basisu) without a PNG/JPEG fallback, Draco or meshopt compressed geometry.
"""

from __future__ import annotations

import base64
import io
import json
import os
import struct
import warnings
from pathlib import Path
from urllib.parse import unquote

import numpy as np
from PIL import Image

from activesplat.episode import remove_quietly
from activesplat.errors import SceneError, cannot_write
from activesplat.sim.materials import (
    CLAMP_TO_EDGE,
    MIRRORED_REPEAT,
    REPEAT,
    WRAP_MODES,
    Material,
    Surface,
    image_rgb,
)

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
              5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
_UNSUPPORTED_GEOMETRY = {
    "KHR_draco_mesh_compression": "Draco-compressed geometry",
    "EXT_meshopt_compression": "meshopt-compressed geometry",
}
BASISU_HELP = ("KTX2 / Basis Universal textures (KHR_texture_basisu) cannot be decoded here: no maintained "
               "Python decoder installs without the native libktx (pyktx builds only against it). Convert "
               "the textures to PNG or JPEG (e.g. KTX-Software: `ktx extract --transcode rgba8 in.ktx2 "
               "out.png`) and load the file that references them")


class GltfWarning(UserWarning):
    """A texture problem that falls back to the material's base colour."""


class _Gltf:
    """The JSON header, binary buffers and accessor reader of one file."""

    def __init__(self, path: Path):
        self.path = path
        data = path.read_bytes()
        binary = None
        if data[:4] == b"glTF":
            header, binary = _split_glb(data, path)
        else:
            try:
                header = json.loads(data.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise SceneError(f"{path} is neither binary glTF nor glTF JSON ({exc})") from None
        if not isinstance(header, dict) or "asset" not in header:
            raise SceneError(f"{path} is not a glTF 2.0 file (no 'asset')")
        self.header = header
        for name in header.get("extensionsRequired", []):
            if name in _UNSUPPORTED_GEOMETRY:
                raise SceneError(f"{path} requires {name} ({_UNSUPPORTED_GEOMETRY[name]}), which this "
                                 f"simulator does not decode; decompress it first (e.g. `gltf-transform "
                                 f"copy in.glb out.glb`)")
        self.buffers = [self._buffer(i, b, binary) for i, b in enumerate(header.get("buffers", []))]
        self._accessors: dict[int, np.ndarray] = {}

    def _uri_bytes(self, uri: str) -> bytes:
        if uri.startswith("data:"):
            return base64.b64decode(uri.split(",", 1)[1])
        return (self.path.parent / unquote(uri)).read_bytes()

    def _buffer(self, index: int, buffer: dict, binary: bytes | None) -> bytes:
        if "uri" not in buffer:
            if binary is None:
                raise SceneError(f"{self.path}: buffer {index} has no uri and the file has no binary chunk")
            return binary
        try:
            return self._uri_bytes(buffer["uri"])
        except (OSError, ValueError) as exc:
            raise SceneError(f"{self.path}: cannot read buffer {buffer['uri']!r} ({exc})") from None

    def view_bytes(self, index: int) -> bytes:
        view = self.header["bufferViews"][index]
        start = view.get("byteOffset", 0)
        return self.buffers[view["buffer"]][start : start + view["byteLength"]]

    def accessor(self, index: int) -> np.ndarray:
        """(count, components) array; normalized integers become floats in [0, 1] / [-1, 1]."""
        if index not in self._accessors:
            self._accessors[index] = self._read_accessor(self.header["accessors"][index])
        return self._accessors[index]

    def _read_accessor(self, acc: dict) -> np.ndarray:
        dtype = np.dtype(_COMPONENT[acc["componentType"]]).newbyteorder("<")
        ncomp, count = _NCOMP[acc["type"]], acc["count"]
        if "bufferView" in acc:
            view = self.header["bufferViews"][acc["bufferView"]]
            buffer = self.buffers[view["buffer"]]
            offset = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
            stride = view.get("byteStride") or dtype.itemsize * ncomp
            if count and offset + stride * (count - 1) + dtype.itemsize * ncomp > len(buffer):
                raise SceneError(f"{self.path}: an accessor reads past the end of its buffer")
            out = np.ndarray((count, ncomp), dtype, buffer, offset, (stride, dtype.itemsize)).copy()
        else:
            out = np.zeros((count, ncomp), dtype)
        if "sparse" in acc:
            sparse = acc["sparse"]
            idx_dtype = np.dtype(_COMPONENT[sparse["indices"]["componentType"]]).newbyteorder("<")
            n = sparse["count"]
            raw = self.view_bytes(sparse["indices"]["bufferView"])
            idx = np.frombuffer(raw, idx_dtype, n, sparse["indices"].get("byteOffset", 0))
            raw = self.view_bytes(sparse["values"]["bufferView"])
            values = np.frombuffer(raw, dtype, n * ncomp, sparse["values"].get("byteOffset", 0))
            out[idx.astype(np.int64)] = values.reshape(n, ncomp)
        if acc.get("normalized") and dtype.kind in "iu":
            out = np.maximum(out.astype(np.float32) / np.iinfo(dtype).max, -1.0)
        return out


def _split_glb(data: bytes, path: Path) -> tuple[dict, bytes | None]:
    if len(data) < 20:
        raise SceneError(f"{path}: binary glTF shorter than its header")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != _GLB_MAGIC or version != 2:
        raise SceneError(f"{path}: not a glTF 2.0 binary (version {version})")
    pos, header, binary = 12, None, None
    while pos + 8 <= min(length, len(data)):
        size, kind = struct.unpack_from("<II", data, pos)
        chunk = data[pos + 8 : pos + 8 + size]
        if kind == _JSON_CHUNK and header is None:
            try:
                header = json.loads(chunk.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise SceneError(f"{path}: unreadable glTF JSON chunk ({exc})") from None
        elif kind == _BIN_CHUNK and binary is None:
            binary = chunk
        pos += 8 + size + (-size % 4)
    if header is None:
        raise SceneError(f"{path}: binary glTF without a JSON chunk")
    return header, binary


# --------------------------------------------------------------------------- materials
def warn_material(path: Path, material: str | None, problem: str) -> None:
    """A GltfWarning shown as `FILE:0: GltfWarning: material 'NAME': PROBLEM; ...` (no source line)."""
    warnings.warn_explicit(f"material {material!r}: {problem}; its faces show the base colour", GltfWarning,
                           filename=str(path), lineno=0)


def _texture_source(gltf: _Gltf, texture: dict, material: str) -> int | None:
    """Image index of a texture: EXT_texture_webp, else `source`; KTX2 without a fallback stops."""
    ext = texture.get("extensions", {})
    if "EXT_texture_webp" in ext:
        return ext["EXT_texture_webp"].get("source")
    source = texture.get("source")
    images = gltf.header.get("images", [])
    is_ktx2 = source is not None and images[source].get("mimeType") == "image/ktx2"
    if source is not None and images[source].get("uri", "").lower().endswith(".ktx2"):
        is_ktx2 = True
    if "KHR_texture_basisu" in ext and (source is None or is_ktx2) or is_ktx2:
        raise SceneError(f"{gltf.path}: material {material!r}: {BASISU_HELP}")
    return source


def _decode_image(gltf: _Gltf, index: int, material: str, cache: dict) -> np.ndarray | None:
    if index in cache:
        return cache[index]
    image = gltf.header["images"][index]
    where = image.get("uri", f"image {index}")[:80]
    try:
        if "bufferView" in image:
            blob = gltf.view_bytes(image["bufferView"])
        else:
            blob = gltf._uri_bytes(image["uri"])
    except (OSError, ValueError, KeyError) as exc:
        warn_material(gltf.path, material, f"texture {where!r} is missing ({type(exc).__name__})")
        cache[index] = None
        return None
    try:
        with Image.open(io.BytesIO(blob)) as img:
            cache[index] = image_rgb(img)
    except Exception as exc:  # Pillow raises many types on unknown or corrupt images
        warn_material(gltf.path, material, f"texture {where!r} is not an image format Pillow reads "
                                   f"({type(exc).__name__})")
        cache[index] = None
    return cache[index]


def _read_material(gltf: _Gltf, index: int | None, images: dict) -> tuple[Material, int, dict | None]:
    """(Material, TEXCOORD set of its base colour texture, KHR_texture_transform or None)."""
    if index is None:
        return Material("default", np.ones(3)), 0, None
    mat = gltf.header["materials"][index]
    name = mat.get("name") or f"material {index}"
    pbr = mat.get("pbrMetallicRoughness", {})
    factor = pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
    info = pbr.get("baseColorTexture")
    spec_gloss = mat.get("extensions", {}).get("KHR_materials_pbrSpecularGlossiness")
    if spec_gloss is not None and "pbrMetallicRoughness" not in mat:
        factor = spec_gloss.get("diffuseFactor", factor)
        info = spec_gloss.get("diffuseTexture")
    material = Material(name, np.clip(np.asarray(factor[:3], dtype=np.float64), 0.0, 1.0))
    if info is None:
        return material, 0, None
    textures = gltf.header.get("textures", [])
    if not 0 <= info.get("index", -1) < len(textures):
        warn_material(gltf.path, name, f"texture index {info.get('index')} does not exist")
        return material, 0, None
    texture = textures[info["index"]]
    source = _texture_source(gltf, texture, name)
    if source is None:
        warn_material(gltf.path, name, "texture has no image")
        return material, 0, None
    material.texture = _decode_image(gltf, source, name, images)
    if material.texture is not None and "sampler" in texture:
        sampler = gltf.header["samplers"][texture["sampler"]]
        for axis in ("S", "T"):
            mode = sampler.get(f"wrap{axis}", REPEAT)
            if mode not in WRAP_MODES:
                warn_material(gltf.path, name, f"unknown wrap{axis} {mode} (REPEAT used)")
                mode = REPEAT
            setattr(material, f"wrap_{axis.lower()}", mode)
    transform = info.get("extensions", {}).get("KHR_texture_transform")
    tex_coord = (transform or {}).get("texCoord", info.get("texCoord", 0))
    return material, tex_coord, transform


def _transform_uv(uv: np.ndarray, transform: dict | None) -> np.ndarray:
    """KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv."""
    if not transform:
        return uv
    sx, sy = transform.get("scale", [1.0, 1.0])
    ox, oy = transform.get("offset", [0.0, 0.0])
    r = transform.get("rotation", 0.0)
    c, s = np.cos(r), np.sin(r)
    u, v = uv[:, 0] * sx, uv[:, 1] * sy
    return np.stack([c * u + s * v + ox, -s * u + c * v + oy], axis=1)


# --------------------------------------------------------------------------- geometry
def _node_matrix(node: dict) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major
    t = np.eye(4)
    t[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    r = np.eye(4)
    r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    return t @ r @ np.diag([*node.get("scale", [1.0, 1.0, 1.0]), 1.0])


def _mesh_instances(header: dict):
    """(mesh index, 4x4 world matrix) of every node with a mesh in the default scene."""
    nodes = header.get("nodes", [])
    scenes = header.get("scenes", [])
    if scenes:
        roots = scenes[header.get("scene", 0)].get("nodes", [])
    else:  # no scene: every node that is nobody's child
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    stack = [(i, np.eye(4), 0) for i in roots]
    while stack:
        i, parent, depth = stack.pop()
        if depth > 256:
            raise SceneError("glTF node hierarchy deeper than 256 (a cycle?)")
        world = parent @ _node_matrix(nodes[i])
        if "mesh" in nodes[i]:
            yield nodes[i]["mesh"], world
        stack += [(c, world, depth + 1) for c in nodes[i].get("children", [])]


def _triangles(gltf: _Gltf, prim: dict, n_vertices: int) -> np.ndarray | None:
    mode = prim.get("mode", 4)
    if "indices" in prim:
        idx = gltf.accessor(prim["indices"]).reshape(-1).astype(np.int64)
    else:
        idx = np.arange(n_vertices, dtype=np.int64)
    if mode == 4:
        tri = idx[: len(idx) // 3 * 3].reshape(-1, 3)
    elif mode == 5:  # strip: alternate winding
        k = np.arange(max(len(idx) - 2, 0))
        tri = np.stack([idx[k], idx[k + 1 + k % 2], idx[k + 2 - k % 2]], axis=1)
    elif mode == 6:  # fan
        k = np.arange(1, max(len(idx) - 1, 1))
        tri = np.stack([np.full(len(k), idx[0]) if len(idx) else k, idx[k], idx[k + 1]], axis=1)
    else:
        return None  # points and lines have no surface
    if len(tri) and (tri.max() >= n_vertices or tri.min() < 0):
        raise SceneError(f"{gltf.path}: a primitive's indices point past its vertices")
    return tri


def read_gltf(path) -> tuple[np.ndarray, np.ndarray, Surface]:
    """(vertices (V, 3) float64 world frame, faces (F, 3) int64, Surface) of a .glb / .gltf file."""
    gltf = _Gltf(Path(path))
    header = gltf.header
    materials: dict[int | None, tuple[Material, int, dict | None]] = {}
    images: dict[int, np.ndarray | None] = {}
    verts, faces, face_mat, face_uv, face_col = [], [], [], [], []
    n_verts, any_uv, any_col = 0, False, False
    for mesh_index, world in _mesh_instances(header):
        for prim in header["meshes"][mesh_index].get("primitives", []):
            attrs = prim.get("attributes", {})
            if "POSITION" not in attrs:
                continue
            pos = gltf.accessor(attrs["POSITION"]).astype(np.float64)
            tri = _triangles(gltf, prim, len(pos))
            if tri is None or len(tri) == 0:
                continue
            key = prim.get("material")
            if key not in materials:
                materials[key] = _read_material(gltf, key, images)
            material, tex_coord, transform = materials[key]
            verts.append(pos @ world[:3, :3].T + world[:3, 3])
            faces.append(tri + n_verts)
            n_verts += len(pos)
            face_mat.append(np.full(len(tri), list(materials).index(key), np.int32))
            uv = None
            if material.texture is not None and f"TEXCOORD_{tex_coord}" in attrs:
                uv = gltf.accessor(attrs[f"TEXCOORD_{tex_coord}"]).astype(np.float64)
                uv = _transform_uv(uv, transform)
                any_uv = True
            if uv is None and material.texture is not None:  # no TEXCOORD_n: NaN, so the base colour shows
                uv = np.full((len(pos), 2), np.nan)
                any_uv = True
            face_uv.append((uv if uv is not None else np.zeros((len(pos), 2)))[tri].astype(np.float32))
            col = None
            if "COLOR_0" in attrs:
                col = gltf.accessor(attrs["COLOR_0"])[:, :3].astype(np.float32)
                any_col = True
            face_col.append((col if col is not None else np.ones((len(pos), 3), np.float32))[tri])
    if not faces:
        raise SceneError(f"mesh file {path} contains no triangles")
    vertices = np.concatenate(verts)
    surface = Surface([m for m, _, _ in materials.values()], np.concatenate(face_mat),
                      np.concatenate(face_uv) if any_uv else None,
                      np.concatenate(face_col) if any_col else None)
    _check_uvs(surface, Path(path))
    return vertices, np.concatenate(faces), surface


def _check_uvs(surface: Surface, path: Path) -> None:
    """Faces with non-finite UVs lose their texture (warning per material)."""
    if surface.face_uv is None:
        return
    bad = ~np.isfinite(surface.face_uv).all(axis=(1, 2))
    if not bad.any():
        return
    for m in np.unique(surface.face_material[bad]):
        material = surface.materials[m]
        if material.texture is not None:
            count = int((bad & (surface.face_material == m)).sum())
            warn_material(path, material.name, f"{count} faces have no or non-finite (NaN/inf) UVs")
    surface.drop_texture(bad)


# --------------------------------------------------------------------------- writing
def write_glb(path, vertices: np.ndarray, faces: np.ndarray, surface: Surface) -> Path:
    """Binary glTF of a mesh and its Surface: one primitive per material (its faces in order,
    unshared corners so per-corner UVs and colours survive), PNG textures, NEAREST samplers with the
    material's wrap modes. read_gltf of the file gives back the same triangles and pixels. Written under a
    temporary name and renamed when complete."""
    path = Path(path)
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    chunks: list[bytes] = []
    header: dict = {"asset": {"version": "2.0", "generator": "activesplat"}, "scene": 0,
                    "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}], "meshes": [{"primitives": []}],
                    "materials": [], "accessors": [], "bufferViews": [], "buffers": []}
    offset = 0

    def add_view(data: bytes, target: int | None = None) -> int:
        nonlocal offset
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(data)}
        if target:
            view["target"] = target
        header["bufferViews"].append(view)
        chunks.append(data + b"\0" * (-len(data) % 4))
        offset += len(data) + (-len(data) % 4)
        return len(header["bufferViews"]) - 1

    def add_accessor(array: np.ndarray, kind: str) -> int:
        array = np.ascontiguousarray(array, dtype=np.float32)
        acc = {"bufferView": add_view(array.tobytes(), 34962), "componentType": 5126,
               "count": len(array), "type": kind}
        if kind == "VEC3":
            acc["min"], acc["max"] = array.min(axis=0).tolist(), array.max(axis=0).tolist()
        header["accessors"].append(acc)
        return len(header["accessors"]) - 1

    for m, material in enumerate(surface.materials):
        sel = np.flatnonzero(surface.face_material == m)
        if len(sel) == 0:
            continue
        entry = {"name": material.name, "doubleSided": True,
                 "pbrMetallicRoughness": {"baseColorFactor": [*map(float, material.base_colour), 1.0],
                                          "metallicFactor": 0.0, "roughnessFactor": 1.0}}
        attrs = {"POSITION": add_accessor(tri[sel].reshape(-1, 3), "VEC3")}
        if material.texture is not None and surface.face_uv is not None:
            png = io.BytesIO()
            Image.fromarray(material.texture).save(png, format="PNG")
            image = {"bufferView": add_view(png.getvalue()), "mimeType": "image/png"}
            header.setdefault("images", []).append(image)
            header.setdefault("samplers", []).append({"magFilter": 9728, "minFilter": 9728,
                                                      "wrapS": material.wrap_s, "wrapT": material.wrap_t})
            header.setdefault("textures", []).append({"source": len(header["images"]) - 1,
                                                      "sampler": len(header["samplers"]) - 1})
            entry["pbrMetallicRoughness"]["baseColorTexture"] = {"index": len(header["textures"]) - 1}
            attrs["TEXCOORD_0"] = add_accessor(surface.face_uv[sel].reshape(-1, 2), "VEC2")
        if surface.face_colour is not None:
            attrs["COLOR_0"] = add_accessor(surface.face_colour[sel].reshape(-1, 3), "VEC3")
        header["materials"].append(entry)
        primitive = {"attributes": attrs, "material": len(header["materials"]) - 1}
        header["meshes"][0]["primitives"].append(primitive)
    binary = b"".join(chunks)
    header["buffers"].append({"byteLength": len(binary)})
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    tmp = path.with_name(path.name + ".partial")  # renamed when complete: no half-written .glb is left
    try:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with tmp.open("wb") as f:
                f.write(struct.pack("<III", _GLB_MAGIC, 2, total))
                f.write(struct.pack("<II", len(text), _JSON_CHUNK) + text)
                f.write(struct.pack("<II", len(binary), _BIN_CHUNK) + binary)
            os.replace(tmp, path)
        except OSError as exc:
            raise cannot_write(path, exc) from None
    except BaseException:
        remove_quietly(tmp)  # never a half-written file
        raise
    return path


__all__ = ["BASISU_HELP", "CLAMP_TO_EDGE", "MIRRORED_REPEAT", "REPEAT", "GltfWarning", "read_gltf",
           "write_glb"]
