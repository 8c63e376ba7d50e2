"""Exceptions raised by exo_ctrl.

Every error the library raises on purpose derives from :class:`ExoCtrlError`,
and, where it fits, from the matching built-in (``ValueError`` for bad input,
``RuntimeError`` for a failed run), so callers can catch either.  Each
subclass carries the data that explains it as attributes.
"""

from __future__ import annotations

import math
import os

__all__ = [
    "CuffBoundTooTight",
    "ExoCtrlError",
    "InvalidLog",
    "InvalidModel",
    "InvalidParameter",
    "InvalidScenario",
    "KernelStatusError",
    "MissingDependency",
    "OutputError",
    "PluginError",
    "RecordingError",
    "SimulationDiverged",
    "SweepError",
    "Terminated",
    "UnreachableFootTarget",
]


class ExoCtrlError(Exception):
    """Base class of every error raised by exo_ctrl."""


#: The longest integer an :class:`InvalidParameter` message shows whole [digits].
_LONGEST_VALUE = 100


class InvalidParameter(ExoCtrlError, ValueError):
    """A parameter is outside what is allowed.

    Attributes:
        name: parameter name as the user spells it (``step_length``).
        value: the offending value.
        allowed: what is allowed, in words with units (``"in (0, 2] m"``).

    """

    def __init__(self, name: str, value: object, allowed: str, detail: str = "") -> None:
        self.name = name
        self.value = value
        self.allowed = allowed
        shown = repr(value)
        if isinstance(value, int) and len(shown) > _LONGEST_VALUE:  # a 400-digit number
            shown = f"{shown[:40]}…{shown[-12:]} ({len(shown)} digits)"
        message = f"{name} must be {allowed}; got {shown}"
        if detail:
            message += f" ({detail})"
        super().__init__(message)


class InvalidScenario(ExoCtrlError, ValueError):
    """A scenario file (or a ``--set`` override) cannot be used.

    Attributes:
        source: the file's path, or the option that set the key (``--set``,
            ``--period``).
        key: the key path at fault (``gait.step_length``; "" for the whole file).
        reason: what is wrong and what is allowed.

    """

    def __init__(self, source: str, key: str, reason: str) -> None:
        self.source = source
        self.key = key
        self.reason = reason
        if source.startswith("--"):  # an option of the command line set the key
            super().__init__(f"{source}: {key}: {reason}" if key else f"{source}: {reason}")
            return
        where = f"{source}: {key}" if key else source
        super().__init__(f"scenario {where}: {reason}")


class InvalidModel(ExoCtrlError, ValueError):
    """A robot model (URDF) cannot be used.

    Attributes:
        source: file path or model name.
        element: the link, joint or frame at fault ("" for the whole file).
        reason: what is wrong and what is required.

    """

    def __init__(self, source: str, element: str, reason: str) -> None:
        self.source = source
        self.element = element
        self.reason = reason
        where = f"{element!r} in {source}" if element else source
        super().__init__(f"invalid model: {where}: {reason}")


class UnreachableFootTarget(ExoCtrlError, ValueError):
    """A planned foot point lies outside the leg's reachable annulus.

    Attributes:
        point: (x, z) of the foot relative to the hip [m].
        reach: (min_reach, max_reach) distance hip to foot [m].
        time: time of the point on the plan [s], or None.

    ``cause``: what set the point, appended to the message (the gait's parameters).

    """

    def __init__(
        self,
        point: tuple[float, float],
        reach: tuple[float, float],
        time: float | None = None,
        what: str = "foot target",
        cause: str = "",
    ) -> None:
        self.point = point
        self.reach = reach
        self.time = time
        distance = math.hypot(point[0], point[1])  # no overflow for a point 1e200 m away
        at = f" at t = {time:.4g} s" if time is not None else ""
        super().__init__(
            f"{what} (x = {point[0]:.4g} m, z = {point[1]:.4g} m){at} is "
            f"{distance:.4g} m from the hip; the leg reaches from "
            f"{reach[0]:.4g} m to {reach[1]:.4g} m" + (f" ({cause})" if cause else "")
        )


class CuffBoundTooTight(ExoCtrlError, ValueError):
    """A cuff-force bound whose margin leaves less than the force the gait needs.

    The QP holds each cuff's predicted force within F_max − m_c
    (:mod:`exo_ctrl.control.qp.margin`); below the working force F_work,c
    (the nominal patient's gravity load along the plan) no command can keep
    the bound while carrying the leg.  With the pelvis supported the working
    force is the whole load the plan puts on the cuff: the QP would hold a
    lower bound by leaving the plan, and a leg off its plan on the belt can
    strike it.

    Attributes:
        bound_N: F_max, the user's bound on this cuff [N].
        margin_N: m_c, the cuff's margin [N].
        working_N: F_work,c [N].
        cuff: the cuff's name.
        gait: the gait, in words.
        supported: the pelvis is supported (the working force is the plan's load).
        given: the bound as the user gave it, one number or (thigh, shank) [N]
            (None: ``bound_N``).

    """

    def __init__(
        self,
        bound_N: float,
        margin_N: float,
        working_N: float,
        cuff: str,
        gait: str,
        supported: bool = False,
        given: object = None,
    ) -> None:
        self.bound_N = bound_N
        self.margin_N = margin_N
        self.working_N = working_N
        self.cuff = cuff
        self.gait = gait
        self.supported = supported
        need = f"the {working_N:.1f} N the cuff carries of the leg's weight along the plan"
        other = "or choose a slower gait"
        if supported:
            need = (
                f"the {working_N:.1f} N the plan puts on the cuff: with the pelvis supported "
                "the QP cannot leave the plan to hold its bound, since a leg off its plan can "
                "strike the belt"
            )
            other = "or add cuff sensors (--cuff-sensors), which shrink the margin"
        shown, which = f"{bound_N:g} N", "the bound"
        if isinstance(given, (tuple, list)) and len(set(given)) > 1:  # (thigh, shank)
            region = "shank" if cuff.endswith("_shank") else "thigh"
            shown, which = f"[{given[0]:g}, {given[1]:g}] N (thigh, shank)", f"the {region} bound"
        super().__init__(
            f"qp.cuff_force_limit_N = {shown} cannot be held on {gait}: the "
            f"{cuff} cuff's margin of {margin_N:.1f} N (what the device does not know) "
            f"leaves {bound_N - margin_N:.1f} N, less than {need}; raise "
            f"{which} to at least {math.ceil(margin_N + working_N)} N {other}"
        )


class SimulationDiverged(ExoCtrlError, RuntimeError):
    """A simulated quantity became non-finite or absurdly large.

    Attributes:
        time: simulated time of the failure [s].
        quantity: name of the quantity that blew up.
        value: its value.
        limit: the bound it crossed.

    """

    def __init__(self, time: float, quantity: str, value: float, limit: float) -> None:
        self.time = time
        self.quantity = quantity
        self.value = value
        self.limit = limit
        super().__init__(
            f"simulation diverged at t = {time:.4f} s: {quantity} = {value:.4g} "
            f"(allowed magnitude {limit:.4g})"
        )


class RecordingError(ExoCtrlError, RuntimeError):
    """A recording could not be written or read back."""


class InvalidLog(ExoCtrlError, ValueError):
    """A logged series (CSV file or arrays) cannot be used.

    Attributes:
        source: file path or ``"arrays"``.
        reason: what is wrong and what is required.
        line: 1-based line of the file at fault (None when not a line).
        column: the column at fault ("" when none).

    """

    def __init__(self, source: str, reason: str, line: int | None = None, column: str = "") -> None:
        self.source = source
        self.reason = reason
        self.line = line
        self.column = column
        where = source
        if line is not None:
            where += f", line {line}"
        if column:
            where += f", column {column!r}"
        super().__init__(f"invalid log {where}: {reason}")


class PluginError(ExoCtrlError, ValueError):
    """A user's controller or estimator broke its interface's contract during a run.

    Attributes:
        plugin: its ``module:Class`` name.
        tick: the control tick k at fault.
        time: its time t_k [s].
        reason: what it returned and what is allowed.
        kind: ``"controller"`` or ``"estimator"``.

    """

    def __init__(
        self, plugin: str, tick: int, time: float, reason: str, kind: str = "controller"
    ) -> None:
        self.plugin = plugin
        self.tick = tick
        self.time = time
        self.reason = reason
        self.kind = kind
        super().__init__(f"{kind} {plugin} at tick {tick} (t = {time:.4g} s): {reason}")


class SweepError(ExoCtrlError, RuntimeError):
    """A sweep cannot run (e.g. the Dask scheduler cannot be reached)."""


class MissingDependency(ExoCtrlError, ImportError):
    """An optional dependency is not installed; the message says what to install."""


class KernelStatusError(ExoCtrlError, RuntimeError):
    """A compiled kernel returned a status its caller cannot answer (a programming error)."""


class OutputError(ExoCtrlError, OSError):
    """Writing an output file failed (disk full, device error, permission).

    Attributes:
        path: the output path as the user gave it.
        reason: the operating system's reason (``"No space left on device"``).

    """

    def __init__(self, path: str | os.PathLike[str], reason: str) -> None:
        self.path = str(path)
        self.reason = reason
        super().__init__(f"cannot write {self.path}: {reason}")


class Terminated(KeyboardInterrupt):
    """The process was asked to stop by a signal (SIGTERM): ends a run as Ctrl-C does.

    Not an error (like KeyboardInterrupt, which it derives from): the run
    stops where it is, keeps its data, and its recording gets its end.

    Attributes:
        signal_name: the signal's name (``"SIGTERM"``).

    """

    def __init__(self, signal_name: str) -> None:
        self.signal_name = signal_name
        super().__init__(f"terminated by {signal_name}")
