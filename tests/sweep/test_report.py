"""Tests of exo_ctrl.sweep.report: the load diagrams and the report's worst cases."""

from __future__ import annotations

import numpy as np

from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.sim import SimConfig
from exo_ctrl.sweep import PARAMETERS, SweepPaths, run_sweep


def test_plots_and_report_name_the_worst_case(tmp_path, make_spec):
    # Started on the gait at speed: a short run's plan then holds the full 0.5 m lift.
    at_speed = SimConfig(ramp_in_s=0.0, cuff_fit="slack")
    spec = make_spec(
        "step_length=0.3,0.45", "patient_shank_mass=3,6", "lift_height=0.1,0.5", base=at_speed
    )
    out = tmp_path / "r.parquet"
    table = run_sweep(spec, out, workers=1, progress=False)
    paths = SweepPaths.for_output(out)
    for name in spec.names:
        png = paths.plot(name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    cols = {n: np.array(table.column(n).to_pylist()) for n in table.column_names}
    ok = cols["status"] == "completed"
    assert 0 < ok.sum() < len(table)  # some fail (a 0.5 m lift overflexes the knee)
    report = paths.report.read_text().splitlines()
    for title, key, names, unit in (
        ("peak drive torque", "peak_drive_torque_Nm", JOINT_NAMES, "N·m"),
        ("peak cuff force", "peak_cuff_force_N", CUFF_NAMES, "N"),
    ):
        values = np.column_stack([cols[f"{key}_{n}"] for n in names])
        per_run = np.where(ok, np.nan_to_num(values, nan=-1).max(axis=1), -1)
        row = int(np.argmax(per_run))
        name = names[int(np.argmax(values[row]))]
        (line,) = [s for s in report if s.startswith(f"worst {title}:")]
        point = ", ".join(f"{n}={cols[n][row]:.10g} {PARAMETERS[n].unit}" for n in spec.names)
        assert line == (
            f"worst {title}: {per_run[row]:.6g} {unit} at {name}, run {row} "
            f"({cols['run_id'][row]}): {point}"
        )
    # The maxima table counts, per joint, the completed runs whose drive was clipped.
    head = report.index("maxima over completed runs:")
    for i, j in enumerate(JOINT_NAMES):
        shares = [cols[f"share_at_{x}_limit_{j}"][ok].astype(float) for x in ("torque", "current")]
        clipped = int(((shares[0] > 0) | (shares[1] > 0)).sum())
        assert report[head + 2 + i].split()[0] == j
        assert report[head + 2 + i].split()[-1] == str(clipped)
    failures = [s for s in report if s.startswith("  run ")]
    assert len(failures) == int((~ok).sum())
    assert all("lift_height=0.5 m" in s for s in failures)
