"""Golden runs for tests/sim/test_golden.py.

PD and CT: the pre-redesign main (commit 0fa854c), run once on that commit with
``.venv/bin/python tests/data/make_golden.py``.  It writes
tests/data/golden_runs.npz: for each scenario every logged signal of the default
2.4 s run, float64, keyed "<scenario>/<signal>".

QP (``qp``, ``qp_spastic``): made again with ``.venv/bin/python
tests/data/make_golden.py --qp`` when the QP began handing a drive at its cap the
command's own voltage, which the driver holds at the cap, in place of the cap's
steady-state voltage (exo_ctrl/control/qp/torque_box.py; issue 31): the runs of
the test's legacy configuration with that QP, the signals the file held, the other
runs left as they are.
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np

DATA = Path(__file__).with_name("golden_runs.npz")

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

#: The runs made again with the present QP (module docstring).
REMADE = ("qp", "qp_spastic")


def signals_of(result) -> dict[str, np.ndarray]:
    """Every logged signal of a run, float64."""
    return {
        signal: np.ascontiguousarray(values, dtype=np.float64)
        for signal, values in result.signals.items()
    }


def remake_qp() -> None:
    """The QP's runs of the test's legacy configuration, with the present code, into DATA."""
    from exo_ctrl.sim import SimConfig, simulate

    spec = importlib.util.spec_from_file_location(
        "golden_test", Path(__file__).parents[1] / "sim" / "test_golden.py"
    )
    test = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(test)
    with np.load(DATA) as data:
        out = {key: data[key] for key in data.files}
    for name in REMADE:
        overrides, _ = test.SCENARIOS[name]
        result = simulate(SimConfig(**test.LEGACY, **overrides))
        print(name, result.status)
        new = signals_of(result)
        for key in [k for k in out if k.startswith(name + "/")]:  # the signals kept then
            out[key] = new[key.split("/", 1)[1]]
    np.savez_compressed(DATA, **out)


if __name__ == "__main__":
    if sys.argv[1:] == ["--qp"]:
        remake_qp()
    else:  # on commit 0fa854c, whose API this is
        from exo_ctrl.simulate import SimConfig, simulate

        out = {}
        for name, overrides in SCENARIOS.items():
            result = simulate(SimConfig(**overrides))
            print(name, result.status, result.n_ticks, result.safety_state)
            out.update({f"{name}/{s}": v for s, v in signals_of(result).items()})
        np.savez_compressed(DATA, **out)
