"""Angles with a physical range are refused outside it, in one message that states the range (below it
as above it)."""

import pytest

from activesplat.errors import InvalidInputError
from activesplat.planning.config import HighLossConfig, PanoramaConfig, RotationCandidateConfig
from activesplat.planning.controller import ControllerConfig
from activesplat.planning.explorer_config import ExplorerConfig


@pytest.mark.parametrize("make, ok, bad, needle", [
    (lambda v: ExplorerConfig(bootstrap_pitch_deg=v), (0, 45, 90), (-1, 90.5, 200),
     "ExplorerConfig.bootstrap_pitch_deg must be in [0, 90] degrees"),
    (lambda v: ExplorerConfig(controller=ControllerConfig(max_pitch_deg=v)), (0, 45, 90), (95, 200),
     "ControllerConfig.max_pitch_deg must be in [0, 90] degrees"),
    (lambda v: PanoramaConfig(back_face_margin_deg=v), (0, 15, 89), (-1, 90, 120),
     "PanoramaConfig.back_face_margin_deg must be in [0, 90) degrees"),
    (lambda v: RotationCandidateConfig(min_offset_deg=v), (0, 15, 180), (-5, 181),
     "RotationCandidateConfig.min_offset_deg must be in [0, 180] degrees"),
    (lambda v: HighLossConfig(min_offset_deg=v), (0, 180), (-5, 270),
     "HighLossConfig.min_offset_deg must be in [0, 180] degrees"),
    (lambda v: HighLossConfig(drop_within_deg=v), (0, 5, 180), (-1, 200),
     "HighLossConfig.drop_within_deg must be in [0, 180] degrees"),
])
def test_angles_out_of_range(make, ok, bad, needle):
    for v in ok:
        make(v)
    for v in bad:
        with pytest.raises(InvalidInputError) as exc:
            make(v)
        assert str(exc.value).startswith(needle) and str(exc.value).endswith(f"got {v}"), str(exc.value)
