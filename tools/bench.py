"""Benchmark of the control tick, its library floor, the real-time factor and the cold start.

    .venv/bin/python tools/bench.py [--ticks N] [--json PATH] [--scenarios pd,ct,...] [--env]
    .venv/bin/python tools/bench.py --cold [--repeat N] [--helper on|off] [--scenarios ...]

For each scenario (:data:`SCENARIOS`: the default run with PD, CT and QP,
users' controllers (``impedance`` in Python, the paper's PD in numpy and
numba-compiled: ``numpy_pd``, ``numba_pd``),
and the QP on the spastic patient at a 150 N cuff bound, where its bound
binds): the cost of one control tick (sensors, estimator, controller,
safety supervisor, plant step, logging: exactly ``Runner.tick``), median
and p99; the floor, the library calls the tick makes timed alone in the
same run (:func:`floor_calls`, and for the QP proxsuite's share, see
:func:`bench_scenario`); their ratio; and the real-time factor of the run
(simulated time / wall time), without and with a rerun recording (best of
:data:`RTF_PAIRS` runs each), and their ratio, the median of the ratios of
pairs of runs made one after the other (the ratio of the two bests moved
from 0.63 to 1.18 between two scenarios that are the same run, pd and
pd_kalman, on a machine whose speed drifts); and, as "whole run", the same
median over each ``simulate`` call's wall time, set-up and the recorder's
start (its writer process, the blueprint, the static scene) and end (the
outcome, the last write) included, which the real-time factor leaves out:
what a short recorded run costs.  For the
QP also the share of ticks that called proxsuite and the median of its
update + solve + checks on those ticks (a tick's solve takes a few
iterations, the floor's warm re-solve of a solved problem none).
Absolute times drift on shared machines; the ratio is the figure to compare.

``--env`` also times the Gymnasium environment's step (:func:`bench_env`:
voltage, torque and residual actions at one tick a step, and residual at
ten) beside the built-in PD's tick measured right after it on the same run.

The peer (with MuJoCo installed: ``.venv/bin/pip install -e ".[bench]"``): right after
each scenario, the same exoskeleton, patient legs and cuffs in MuJoCo stepped
by a plain Python PD loop (``tools/mujoco_peer.py``: no motors, sensors,
estimator, supervisor or logging; :data:`PEER_S` simulated seconds, best of
:data:`RTF_PAIRS` runs), its real-time factor and ours over it.

``--cold`` measures instead the first run after an install: a short run of
each scenario in a fresh process with a fresh, empty numba cache directory
(``NUMBA_CACHE_DIR``), so every kernel it needs compiles, then the same run
again in a new process that loads them from that cache.  Besides the wall
times it prints the child process's CPU time (user + system), which a
shared machine inflates less, the compile helper's included; ``--repeat N``
takes the best of N such pairs (each figure its smallest).  The run compiles
as the CLI's does, with a helper process on the second core
(:mod:`exo_ctrl.sim.warmup`); ``--helper off`` compiles in one process.
``tools/compile_profile.py`` breaks a cold start down by kernel (in one process).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mujoco_peer  # tools/: the peer, the same bodies in MuJoCo

from exo_ctrl._io import output_problem
from exo_ctrl.cli.common import write_json
from exo_ctrl.envs import TreadmillEnv
from exo_ctrl.estimation import CuffForceKalman
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.record import RerunRecorder
from exo_ctrl.scenario.load import load_scenario
from exo_ctrl.sim import Runner, SimConfig, build, simulate

#: Simulated time of each run of the MuJoCo peer (tools/mujoco_peer.py) [s].
PEER_S = 5.0


def _time_calls(calls, repeats: int = 2000) -> float:
    """Median time of running ``calls`` once each [µs]."""
    samples = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter_ns()
        for call in calls:
            call()
        samples[i] = time.perf_counter_ns() - t0
    return float(np.median(samples)) / 1e3


def floor_calls(runner: Runner) -> list:
    """The Pinocchio calls one tick makes, as zero-argument callables.

    Plant: one ABA of the model holding both bodies (with contact on and the
    pelvis fixed, also a CRBA on the steps with a foot on the belt: added by
    :func:`bench_scenario`, weighted by their share).  Estimator: CRBA and
    nonLinearEffects of the exoskeleton (the Kalman filter's: of the
    exoskeleton and of the patient).  CT: none (its
    feedforward is tabulated along the plan when the controller is built).
    QP: the cuff model's CRBA and nonLinearEffects of the model holding both
    bodies.  Each is called with the present state.  (The QP's proxsuite
    call is not made every tick: see :func:`bench_scenario`.)
    """
    setup = runner.setup
    plant = setup.plant
    q, v, tau = plant.q.copy(), plant.v.copy(), np.zeros(8)
    qe, ve = q[:4].copy(), v[:4].copy()
    pm, pd = plant.model, plant.data
    if pm.nq == 9:  # the pelvis on its guide: [z, q_all], and the friction solve's CRBA
        q9, v9, tau9 = np.r_[plant.pelvis_z, q], np.r_[0.0, v], np.zeros(9)
        calls = [
            lambda: pin.aba(pm, pd, q9, v9, tau9),
            lambda: pin.crba(pm, pd, q9),
        ]
    else:
        calls = [
            lambda: pin.aba(pm, pd, q, v, tau),
        ]
    est = runner.estimator
    if isinstance(est, CuffForceKalman):  # both models at the last posterior
        qp, vp = q[4:].copy(), v[4:].copy()
        for (mm, md), (qq, vv) in zip(est.models, ((qe, ve), (qp, vp)), strict=True):
            calls += [
                lambda mm=mm, md=md, qq=qq: pin.crba(mm, md, qq),
                lambda mm=mm, md=md, qq=qq, vv=vv: pin.nonLinearEffects(mm, md, qq, vv),
            ]
    else:
        em, ed = est._model, est._data
        calls += [
            lambda: pin.crba(em, ed, qe),
            lambda: pin.nonLinearEffects(em, ed, qe, ve),
        ]
    ff = getattr(setup.controller, "_ff", None)
    if setup.online is not None and ff is not None:  # CT's feedforward row, every tick
        row = (setup.plan.q[0].copy(), setup.plan.dq[0].copy(), setup.plan.ddq[0].copy())
        calls.append(lambda: pin.rnea(ff._me, ff._de, *row))
        if ff._mp is not None:
            calls.append(lambda: pin.rnea(ff._mp, ff._dp, *row))
    # An interaction mode's exoskeleton model (path: its transparent part's;
    # path's own feet and Jacobians are closed-form, no Pinocchio call).
    mode_ctrl = getattr(setup.controller, "_free", setup.controller)
    modes = getattr(mode_ctrl, "_m", None)
    if modes is not None:
        md = mode_ctrl._d
        calls.append(lambda: pin.nonLinearEffects(modes, md, qe, ve))
    own = runner.patient_model  # the active patient's feedforward (plant side)
    if hasattr(own, "_pm"):
        qp4, vp4, ap4 = q[4:].copy(), v[4:].copy(), np.zeros(4)
        calls.append(lambda: pin.rnea(own._pm, own._pd, qp4, vp4, ap4))
    model = getattr(setup.controller, "cuff_model", None)
    if model is not None:
        cm, cd = model.model, model.data
        q_all, v_all = np.concatenate((qe, qe)), np.concatenate((ve, ve))
        calls += [
            lambda: pin.crba(cm, cd, q_all),
            lambda: pin.nonLinearEffects(cm, cd, q_all, v_all),
        ]
    return calls


def makes_contact_crba(runner: Runner) -> bool:
    """Whether the plant makes a CRBA (its friction solve) on the steps with a foot on the belt.

    With contact on and the pelvis fixed; on its guide the CRBA is every
    step's, in :func:`floor_calls`.
    """
    return runner.setup.config.contact.enabled and runner.setup.plant.model.nq == 8


def library_floor(runner: Runner, contact_share: float) -> float:
    """The floor of one tick [µs]: :func:`floor_calls` timed, and the contact CRBA's share.

    ``contact_share``: the share of the timed ticks with a foot on the belt
    (:func:`makes_contact_crba`; ignored otherwise).  The QP's proxsuite
    share is :func:`bench_scenario`'s.
    """
    floor = _time_calls(floor_calls(runner))
    if makes_contact_crba(runner):
        plant = runner.setup.plant
        q_now = plant.q.copy()
        floor += contact_share * _time_calls([lambda: pin.crba(plant.model, plant.data, q_now)])
    return floor


#: Pairs of runs, without and with a recording, for the real-time factors.
RTF_PAIRS = 5

#: The clinic-bws preset's gait (exo_ctrl/scenario/presets).
CLINIC_GAIT = load_scenario(preset="clinic-bws").config.gait

#: The benchmarked scenarios: controller and SimConfig overrides.
SCENARIOS = {
    "pd": {"controller": "pd"},
    "ct": {"controller": "ct"},
    # CT on the belt: the feet in contact, friction impulses (plant/contact.py),
    # the precomputed plan.
    "ct_contact": {"controller": "ct", "contact": ContactParams(enabled=True), "sync": False},
    # The same with the plan generated each tick from the measured belt speed
    # (plan/online.py) and CT's feedforward row recomputed (two RNEA calls).
    "ct_sync": {"controller": "ct", "contact": ContactParams(enabled=True), "sync": True},
    # CT with the pelvis on its guide at 50 % body-weight support (plant/pelvis.py): the
    # stance legs carry the rest; nine coordinates, a foot always on the belt (a CRBA and
    # the coupled friction solve every step), the clinic-bws preset's gait within the
    # drives' reach on its synchronised plan (the paper's 1.2 s gait saturates the drives
    # there, and its shank cuffs pass 130 N: the supervisor stops it in the ramp-in).
    "ct_bws": {
        "controller": "ct",
        "contact": ContactParams(enabled=True),
        "pelvis": PelvisParams(supported=True, bws_fraction=0.5),
        "gait": CLINIC_GAIT,
    },
    "qp": {"controller": "qp"},
    # PD with the coupled model's Kalman filter as the estimator (estimation/kalman.py).
    "pd_kalman": {"controller": "pd", "estimator": "kalman"},
    # Interaction modes (control/modes) with the active patient (plant/patient_active.py:
    # one RNEA per plant step in the truth, in the floor), and PD with that patient.
    # (A passive patient drops out of a transparent device: the supervisor holds.)
    "pd_active": {"controller": "pd", "patient_torque": "active"},
    "transparent": {"mode": "transparent", "patient_torque": "active"},
    "aan": {"mode": "aan", "patient_torque": "active"},
    # Path control with free timing (control/modes/path.py), the default 0.03 m tunnel.
    "path": {"mode": "path", "patient_torque": "active"},
    # A user's controller in Python on the public interface (docs/controllers.md): the joint
    # impedance of examples/impedance.py, torque commands through the driver's current loop;
    # its own Pinocchio calls (two gravity vectors) are not in the floor.
    "impedance": {"controller": "examples.impedance:Impedance"},
    # The paper's PD written by a user (examples/numba_pd.py): in numpy, and with its
    # arithmetic one numba-compiled call; beside pd, the built-in compiled one.
    "numpy_pd": {"controller": "examples.numba_pd:NumpyPD"},
    "numba_pd": {"controller": "examples.numba_pd:NumbaPD"},
    # The QP where its bound binds (tests/test_qp.py's spastic run).
    "qp_spastic": {
        "controller": "qp",
        "patient_torque": "spastic",
        "cuff_force_limit_N": 150.0,
        "safety": False,
    },
}


def bench_scenario(name: str, ticks: int) -> dict[str, float]:
    """Tick, floor, ratio and real-time factors of one scenario (module docstring).

    The QP calls proxsuite only on ticks whose clipped command violates a
    cuff row (qp.py, "Ticks without proxsuite"); its floor adds proxsuite's
    warm update + solve of the last solved problem, timed alone, times the
    share of the timed ticks that called it.
    """
    config = SimConfig(**SCENARIOS[name])
    setup = build(config)
    runner = Runner(setup)
    n = min(ticks, config.n_ticks)
    samples = np.empty(n)
    chunk = runner.chunk
    solve = np.zeros(n)  # the QP's own update + solve + checks, in the loop [µs]
    ctrl = setup.controller
    plant = setup.plant
    # With the pelvis fixed the plant adds a CRBA (its friction solve) on the
    # steps that find a foot on the belt: counted per tick, weighted into the floor.
    contact_any = plant.record["contact"]["any"]
    crba_ticks = 0
    for k in range(n):
        t0 = time.perf_counter_ns()
        runner.tick(k, k % chunk)
        samples[k] = time.perf_counter_ns() - t0
        solve[k] = getattr(ctrl, "solve_time_us", 0.0)
        crba_ticks += k >= n // 10 and bool(contact_any[0])
    tick = samples[n // 10 :] / 1e3  # skip warm-up
    floor = library_floor(runner, crba_ticks / tick.size)
    extra = {}
    if makes_contact_crba(runner):
        extra["contact_crba_share"] = crba_ticks / tick.size
    if hasattr(ctrl, "solver_ticks"):
        share = ctrl.solver_ticks / n
        if ctrl.solver_ticks:
            floor += share * _time_calls([ctrl.qp.update_and_solve])
        solved = solve[n // 10 :][solve[n // 10 :] > 0]
        extra["qp_solver_share"] = share
        extra["qp_solve_in_loop_median_us"] = float(np.median(solved)) if solved.size else 0.0
    plain, recorded = np.empty(RTF_PAIRS), np.empty(RTF_PAIRS)
    whole = np.empty((RTF_PAIRS, 2))  # each simulate() call's wall time [s], without, with
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(RTF_PAIRS):  # alternating: a change of the machine's speed hits both
            t0 = time.perf_counter()
            plain[i] = simulate(config).summary()["real_time_factor"]
            t1 = time.perf_counter()
            recorder = RerunRecorder(Path(tmp) / f"b{i}.rrd")
            recorded[i] = simulate(config, observers=[recorder]).summary()["real_time_factor"]
            whole[i] = (t1 - t0, time.perf_counter() - t1)
    median = float(np.median(tick))
    return {
        "tick_median_us": median,
        "tick_p99_us": float(np.percentile(tick, 99)),
        "floor_us": floor,
        "ratio": median / floor,
        "real_time_factor": float(plain.max()),
        "real_time_factor_recording": float(recorded.max()),
        "recording_ratio": float(np.median(recorded / plain)),
        "recording_ratio_whole_run": float(np.median(whole[:, 0] / whole[:, 1])),
        **extra,
    }


#: The environment's steps timed (--env): action kind and ticks per step.
ENV_CASES = (("voltage", 1), ("torque", 1), ("residual", 1), ("residual", 10))


def bench_env(action: str, ticks_per_step: int, steps: int) -> dict[str, float]:
    """The Gymnasium environment's step on the default run (``SimConfig()``, as ``pd``'s).

    Times ``env.step`` alone (a zero action; an episode that ends is reset,
    untimed), and, in the same run, ``Runner.tick`` of the built-in PD on the
    same configuration: the step's cost over the tick's is what the
    environment adds (the observation, the reward, the checks).
    """
    env = TreadmillEnv(SimConfig(), action=action, control_rate=1000.0 / ticks_per_step)
    zero = np.zeros(4)
    samples = np.empty(steps)
    env.reset(seed=0)
    for i in range(steps):
        t0 = time.perf_counter_ns()
        _, _, terminated, truncated, _ = env.step(zero)
        samples[i] = time.perf_counter_ns() - t0
        if terminated or truncated:
            env.reset()
    env.close()
    step = samples[steps // 10 :] / 1e3
    runner = Runner(build(SimConfig()))
    ticks = np.empty(min(steps * ticks_per_step, runner.setup.config.n_ticks))
    for k in range(ticks.size):
        t0 = time.perf_counter_ns()
        runner.tick(k, k % runner.chunk)
        ticks[k] = time.perf_counter_ns() - t0
    tick = float(np.median(ticks[ticks.size // 10 :])) / 1e3
    median = float(np.median(step))
    return {
        "step_median_us": median,
        "step_p99_us": float(np.percentile(step, 99)),
        "pd_tick_median_us": tick,
        "per_tick_ratio": median / ticks_per_step / tick,
    }


_COLD_RUN = """
import time
t0 = time.perf_counter()
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.plant import BeltParams, ContactParams, PelvisParams
from exo_ctrl.plan import GaitParams
t1 = time.perf_counter()
result = simulate(SimConfig(**{overrides!r}, duration_s=0.05), warmup={warmup!r})
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def cold_start(name: str, helper: bool = True) -> dict[str, float]:
    """Import and first-run times [s] of one scenario with an empty and with a filled cache.

    ``helper``: compile with the helper process as the CLI does
    (:mod:`exo_ctrl.sim.warmup`; its CPU time is counted), or in one process.
    """
    with tempfile.TemporaryDirectory() as cache:
        # The helper forced on (or off): the load average a previous cold run leaves
        # would otherwise keep it from starting (exo_ctrl/sim/warmup.py, core_free).
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, EXO_CTRL_WARMUP="1" if helper else "0")
        code = _COLD_RUN.format(overrides=SCENARIOS[name], warmup=helper)
        out = {}
        for kind in ("cold", "warm"):
            t0, before = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
            run = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            )
            total, after = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
            imports, first = (float(x) for x in run.stdout.split())
            out[f"{kind}_total_s"] = total
            out[f"{kind}_cpu_s"] = (after.ru_utime - before.ru_utime) + (
                after.ru_stime - before.ru_stime
            )
            out[f"{kind}_import_s"] = imports
            out[f"{kind}_run_s"] = first
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2400, help="ticks to time (default 2400)")
    parser.add_argument(
        "--scenarios",
        default=",".join(SCENARIOS),
        help=f"comma-separated, of {', '.join(SCENARIOS)} (default: all)",
    )
    parser.add_argument("--json", default=None, metavar="PATH", help="write the figures as JSON")
    parser.add_argument(
        "--cold", action="store_true", help="measure the first run after an install instead"
    )
    parser.add_argument(
        "--env",
        action="store_true",
        help="also time the Gymnasium environment's step (exo_ctrl.envs) beside pd's tick",
    )
    parser.add_argument(
        "--repeat", type=int, default=1, help="--cold: the best of N measurements (default 1)"
    )
    parser.add_argument(
        "--helper",
        choices=("on", "off"),
        default="on",
        help="--cold: compile with the helper process as the CLI does (on, default) or in one",
    )
    args = parser.parse_args()
    names = [name.strip() for name in args.scenarios.split(",")]
    unknown = [name for name in names if name not in SCENARIOS]
    if unknown:
        parser.error(f"--scenarios: unknown {unknown}; allowed: {', '.join(SCENARIOS)}")
    if args.json is not None and (problem := output_problem(args.json)):
        print(f"bench: --json {args.json}: {problem}", file=sys.stderr)
        return 2
    results = {}
    if args.cold:
        print(f"{'scenario':<12}{'cold: import':>13}{'run':>7}{'total':>8}{'CPU':>7}"
              f"{'warm: import':>14}{'run':>7}{'total':>8}{'CPU':>7}")  # fmt: skip
        for name in names:
            runs = [cold_start(name, args.helper == "on") for _ in range(max(args.repeat, 1))]
            r = {key: min(run[key] for run in runs) for key in runs[0]}
            results[name] = r
            print(
                f"{name:<12}{r['cold_import_s']:>12.1f}s{r['cold_run_s']:>6.1f}s"
                f"{r['cold_total_s']:>7.1f}s{r['cold_cpu_s']:>6.1f}s{r['warm_import_s']:>13.1f}s"
                f"{r['warm_run_s']:>6.1f}s{r['warm_total_s']:>7.1f}s{r['warm_cpu_s']:>6.1f}s"
            )
    else:
        peer = mujoco_peer.Peer(build(SimConfig(duration_s=PEER_S))) if mujoco_peer.mujoco else None
        print(
            f"{'scenario':<12}{'tick median':>12}{'tick p99':>10}{'floor':>8}{'ratio':>7}"
            f"{'RTF':>7}{'RTF rec':>9}{'rec/no rec':>12}{'whole run':>11}"
            + (f"{'MuJoCo RTF':>12}{'RTF/MuJoCo':>12}" if peer else "")
        )
        for name in names:
            r = bench_scenario(name, args.ticks)
            if peer is not None:  # right after the scenario: the machine's speed drifts
                wall = min(mujoco_peer.run_peer(peer)[0] for _ in range(RTF_PAIRS))
                r["mujoco_real_time_factor"] = PEER_S / wall
                r["over_mujoco"] = r["real_time_factor"] / r["mujoco_real_time_factor"]
            results[name] = r
            print(
                f"{name:<12}{r['tick_median_us']:>10.1f}µs{r['tick_p99_us']:>8.1f}µs"
                f"{r['floor_us']:>6.1f}µs{r['ratio']:>7.2f}{r['real_time_factor']:>7.1f}"
                f"{r['real_time_factor_recording']:>9.1f}{r['recording_ratio']:>12.2f}"
                f"{r['recording_ratio_whole_run']:>11.2f}"
                + (
                    f"{r['mujoco_real_time_factor']:>12.1f}{r['over_mujoco']:>12.2f}"
                    if peer
                    else ""
                )
            )
            if "qp_solver_share" in r:
                print(
                    f"{'':<12}proxsuite called on {100 * r['qp_solver_share']:.1f} % of the ticks"
                    f"; their update + solve + checks: median "
                    f"{r['qp_solve_in_loop_median_us']:.1f} µs"
                )
            if "contact_crba_share" in r:
                print(
                    f"{'':<12}the plant's contact CRBA on {100 * r['contact_crba_share']:.0f} %"
                    " of the ticks (in the floor)"
                )
    if args.env and not args.cold:
        print(f"\n{'env step':<20}{'median':>10}{'p99':>10}{'pd tick':>10}{'per tick/pd':>13}")
        for action, per_step in ENV_CASES:
            r = bench_env(action, per_step, max(args.ticks // per_step, 100))
            name = f"{action}, {per_step} tick{'s' if per_step > 1 else ''}"
            results[f"env_{action}_{per_step}"] = r
            print(
                f"{name:<20}{r['step_median_us']:>8.1f}µs{r['step_p99_us']:>8.1f}µs"
                f"{r['pd_tick_median_us']:>8.1f}µs{r['per_tick_ratio']:>13.2f}"
            )
    if args.json is not None:
        write_json(args.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
