"""``exo-ctrl simulate``'s long options: each another spelling of one scenario key.

:data:`LONG_OPTIONS` is the one part written here: an option's name, the
key path it sets and, for a few, the form its value takes on the command
line where that differs from the key's (``on``/``off`` for a switch,
``DX,DZ`` for a pair, a preset's name for the drive).  Everything else an
option shows comes from the dataclasses, as the scenario file's comments do
(:mod:`exo_ctrl.sim.scenario_file`): its meaning and unit (the field's
``Attributes:`` entry), its type (the field's annotation) and its default
(the field's value in ``SimConfig()``, the ``paper-free-air`` preset).

Given, an option becomes settings ``key = value`` (:func:`option_settings`),
applied to the scenario document as ``--set`` is.  A few forms also imply
other keys (``--pelvis supported`` the supported gait's hip height,
excursion and duty factor), set first so that an option given for one of
them wins.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
from collections.abc import Callable
from typing import Any

from ..control import PDGains
from ..control.modes import MODES
from ..estimation import ESTIMATORS
from ..exceptions import InvalidParameter
from ..model import SEXES
from ..plan import EXERCISES
from ..plant import MOTOR_PRESETS, CuffParams, motor_preset
from ..plant.patient_active import PATIENT_KINDS
from ..safety import STOP_REACTIONS
from ..sensing.cuff_load import CUFF_SENSOR_SETS
from ..sim import SimConfig
from ..sim.config import CUFF_FITS
from ..sim.plain import field_types
from ..sim.scenario_file import (
    document_from_config,
    field_docs,
    plain_text,
    table_class,
)
from ..sim.session import load_session

__all__ = [
    "GAIT_OPTIONS",
    "LONG_OPTIONS",
    "SUPPORTED_GAIT",
    "LongOption",
    "add_long_options",
    "given_options",
    "option_settings",
]

#: The gait's hip height H_s, excursion e [m], duty factor β and period T [s] that
#: ``--pelvis supported`` sets (where no option gives them), the ``clinic-bws`` preset's: the
#: 0.52 + 0.52 m legs extend to 26° of knee flexion at mid-stance (a 0.90 m fixed hip
#: walks a 56–60° crouch, tests/plan/test_hip_excursion.py); β = 0.6, normal walking's 60 %
#: stance (Perry & Burnfield, Gait Analysis, 2nd ed. 2010, ch. 1), so that the load passes from
#: foot to foot over a double support and the plan's loading phase can sink the loaded foot
#: (:mod:`exo_ctrl.plan.loading`); T = 1.6 s and e = 2.5 cm keep the planned torque within the
#: default drives at 30–50 % support (the 1.2 s period with e = 5 cm needs up to 203 N·m:
#: docs/performance.md, touchdowns under load).
SUPPORTED_GAIT = {"hip_height": 1.0, "pelvis_excursion": 0.025, "duty_factor": 0.6, "period": 1.6}

#: The forms an option's text can take (:class:`LongOption`).
FORMS = (
    "value",
    "switch",
    "flag",
    "pair",
    "joints",
    "regions",
    "session",
    "motor",
    "cuffs",
    "compliance",
)


@dataclasses.dataclass(frozen=True)
class LongOption:
    """One long option: a spelling of the scenario key ``key``.

    Attributes:
        option: the option (``--step-length``).
        key: the scenario key path it sets (``gait.step_length``).
        group: the heading it is listed under.
        form: how its text becomes the key's value, one of :data:`FORMS`:
            ``value`` the key's own type; ``switch`` one of two words for a
            boolean (:attr:`words`, true first); ``flag`` no text, sets
            :attr:`const`; ``pair`` ``A,B``; ``joints`` one number for every
            joint or four in joint order; ``regions`` one number for every
            cuff or ``THIGH,SHANK``; ``session`` a session JSON file;
            ``motor`` a drive preset's name; ``cuffs`` ``split`` (unset: the
            published cuffs) or ``isotropic``; ``compliance`` a stiffness
            that also switches the joint spring on.
        choices: the values allowed, for a ``value`` of a closed set.
        words: a ``switch``'s words for true and false.
        const: what a ``flag`` sets.
        metavar: the value's name in the help (default: from the key).

    """

    option: str
    key: str
    group: str
    form: str = "value"
    choices: tuple[str, ...] | None = None
    words: tuple[str, str] = ("on", "off")
    const: Any = True
    metavar: str | None = None

    @property
    def dest(self) -> str:
        """The attribute argparse gives the option."""
        return self.option.removeprefix("--").replace("-", "_")


_GAIT = "gait (paper §III)"
_RUN = "the run"
_DRIVE = "drives and joints"
_BELT = "treadmill belt and foot contact"
_PELVIS = "pelvis and body-weight support"
_DEVICE = "what the device believes (the plant simulates urdf.exo and urdf.patient)"
_MODES = "interaction modes and the patient's torques"
_ACTIVE = "active patient (interaction.patient_torque = active)"
_SAFETY = "safety"


def _o(option: str, key: str, group: str, **kw: Any) -> LongOption:
    return LongOption(option, key, group, **kw)


#: The gait's options, shared with ``exo-ctrl gait``.
GAIT_OPTIONS: tuple[LongOption, ...] = (
    _o("--step-length", "gait.step_length", _GAIT, metavar="S"),
    _o("--lift-height", "gait.lift_height", _GAIT, metavar="H"),
    _o("--hip-height", "gait.hip_height", _GAIT, metavar="HS"),
    _o("--pelvis-excursion", "gait.pelvis_excursion", _GAIT, metavar="M"),
    _o("--shape-coeff", "gait.shape_coeff", _GAIT, metavar="KV"),
    _o("--period", "gait.period", _GAIT, metavar="T"),
    _o("--duty-factor", "gait.duty_factor", _GAIT, metavar="B"),
    _o("--landing-speed", "gait.landing_speed_mps", _GAIT, metavar="M/S"),
    _o("--landing-depth", "gait.landing_depth_m", _GAIT, metavar="M"),
    _o("--exo", "urdf.exo", _GAIT, metavar="URDF"),
)

#: Every long option of ``simulate``, in the order they are listed.
LONG_OPTIONS: tuple[LongOption, ...] = (
    *GAIT_OPTIONS,
    _o("--patient", "urdf.patient", _RUN, metavar="URDF|human"),
    _o("--exercise", "run.exercise", _RUN, choices=EXERCISES),
    _o("--ramp-in", "run.ramp_in_s", _RUN),
    _o("--ramp-out", "run.ramp_out_s", _RUN),
    _o("--cuff-fit", "run.cuff_fit", _RUN, choices=CUFF_FITS),
    _o("--misalignment-hip", "misalignment.hip_xz", _RUN, form="pair", metavar="DX,DZ"),
    _o("--misalignment-knee", "misalignment.knee_xz", _RUN, form="pair", metavar="DX,DZ"),
    _o("--rate", "run.control_rate_hz", _RUN, metavar="HZ"),
    _o("--substeps", "run.plant_substeps", _RUN, metavar="N"),
    _o("--motor", "motor", _DRIVE, form="motor", choices=MOTOR_PRESETS),
    _o("--joint-stiffness", "joint_compliance.stiffness_Nm_per_rad", _DRIVE, form="compliance"),
    _o("--joint-damping", "joint_compliance.damping_Nm_s_per_rad", _DRIVE, metavar="NM_S_PER_RAD"),
    _o("--kp", "gains.kp", _DRIVE, form="joints", metavar="V/RAD"),
    _o("--kd", "gains.kd", _DRIVE, form="joints", metavar="V.S/RAD"),
    _o("--contact", "contact.enabled", _BELT, form="switch"),
    _o("--patient-feet", "contact.patient_feet", _BELT, form="switch"),
    _o("--friction", "contact.friction_coeff", _BELT, metavar="MU"),
    _o("--belt-height", "contact.belt.height_m", _BELT),
    _o("--belt-mass", "contact.belt.mass_kg", _BELT),
    _o("--belt-bandwidth", "contact.belt.bandwidth_hz", _BELT),
    _o("--speed-profile", "treadmill.speed_profile", _BELT, metavar="T1:V1,T2:V2,..."),
    _o("--sync", "treadmill.sync", _BELT, form="switch"),
    _o("--pelvis", "pelvis.supported", _PELVIS, form="switch", words=("supported", "fixed")),
    _o("--bws", "pelvis.bws_fraction", _PELVIS, metavar="FRACTION"),
    _o("--body-mass", "pelvis.body_mass_kg", _PELVIS),
    _o("--cuff-force-limit", "qp.cuff_force_limit_N", _DEVICE, form="regions", metavar="N"),
    _o("--controller-patient", "belief.patient", _DEVICE, metavar="nominal|truth|URDF"),
    _o("--controller-exo", "belief.exo", _DEVICE, metavar="URDF"),
    _o("--controller-cuffs", "belief.cuffs", _DEVICE, form="cuffs", choices=("isotropic", "split")),
    _o("--patient-height", "belief.patient_height_m", _DEVICE),
    _o("--patient-mass", "belief.patient_mass_kg", _DEVICE),
    _o("--patient-sex", "belief.patient_sex", _DEVICE, choices=SEXES),
    _o("--estimator", "estimation.estimator", _DEVICE, choices=ESTIMATORS),
    _o("--cuff-sensors", "cuff_sensors.mode", _DEVICE, choices=CUFF_SENSOR_SETS),
    _o("--patient-torque", "interaction.patient_torque", _MODES, choices=PATIENT_KINDS),
    _o("--mode", "interaction.mode", _MODES, choices=MODES),
    _o("--tunnel-width", "path.tunnel_width_m", _MODES),
    _o("--path-support", "path.support_N", _MODES),
    _o("--session", "session", _MODES, form="session", metavar="FILE.json"),
    _o("--guidance", "modes.guidance", _MODES, metavar="G"),
    _o("--force-gain", "modes.force_gain", _MODES, form="joints", metavar="K"),
    _o("--aan-forgetting", "modes.aan_forgetting", _MODES, metavar="F"),
    _o("--aan-gain", "modes.aan_gain", _MODES, form="joints", metavar="NM_PER_RAD"),
    _o("--patient-strength", "patient_active.strength", _ACTIVE, form="joints", metavar="S"),
    _o("--patient-step-length", "patient_active.step_length_m", _ACTIVE),
    _o("--patient-period", "patient_active.period_s", _ACTIVE),
    _o("--patient-delay", "patient_active.delay_s", _ACTIVE),
    _o("--patient-seed", "patient_active.seed", _ACTIVE, metavar="S"),
    _o("--patient-spastic", "patient_active.spastic", _ACTIVE, form="flag"),
    _o("--no-safety", "safety.safety", _SAFETY, form="flag", const=False),
    _o(
        "--safety-force",
        "safety.safety_use_estimate",
        _SAFETY,
        form="switch",
        words=("estimate", "truth"),
    ),
    _o("--safety-widen", "safety.safety_widen", _SAFETY, form="flag"),
    _o("--stop-reaction", "safety.stop_reaction", _SAFETY, choices=STOP_REACTIONS),
    _o("--estop-at", "safety.estop_at_s", _SAFETY),
)

#: What a form adds to the key's own meaning in the option's help.
_FORM_NOTES = {
    "pair": "given as two numbers A,B",
    "joints": "one number for every joint, or four in joint order (left hip, left knee, "
    "right hip, right knee)",
    "regions": "one number for every cuff, or two, THIGH,SHANK, each for both legs' cuffs",
    "session": "read from a JSON file: a list of segments, each {duration [s], mode, its "
    "parameters, belt_speed [m/s]} (exo_ctrl/sim/session.py); the run lasts their sum",
    "motor": "a preset: default (an energy-consistent brushless motor with the paper's "
    "winding, a 120:1 harmonic drive) or paper-printed (Table I as printed: not "
    "energy-consistent, warns; its own gains kp 100, kd 2 unless given)",
    "cuffs": "split (unset: the published normal and shear stiffness of the cuff-tissue "
    "interface, exo_ctrl/plant/cuffs.py, the run's cuffs section) or isotropic (the paper's "
    "8 N/mm in every direction)",
    "compliance": "above 0 switches the joint spring on (joint_compliance.enabled)",
}


#: An option's value's name by the unit its key ends with.
_METAVARS = {
    "_s": "SEC",
    "_m": "M",
    "_kg": "KG",
    "_hz": "HZ",
    "_N": "N",
    "_Nm_per_rad": "NM_PER_RAD",
}


def _field(key: str) -> tuple[type, str]:
    """The dataclass holding scenario key ``key`` and the field's name."""
    *tables, name = key.split(".")
    cls = table_class(tables)
    if cls is None:
        raise KeyError(key)  # the table is this module's own
    return cls, name


@functools.cache
def _defaults() -> dict[str, Any]:
    """``SimConfig()``'s scenario document: every key's default."""
    return document_from_config(SimConfig())


def _default(key: str) -> Any:
    value: Any = _defaults()
    for part in key.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    return value


def _number_type(opt: LongOption) -> Callable[[str], Any] | None:
    """The argparse type of a ``value`` option: its field's number type, else text."""
    cls, name = _field(opt.key)
    text = str(field_types(cls).get(name))
    if text in ("<class 'int'>", "int | None", "typing.Optional[int]"):
        return int
    if text in ("<class 'float'>", "float | None", "typing.Optional[float]"):
        return float
    return None


def _shown(opt: LongOption) -> str:
    """The option's default as its text would give it."""
    value = _default(opt.key)
    if opt.form == "switch":
        return "none" if value is None else opt.words[0 if value else 1]
    if opt.form == "flag":
        return "off"
    if opt.form == "motor":
        return "default"
    if opt.form == "cuffs":
        return "split" if value is None else "isotropic"
    if opt.form == "compliance":
        return "0: a rigid drive"
    if opt.form == "joints" and isinstance(value, (list, tuple)) and len(set(value)) == 1:
        value = value[0]
    if value is None:
        return "none"
    if isinstance(value, (list, tuple)):
        return ",".join(f"{x:g}" for x in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _help(opt: LongOption) -> str:
    """The option's help: the field's meaning and unit, the key, the form, the default."""
    cls, name = _field(opt.key)
    if opt.form in ("motor", "session"):
        text = field_docs(SimConfig).get(opt.key, opt.key)
    else:
        text = field_docs(cls).get(name, name)
    text = plain_text(text).rstrip(".")
    if opt.form == "flag":
        text = f"sets {opt.key} = {str(opt.const).lower()}, the key being: {text}"
    note = _FORM_NOTES.get(opt.form)
    if note:
        text += f"; {note}"
    if opt.key == "pelvis.supported":  # the gait it implies (SUPPORTED_GAIT)
        implied = ", ".join(f"gait.{name} = {v:g}" for name, v in SUPPORTED_GAIT.items())
        text += f"; supported also sets {implied} where no option gives them"
    return f"{text} (scenario key {opt.key}) (default {_shown(opt)})"


def add_long_options(
    parser: argparse.ArgumentParser, options: tuple[LongOption, ...] = LONG_OPTIONS
) -> list[argparse.Action]:
    """Add ``options`` to ``parser``, each absent from the parsed namespace unless given.

    Returns:
        the actions added, in order.

    """
    groups: dict[str, Any] = {}
    actions = []
    for opt in options:
        if opt.group not in groups:
            groups[opt.group] = parser.add_argument_group(opt.group)
        group = groups[opt.group]
        kw: dict[str, Any] = {"default": argparse.SUPPRESS, "help": _help(opt), "dest": opt.dest}
        if opt.form == "flag":
            actions.append(group.add_argument(opt.option, action="store_true", **kw))
            continue
        if opt.form == "switch":
            kw["choices"] = opt.words
        elif opt.choices is not None:
            kw["choices"] = opt.choices
        elif opt.form in ("value", "compliance"):
            kw["type"] = _number_type(opt) if opt.form == "value" else float
        metavar = opt.metavar
        if metavar is None and "choices" not in kw:
            name = opt.key.rsplit(".", 1)[-1]
            unit = next((m for suffix, m in _METAVARS.items() if name.endswith(suffix)), None)
            metavar = unit or name.upper()
        actions.append(group.add_argument(opt.option, metavar=metavar, **kw))
    return actions


def given_options(args: argparse.Namespace) -> list[LongOption]:
    """The long options given in ``args``, in :data:`LONG_OPTIONS`' order."""
    return [opt for opt in LONG_OPTIONS if hasattr(args, opt.dest)]


def option_settings(args: argparse.Namespace) -> list[tuple[str, Any, str]]:
    """The settings the long options given in ``args`` make: (key path, value, option).

    A form's implied settings first, then each option's own, so that an
    option given for an implied key wins.  A value of None unsets its key.

    Raises:
        InvalidParameter: a value that does not read in its form, a session
            file that cannot be read.

    """
    implied: list[tuple[str, Any, str]] = []
    own: list[tuple[str, Any, str]] = []
    for opt in given_options(args):
        value = getattr(args, opt.dest)
        main, extra = _read(opt, value)
        own.append((opt.key, main, opt.option))
        implied += [(key, val, opt.option) for key, val in extra]
    return implied + own


def _read(opt: LongOption, value: Any) -> tuple[Any, list[tuple[str, Any]]]:
    """An option's parsed value as its key's plain value, and the settings it implies."""
    if opt.form == "value":
        return value, []
    if opt.form == "flag":
        return opt.const, []
    if opt.form == "switch":
        on = value == opt.words[0]
        supported = on and opt.key == "pelvis.supported"
        return on, [(f"gait.{name}", v) for name, v in SUPPORTED_GAIT.items()] if supported else []
    if opt.form == "pair":
        return list(_numbers(opt, value, (2,))), []
    if opt.form == "regions":
        numbers = _numbers(opt, value, (1, 2))
        return (numbers[0] if len(numbers) == 1 else list(numbers)), []
    if opt.form == "joints":
        numbers = _numbers(opt, value, (1, 4))
        return list(numbers * 4 if len(numbers) == 1 else numbers), []
    if opt.form == "session":
        session = load_session(value)
        return _plain(session), [("run.duration_s", session.total_s)]
    if opt.form == "motor":
        extra = []
        if value == "paper-printed":
            gains = PDGains.paper_printed()
            extra = [("gains.kp", list(gains.kp)), ("gains.kd", list(gains.kd))]
        return _plain(motor_preset(value)), extra
    if opt.form == "cuffs":
        return (_plain(CuffParams.isotropic()) if value == "isotropic" else None), []
    if opt.form == "compliance":
        return value, [("joint_compliance.enabled", value > 0)]
    raise ValueError(f"unknown form {opt.form!r}")  # the table is this module's own


def _numbers(opt: LongOption, text: str, counts: tuple[int, ...]) -> tuple[float, ...]:
    """``text`` as comma-separated numbers, as many as one of ``counts``."""
    allowed = " or ".join(str(n) for n in counts)
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in counts:
        raise InvalidParameter(opt.option, text, f"{allowed} comma-separated numbers")
    return values


def _plain(part: Any) -> Any:
    """A parameter dataclass as a scenario document's table (tuples as lists)."""
    return _as_lists(dataclasses.asdict(part))


def _as_lists(data: Any) -> Any:
    if isinstance(data, dict):
        return {key: _as_lists(value) for key, value in data.items()}
    if isinstance(data, (list, tuple)):
        return [_as_lists(value) for value in data]
    return data
