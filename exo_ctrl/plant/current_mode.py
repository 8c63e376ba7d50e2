r"""The servo driver's current mode: a PI on the measured current, inside the plant's step.

A drive in current mode is handed a current reference ``I*`` [A] instead of
a voltage; the driver's PI on its own current measurement sets the voltage
at the driver's rate, far above the control rate.  A servo driver samples
its PI current controller at 25 kHz (maxon EPOS4 50/5 Hardware Reference,
rel6852, 2017, §2.1: "Sampling rate PI current controller 25 kHz (40 µs)")
and is tuned to settle within about 1 ms with under 5 % overshoot (Moog MSD
Servo Drive Device Help, CB40859-001, 2018, §7.3); at 25 kHz a bandwidth of
1/18 of the sampling rate (TI's default for its servo current loop, SPRACO3)
is 1.4 kHz.  :data:`CURRENT_LOOP_BANDWIDTH_HZ` takes f_c = 1 kHz.

**The closed loop.**  Pole-zero cancellation, the usual tuning of a current
PI: with ``K_p = L ω_c`` and ``K_i = R ω_c`` (ω_c = 2π f_c) the PI's zero
cancels the winding's pole R/L, and the winding ``L dI/dt + R I + e = U``
under ``U = e + K_p (I* − I) + K_i ∫(I* − I) dt`` (the back-EMF ``e = i_G
ω / k_E`` fed forward) closes as a first-order lag of bandwidth ω_c.  At
25 kHz the sampling delay (40 µs against 1/ω_c = 160 µs) is left out, so the
loop's response over a step h with ``I*`` and ω held is exact, with no
25 kHz sub-steps: with ``y = ω_c h``, ``ε_c = e^{−y}`` and
``φ_c = (1 − ε_c)/y``,

.. math::

    I(h) = I^* + (I_0 - I^*)\,ε_c, \qquad
    \bar I = I^* + (I_0 - I^*)\,φ_c,

and the voltage the driver applies, ``U(t) = e + R I(t) + L dI/dt = e + L ω_c
I^* + (R − L ω_c) I(t)``, is affine in a current that moves monotonically
from ``I_0`` to ``I(h)``, so it is within the supply over the whole step iff
``U(0)`` and ``U(h)`` are.  Its mean over the step, ``Ū = e + R Ī + L (I(h)
− I_0)/h``, is the drive's ``applied_voltage_V``.  The mean current does not
depend on the speed: the drive has no back-EMF damping (the driver
compensates it), only the gearbox's (:mod:`exo_ctrl.plant.motor`).

**Voltage-limited.**  When the lag would need more than the supply at some
instant of the step, the driver is voltage-limited: it applies, held over the
step, the voltage that ends the step on the lag's current,

.. math::

    U = e + R\,\frac{I(h) - ε I_0}{1 - ε}, \qquad ε = e^{-h R / L},

clipped to ``±U_max``; the step is then the voltage step of
:mod:`exo_ctrl.plant.motor` (its current never passes the lag's).

**The reference.**  ``I*`` is clipped to ``±I_max`` here; the controller's
side (:mod:`exo_ctrl.control.current_loop`) makes it from a torque.  A drive
is in current mode for a step when the voltage it is handed is the
feedforward voltage ``u_ff`` written with the reference (the controller's
own command, passed on unchanged by the supervisor); any other voltage (the
supervisor's stop command, a command delayed by a fault) it applies as a
voltage.  ``u_ff`` is NaN until a reference is written: voltage commands never
enter current mode.
"""

from __future__ import annotations

from typing import Any

from .._jit import kernel

__all__ = ["CURRENT_LOOP_BANDWIDTH_HZ", "CURRENT_MODE", "follow_reference"]

#: f_c, the current loop's bandwidth in a real servo driver [Hz] (module docstring).
CURRENT_LOOP_BANDWIDTH_HZ = 1000.0

#: The code of a drive's step in current mode, in its ``held`` field
#: (0.0: a voltage step, 1.0: held at its limit; :mod:`exo_ctrl.plant.energy`).
CURRENT_MODE = 2.0


@kernel
def follow_reference(m: Any, j: int, omega: float) -> tuple[bool, float]:
    """Drive j's step in current mode on the drives' record ``m`` (module docstring).

    Returns ``(True, Ū)`` when the lag stayed within the supply: the step
    is written (``current``, ``mean``, ``u``, ``i_prev``, ``i_asym`` = I*,
    ``held`` = :data:`CURRENT_MODE`, ``saturated`` 0); else ``(False, U)``,
    nothing written, ``U`` [V] the voltage for the voltage step.
    """
    i_max, u_max, res = m.i_max, m.u_max, m.res
    ref = min(max(m.i_ref[j], -i_max), i_max)
    i0 = m.current[j]
    d0 = i0 - ref
    end = ref + d0 * m.eps_c
    emf = m.kb * omega
    slope = res - m.wcl  # R − L ω_c
    u0 = emf + m.wcl * ref + slope * i0
    u1 = emf + m.wcl * ref + slope * end
    if abs(u0) > u_max or abs(u1) > u_max:
        eps = m.eps
        return False, emf + res * (end - eps * i0) / (1.0 - eps)
    mean = ref + d0 * m.phi_c
    m.current[j] = end
    m.mean[j] = mean
    m.u[j] = emf + res * mean + m.ind * (end - i0) / m.h
    m.i_prev[j] = i0
    m.i_asym[j] = ref
    m.held[j] = CURRENT_MODE
    m.saturated[j] = 0.0
    return True, m.u[j]
