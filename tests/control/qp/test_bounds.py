"""The QP's cuff-force bound per body region (control/qp/bounds.py): (thigh, shank).

References: the user's bounds themselves (each cuff's true peak within 5 % of its own
region's bound), ISO/TS 15066's regions (thighs and shanks), and the refusal's threshold
recomputed from the margin's own terms.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from exo_ctrl import cli, simulate
from exo_ctrl.cli.simulate import sim_config
from exo_ctrl.control.qp.bounds import bound_words, cuff_limits
from exo_ctrl.exceptions import CuffBoundTooTight, InvalidParameter
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.scenario import load_scenario
from exo_ctrl.sim import build
from exo_ctrl.sim.scenario_file import document_from_config

THIGHS = [i for i, name in enumerate(CUFF_NAMES) if name.endswith("_thigh")]
SHANKS = [i for i, name in enumerate(CUFF_NAMES) if name.endswith("_shank")]


def test_one_bound_is_every_cuffs_and_two_are_the_thighs_and_the_shanks() -> None:
    np.testing.assert_array_equal(cuff_limits(120.0), np.full(4, 120.0))
    pair = cuff_limits((200.0, 120.0))
    np.testing.assert_array_equal(pair[THIGHS], [200.0, 200.0])
    np.testing.assert_array_equal(pair[SHANKS], [120.0, 120.0])
    assert bound_words(120) == "120 N"
    assert bound_words([200, 120]) == "200 N on the thighs, 120 N on the shanks"
    assert bound_words((130, 130)) == "130 N"


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ((1.0, 2.0, 3.0), "cuff_force_limit must be one bound > 0 [N], or two: (thigh, shank)"),
        ((200.0, 0.0), "cuff_force_limit shank must be > 0 N; got 0.0"),
        (float("nan"), "cuff_force_limit must be a finite number [N]; got nan"),
        ("120", "cuff_force_limit must be a finite number [N]; got '120'"),
    ],
)
def test_a_bound_that_is_not_one_or_two_positive_numbers_is_refused(given, message) -> None:
    with pytest.raises(InvalidParameter) as caught:
        cuff_limits(given)
    assert str(caught.value).startswith(message)


def _cli(*args: str):
    return sim_config(cli.build_parser().parse_args(["simulate", *args]))


def test_the_command_line_and_the_scenario_file_give_the_pair() -> None:
    config = _cli("--controller", "qp", "--cuff-force-limit", "200,120")
    assert config.cuff_force_limit_N == (200.0, 120.0)
    assert _cli("--cuff-force-limit", "140").cuff_force_limit_N == 140.0
    assert list(document_from_config(config)["qp"]["cuff_force_limit_N"]) == [200.0, 120.0]
    again = load_scenario(preset="paper-free-air", overrides=["qp.cuff_force_limit_N=[200, 120]"])
    assert again.config.cuff_force_limit_N == (200.0, 120.0)
    with pytest.raises(InvalidParameter) as caught:
        _cli("--cuff-force-limit", "1,2,3")
    assert str(caught.value) == (
        "--cuff-force-limit must be 1 or 2 comma-separated numbers; got '1,2,3'"
    )


def test_the_qp_holds_each_cuff_within_its_regions_bound() -> None:
    """A spastic patient in free air: shanks at 100 N, thighs at 150 N.

    Each true peak within 5 % of its own bound, and a thigh above the shanks' bound: one
    bound of 100 N for all four keeps the thighs there (measured 72 N).
    """
    base = load_scenario(preset="spastic-qp", overrides=["safety.safety=false"]).config
    loose = simulate(dataclasses.replace(base, cuff_force_limit_N=1000.0)).summary()
    assert min(loose["peak_cuff_force_N"][CUFF_NAMES[c]] for c in SHANKS) > 100.0 * 1.05
    config = dataclasses.replace(base, cuff_force_limit_N=(150.0, 100.0))
    result = simulate(config)
    np.testing.assert_array_equal(result.config.cuff_force_limit_N, (150.0, 100.0))
    peak = np.linalg.norm(result.cuff_force, axis=2).max(axis=0)
    bound = cuff_limits((150.0, 100.0))
    assert (peak <= 1.05 * bound).all(), peak
    assert peak[THIGHS].max() > 100.0  # the thighs' own bound, not the shanks'
    uniform = simulate(dataclasses.replace(base, cuff_force_limit_N=100.0))
    assert np.linalg.norm(uniform.cuff_force, axis=2).max() <= 105.0


def test_a_region_whose_bound_leaves_less_than_the_plans_load_is_refused_by_name() -> None:
    """clinic-bws with the QP: the thighs carry the patient's weight, the shanks far less."""
    config = load_scenario(
        preset="clinic-bws", overrides=["run.controller=qp", "qp.cuff_force_limit_N=1000"]
    ).config
    margin = build(config, start=False).controller.margin
    need = margin.static_N + margin.load_N  # the plan's load plus the margin, per cuff
    assert need[THIGHS].max() > 150.0 > 120.0 > need[SHANKS].max()
    c = int(np.flatnonzero(need > cuff_limits((150.0, 120.0)))[0])  # the first one refused
    with pytest.raises(CuffBoundTooTight) as caught:
        build(dataclasses.replace(config, cuff_force_limit_N=(150.0, 120.0)), start=False)
    text = str(caught.value)
    assert text.startswith(
        "qp.cuff_force_limit_N = [150, 120] N (thigh, shank) cannot be held on the gait with "
        f"period 1.6 s and step_length 0.35 m: the {CUFF_NAMES[c]} cuff's margin of "
        f"{margin.static_N[c]:.1f} N"
    )
    assert text.endswith(
        f"raise the thigh bound to at least {math.ceil(need[c])} N or add cuff sensors "
        "(--cuff-sensors), which shrink the margin"
    )
    setup = build(dataclasses.replace(config, cuff_force_limit_N=(200.0, 120.0)), start=False)
    np.testing.assert_array_equal(setup.controller.record["limit"][0], cuff_limits((200, 120)))
    assert any("200 N on the thighs, 120 N on the shanks" in w for w in setup.notes)
