"""Golden runs of the pre-redesign main (commit 0fa854c), for tests/sim/test_golden.py.

Ran once on that commit:  .venv/bin/python tests/data/make_golden.py
It writes tests/data/golden_runs.npz: for each scenario every logged signal
of the default 2.4 s run, float64, keyed "<scenario>/<signal>".
"""

from pathlib import Path

import numpy as np
from exo_ctrl.simulate import SimConfig, simulate

SCENARIOS = {
    "pd": {"controller": "pd"},
    "ct": {"controller": "ct"},
    "qp": {"controller": "qp"},
    "qp_spastic": {
        "controller": "qp",
        "patient_torque": "spastic",
        "cuff_force_limit_N": 150.0,
        "safety": False,
    },
    "ct_spastic": {"controller": "ct", "patient_torque": "spastic", "safety": False},
    "pd_estop": {"controller": "pd", "estop_at_s": 1.0},
    "ct_estop": {"controller": "ct", "estop_at_s": 1.0},
}

if __name__ == "__main__":
    out = {}
    for name, overrides in SCENARIOS.items():
        result = simulate(SimConfig(**overrides))
        print(name, result.status, result.n_ticks, result.safety_state)
        for signal, values in result.signals.items():
            out[f"{name}/{signal}"] = np.ascontiguousarray(values, dtype=np.float64)
    np.savez_compressed(Path(__file__).with_name("golden_runs.npz"), **out)
