"""Compare your controller with the built-in PD and computed torque on one scenario.

:func:`exo_ctrl.compare` runs the scenario once per controller (here the
joint impedance controller of ``examples/impedance.py`` beside ``pd`` and
``ct``) and returns the table of the runs' figures; the same from the
command line, from the repository's root::

    exo-ctrl compare --controllers pd,ct,examples.impedance:Impedance --out cmp/

Run it::

    python examples/compare_mine.py
"""

from __future__ import annotations

import sys
from pathlib import Path

from exo_ctrl import CompareTable, SimConfig, compare

sys.path.insert(0, str(Path(__file__).resolve().parent))  # impedance.py beside this file
from impedance import Impedance


def main(duration_s: float = 3.6) -> CompareTable:
    """The table of PD, CT and the impedance controller on the default scenario."""
    table = compare(SimConfig(duration_s=duration_s), controllers=("pd", "ct", Impedance()))
    for row in table.rows:
        error = max(row.figures["rms_tracking_error_rad"].values())
        print(f"{row.label:24s} {row.status:10s} worst RMS tracking error {error:.4f} rad")
    return table


if __name__ == "__main__":
    main()
