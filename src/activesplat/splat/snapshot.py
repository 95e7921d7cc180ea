"""Renders of the online map for many views in a row, of a map that does not change meanwhile (a
replan's panoramas): :class:`MapSnapshot`, made by ``Mapper.snapshot``."""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from activesplat.splat.gaussians import activate, is_flat, seen_from_behind
from activesplat.splat.kernels import quat_normal
from activesplat.splat.lod import LOD_INFLATE, voxel_lod

if TYPE_CHECKING:
    from activesplat.splat.mapper import Mapper


class MapSnapshot:
    """Renders of a :class:`Mapper`'s map as it is at the snapshot, for many views in a row: the replan's
    panoramas, ~30 positions x 3 cameras of an unchanged map. :meth:`Mapper.render` activates the
    parameters of a view's rows (and, for front faces, their normals and flatness) anew for every view;
    here that is done once for every Gaussian, on first use, and each view selects its frustum's rows of
    the result. The images are bit-identical to :meth:`Mapper.render`'s (the same per-row arithmetic;
    ``tests/splat/test_mapper.py``). Valid until the map changes: a call after ``add_frame`` (or after
    the map's size changed) raises RuntimeError.

    With ``lod_voxel_m`` the views are rendered from a coarser copy of the map instead, its Gaussians
    merged per voxel of that size (``splat.lod.voxel_lod``, ``lod_inflate``; the replan's scoring
    panoramas, ``PanoramaConfig.score_lod_voxel_m``): not the same images, about as many fewer Gaussians
    to draw as the merge removes."""

    def __init__(self, mapper: Mapper, lod_voxel_m: float | None = None, lod_inflate: float = LOD_INFLATE):
        self._mapper = mapper
        self._state = (mapper.received, len(mapper.gaussians))
        self._active: tuple[torch.Tensor, ...] | None = None
        self._facing: tuple[torch.Tensor, torch.Tensor] | None = None
        self._lod = None if lod_voxel_m is None else (float(lod_voxel_m), float(lod_inflate))
        self._params: dict[str, torch.Tensor] | None = None

    def __call__(self, pose, K=None, width: int | None = None, height: int | None = None,
                 front_alpha: bool = False, behind_margin_deg: float = 0.0):
        """:meth:`Mapper.render` of the snapshot's map (same arguments, same outputs)."""
        m = self._mapper
        if (m.received, len(m.gaussians)) != self._state:
            raise RuntimeError("MapSnapshot: the map changed since the snapshot was taken; take a new one")
        pose, K, width, height = m._camera(pose, K, width, height)
        with torch.no_grad():
            if self._params is None:
                self._params = {name: t.detach() for name, t in m.gaussians.params.items()}
                if self._lod is not None:
                    self._params = voxel_lod(self._params, *self._lod)
            p = self._params
            if self._active is None:
                self._active = activate(p)
            rows = m._view_rows(pose, K, width, height, params=p)
            active = [t.index_select(0, rows) for t in self._active]
            if not front_alpha:
                return m._draw(pose, K, width, height, tuple(active))
            if self._facing is None:
                self._facing = (is_flat(p["log_scales"]), quat_normal(p["quats"]))
            flat, normal = (t.index_select(0, rows) for t in self._facing)
            behind = seen_from_behind(flat, normal, active[0], pose[:3, 3], behind_margin_deg)
            return m._draw_front(pose, K, width, height, tuple(active), behind)
