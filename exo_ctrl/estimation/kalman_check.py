r"""The joint torques' check of the cuff model's error, for :mod:`.kalman_cuff`.

With cuff sensors each measured axis carries the cuff model's error b and
the sensor's bias β (:mod:`.kalman_cuff`); the readings see b + β.  This
check sees b alone, where the joint torques see it: x follows the joint
torques (the encoders' update of the exoskeleton's dynamics, τ_s an input),
so the model's forces already give what each exoskeleton joint sees, and
b must add nothing there.  Per leg and exoskeleton joint j (hip, knee),
after each fresh sample's updates, a scalar pseudo-measurement of (b, β):

    0 = gᵀ (b, β) + ε_j,   g = (g_jca over the read axes (c, a), 0 for β),
    g_jca = aᵀ J_e,c e_j,   ε_j ~ N(0, σ_τ² + ε_τ² τ_j² + h_jᵀ P h_j),

J_e,c e_j the joint's column of rows c and 4 + c of J_Δ (the exoskeleton's
cuff point's Jacobian), τ_j = Σ_(c, a) g_jca aᵀ f_c the model's cuff torque
at the joint over both axes, h_j = Σ_(c, a) g_jca h_ca its view on the leg's
state x (h_ca the reading's row, :mod:`.kalman_cuff`; d's entries zero).
Then, as the readings' update,

    y = −gᵀ (b, β),   S = gᵀ B g + var(ε_j),
    (b, β) ← (b, β) + B g y / S,   B ← B − B g gᵀ B / S.

A joint that sees an axis the set does not read, Σ_(c, a unread) g_jca²
(ρ² (aᵀ f_c)² + σ_00²) > (κ σ_τ)², checks nothing (that axis's model error is
in no b).  The constants: :mod:`.kalman_cuff`.
"""

from __future__ import annotations

from .._jit import kernel, leaf

__all__ = ["add_to_bias", "bias_update", "downdate", "gain", "torque_check"]


@leaf
def add_to_bias(st, s, i, d):
    """Add ``d`` to entry i of leg s's (b, β): i < 4 b of cuff 2 s + i // 2, axis i % 2; else β."""
    if i < 4:
        st.model_error[2 * s + i // 2, i % 2] += d
    else:
        st.sensor_bias[2 * s + (i - 4) // 2, i % 2] += d


@leaf
def gain(M, v, out, n, S):
    """Write M v into ``out`` (first n entries); return S + vᵀ M v, added in index order."""
    for i in range(n):
        x = 0.0
        for j in range(n):
            x += M[i, j] * v[j]
        out[i] = x
        S += v[i] * x
    return S


@leaf
def downdate(M, g, S, n):
    """M ← M − g gᵀ / S over the first n rows and columns, kept symmetric (a scalar update)."""
    for i in range(n):
        for j in range(i, n):
            x = M[i, j] - g[i] * g[j] / S
            M[i, j] = x
            M[j, i] = x


@leaf
def bias_update(st, s, B, pg, y, S):
    """Leg s's (b, β) += B g y and B -= B g gᵀ B / S, ``pg`` = B g (a scalar update's gain)."""
    for i in range(8):
        add_to_bias(st, s, i, pg[i] * y)
    downdate(B, pg, S, 8)


@kernel
def torque_check(st, cr, axes):
    """The joint torques' check of b: 0 = G_j b + ε per exoskeleton joint j (module docstring).

    ``st``, ``cr``: the filter's and the device's cuff records (elements), ``cr.f``,
    ``cr.cs`` and ``st.jd`` as :func:`~.kalman_cuff.cuff_sensor_update` left them
    (the forces at the step's midpoint); ``axes``: the axes read per cuff.
    Uses rows 4–6 of ``st.work``.
    """
    pg, gr, hx = st.work[4], st.work[5], st.work[6]
    h = st.h
    for s in range(2):
        joints = st.joints[s]
        B = st.bias_cov[s]
        P = st.cov[s]
        for j in range(2):
            g = joints[j]
            for i in range(8):
                gr[i] = 0.0
            for i in range(10):
                hx[i] = 0.0
            y = 0.0
            seen = 0.0  # the model's cuff torque at the joint
            unread = 0.0  # the variance of the unread axes' model error the joint sees
            for k in range(2):
                c = 2 * s + k
                cc, sc = cr.cs[c], cr.cs[8 + c]
                ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
                uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
                for a in range(2):
                    ax, az = (-uz, ux) if a == 0 else (ux, uz)
                    x = ax * st.jd[c, g] + az * st.jd[4 + c, g]
                    k_a, c_a = (cr.k, cr.c) if a == 0 else (cr.k_u, cr.c_u)
                    for i in range(4):  # the joint's view of the model's force, on x
                        jn = ax * st.jd[c, joints[i]] + az * st.jd[4 + c, joints[i]]
                        hx[i] -= x * k_a * jn
                        hx[4 + i] += x * (0.5 * h * k_a - c_a) * jn
                    f = ax * cr.f[c] + az * cr.f[4 + c]
                    seen += x * f
                    if a < axes:
                        gr[2 * k + a] = x
                        y -= x * st.model_error[c, a]
                    else:
                        unread += x * x * (st.var_model_start * f * f + st.var_model_start_floor)
            if unread > st.var_check_blind:
                continue  # the joint sees an unread axis's model error, which b does not carry
            S = st.var_torque_check + st.var_check_rel * seen * seen
            S = gain(P, hx, pg, 8, S)  # x's uncertainty of that view: hxᵀ P hx (d's are 0)
            S = gain(B, gr, pg, 8, S)  # and pg = B g for the update
            bias_update(st, s, B, pg, y / S, S)
