"""The first run's compile on two cores: a helper process compiles the tick's back half.

The first run of a feature set after an install compiles some 40–60 kernels
(numba, ``cache=True``), 10–17 s on one core of these machines, while the
second core idles.  numba compiles one kernel at a time per process (its
compiler lock), but each process saves what it compiles to the cache on disk,
and a kernel's first call with new argument types looks there before it
compiles.  So :class:`Warmup`, when the cache holds no marker for the run's
features (:func:`feature_key`), starts a helper: a child Python process that
builds the same run without starting it (the kernels the build itself calls,
the synchronised plan's start and the cuff-load model's, are left to this
process: both would compile them at once) and calls the tick's stages in the reverse of the order
this process first calls them (the estimator's step, the applied log row,
the plant's step, the supervisor, the controller;
:meth:`~exo_ctrl.sim.tick.Runner.compile_back`), while this process compiles
from the front (the cuffs' fit, the statistics, the sensors, the
estimator's start).  Where they meet, each loads what the other saved.

**Why it is safe.**  numba keeps one index file per kernel and saves an entry
by reading the index, adding the entry under the next free data-file number
and replacing the index, then the data file.  Two processes saving *different*
signatures of one kernel at the same moment can both take the same number, and
the index can end up naming the other signature's machine code.  Both
processes here build the same run, and every kernel is called with one
signature per run (``tests/sim/test_warmup.py`` checks the index files after a
cold run), so the two can only save the same entry, under the same name, with
equal contents.  A save the other process interrupts half-way (an index entry
whose data file is missing) is compiled again by numba.

**The helper** only compiles: it writes nothing but numba's cache, its output
goes nowhere, and any error in it is ignored (it costs time, never a result).
It dies with this process (``prctl(PR_SET_PDEATHSIG)`` on Linux and a watch on
its parent), and :meth:`Warmup.finish` stops it when the run ends.  A run that
completes leaves the marker (with the helper off too: a library run), so
later runs of these features start no helper, and say they load the kernels.
The CLI's ``simulate`` uses it; ``simulate(..., warmup=True)`` from Python;
``EXO_CTRL_WARMUP=0`` turns it off, ``EXO_CTRL_WARMUP=1`` starts it even
when no core seems free (:func:`core_free`).  Sweeps do not use it (their pools compile
the first point in the parent, then share the cache).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numba

from .. import _jit_cache
from ..control import controller_name
from ..estimation import ESTIMATORS, estimator_name
from .config import CONTROLLERS, SimConfig

__all__ = ["ENV", "Warmup", "core_free", "feature_key", "marker_dir"]

#: The environment variable: "0" turns the helper off, "1" starts it whatever the load.
ENV = "EXO_CTRL_WARMUP"

_PACKAGE = Path(__file__).resolve().parents[1]

#: The largest configuration sent to the helper: what a pipe takes without a reader (Linux) [B].
_PIPE_BYTES = 65536


def feature_key(config: SimConfig) -> str:
    """The run's features that set its kernels' argument types, hashed with the sources.

    Two runs with equal keys compile the same kernels (the gait, gains and
    durations change values, not types).  A feature left out of the key costs
    at worst a helper that was not needed, or one not started: never a result.
    """
    belief = config.belief
    features = (
        controller_name(config.controller),
        config.mode,
        estimator_name(config.estimator),
        config.patient_torque,
        config.safety,
        config.stop_reaction,
        config.estop_at_s is None,
        tuple(sorted({type(f).__name__ + str(getattr(f, "kind", "")) for f in config.faults})),
        config.exercise,
        config.session is None,
        config.speed_profile is None,
        config.sync,
        config.contact.enabled,
        config.contact.patient_feet,
        config.pelvis.supported,
        config.joint_compliance.enabled,
        config.plant_substeps == 1,
        config.cuffs.is_isotropic,
        belief.cuffs is None or belief.cuffs.is_isotropic,
        belief.motor is None,
        config.cuff_fit,
        config.ramp_in_s == 0.0,
    )
    digest = hashlib.sha256(_package_sources().encode())
    digest.update(repr(features).encode())
    return digest.hexdigest()[:24]


@functools.cache
def _package_sources() -> str:
    """The package's source hash, once per process (8 ms here: every ``.py`` file read).

    The compiled kernels of a process are those of the sources it imported,
    so a hash taken later in the same process would name the same kernels.
    """
    return _jit_cache.source_hash(_PACKAGE)


def marker_dir() -> Path | None:
    """Where the markers live: beside the cache's source stamp; None if not writable.

    (:func:`exo_ctrl._jit_cache.stamp_path`: the stamp's refresh deletes the old markers.)
    """
    root = _jit_cache.stamp_path(_PACKAGE, numba.config.CACHE_DIR).parent
    return root if os.access(root, os.W_OK) else None


def core_free() -> bool:
    """Whether a core is free for the helper: the 1-minute load average below cores − ½.

    On a machine whose cores are all busy the helper's compiles only take
    time from this process's (measured here, PD, with one other busy process
    on two cores: 16 → 20 s).
    """
    try:
        cores = len(os.sched_getaffinity(0))
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        return False
    return cores >= 2 and load < cores - 0.5


class Warmup:
    """The helper of one run (module docstring): start it, then :meth:`finish` it.

    Args:
        config: the run.
        enabled: False: no helper (as ``EXO_CTRL_WARMUP=0``); the marker
            is still read and, after a completed run, written.

    Attributes:
        process: the helper, or None when none was started (the cache is warm
            for these features, no cache directory can be written, no core is
            free, :func:`core_free`, or it is off).
        warm: a run of these features has completed since the cache was
            made (with or without a helper, from the command line or the
            library): its kernels are loaded, not compiled (the marker;
            False when unknown).

    """

    def __init__(self, config: SimConfig, enabled: bool = True) -> None:
        self.process: subprocess.Popen | None = None
        self._marker: Path | None = None
        self.warm = False
        where = marker_dir()
        if where is None:
            return
        self._marker = where / _jit_cache.WARM_MARKERS.replace("*", feature_key(config))
        self.warm = self._marker.exists()
        setting = os.environ.get(ENV, "")
        if not enabled or setting == "0":
            return
        users = (controller_name(config.controller), estimator_name(config.estimator))
        if users[0] not in CONTROLLERS or users[1] not in ESTIMATORS:
            return  # a user's controller or estimator: its code runs in the user's process only
        if self.warm or (setting != "1" and not core_free()):
            return
        try:
            payload = pickle.dumps(config)
        except Exception:  # a configuration that does not pickle: no helper
            return
        if len(payload) > _PIPE_BYTES:  # written at once, never waiting for the child
            return
        with contextlib.suppress(OSError):
            self.process = subprocess.Popen(
                [sys.executable, "-m", "exo_ctrl.sim.warmup_helper", str(os.getpid())],
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            if self.process.stdin is not None:
                with contextlib.suppress(OSError):
                    self.process.stdin.write(payload)
                    self.process.stdin.close()

    def finish(self, completed: bool) -> None:
        """Stop the helper; mark the cache warm for these features if the run ``completed``."""
        if self.process is not None:
            if self.process.poll() is None:
                self.process.kill()
            self.process.wait()
            self.process = None
        if completed and self._marker is not None:
            with contextlib.suppress(OSError):
                self._marker.touch()
