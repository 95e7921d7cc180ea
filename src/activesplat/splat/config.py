"""Configuration of the online Gaussian mapper (paper sec. III-A, docs/protocol.md §2).

Every number of the mapper lives here with a comment naming its source: the paper (eqs. 5-10), the
authors' release (a ROS package on top of SplaTAM), or this project (CPU budget). Where paper and
release disagree the field's comment says which one is the default and why.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from activesplat.errors import InvalidInputError

REMOVED_FIELDS = ("area_budget_slack", "area_budget_cell_m", "densify_median_depth",
                  "densify_represented_tol", "densify_represented_px", "densify_represented_age",
                  "init_max_elongation", "init_slant_fill", "cull_occluded_masks")
"""MapperConfig fields removed since (each with its reason in `activesplat.config.REMOVED`): an older
mapper.json that holds them still loads."""

ADDED_FIELDS = {
    "init_normal_scale": 1.0,
    "densify_front_faces_only": False,
    "edge_band_px": 0,
    "detail_colour_range": None,
    "cull_occluded_margin_m": None,
    "planar_depth": False,
}
"""MapperConfig fields added with a default that is not what the mapper did before them -> the value that
maps as it did (the ``mapper`` entries of `activesplat.config.ADDED`): an older mapper.json that lacks one
was written before it and reads as that value."""


@dataclass(frozen=True)
class Schedule:
    """When to map and when to store a keyframe, counted in accepted frames (docs/protocol.md §2)."""

    map_every: int  # run densification + optimisation on every n-th frame (release: 5, looking around 2)
    keyframe_every: int  # store every n-th frame in the keyframe buffer (release: 5, looking around 1)
    iterations: int  # Adam iterations per mapped frame (release: 2)


@dataclass(frozen=True)
class LearningRates:
    """Adam learning rates of the release (SplaTAM's mapping rates), docs/protocol.md §2.

    The colour parameter is stored as the 3DGS degree-0 SH coefficient f_dc = (rgb - 0.5) / C0 so
    that PLY files round-trip bit-exactly; Adam is invariant to a constant gradient scale, so the
    rate on f_dc is the release's RGB rate divided by C0, which gives the same RGB steps.
    """

    means: float = 1e-3  # project: release 1e-4 (see MapperConfig, "depth bias")
    colors: float = 2.5e-3  # release: on plain RGB, converted to f_dc units by GaussianMap
    quats: float = 1e-3  # release
    opacities: float = 0.05  # release: on the opacity logit
    scales: float = 1e-3  # release: on the log-scale (1e-2 measured as an option: MapperConfig docstring)


@dataclass(frozen=True)
class MapperConfig:
    """Online mapping: initialisation, densification (eq. 8), losses (eqs. 5-7), pruning, schedule.

    Densification threshold ``densify_k`` (eq. 8): the paper uses k = 50 times the median depth error,
    the release k = 2 (only where D_obs < 5 m). Default: 5, between the two. With the paper's 50 the
    depth test never fires in practice: the median error of a mapped view is 1-2 cm, so an object had
    to appear 0.5-1 m in front of the map to get Gaussians, and a table, a chair or a door frame first
    seen against the floor or wall behind it (or a surface mapped from afar and seen again close) stayed
    missing wherever the opacity test was already satisfied. Replays of the 2000-step seed-0 explorations
    (``benchmarks/mapper.py --episode E``, medium-2-plain's, isotropic Gaussians) give train / test PSNR
    30.14 / 27.28 dB at k = 50, 30.72 / 27.69 at 10, 31.31 / 28.12 at 5, 31.47 / 28.05 at 3 and
    31.41 / 28.19 at 2, with 594k, 604k, 632k, 695k and 765k Gaussians: below 5 the gain stops and the
    test fires on the centimetre errors of a still-converging surface, adding Gaussians on top of it.

    Pixel subsampling (``pixel_stride``): the paper adds one Gaussian per valid-depth pixel. On CPU
    the project adds one per ``pixel_stride`` x ``pixel_stride`` block (radius scaled by the
    stride so the surface stays covered), which divides the Gaussian count by stride^2.

    Initial radius and opacity (``init_radius_scale`` 0.75, ``init_opacity`` 0.99; paper 1.0 and 0.5):
    the paper's radius depth/focal at opacity 0.5 leaves a freshly covered surface at O ~ 0.973,
    below tau_o1 = 0.98, so eq. 8 would cover it again on every mapped frame; widening the
    Gaussians fixes that but blurs colour and mixes depths across edges (foreground bleeding
    ~3 px), and the release's 2 iterations per mapped frame cannot sharpen them. Smaller, more
    opaque Gaussians give O >= 0.987 everywhere and ~1.5 px bleeding: on small-0 (first 100 steps)
    keyframe PSNR 27.4 -> 28.7 dB and depth L1 4.4 -> 2.6 cm against (1.25, 0.5).

    Depth bias (``init_opacity`` 0.99, ``lr.means`` 1e-3; were 0.9 and the release's 1e-4): the
    rendered depth is the un-normalised sum w_i z_i of the Gaussians' *centre* depths, composited
    front to back, so on a surface seen at an angle the nearer of two overlapping neighbours gets the
    larger weight and the render sits in front of the truth (signed error -3 cm on small-0), and any
    opacity shortfall 1 - O shortens it by (1 - O) x depth. The fix is letting the depth loss move the
    centres: at 1e-4 m per Adam step a Gaussian moves at most a few mm in its handful of iterations, at
    1e-3 it can absorb the bias; 0.99 (the rasterizer's alpha cap) makes surfaces opaque at once.
    Measured on small-0, first 100 steps of benchmarks/mapper.py (depth L1 of sum w_i z_i / PSNR):
    (0.9, 1e-4) 3.02 cm / 27.6 dB; (0.9, 1e-3) 2.07 cm / 27.05 dB; (0.99, 1e-3) 1.78 cm / 27.05 dB;
    (0.99, 2e-3) 2.03 cm; (0.99, 1e-3, radius 0.6) 2.24 cm (coverage holes); (0.99, 1e-3, w_d = 2)
    1.71 cm (kept the paper's w_d = 1: within noise).

    Flat Gaussians (``init_normal_scale``; paper, release and SplaTAM: isotropic, i.e. 1). An isotropic
    Gaussian on a surface seen at a slant sticks out of it by its radius: seen along the surface (a
    corridor wall, the floor ahead) its disc covers the pixels of the surface farther on, in front of
    them, so the render's depth sits in front of the truth and colours smear along the wall. Below 1,
    a new Gaussian whose pixel lies on one plane is turned to the plane and made this fraction of its
    radius thick along the normal: seen head-on it covers the same pixels as before, seen edge-on it is
    a thin line. The plane comes from the back-projected neighbours ``pixel_stride`` pixels away; pixels
    whose neighbours are not on one plane with them (``init_plane_tol``, inverse depth: a depth edge or a
    curved surface) stay isotropic. Default 0.1 (0.05 gives the same map).
    Replays as above: medium-2-plain train / test 31.31 / 28.12 -> 31.99 / 28.35 dB at k = 5, depth L1
    4.76 / 8.10 -> 4.15 / 7.45 cm; the textured medium-0..3 in docs/mapping.md.

    Back faces (``densify_front_faces_only``; paper and release: every Gaussian counts). Eq. 8's opacity
    test is satisfied by whatever renders opaque, including the Gaussians of a wall's other face or the
    far side of an object: a wall face first seen after its back was mapped renders in the back's colours
    (the room behind), and the depth test does not fire for a wall thinner than k times the median
    error. A flat Gaussian knows which side observed it (its normal is turned to that camera), so the
    eq. 8 / eq. 10 render can leave out the flat Gaussians a view sees from behind; the surface the view
    does see then gets its own Gaussians, in front of the others. Only the masks change: every other
    render (training, planning, evaluation) draws every Gaussian. Replays of the seed-0 explorations
    (flat Gaussians, k = 5): train / test PSNR +0.36 / +0.11 dB on medium-0, +0.84 / +0.59 on
    medium-1, +0.78 / +0.55 on medium-2, +0.82 / +0.89 on medium-3, +0.43 / +0.27 on medium-2-plain,
    for 16-25 % more Gaussians. Requiring the camera 15 degrees behind the plane instead of just behind
    it changed nothing (medium-0: the same PSNR to 0.01 dB).

    Depth edges (``edge_band_px``; paper and release: one Gaussian per pixel, the project one per
    ``pixel_stride`` block). A Gaussian of the stride grid reaches about its radius (1.5 px at stride 2)
    past the pixel it was made from, so at a depth jump the near surface's Gaussians cover a pixel or two
    of what lies behind, and the blended depth there is a mix of both: on the train views of a medium-0
    replay the pixels within 3 px of a depth jump were 6 % of the image and held 44 % of the depth error
    (17 cm on average against 1.5 cm elsewhere). With this field > 0, every masked pixel on the near side
    of a jump and within that many pixels of it gets its own Gaussian with the radius of stride 1, instead
    of the grid's one per block (``densify.depth_edge_band``: a jump is a kink of more than ``edge_jump``
    in the inverse depth, which is affine on a plane, so a far floor whose depth grows fast but smoothly
    is none; only the near side's Gaussians reach over something else, and the far side keeps the grid,
    which leaves no holes where a near object is later removed). Replays of the seed-0 explorations
    (``benchmarks/mapper.py --episode E``; before = ``--set edge_band_px=0``), mean of medium-0..3: train
    PSNR / LPIPS / depth L1 29.29 / 0.267 / 3.05 -> 29.67 / 0.245 / 2.44 cm, test 26.91 / 0.338 / 5.26 ->
    27.09 / 0.321 / 4.80 cm, every house better on both splits, for 9 % more Gaussians and 10 % more
    mapper CPU. Both sides of the jump at pixel resolution, with any 5 % step between neighbours counted
    as a jump, scored higher on the train views and lower on the test views for twice the extra Gaussians.
    It was off until 2026-12-03: the tuning explorations run with it on earlier defaults
    (medium-0..3 x seeds 0, 1) reached 79.47 % instead of 85.94 %, one run losing half the house; with the
    defaults of 2026-11-27 86.21 vs 86.60 % (tuning) and 85.37 vs 86.37 % (fresh medium-100..109). With
    the defaults of 2026-12-02 (docs/mapping.md, "Depth edges, again"): seed 0 on medium-0..3 and fresh
    medium-100..107 level with the grid alone (+0.07 points over the twelve houses, six higher, seven
    within a point), small-0..3 level (+0.03), and the live maps better on every mean: train 31.09 vs
    30.97 dB, test 28.21 vs 28.03 dB, LPIPS 0.246 vs 0.259, depth L1 4.41 vs 4.82 cm; the plain house's
    train views 34.64 vs 32.92 dB. On one replayed trajectory: train depth L1 2.50 -> 2.18 cm, test
    27.87 -> 28.00 dB. Default 2 since. Costs: 5-9 % more Gaussians and 6-10 % more mapper CPU, and a
    second pass over the same trajectory adds 9.8 % Gaussians instead of 8.0 %.

    Colour detail (``detail_colour_range``; paper and release: one Gaussian per pixel everywhere, the
    project one per ``pixel_stride`` block). Where the observed colours of a block span more than this
    (max - min of a channel), the block's detail is finer than one Gaussian can show: every masked pixel
    of it gets its own Gaussian with the radius of stride 1 (``densify.colour_detail``), as the depth
    edges above do at depth jumps. One Gaussian per pixel everywhere (``pixel_stride=1``) measures what
    the stride costs: on the medium-0 / medium-1 replays train PSNR 29.32 / 29.23 -> 30.46 / 30.20 dB,
    LPIPS 0.251 / 0.271 -> 0.134 / 0.154, test PSNR 25.06 / 27.25 -> 24.90 / 27.17 dB, for 4x the
    Gaussians and 3.2x the mapper CPU (docs/mapping.md). With 0.1 (the default), mean of
    the medium-0..3 replays: train PSNR / LPIPS / depth L1 29.29 / 0.267 / 3.05 -> 29.85 / 0.224 /
    2.69 cm, test 26.91 / 0.338 / 5.26 -> 27.11 / 0.301 / 5.08 cm, every house better on both splits, for
    19 % more Gaussians; small-100..103 test 29.99 -> 30.19 dB. The tuning explorations are not worse for
    it (with the explorer's detour rule: 86.21 % without it, 86.49 % with it; docs/benchmark.md "Rooms
    passed on the way"). None = the grid alone.

    Voxel budget (``densify_voxel_m``; paper, release and SplaTAM: none; an option, off). A budget per
    observed surface area: a new Gaussian's centre (its back-projected pixel) must fall in a voxel of this
    size that holds no centre of the map's Gaussians in view, and at most one new centre goes into each
    voxel (a grid pick before a colour-detail one). A plane crossing voxels of size v gets at most one
    centre per v^2 of its area when it is aligned with the voxel axes (2 cm: 2500 per m^2) and up to
    sqrt(3) times that at a slant. The centres the budget keeps get a radius of at least
    ``densify_voxel_radius`` x v, so that the wider spacing leaves no holes for the opacity test (which
    could not fill them again). With ``densify_voxel_depth_test_only`` the opacity test's holes are exempt
    and only eq. 8's depth test is budgeted. Replay of a 4000-step medium-0 exploration
    (``benchmarks/mapper.py --episode E --set densify_voxel_m=...``; docs/mapping.md "A voxel budget"):
    defaults 807k -> 1045k Gaussians from step 2000 to 4000 (+29 %) for +13 % observed surface, keyframes
    31.68 dB / 1.61 cm, render-eval test 30.25 dB / LPIPS 0.202 / 2.23 cm, mapper 166-183 ms per step;
    2 cm: 549k -> 668k (+22 %), 30.05 dB / 2.48 cm, test 29.41 / 0.243 / 2.72 cm, 130 ms; 3 cm: 374k ->
    441k (+18 %), 28.73 dB / 3.71 cm, test 28.54 / 0.301 / 3.48 cm, 105 ms; 2 cm on the depth test only:
    677k -> 829k (+22 %), 30.53 dB / 2.43 cm, test 29.63 / 0.226 / 2.73 cm. Explorations with 2 cm
    (medium-0..3 and medium-100..103, seed 0): completion -0.09 points (SE 0.29), maps -32 %, live
    render-eval test 28.35 -> 27.68 dB, LPIPS 0.248 -> 0.285 on medium-0..3. Memory and time for quality,
    and the growth beyond the new surface does not stop: off.

    Merging (``merge_voxel_m``; paper, release and SplaTAM: none; 3DGS prunes but never merges). After the
    Adam iterations of a mapped frame, the Gaussians of the current view (its frustum, not hidden behind the
    observed depth) are grouped by the voxel of this size holding their centre. A Gaussian is merged into
    its voxel's first (oldest) row when both are flat, their normals are within ``merge_normal_deg`` and
    face the same way (the two faces of a thin object never merge), no colour channel differs by more than
    ``merge_colour_tol``, both are more opaque than ``merge_min_opacity`` and their in-plane radii are
    within ``merge_scale_ratio`` of each other. The merged Gaussian keeps the first one's plane and matches
    the group's centres and in-plane covariances (weights: opacity x area), with the mean colour and the
    largest opacity (splat/merge.py). What the data left different after the iterations (texture, a
    corrected depth) is not merged. Replay of a 4000-step medium-0 exploration (``benchmarks/mapper.py
    --episode E --set merge_voxel_m=V``, docs/mapping.md "Merging Gaussians that render alike"): defaults
    807k -> 1045k Gaussians from step 2000 to 4000, keyframes 31.68 dB / 1.61 cm, render-eval test 30.25 dB
    / SSIM 0.878 / LPIPS 0.202 / 2.23 cm, 166 ms per step; 1 cm: 688k -> 854k, 31.65 dB / 1.65 cm, test
    30.23 / 0.878 / 0.203 / 2.24 cm, 147 ms; 2 cm: 576k -> 723k (-31 %), 31.51 dB / 1.74 cm, test 30.21 /
    0.877 / 0.206 / 2.31 cm, 128 ms. The growth from step 2000 to 4000 (+24-26 % against +29 %) is still
    twice the new surface's (+13 %). Explorations with 1 cm (17 medium runs, seeds 0-1 of the tuning houses
    and fresh medium-101..109): maps -13 %, tuning +1.10 points, fresh -3.10 (-0.21 without one collapse:
    medium-105, 84.25 -> 58.04 %, three rooms off the corridor's far end never reached); the live maps'
    train LPIPS is 0.01-0.02 worse (1 and 2 cm, four maps). Off.

    Coarse refresh (``refresh_coarse_factor``; paper, release and SplaTAM: none). Eq. 8 adds Gaussians
    only where the map is transparent, so a wall first seen from 4 m keeps the 4-5 cm Gaussians it got
    there when the robot walks up to it, and every close view of it renders blurred. A mapped frame first
    finds the Gaussians it sees whole (footprint inside the image, nothing observed in front of them, the
    observed depth at the centre on them) and at least this factor finer than their size (largest scale
    > factor x the radius a new Gaussian would get at their depth, and > factor x
    ``refresh_min_radius_m``), and makes them transparent before the eq. 8 render; the pruning at the
    end of the frame removes them. Where they rendered with opacity above ``refresh_footprint_alpha``,
    new Gaussians are added from this frame's pixels whatever the eq. 8 render says: without that, the
    back face of a wall or the room behind it fills the opacity test and the hole stays (seen as
    see-through walls in the first trial). Only what the current view observes in full is replaced,
    so nothing is lost out of view; the density grows where the robot came close, not with time.

    Planar depth (``planar_depth``; paper, release and SplaTAM: each Gaussian renders its centre's depth).
    A flat Gaussian on a wall seen at a slant renders one depth over its whole footprint, and where the
    footprints overlap the nearer centres, blended first, pull every pixel forward. With this option
    each Gaussian's depth at a pixel follows the slope of its densest point along the pixel rays (its
    tangent plane, for a flat one), capped at the slope of a plane turned 45 degrees from the camera
    (``splat/raster/planar.py``, which has the formula, the cap and why). The depth loss, eq. 8's depth
    test and the median depth of eq. 10 and the planner all see it; render-eval renders such a map the
    same way (it reads ``mapper.json``). Known-map look-arounds of medium-0..3
    (``benchmarks/mapper_ceiling.py``): test depth L1 2.50 -> 2.14 cm, train 2.20 -> 1.87 cm, test PSNR
    30.99 -> 31.03 dB, train 31.52 -> 31.45, LPIPS 0.185 either way. Explorations on fresh houses
    (medium-100..109, seed 0): completion 86.13 -> 85.69 %, within the spread of one seed per house
    (docs/mapping.md).

    Scale learning rate (``lr.scales``; release and SplaTAM 1e-3, 3DGS 5e-3; an option, the release's
    rate stays the default). At 1e-3 per Adam step on the log-scale a Gaussian's size changes by at most
    0.1 % per iteration and it sees a few dozen iterations, so the 2-px grid's Gaussians keep the radius
    they were born with and, along silhouettes, reach past the edge and mix the near and the far depth.
    At 1e-2 the losses shrink them there. 700 frames of the medium-1 tour (``benchmarks/mapper.py
    --episode T --steps 700 --set lr.scales=V``), keyframe PSNR / depth L1: 1e-3 34.06 dB / 1.28 cm, 3e-3
    34.09 / 1.21, 5e-3 34.11 / 1.16, 1e-2 34.10 / 1.10, 2e-2 33.95 / 1.08. Tours of medium-0..3 at 1e-2:
    test depth L1 2.14 -> 1.88 cm, test PSNR 31.03 -> 31.17 dB, LPIPS 0.185 -> 0.183, train depth L1
    1.87 -> 1.68 cm (train LPIPS 0.186 -> 0.191), the plain house test 32.68 -> 32.95 dB, 3-5 % fewer
    Gaussians. Not the default because of what it does to exploration (docs/mapping.md): medium-0..3 x 2 seeds
    86.20 -> 85.73 %; fresh medium-100..109 seed 0 85.69 -> 84.34 %, one
    house collapsing (medium-105, 84.07 -> 70.54 %: room 1's goals had no path from the corridor at step
    957 and stayed closed; with ``--explorer.retry-unreachable`` the same run gives 83.64 %, but the ten
    houses with both options 85.00 %), the other nine 85.87 % either way; small-100..109 88.52 -> 88.31 %,
    their live maps test 30.79 -> 30.67 dB. ``refine`` takes the learning rates of the map's mapper.json.

    Capped birth radius (``init_max_radius_m``, ``init_capped_fill``; paper, release and SplaTAM: the
    projective radius whatever the depth). A new Gaussian's radius grows with its depth (1.2 cm per metre on
    the 2-px grid of the 256-px, 90-degree camera), and the release's scale learning rate leaves it there:
    what the robot first saw from 6-8 m keeps 7-9 cm Gaussians when it walks up to it, which blur close
    views and, at wall ends, reach tens of pixels past the edge. The cap bounds the radius; on its own it
    leaves the far grid's Gaussians apart (the capped radius under half the grid's spacing), which close
    views show as a lattice and as unmapped gaps. With ``init_capped_fill`` every pixel beyond that depth
    gets its own Gaussian (as the depth edges do), so the far surface is covered in one frame. Replays of
    the seed-0 explorations of medium-0..3 (``benchmarks/mapper.py --episode E --set
    init_max_radius_m=0.03``), test PSNR / LPIPS / depth L1, train PSNR / LPIPS: defaults 28.21 dB / 0.246 /
    4.41 cm, 31.09 / 0.169; cap 3 cm 28.33 / 0.214 / 4.20, 31.64 / 0.143, +12 % Gaussians. The same cap in
    the loop (medium-0..3, seed 0): completion -0.34 points (87.08 / 89.17 / 83.21 / 86.75 -> 86.89 / 89.35
    / 82.87 / 85.74 %) and live test 28.21 -> 27.59 dB, depth L1 4.41 -> 5.80 cm, unmapped 0.7 -> 1.6 % of
    the test pixels (train 31.09 -> 31.50 dB): off. Cap and fill: replays 28.38 / 0.218 / 4.04 cm, 31.66 /
    0.144, +14 % Gaussians; in the loop completion -0.18 points, live test 28.21 -> 27.66 dB (two houses
    -1.4 to -1.8 dB on routes that left more unseen, two +0.2 and +0.7), LPIPS 0.246 -> 0.231, depth L1
    4.41 -> 4.85 cm, train 31.09 -> 31.83 dB. Fresh medium-100..107, seed 0: test 28.91 -> 29.10 dB, LPIPS
    0.252 -> 0.226, depth L1 4.11 -> 4.09 cm, completion 85.38 -> 85.18 %, rotations 46.8 -> 44.3 % of the
    actions. Over the twelve houses the test PSNR is level (-0.06 dB) and completion -0.14 points. Four
    houses nobody had run (medium-170..173, seed 0): completion 87.40 -> 86.32 % (all four lower), test
    29.05 -> 29.07 dB, LPIPS 0.257 -> 0.226; medium-2-plain seed 1 lost again (84.19 -> 82.64 %, 29.69 ->
    28.14 dB). Off (docs/mapping.md, "A capped birth radius").

    Floater pruning (``prune_floater_margin_m``): a Gaussian whose centre the current frame sees as free
    space (projects in front of the observed depth by more than the margin, where the whole 3x3
    neighbourhood is valid and farther) is removed; this is how a map with known poses loses
    Gaussians left by a wrong early depth, and what keeps moved objects from staying in the map.

    The eq. 8 / eq. 10 render (``mask_downscale``) runs at half resolution and is upsampled
    (nearest): new Gaussians are placed on a 2-px grid anyway, so a full-resolution render would
    only cost time; the release itself downsamples the eq. 10 mask (to 90x90) before clustering.
    The Adam iterations (``train_downscale``) also render and compare at half resolution (2x2 block
    means of the observation): the Gaussians sit on a 2-px grid, so the map has no finer detail to
    fit; on small-0 (first 100 steps) it cuts mapper time 96 -> 68 ms/step for -0.4 dB PSNR and
    +0.4 cm depth L1. Default now 1 (full resolution): once the depth bias was fixed (below) the
    remaining depth error is foreground bleeding at depth edges, which the half-resolution loss cannot
    see; on small-0 (300 steps) depth L1 2.47 -> 1.93 cm, PSNR 28.0 -> 29.2 dB.
    """

    # --- losses, eqs. 5-7 (paper = release = SplaTAM)
    lambda_l1: float = 0.8  # eq. 5, lambda_1
    lambda_ssim: float = 0.2  # eq. 5, lambda_2
    weight_color: float = 0.5  # eq. 7, w_c
    weight_depth: float = 1.0  # eq. 7, w_d
    ssim_window: int = 11  # pytorch-msssim default Gaussian window (sigma 1.5), as SplaTAM

    # --- optimiser (release)
    lr: LearningRates = field(default_factory=LearningRates)
    """Adam learning rate of each Gaussian parameter (release: SplaTAM's mapping rates)."""
    adam_eps: float = 1e-15  # release / SplaTAM

    # --- initialisation (docs/protocol.md §2)
    init_opacity: float = 0.99  # project: paper/release 0.5 (see class docstring)
    pixel_stride: int = 2  # project: one Gaussian per stride x stride pixels (1 = paper)
    init_radius_scale: float = 0.75  # project: radius = scale * stride * depth / focal (paper 1.0)
    # project: a new Gaussian's radius is at most this (m); None = no cap (paper, release; see class
    # docstring "Capped birth radius")
    init_max_radius_m: float | None = None
    # project: with the cap, every pixel (not one per stride block) where the capped radius is under half
    # the grid's spacing (see class docstring "Capped birth radius")
    init_capped_fill: bool = False
    # project: a new Gaussian on a plane is this fraction of its radius thick along the plane's normal
    # (paper, release and SplaTAM: 1 = isotropic; see class docstring "Flat Gaussians")
    init_normal_scale: float = 0.1
    # project: pixels on the near side of an observed depth jump, within this many pixels of it, each get a
    # Gaussian of stride 1's radius instead of one per pixel_stride block (0 = off; docstring "Depth edges")
    edge_band_px: int = 2
    edge_jump: float = 0.05  # project: a kink of 5 % in the inverse depth is a jump
    # project: in a pixel_stride block whose colours span more than this (max - min of a channel, colours in
    # [0, 1]), every pixel gets a Gaussian of stride 1's radius (None = the grid alone, as before; paper: one
    # Gaussian per pixel everywhere; docstring "Colour detail")
    detail_colour_range: float | None = 0.1
    init_plane_tol: float = 0.02  # project: neighbours within 2 % (inverse depth) count as one plane
    min_depth_m: float = 0.05  # project: depth below this is treated as invalid (sensor noise)

    mask_downscale: int = 2  # project: the eq. 8 / eq. 10 render runs at 1/2 resolution (CPU time)
    train_downscale: int = 1  # project: Adam iterations render/compare at 1/d resolution (release 1)

    # project: each Gaussian's rendered depth follows its plane over its footprint, in every render of the
    # mapper (eq. 7 loss, eq. 8 / eq. 10 masks) and of render-eval (paper and release: the centre's depth,
    # False; see class docstring "Planar depth")
    planar_depth: bool = True

    # --- densification, eq. 8
    densify_opacity: float = 0.98  # tau_o1 (paper)
    densify_k: float = 5.0  # project: k x median depth error (paper 50, release 2; see class docstring)
    densify_max_depth_m: float | None = None  # release applies the depth test only below 5 m; None = off
    # project: at most one new Gaussian centre per voxel of this size (metres), none in a voxel that already
    # holds a centre of the map (see class docstring "Voxel budget"); None = off (paper, release)
    densify_voxel_m: float | None = None
    densify_voxel_radius: float = 1.0  # project: a kept Gaussian's radius is at least this x densify_voxel_m
    densify_voxel_depth_test_only: bool = False  # project: the budget spares the opacity test's holes
    # project: the eq. 8 / eq. 10 render leaves out the flat Gaussians seen from behind (the far face of a
    # wall or an object); False = every Gaussian, as paper and release (see class docstring "Back faces")
    densify_front_faces_only: bool = True

    # --- coarse refresh (project; see class docstring "Coarse refresh"): None = off (paper, release)
    refresh_coarse_factor: float | None = None
    refresh_min_radius_m: float = 0.01  # project: never refresh for Gaussians finer than this x the factor
    refresh_sigmas: float = 2.0  # project: footprint (in sigmas) that must be seen whole and unoccluded
    refresh_footprint_alpha: float = 0.1  # project: where they render above this, eq. 8 adds anew
    refresh_depth_margin_m: float = 0.05  # project: depth tolerance of the visibility test (>= the scale)

    # --- high-loss mask, eq. 10 (computed before densification, on the median depth as the release)
    high_loss_opacity: float = 0.8  # tau_o2 (paper eq. 10)
    high_loss_depth_m: float = 0.3  # epsilon_1 (paper eq. 10)

    # --- pruning (paper: "as in 3DGS"; the release prunes nothing)
    prune_opacity: float = 0.005  # 3DGS min_opacity
    prune_max_scale_m: float = 0.5  # project: 3DGS uses 0.1 x scene extent; indoor extent ~5 m
    # project: optional global cap, the least opaque Gaussians anywhere dropped beyond it. Off (None): it
    # made the map forget rooms mapped early once a multi-room house filled it (see class docstring)
    max_gaussians: int | None = None
    # project: floaters = Gaussians whose centre the current frame sees as free space (in front of the
    # observed depth, min over a 3x3 neighbourhood, by more than the margin); None = off
    prune_floater_margin_m: float | None = 0.1
    prune_floater_window_px: int = 1

    # --- merging (project; see class docstring "Merging"): None = off (paper, release)
    merge_voxel_m: float | None = None  # project: flat Gaussians with centres in one such voxel may merge
    merge_normal_deg: float = 20.0  # project: their normals within this angle, facing the same way
    merge_colour_tol: float = 0.05  # project: no colour channel differs by more (colours in [0, 1])
    merge_min_opacity: float = 0.5  # project: both at least this opaque
    merge_scale_ratio: float = 2.0  # project: in-plane radii within this factor of each other

    # --- schedule (release): normal walking, and the denser look-around schedule
    schedule: Schedule = field(default_factory=lambda: Schedule(map_every=5, keyframe_every=5, iterations=2))
    """Schedule while the agent follows a path (release: map and store a keyframe every 5th frame)."""
    dense_schedule: Schedule = field(default_factory=lambda: Schedule(map_every=2, keyframe_every=1,
                                                                       iterations=2))
    """Denser schedule while the agent looks around on the spot (release: map every 2nd frame, a keyframe
    every frame)."""
    window_overlap: int = 10  # release: keyframes chosen by overlap; window = these + last keyframe + current
    overlap_pixels: int = 1600  # release / SplaTAM: pixels sampled for the overlap test
    overlap_border_px: int = 20  # release / SplaTAM: projections this close to the border do not count
    current_frame_first: bool = True  # project: iteration 0 always trains the current (densified) frame
    # project: Adam with per-row state that moves only the Gaussians a trained view gives a gradient
    # (splat/optim.py); False = the release's one torch Adam over the whole map, whose stale momentum
    # keeps moving Gaussians out of view
    sparse_adam: bool = True
    # project: an Adam iteration renders only the Gaussians in its view frustum that its observed depth does
    # not hide (centre behind every observed depth within cull_window_px by more than this margin, footprint
    # within the window; see gaussians.frustum_rows). None = frustum only. Where the map agrees with the
    # observation the render is unchanged; where a new object hides mapped surfaces, those are left as they
    # are instead of being pushed to explain the object. The eq. 8 / eq. 10 render is not depth-culled.
    cull_occluded_margin_m: float | None = 0.1
    cull_window_px: int = 8

    seed: int = 0  # ours: numpy generator for overlap sampling and window picks

    def __post_init__(self) -> None:
        # the fields with a bound of their own first, so that a negative value gets the real bound (a
        # pixel_stride of -1 "must be >= 1", as 0 does); every other number must be >= 0 (at the end)
        for name in ("schedule", "dense_schedule"):
            s = getattr(self, name)
            if s.map_every < 1 or s.keyframe_every < 1 or s.iterations < 0:
                raise InvalidInputError(f"MapperConfig.{name} needs map_every >= 1, keyframe_every >= 1 and "
                                        f"iterations >= 0, got {s}")
        for name in ("pixel_stride", "mask_downscale", "train_downscale"):
            if getattr(self, name) < 1:
                raise InvalidInputError(f"MapperConfig.{name} must be >= 1, got {getattr(self, name)}")
        if self.refresh_coarse_factor is not None and self.refresh_coarse_factor <= 1.0:
            raise InvalidInputError(f"MapperConfig.refresh_coarse_factor must be > 1 (or None = off), got "
                                    f"{self.refresh_coarse_factor}: a view would replace what it just added")
        if not 0.0 < self.init_normal_scale <= 1.0:
            raise InvalidInputError(f"MapperConfig.init_normal_scale must be in (0, 1], got "
                                    f"{self.init_normal_scale}")
        for name in ("densify_voxel_m", "merge_voxel_m", "init_max_radius_m"):
            if getattr(self, name) is not None and getattr(self, name) <= 0.0:
                raise InvalidInputError(f"MapperConfig.{name} must be > 0 (or None = off), got "
                                        f"{getattr(self, name)}")
        if self.merge_scale_ratio < 1.0 or not 0.0 <= self.merge_min_opacity < 1.0:
            raise InvalidInputError(f"MapperConfig needs merge_scale_ratio >= 1 and merge_min_opacity in "
                                    f"[0, 1), got {self.merge_scale_ratio} and {self.merge_min_opacity}")
        if not 0.0 < self.init_opacity < 1.0:
            raise InvalidInputError(f"MapperConfig.init_opacity must be in (0, 1), got {self.init_opacity}")
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0:
                raise InvalidInputError(f"MapperConfig.{f.name} must be >= 0, got {value}")

    @classmethod
    def from_dict(cls, d: dict) -> MapperConfig:
        """The config back from `dataclasses.asdict` output (mapper.json, checkpoints). A field added since
        the file was written (`ADDED_FIELDS`) reads as the value the map was built with (a config written
        before ``planar_depth`` existed made its map with centre depths: False). A field removed since
        (`REMOVED_FIELDS`) only shaped how the map was built: it is left out, so the map of an older
        version can still be evaluated, refined and viewed."""
        d = {k: v for k, v in d.items() if k not in REMOVED_FIELDS}
        for name, old in ADDED_FIELDS.items():
            d.setdefault(name, old)
        d["lr"] = LearningRates(**d["lr"])
        d["schedule"] = Schedule(**d["schedule"])
        d["dense_schedule"] = Schedule(**d["dense_schedule"])
        return cls(**d)
