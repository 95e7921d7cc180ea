"""MapperConfig states a field's own bound, whichever side of it the value lies on: a negative
pixel_stride is not told "must be >= 0" when 0 is refused too."""

import pytest

from activesplat.errors import InvalidInputError
from activesplat.splat.config import MapperConfig, Schedule


@pytest.mark.parametrize("field, values, needle", [
    ("pixel_stride", (0, -1), "MapperConfig.pixel_stride must be >= 1"),
    ("mask_downscale", (0, -3), "MapperConfig.mask_downscale must be >= 1"),
    ("refresh_coarse_factor", (1.0, -2.0), "MapperConfig.refresh_coarse_factor must be > 1"),
    ("init_normal_scale", (0.0, -0.5), "MapperConfig.init_normal_scale must be in (0, 1]"),
    ("densify_voxel_m", (0.0, -0.1), "MapperConfig.densify_voxel_m must be > 0"),
    ("init_opacity", (0.0, -0.2), "MapperConfig.init_opacity must be in (0, 1)"),
    ("lambda_l1", (-0.1,), "MapperConfig.lambda_l1 must be >= 0"),
])
def test_the_real_bound_on_both_sides(field, values, needle):
    for v in values:
        with pytest.raises(InvalidInputError, match=needle.replace("(", r"\(").replace(")", r"\)")):
            MapperConfig(**{field: v})


def test_schedule_bounds():
    with pytest.raises(InvalidInputError, match="map_every >= 1, keyframe_every >= 1 and iterations >= 0"):
        MapperConfig(schedule=Schedule(map_every=0, keyframe_every=1, iterations=2))
