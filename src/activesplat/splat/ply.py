"""Standard 3DGS PLY files (binary little endian), readable by common splat viewers.

Vertex properties, all float32, in this order: x y z, nx ny nz (zeros), f_dc_0..2 (SH degree 0,
rgb = 0.5 + C0 f_dc), opacity (logit), scale_0..2 (log), rot_0..3 (quaternion wxyz, unnormalised).
The map stores exactly these raw values, so save -> load is bit-exact. Loading accepts any extra
vertex properties (e.g. f_rest_* of higher SH degrees) and ignores them.

The map's colours are SH degree 0, so the file has no f_rest_* properties (the higher-degree
coefficients). Readers that take the degree from the properties present, or use f_dc only
(antimatter15/splat), read it; the original 3DGS loader (``GaussianModel.load_ply``) asserts
3 (d + 1)^2 - 3 of them for its ``--sh_degree d``, 45 for the default 3. ``save_ply(..., sh_degree=3)``
(``activesplat export DIR --ply FILE --sh-degree 3``) writes them, all zero, between f_dc_2 and opacity
where that repository puts them: the same colours, 62 instead of 17 floats per Gaussian.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from activesplat.errors import InvalidInputError
from activesplat.splat.gaussians import GaussianMap

PLY_FIELDS = (
    "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
    "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
)
_PLY_TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8", "uchar": "u1",
              "uint8": "u1", "char": "i1", "int8": "i1", "short": "<i2", "int16": "<i2", "ushort": "<u2",
              "uint16": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4"}


SH_DEGREES = (0, 1, 2, 3)
"""Spherical-harmonics degrees ``save_ply`` can lay a file out for (the 3DGS range)."""


def ply_fields(sh_degree: int = 0) -> tuple[str, ...]:
    """Vertex properties, in order, of a file laid out for SH degree ``sh_degree``: ``PLY_FIELDS`` with
    3 ((d + 1)^2 - 1) f_rest_* after f_dc_2 (none for degree 0)."""
    if isinstance(sh_degree, bool) or sh_degree not in SH_DEGREES:
        choices = ", ".join(map(str, SH_DEGREES))
        raise InvalidInputError(f"SH degree must be one of {choices}, got {sh_degree!r}")
    rest = tuple(f"f_rest_{i}" for i in range(3 * ((sh_degree + 1) ** 2 - 1)))
    return PLY_FIELDS[:9] + rest + PLY_FIELDS[9:]


def save_ply(gmap: GaussianMap, path: str | Path, sh_degree: int = 0) -> Path:
    """Write ``gmap`` as a 3DGS PLY file; returns the path. ``sh_degree`` > 0 adds the higher-degree
    coefficients f_rest_* as zeros (module docstring)."""
    path = Path(path)
    fields = ply_fields(sh_degree)
    raw = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in gmap.params.items()}
    n = len(gmap)
    data = np.zeros(n, dtype=[(name, "<f4") for name in fields])
    for i, axis in enumerate("xyz"):
        data[axis] = raw["means"][:, i]
    for i in range(3):
        data[f"f_dc_{i}"] = raw["f_dc"][:, i]
        data[f"scale_{i}"] = raw["log_scales"][:, i]
    for i in range(4):
        data[f"rot_{i}"] = raw["quats"][:, i]
    data["opacity"] = raw["opacity_logits"]
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {n}"]
    header += [f"property float {name}" for name in fields]
    header.append("end_header")
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(data.tobytes())
    return path


def _read_header(f, path: Path) -> tuple[int, np.dtype]:
    """Parse the header up to ``end_header``; returns (vertex count, vertex record dtype)."""
    if f.readline().strip() != b"ply":
        raise InvalidInputError(f"{path}: not a PLY file (missing 'ply' magic)")
    count, props, in_vertex, seen_vertex = 0, [], False, False
    while True:
        line = f.readline()
        if not line:
            raise InvalidInputError(f"{path}: PLY header has no end_header")
        words = line.decode("ascii", errors="replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "end_header":
            break
        if words[0] == "format" and words[1:2] != ["binary_little_endian"]:
            raise InvalidInputError(f"{path}: only binary_little_endian PLY is supported, got {words[1:2]}")
        if words[0] == "element":
            if seen_vertex:
                raise InvalidInputError(f"{path}: elements after 'vertex' are not supported")
            in_vertex = words[1] == "vertex"
            if not in_vertex:
                raise InvalidInputError(f"{path}: first PLY element must be 'vertex', got {words[1]!r}")
            seen_vertex, count = True, int(words[2])
        elif words[0] == "property" and in_vertex:
            if words[1] == "list" or words[1] not in _PLY_TYPES:
                raise InvalidInputError(f"{path}: unsupported vertex property {' '.join(words[1:])!r}")
            props.append((words[2], _PLY_TYPES[words[1]]))
    return count, np.dtype(props)


def load_ply(path: str | Path, device: str | torch.device = "cpu") -> GaussianMap:
    """Read a 3DGS PLY file into a :class:`GaussianMap` (raw values as stored)."""
    path = Path(path)
    if not path.is_file():
        raise InvalidInputError(f"{path}: PLY file does not exist")
    with open(path, "rb") as f:
        count, dtype = _read_header(f, path)
        missing = [name for name in PLY_FIELDS if name not in (dtype.names or ()) and name[0] != "n"]
        if missing:
            raise InvalidInputError(f"{path}: not a 3DGS PLY, missing vertex properties {missing}")
        body = f.read(count * dtype.itemsize)
    if len(body) != count * dtype.itemsize:
        raise InvalidInputError(f"{path}: truncated, expected {count} vertices")
    data = np.frombuffer(body, dtype=dtype, count=count)

    def cols(names: list[str]) -> torch.Tensor:
        return torch.from_numpy(np.stack([data[n].astype(np.float32) for n in names], axis=1)).to(device)

    raw = {
        "means": cols(["x", "y", "z"]),
        "f_dc": cols([f"f_dc_{i}" for i in range(3)]),
        "opacity_logits": cols(["opacity"])[:, 0].contiguous(),
        "log_scales": cols([f"scale_{i}" for i in range(3)]),
        "quats": cols([f"rot_{i}" for i in range(4)]),
    }
    try:
        return GaussianMap(raw)
    except InvalidInputError as err:
        raise InvalidInputError(f"{path}: {err}") from None
