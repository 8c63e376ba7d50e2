"""The belt-speed encoder: counts of the belt's travel differenced over a window."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import BeltParams
from exo_ctrl.sensing import BeltEncoder, BeltEncoderParams

H = 1e-3


def test_the_encoder_reads_the_speed_within_its_resolution() -> None:
    params = BeltParams()
    rec = params.new_record()
    enc = BeltEncoder(BeltEncoderParams(), H)
    res = BeltEncoderParams().resolution_m / BeltEncoderParams().window_s
    readings = []
    for k in range(200):
        rec["v"] = 0.583
        rec["x"] = 0.583 * k * H
        readings.append(enc.read(k, rec))
    readings = np.array(readings[10:])
    assert np.all(np.abs(readings - 0.583) <= res * (1 + 1e-9))
    assert abs(readings.mean() - 0.583) < 0.2 * res


def test_bad_encoder_parameters_are_refused() -> None:
    with pytest.raises(InvalidParameter, match="belt encoder resolution must be > 0 m"):
        BeltEncoderParams(resolution_m=0.0)
