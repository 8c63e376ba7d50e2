"""The fault-injection campaign: one fault at a time in the default run, detected or not.

    .venv/bin/python tools/faults.py [--seeds N] [--controller pd|ct|qp] [--mode MODE]
        [--stop-reaction hold|yield] [--kinds KIND,...] [--target NAME] [--out DIR]

For each fault of :data:`exo_ctrl.sim.faults.FAULT_KINDS` and each seed, the
default scenario (standing, 1.2 s ramp-in, 3.6 s in all) runs with that one
fault injected at a seeded time in [1.5, 2.5] s (after the ramp-in) on a
seeded joint or cuff (:func:`plan_fault`).  Each run reports
(:class:`FaultResult`): whether the supervisor detected it (its first
violation, or warning, at or after the onset: the cuff-load monitor,
:mod:`exo_ctrl.safety.cuff_load`, warns of an unloaded cuff and does not
stop), the time to detection and the channel, the
state reached (normal, stopping, holding, power_cut), the worst cuff force
after the onset (the plant's, the truth) and the worst joint excursion after
the onset, max |q - q_ref| over the joints with q_ref the plan while normal
and the hold posture (the angle read at the stop) after; and, with ``--out``,
whether its recording holds every tick and the fault's event
(:func:`recording_holds`).  ``belt_stop`` runs with the belt (contact on),
twice: with the plan synchronised with the measured belt speed (sync on, not
with the QP nor in aan and path, which need the precomputed plan) and with
the precomputed plan (sync off); for it the table also gives the feet's
slip on the stopped belt after the onset (the largest slip speed and the
distance slid, both feet, in contact).  Prints a Markdown table; exit 0.

``--mode MODE`` (default ``tracking``) runs the campaign in an interaction
mode (:mod:`exo_ctrl.control.modes`: guidance, transparent, aan, path) with
``--patient-torque active`` (the active patient's defaults,
:mod:`exo_ctrl.plant.patient_active`): a passive patient would drop out of a
free device.  Outside ``tracking`` the device does not impose the plan, so
the excursion's reference while normal is the same mode's run without the
fault (same seeds: the same patient and sensor noise), and the hold posture
after the stop, as in tracking.

``--stop-reaction hold|yield`` sets the supervisor's stop reaction
(:mod:`exo_ctrl.safety.stop_reaction`; default: the mode's).  After a
``yield`` the patient is not held, so the excursion's reference stays the
run without the fault (the plan in tracking).  The table also gives the
worst true thigh and shank cuff forces from the stop on, against ISO/TS
15066's 220 N and 130 N.

Importable: ``run_campaign(seeds=1, controller="pd", mode="tracking") -> list[FaultResult]``.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exo_ctrl import SimConfig, read_recording, simulate
from exo_ctrl.control.modes import MODES
from exo_ctrl.exceptions import ExoCtrlError
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.plant import ContactParams
from exo_ctrl.record import RerunRecorder
from exo_ctrl.safety import STOP_REACTIONS
from exo_ctrl.safety.cuff_load import off_reason
from exo_ctrl.sim.faults import FAULT_KINDS, Fault

#: The window of the seeded onset [s]: after the default 1.2 s ramp-in, 1.1 s before the end.
ONSET_WINDOW_S = (1.5, 2.5)

#: Each kind's size and duration in the campaign (None: to the end), with why.
#: noise burst: 5 mrad std (≈ 100 encoder counts, an EMI burst on the encoder
#: line) for 0.1 s; bias step: 80 N·m (a zero shift of 22 % of a 360 N·m
#: sensor's range, a damaged bridge); drift: 100 N·m/s (a strain gauge
#: coming unglued); saturation: a rail at 20 N·m (an amplifier's gain fault,
#: below what every joint carries in the gait); dropout: 30 ms of stale
#: values; NaN: one corrupted frame; overrun: 20 ms of late commands;
#: belt stop: braked at the belt drive's force limit (1000 N), to the end.
CAMPAIGN = {
    "encoder_freeze": (None, None),
    "encoder_dropout": (None, 0.03),
    "noise_burst": (5e-3, 0.1),
    "torque_bias_step": (80.0, None),
    "torque_drift": (100.0, None),
    "torque_saturation": (20.0, None),
    "nan_reading": (None, 1e-3),
    "control_overrun": ("seeded", 0.02),
    "drive_open": (None, None),
    "drive_short": (None, None),
    "cuff_slip": (None, None),
    "belt_stop": (None, None),
}

#: Why a fault cannot be detected (or injected), by kind (none at present).
UNDETECTABLE: dict[str, str] = {}

#: The runs of a belt fault: (label, SimConfig overrides); sync on is left out with the QP
#: and in aan and path (a precomputed periodic plan).
BELT_VARIANTS = (
    ("sync on", {"contact": ContactParams(enabled=True), "sync": True}),
    ("sync off", {"contact": ContactParams(enabled=True), "sync": False}),
)

#: Faults the supervisor does not detect, and why (the table's note;
#: :func:`not_detected_note`).  The cuff-load monitor warns of a shank cuff that
#: carries less than half the nominal patient's load, where the device carries the
#: legs (tracking, guidance with G = 1).  A slipped thigh cuff moves its load onto
#: the shank cuff and leaves the joint torques as they were: no estimate from them
#: sees it.  Where the monitor is off an unloaded cuff is what the mode expects.
NOT_DETECTED = {
    "cuff_slip": (
        "not detected: the shank cuff takes the thigh's load, the joint torques do not change"
    ),
}


def not_detected_note(result, fault: Fault, mode: str) -> str:
    """Why ``fault`` went undetected in ``result``, a run in ``mode`` (the table's note)."""
    if fault.kind != "cuff_slip" or fault.target.endswith("thigh"):
        return NOT_DETECTED.get(fault.kind, "")
    why = off_reason(mode, result.config.modes.guidance)
    if why:
        return f"not detected: the cuff-load monitor is off ({why})"
    quantity = f"cuff load {fault.target}"
    before = [e for e in result.events if e.get("quantity") == quantity and e["t"] < fault.at_s]
    if before:
        return f"not detected: the cuff was unloaded before, warned at {before[0]['t']:.3f} s"
    return "not detected within the run"


@dataclass
class FaultResult:
    """One run of the campaign (module docstring).

    Attributes:
        kind: the fault's kind.
        label: kind and target.
        seed: the seed.
        at_s: onset [s] (NaN: not injected).
        detected: the supervisor reported a violation at or after the onset.
        detection_s: time from the onset to the first violation [s] (NaN: none).
        channel: the first violation's quantity ("" if none).
        state: the supervisor's final state ("" if not run).
        worst_cuff_force_N: largest cuff force magnitude after the onset [N].
        worst_thigh_N: the same for the thigh cuffs alone [N].
        worst_shank_N: the same for the shank cuffs alone [N].
        worst_excursion_rad: largest |q - q_ref| after the onset [rad].
        ticks: ticks run.
        recording_ok: the recording holds every tick and the fault event
            (None: not recorded).
        note: why not detected or not run.
        variant: the run's variant (``"sync on"``, ``"sync off"`` for the belt; "").
        slip_max_mps: largest slip speed of a foot on the belt after the onset
            [m/s] (NaN: no belt).
        slip_distance_m: distance the feet slid on the belt after the onset,
            ∫ (|s_L| + |s_R|) dt over the ticks in contact [m] (NaN: no belt).
        reaction: the stop reaction that acted ("" if no stop).
        thigh_after_stop_N: largest true thigh cuff force from the stop on [N]
            (NaN: no stop).
        shank_after_stop_N: the same for the shank cuffs [N].

    """

    kind: str
    label: str
    seed: int
    at_s: float = math.nan
    detected: bool = False
    detection_s: float = math.nan
    channel: str = ""
    state: str = ""
    worst_cuff_force_N: float = math.nan
    worst_thigh_N: float = math.nan
    worst_shank_N: float = math.nan
    worst_excursion_rad: float = math.nan
    ticks: int = 0
    recording_ok: bool | None = None
    note: str = ""
    variant: str = ""
    slip_max_mps: float = math.nan
    slip_distance_m: float = math.nan
    reaction: str = ""
    thigh_after_stop_N: float = math.nan
    shank_after_stop_N: float = math.nan


def plan_fault(kind: str, seed: int, dt: float = 1e-3) -> Fault:
    """The campaign's fault of ``kind`` for ``seed``: onset, target and size drawn from it."""
    rng = np.random.default_rng([FAULT_KINDS.index(kind), seed])
    lo, hi = ONSET_WINDOW_S
    at = round(rng.uniform(lo, hi) / dt) * dt
    magnitude, duration = CAMPAIGN[kind]
    target = str(rng.choice(CUFF_NAMES if kind == "cuff_slip" else JOINT_NAMES))
    if kind == "belt_stop":
        target = ""
    if kind == "control_overrun":
        target = ""
        magnitude = int(rng.integers(1, 6)) * dt  # 1-5 ms late
    return Fault(kind, at, target, magnitude, duration, seed=seed)


def region_peaks(force: np.ndarray) -> tuple[float, float]:
    """The largest thigh and shank cuff force [N] of ``force``, (n, 4) in the plant's cuff order."""
    return float(force[:, 0::2].max()), float(force[:, 1::2].max())


def analyse(result, fault: Fault, reference=None) -> FaultResult:
    """The campaign's figures of a run with ``fault`` (module docstring).

    ``reference``: the run without the fault whose angles q are the
    excursion's reference while normal (None: the plan, q*).
    """
    out = FaultResult(fault.kind, fault.label, fault.seed, at_s=fault.at_s)
    out.state = result.safety_state or ""
    out.ticks = int(result.t.shape[0])
    seen = ("violation", "warning")  # a warning (an unloaded cuff) does not stop
    after = [e for e in result.events if e.get("kind") in seen and e["t"] >= fault.at_s - 1e-9]
    if after:
        out.detected = True
        out.detection_s = after[0]["t"] - fault.at_s
        warned = after[0]["kind"] == "warning"
        out.channel = after[0]["quantity"] + (" (warning)" if warned else "")
    s = result.signals
    k0 = round(fault.at_s / result.config.dt)
    force = np.linalg.norm(s["cuff_force"][k0:], axis=-1)
    out.worst_cuff_force_N = float(force.max())
    out.worst_thigh_N, out.worst_shank_N = region_peaks(force)
    ref = s["q_des"].copy() if reference is None else reference.signals["q"].copy()
    stopped = np.flatnonzero(s["safety_state"] != 0)
    starts = [e["message"] for e in result.events if "controlled stop (" in e.get("message", "")]
    out.reaction = starts[0].split("(", 1)[1].split(")", 1)[0] if starts else ""
    if stopped.size:
        after_stop = np.linalg.norm(s["cuff_force"][stopped[0] :], axis=-1)
        out.thigh_after_stop_N, out.shank_after_stop_N = region_peaks(after_stop)
    if stopped.size and out.reaction != "yield":
        k_stop = stopped[0]
        q_meas = s["q_meas"][: k_stop + 1]
        hold = q_meas[-1].copy()
        for j in range(4):  # the last finite reading, as the supervisor holds it
            if not np.isfinite(hold[j]):
                finite = q_meas[np.isfinite(q_meas[:, j]), j]
                hold[j] = finite[-1] if finite.size else np.nan
        ref[k_stop:] = hold
    out.worst_excursion_rad = float(np.nanmax(np.abs(s["q"][k0:] - ref[k0:])))
    if result.config.contact.enabled:
        slip = np.abs(s["foot_slip"][k0:]) * (s["contact_state"][k0:] > 0)
        out.slip_max_mps = float(slip.max())
        out.slip_distance_m = float(slip.sum() * result.config.dt)
    return out


def recording_holds(path: Path, n_ticks: int, fault: Fault) -> bool:
    """Whether the recording at ``path`` holds every tick and the fault's onset event."""
    back = read_recording(path)
    has_event = any(
        e.get("kind") == "fault" and abs(e["t"] - fault.at_s) < 1e-9 for e in back.events
    )
    return back.t.shape[0] == n_ticks and has_event


def run_fault(
    fault: Fault,
    controller: str = "pd",
    out: Path | None = None,
    variant: str = "",
    mode: str = "tracking",
    reference=None,
    **config: object,
) -> FaultResult:
    """Run the default scenario with ``fault`` and analyse it (``config``: SimConfig overrides).

    ``variant``: the run's label beside the fault's (``"sync on"``; in the
    recording's name).  ``mode``: the interaction mode; outside tracking with
    the active patient, and the excursion measured from ``reference``, the
    same run without the fault (None: run here).
    """
    if mode != "tracking":
        config = {"mode": mode, "patient_torque": "active", **config}
        if reference is None:
            reference = simulate(SimConfig(controller=controller, **config))
    cfg = SimConfig(controller=controller, faults=(fault,), **config)
    observers = []
    path = None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        tag = f"_{variant.replace(' ', '_')}" if variant else ""
        path = out / f"{fault.kind}_{fault.target or 'all'}{tag}_seed{fault.seed}.rrd"
        observers.append(RerunRecorder(path))
    result = simulate(cfg, observers=observers)
    res = analyse(result, fault, reference)
    res.variant = variant
    if variant:
        res.label = f"{res.label} ({variant})"
    if not res.detected:
        res.note = not_detected_note(result, fault, mode)
    if path is not None:
        res.recording_ok = recording_holds(path, cfg.n_ticks, fault)
    return res


def run_campaign(
    seeds: int = 1,
    controller: str = "pd",
    out: Path | None = None,
    kinds: tuple[str, ...] = FAULT_KINDS,
    progress: bool = False,
    mode: str = "tracking",
    stop_reaction: str | None = None,
    target: str | None = None,
) -> list[FaultResult]:
    """Every fault of ``kinds`` × ``seeds`` seeds (module docstring), in ``mode``.

    ``stop_reaction``: the supervisor's (None: the mode's default).  ``target``:
    every fault's joint or cuff in place of the seeded one (None: seeded).

    Raises:
        InvalidParameter: a target that is not one of its kind's.
    """
    results = []
    references: dict[str, object] = {}  # per variant: the mode's run without a fault
    # Sync on is left out where the plan must be precomputed: the QP, and aan and
    # path (their phase bins and path are rows of a periodic precomputed plan).
    precomputed = controller == "qp" or mode in ("aan", "path")
    belt = [(name, over) for name, over in BELT_VARIANTS if not (precomputed and over["sync"])]
    runs = [
        (kind, seed, variant)
        for kind in kinds
        for seed in range(seeds)
        for variant in (belt if kind == "belt_stop" else [("", {})])
    ]
    for n, (kind, seed, (name, over)) in enumerate(runs, 1):
        if progress:
            what = f"{kind} {name}".strip()
            print(f"[{n}/{len(runs)}] {what} seed {seed}", file=sys.stderr, flush=True)
        if kind in UNDETECTABLE:
            results.append(FaultResult(kind, kind, seed, note=UNDETECTABLE[kind]))
            continue
        reference = None
        if mode != "tracking":
            if name not in references:
                extra = {"mode": mode, "patient_torque": "active", **over}
                references[name] = simulate(SimConfig(controller=controller, **extra))
            reference = references[name]
        fault = plan_fault(kind, seed)
        if target is not None:
            fault = Fault(kind, fault.at_s, target, fault.magnitude, fault.duration_s, seed)
        over = {**over, "stop_reaction": stop_reaction}
        results.append(run_fault(fault, controller, out, name, mode, reference, **over))
    return results


def table(results: list[FaultResult]) -> str:
    """The campaign as a Markdown table."""
    head = (
        "| fault | seed | onset [s] | detected | after [ms] | first channel | state "
        "| worst cuff force [N] | after the stop: thigh, shank [N] (limits 220, 130) "
        "| worst excursion [rad] | feet slip on the belt: max [m/s], slid [mm] | recording |"
    )
    rows = [head, "|" + "---|" * 12]
    for r in results:
        if r.note and not r.ticks:
            rows.append(f"| {r.label} | {r.seed} | – | no | – | {r.note} | – | – | – | – | – | – |")
            continue
        rec = {None: "–", True: "every tick + event", False: "INCOMPLETE"}[r.recording_ok]
        after = f"{1e3 * r.detection_s:.0f}" if r.detected else "–"
        slip = "–"
        if math.isfinite(r.slip_max_mps):
            slip = f"{r.slip_max_mps:.2f}, {1e3 * r.slip_distance_m:.0f}"
        stop = "–"
        if math.isfinite(r.thigh_after_stop_N):
            over = " (over)" if r.thigh_after_stop_N > 220 or r.shank_after_stop_N > 130 else ""
            stop = f"{r.thigh_after_stop_N:.0f}, {r.shank_after_stop_N:.0f}{over}"
        state = f"{r.state} ({r.reaction})" if r.reaction else r.state
        rows.append(
            f"| {r.label} | {r.seed} | {r.at_s:.3f} | {'yes' if r.detected else 'NO'} | {after} "
            f"| {r.channel or r.note or '–'} | {state} | {r.worst_cuff_force_N:.0f} | {stop} "
            f"| {r.worst_excursion_rad:.3f} | {slip} | {rec} |"
        )
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    """Run the campaign and print its table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=1, help="seeds per fault (default 1)")
    parser.add_argument("--controller", choices=("pd", "ct", "qp"), default="pd")
    parser.add_argument(
        "--mode",
        choices=MODES,
        default="tracking",
        help="interaction mode (default tracking); any other runs with --patient-torque active "
        "and measures the excursion from the same mode's run without the fault",
    )
    parser.add_argument(
        "--stop-reaction",
        choices=STOP_REACTIONS,
        default=None,
        help="the supervisor's stop reaction (default: the mode's, hold in tracking)",
    )
    parser.add_argument(
        "--kinds", default=",".join(FAULT_KINDS), help="faults to run, comma-separated (all)"
    )
    parser.add_argument(
        "--target", default=None, help="every fault's joint or cuff (default: seeded)"
    )
    parser.add_argument("--out", type=Path, default=None, help="directory for the recordings")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    kinds = tuple(k.strip() for k in args.kinds.split(",") if k.strip())
    unknown = [k for k in kinds if k not in FAULT_KINDS]
    if unknown or not kinds:
        parser.error(f"--kinds must be some of {', '.join(FAULT_KINDS)}; got {args.kinds!r}")
    try:
        results = run_campaign(
            args.seeds,
            args.controller,
            args.out,
            kinds,
            progress=True,
            mode=args.mode,
            stop_reaction=args.stop_reaction,
            target=args.target,
        )
    except ExoCtrlError as exc:
        print(f"faults.py: error: {exc}", file=sys.stderr)
        return 2
    who = f"mode {args.mode}, active patient" if args.mode != "tracking" else "mode tracking"
    who += f", stop reaction {args.stop_reaction or 'by mode'}"
    print(f"Fault campaign, controller {args.controller}, {who}, {args.seeds} seed(s) per fault:\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
