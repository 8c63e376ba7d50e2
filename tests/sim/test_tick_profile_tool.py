"""tools/tick_profile.py --boundary's kernel capture: faithful, complete, and undone.

The capture wraps every compiled kernel the tick can call from Python (the
package's module globals and the run's objects' attributes) for a few
ticks.  A run so wrapped must log what an unwrapped twin logs, bit for bit;
every kernel must be back in place afterwards; each captured call must have
its kernel's arguments; and the kernels the tick calls unconditionally must
be counted once a tick.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pinocchio as pin
import pytest

from exo_ctrl.sim import Runner, SimConfig, build

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import tick_profile as tool  # noqa: E402
from bench import SCENARIOS  # noqa: E402

WARM, TICKS = 5, 120


@pytest.mark.parametrize("scenario", ["ct", "ct_contact"])
def test_the_capture_is_faithful_complete_and_undone(scenario: str) -> None:
    config = SimConfig(**{**SCENARIOS[scenario], "duration_s": 0.3})
    wrapped, twin = Runner(build(config), fuse=False), Runner(build(config), fuse=False)
    for k in range(WARM):  # the kernels compiled (or loaded) before any is wrapped
        wrapped.tick(k, k)
        twin.tick(k, k)
    kernels = [(holder, name, obj) for holder, name, obj in tool._kernel_holders(wrapped)]
    calls = tool._captured_calls(wrapped, WARM, TICKS)
    for k in range(WARM, WARM + TICKS):
        twin.tick(k, k)
    # the wrappers passed every call through: the same rows, bit for bit
    assert wrapped.log[: WARM + TICKS].tobytes() == twin.log[: WARM + TICKS].tobytes()
    # and every kernel is back where it was found
    assert all(getattr(holder, name) is obj for holder, name, obj in kernels)
    for name, (kernel, per_tick, args) in calls.items():
        assert len(args) == kernel.py_func.__code__.co_argcount, name
        assert 0.0 < per_tick <= 1.0, name
    # Runner.tick calls these on every tick (the plant's once a step, one step a tick)
    every = (
        "sim.log_rows.write_measured",
        "sim.log_rows.write_applied",
        "plant.step.drift_and_forces",
    )
    for name in every:
        assert calls[name][1] == 1.0, name
    if scenario == "ct_contact":  # the plant's friction solve, a kernel held as an attribute
        assert "plant.contact.friction_impulse" in calls


def test_the_fusion_bound_records_one_tick_in_order_and_restores_pinocchio() -> None:
    """``--fusion``'s record of a PD tick: its kernels and Pinocchio calls in the tick's order.

    The sensors read, the Kalman filter's two CRBA and nonLinearEffects calls on the device's
    two bodies, its step, the measured row, the PD law, the supervisor's check, the plant's
    forces, its ABA, its kick and the applied row (tick.py, kalman.py, plant.py): the kernel
    runs between library calls are what a fused call could compose.
    """
    originals = {name: getattr(pin, name) for name in ("aba", "crba", "nonLinearEffects")}
    _, calls = tool._recorded_tick("pd", warm=WARM)
    assert [name.rsplit(".", 1)[-1] for _, name, _ in calls] == [
        "read_device",
        *("crba", "nonLinearEffects") * 2,
        "kalman_step",
        "write_measured",
        "pd_command",
        "check_readings",
        "drift_and_forces",
        "aba",
        "kick_and_drift",
        "write_applied",
    ]
    kinds = [kind for kind, _, _ in calls]
    assert kinds.count("library") == 5 and kinds.count("kernel") == 8
    assert all(getattr(pin, name) is func for name, func in originals.items())
