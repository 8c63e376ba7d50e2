"""The robustness benchmark: four controllers over a seeded virtual cohort of true patients.

    .venv/bin/python tools/robustness.py [--n 20] [--seed 0] [--duration SEC]
        [--workers 2] [--png PATH]

The cohort is :func:`exo_ctrl.model.benchmark_cohort` (issue 17, item 6):
statures uniform in 1.55–1.95 m, body masses uniform in 50–110 kg within a
body-mass index of 18.5–35 kg/m², either sex, each patient's segments drawn
around de Leva's for that stature and mass (:mod:`exo_ctrl.model.cohort`),
and the true knee axis 0–3 cm from the exoskeleton's in a random direction.
Per patient, what a clinic does: the exoskeleton is adjusted to the
patient's leg lengths (:func:`~exo_ctrl.model.fitted_exo`) and the gait is
the default one scaled to the legs (:func:`gait_for`: hip height, step
length and lift times the leg length over the default exoskeleton's
1.04 m; the same 1.2 s period).  Each patient walks with

- ``pd``: the paper's PD (it holds no model);
- ``ct_nominal``: computed torque with the nominal patient
  (``Belief("nominal")`` with the drawn patient's stature, mass and sex:
  the device knows these and the leg lengths, not the drawn segments);
- ``ct_identified``: computed torque with the patient identified from a
  calibration run on the true patient (``--exercise calibration``, 6 s, CT
  on the nominal model, then :func:`exo_ctrl.estimation.identify_patient`
  with the nominal patient as the prior);
- ``qp``: the QP controller with the nominal patient;

default sensors, cuffs and safety supervisor (on), ``--duration`` seconds
(default 3.6: the 1.2 s ramp-in and two cycles).  The runs go to the sweeps'
process pool (:mod:`exo_ctrl.sweep.run`: spawned workers that die with this
process).  Per run (:func:`metrics`): the RMS over the four joints of the
RMS tracking error [mrad], the peak cuff force over the four cuffs [N], the
worst cuff's force-estimate error (the summary's
``cuff_force_estimate_rms_error_rel``: the 2-D error's RMS over the RMS
true force) [%] and whether the supervisor stopped the device.  Prints a
Markdown table (median and worst over the cohort, per controller) and, with
``--png``, draws a panel per metric.  Exit 0; 2 for bad input.

Importable: ``run_benchmark(n, seed, duration_s, workers) -> Benchmark``.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import math
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl._io import check_output
from exo_ctrl._progress import Progress
from exo_ctrl.estimation.identification import body_model, calibration_samples, identify_patient
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.model import (
    CohortPatient,
    benchmark_cohort,
    fitted_exo,
    load_exo,
    nominal_patient,
    write_urdf,
)
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant.misalignment import Misalignment
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sweep.run import InlineExecutor, local_pool, stop_pool

#: The controllers compared, in the table's order.
CONTROLLERS = ("pd", "ct_nominal", "ct_identified", "qp")

#: The default exoskeleton's leg (thigh + shank) [m], which the default gait is for (Table I).
REFERENCE_LEG_M = 1.04

#: The calibration run before identification [s] (the identification tests' 6 s).
CALIBRATION_S = 6.0

#: The metrics of a run: key, the table's heading, the PNG panel's label.
METRICS = (
    ("rms_error_mrad", "RMS tracking error [mrad]", "RMS tracking error over the joints [mrad]"),
    ("peak_cuff_force_N", "peak cuff force [N]", "peak cuff force, worst cuff [N]"),
    ("estimate_error_pct", "cuff-force estimate error [%]", "cuff-force estimate error [%]"),
)  # fmt: skip


def gait_for(patient: CohortPatient) -> GaitParams:
    """The default gait scaled to the patient's legs (module docstring)."""
    k = (patient.params.thigh_length + patient.params.shank_length) / REFERENCE_LEG_M
    d = GaitParams()
    return dataclasses.replace(
        d,
        hip_height=d.hip_height * k,
        step_length=d.step_length * k,
        lift_height=d.lift_height * k,
    )


def nominal_belief(patient: CohortPatient) -> Belief:
    """What the device knows: the stature, mass and sex (and the leg lengths, from the truth)."""
    return Belief(
        patient="nominal",
        patient_height_m=patient.height_m,
        patient_mass_kg=patient.mass_kg,
        patient_sex=patient.sex,
    )


def write_models(patient: CohortPatient, folder: Path) -> tuple[str, str]:
    """Write the fitted exoskeleton's and the true patient's URDFs; returns their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    exo = write_urdf(fitted_exo(patient.params), folder / f"exo_{patient.index:03d}.urdf")
    truth = write_urdf(patient.params, folder / f"patient_{patient.index:03d}.urdf")
    return str(exo), str(truth)


def base_config(
    patient: CohortPatient, exo_path: str, patient_path: str, duration_s: float
) -> SimConfig:
    """The patient's gait run without a controller or belief chosen yet."""
    return SimConfig(
        gait=gait_for(patient),
        exo=exo_path,
        patient=patient_path,
        misalignment=Misalignment(knee_xz=patient.knee_misalignment_xz),
        duration_s=duration_s,
        belief=nominal_belief(patient),
    )


def identified_urdf(patient: CohortPatient, base: SimConfig, out: Path) -> str:
    """Calibrate on the true patient (CT, nominal model), identify, write the URDF to ``out``.

    Raises:
        ExoCtrlError: the calibration did not complete, or the identification failed.

    """
    calibration = dataclasses.replace(
        base,
        controller="ct",
        exercise="calibration",
        duration_s=CALIBRATION_S,
    )
    result = simulate(calibration)
    if result.status != "completed":
        raise ExoCtrlError(f"the calibration run {result.status}: {result.error}")
    s = result.signals
    samples = calibration_samples(result.t, s["q_meas"], s["tau_sensor"])
    exo = load_exo(base.exo)
    leg = exo.legs["left"]
    prior = nominal_patient(
        leg.thigh_length, leg.shank_length, patient.height_m, patient.mass_kg, patient.sex
    )
    found = identify_patient(samples, exo, body_model(prior), prior)
    return str(write_urdf(found.patient, out))


def case_config(
    patient: CohortPatient, controller: str, folder: Path, duration_s: float
) -> SimConfig:
    """The gait run of ``controller`` (one of :data:`CONTROLLERS`) on ``patient``.

    The URDFs are written into ``folder`` (for ``ct_identified`` after the
    calibration and identification, :func:`identified_urdf`).
    """
    exo_path, patient_path = write_models(patient, folder)
    base = base_config(patient, exo_path, patient_path, duration_s)
    if controller == "ct_identified":
        path = identified_urdf(patient, base, folder / f"identified_{patient.index:03d}.urdf")
        return dataclasses.replace(base, controller="ct", belief=Belief(patient=path))
    return dataclasses.replace(base, controller=controller.removesuffix("_nominal"))


def metrics(summary: dict[str, Any]) -> dict[str, Any]:
    """A run's figures for the benchmark (module docstring) from its summary."""
    rms = np.array(list(summary["rms_tracking_error_rad"].values()), dtype=float)
    rel = [x for x in summary["cuff_force_estimate_rms_error_rel"].values() if x is not None]
    return {
        "rms_error_mrad": 1e3 * float(np.sqrt(np.mean(rms**2))),
        "peak_cuff_force_N": float(max(summary["peak_cuff_force_N"].values())),
        "estimate_error_pct": 100.0 * float(max(rel)) if rel else math.nan,
        "safety_stop": summary["safety_state"] != "normal",
        "status": summary["status"],
    }


def run_case(patient: CohortPatient, controller: str, folder: str, duration_s: float) -> dict:
    """One run (in a worker); never raises for a failed run: ``status`` says so."""
    start = time.perf_counter()
    out: dict[str, Any] = {"patient": patient.index, "controller": controller, "error": ""}
    try:
        config = case_config(patient, controller, Path(folder), duration_s)
        out.update(metrics(simulate(config, keep_history=False).summary()))
    except ExoCtrlError as exc:
        out.update(status="failed", error=f"{type(exc).__name__}: {exc}")
    except Exception as exc:  # any other failure is this run's, not the benchmark's
        out.update(status="error", error=f"{type(exc).__name__}: {exc}")
    out["wall_time_s"] = time.perf_counter() - start
    return out


@dataclass
class Benchmark:
    """The benchmark's results.

    Attributes:
        cohort: the patients.
        duration_s: each gait run's duration [s].
        seed: the cohort's seed.
        runs: one dict per run (:func:`run_case`), in (patient, controller) order.
        wall_time_s: the whole benchmark's wall time [s].

    """

    cohort: list[CohortPatient]
    duration_s: float
    seed: int
    runs: list[dict[str, Any]] = field(default_factory=list)
    wall_time_s: float = 0.0

    def of(self, controller: str) -> list[dict[str, Any]]:
        """The runs of one controller, in patient order."""
        return [r for r in self.runs if r["controller"] == controller]

    def aggregate(self, controller: str, key: str) -> tuple[float, float]:
        """(median, worst) of a metric over the completed runs of ``controller`` (NaN: none)."""
        values = np.array([r[key] for r in self.of(controller) if key in r], dtype=float)
        values = values[np.isfinite(values)]
        if values.size == 0:
            return math.nan, math.nan
        return float(np.median(values)), float(values.max())

    def scenario(self) -> str:
        """The scenario in words (the table's and the PNG's title)."""
        return (
            f"{len(self.cohort)} patients (seed {self.seed}): 1.55-1.95 m, 50-110 kg "
            f"(BMI 18.5-35), knee 0-3 cm off; {self.duration_s:g} s gait, default sensors, "
            "safety on"
        )

    def table(self) -> str:
        """Median and worst per controller, as a Markdown table."""
        head = (
            "| controller | "
            + " | ".join(f"{h} median | worst" for _, h, _ in METRICS)
            + " | safety stops | failed |"
        )
        rows = [f"Robustness over {self.scenario()}", "", head, "|" + "---|" * 9]
        for c in CONTROLLERS:
            cells = []
            for key, _, _ in METRICS:
                med, worst = self.aggregate(c, key)
                cells += [f"{med:.2f}", f"{worst:.2f}"]
            runs = self.of(c)
            stops = sum(bool(r.get("safety_stop")) for r in runs)
            failed = sum(r["status"] not in ("completed",) for r in runs)
            rows.append(f"| {c} | " + " | ".join(cells) + f" | {stops}/{len(runs)} | {failed} |")
        return "\n".join(rows)


def run_benchmark(
    n: int = 20,
    seed: int = 0,
    duration_s: float = 3.6,
    workers: int = 2,
    progress: bool = True,
) -> Benchmark:
    """Run every controller on every patient of the cohort (module docstring).

    Raises:
        InvalidParameter: a bad n, seed, duration or worker count.

    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InvalidParameter("workers", workers, "an integer >= 1")
    if not (isinstance(duration_s, (int, float)) and duration_s > 0):
        raise InvalidParameter("duration", duration_s, "a number > 0 [s]")
    cohort = benchmark_cohort(n, seed)
    bench = Benchmark(cohort, float(duration_s), seed)
    tasks = [(p, c) for p in cohort for c in CONTROLLERS]
    start = time.perf_counter()
    bar = Progress(len(tasks), "robustness", enabled=progress)
    results: dict[tuple[int, str], dict[str, Any]] = {}
    executor = InlineExecutor() if workers == 1 else local_pool(min(workers, len(tasks)))
    clean = False
    with tempfile.TemporaryDirectory(prefix="exo_ctrl_robustness_") as folder:
        try:
            futures = {
                executor.submit(run_case, p, c, f"{folder}/p{p.index:03d}_{c}", duration_s): (
                    p.index,
                    c,
                )
                for p, c in tasks
            }
            pending = set(futures)
            while pending:
                done, pending = cf.wait(pending, timeout=1.0, return_when=cf.FIRST_COMPLETED)
                for future in done:
                    results[futures[future]] = future.result()
                failed = sum(r["status"] != "completed" for r in results.values())
                bar.update(len(results), f"{len(results)}/{len(tasks)} runs, {failed} failed")
            clean = True
        finally:
            if not isinstance(executor, InlineExecutor):
                stop_pool(executor, now=not clean)
            bar.close(len(results))
    bench.runs = [results[(p.index, c)] for p, c in tasks]
    bench.wall_time_s = time.perf_counter() - start
    return bench


def write_png(bench: Benchmark, path: str | Path) -> None:
    """A panel per metric (a dot per patient, a bar at the median, a cross at the worst)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(METRICS) + 1, figsize=(17, 4.8))
    x = np.arange(len(CONTROLLERS))
    colours = ("tab:gray", "tab:blue", "tab:green", "tab:orange")
    jitter = np.linspace(-0.18, 0.18, max(len(bench.cohort), 1))
    for ax, (key, _, label) in zip(axes, METRICS, strict=False):
        for i, c in enumerate(CONTROLLERS):
            values = np.array([r.get(key, math.nan) for r in bench.of(c)], dtype=float)
            ax.scatter(i + jitter[: values.size], values, s=14, color=colours[i], alpha=0.6)
            med, worst = bench.aggregate(c, key)
            ax.hlines(med, i - 0.3, i + 0.3, color=colours[i], linewidth=2.5)
            ax.scatter([i], [worst], marker="x", s=70, color="black", zorder=3)
        if key == "rms_error_mrad":  # PD and the model-based controllers differ 20-fold
            ax.set_yscale("log")
        ax.set_title(label, fontsize=10)
        ax.set_xticks(x, CONTROLLERS, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    stops = [sum(bool(r.get("safety_stop")) for r in bench.of(c)) for c in CONTROLLERS]
    axes[-1].bar(x, stops, color=colours)
    for i, count in enumerate(stops):
        axes[-1].text(i, count, str(count), ha="center", va="bottom", fontsize=10)
    axes[-1].set_title(f"safety stops (of {len(bench.cohort)} runs)", fontsize=10)
    axes[-1].set_xticks(x, CONTROLLERS, fontsize=9)
    axes[-1].set_ylim(0, max(len(bench.cohort), 1))
    axes[-1].yaxis.get_major_locator().set_params(integer=True)
    fig.suptitle(
        f"Robustness over {bench.scenario()}\ndots: patients, bar: median, x: worst",
        fontsize=11,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark, print its table, write the PNG."""
    from exo_ctrl._io import atomic_write
    from exo_ctrl.cli.common import Parser

    parser = Parser(prog="robustness", description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20, help="patients in the cohort (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="the cohort's seed (default 0)")
    parser.add_argument(
        "--duration", type=float, default=3.6, metavar="SEC",
        help="each gait run's duration, ramp-in included [s] (default 3.6)",
    )  # fmt: skip
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    parser.add_argument("--png", default=None, metavar="PATH", help="write the figure here")
    args = parser.parse_args(argv)
    try:
        if args.png is not None:
            check_output(args.png, "--png")
        bench = run_benchmark(args.n, args.seed, args.duration, args.workers)
    except InvalidParameter as exc:
        parser.error(str(exc))
    print(bench.table())
    print(
        f"\n{len(bench.runs)} runs in {bench.wall_time_s:.1f} s wall time on {args.workers} workers"
    )
    for r in bench.runs:
        if r["error"]:
            print(f"patient {r['patient']} {r['controller']}: {r['error']}")
    if args.png is not None:
        with atomic_write(args.png, "wb") as handle:
            write_png(bench, handle)
        print(f"wrote {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
