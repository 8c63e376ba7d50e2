"""Whether the QP's solves repeat bit for bit: one scenario run twice in one process.

    .venv/bin/python tools/qp_repeat.py [--preset spastic-qp] [--duration 0.6]

Runs the preset's scenario twice in this process, keeping every problem the
controller gave proxsuite (the workspace record before each solve: the
target, the rows, their bounds and the torque box) and the solution it got.
Prints whether the commanded voltages are equal bit for bit; if not, the
first tick where they differ and the first solve whose problem was the
same, bit for bit, in both runs (every earlier problem and solution too)
while its solution was not: the solver's answer then depends on something
outside the problem (proxsuite's vectorised dense solver depends on the
solver object; the runs share one, :mod:`exo_ctrl.control.qp.solver_pool`).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl.control.qp.workspace import TorqueQP
from exo_ctrl.scenario.load import preset
from exo_ctrl.sim import simulate


def captured_run(config) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """Run ``config``: its commanded voltages, and each QP problem and solution in order."""
    problems: list[np.ndarray] = []
    solutions: list[np.ndarray] = []
    solve = TorqueQP.solve_in_place

    def keep(self):
        problems.append(self.record.copy())
        ok = solve(self)
        solutions.append(self.record["x"][0].copy())
        return ok

    TorqueQP.solve_in_place = keep
    try:
        volts = simulate(config).signals["voltage_cmd"]
    finally:
        TorqueQP.solve_in_place = solve
    return volts, problems, solutions


def same_problem(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two workspace records hold the same problem (every field but the timing)."""
    return all(np.array_equal(a[n], b[n]) for n in a.dtype.names if n != "solve_time_us")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="spastic-qp", help="a preset with the QP")
    parser.add_argument("--duration", type=float, default=0.6, help="simulated time [s] (0.6)")
    args = parser.parse_args()
    config = dataclasses.replace(preset(args.preset).config, duration_s=args.duration)
    v1, p1, x1 = captured_run(config)
    v2, p2, x2 = captured_run(config)
    print(f"{args.preset}, {args.duration} s: {len(p1)} and {len(p2)} QP solves")
    differ = np.flatnonzero(np.abs(v1 - v2).max(axis=1))
    if not differ.size:
        print("the two runs' voltages are equal bit for bit")
        return 0
    print(f"voltages first differ at tick {differ[0]}, by at most {np.abs(v1 - v2).max():.3g} V")
    for i, (a, b, xa, xb) in enumerate(zip(p1, p2, x1, x2, strict=False)):
        if not same_problem(a, b):
            print(f"solve {i}: the problems differ first (upstream of the solver)")
            break
        if not np.array_equal(xa, xb):
            print(
                f"solve {i}: the same problem, after the same problems and solutions, "
                f"solved to solutions {np.abs(xa - xb).max():.3g} N·m apart"
            )
            break
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
