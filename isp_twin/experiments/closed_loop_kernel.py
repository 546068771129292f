"""The closed loop's per-sample work, compiled (numba): sensors, controllers, friction, physics.

`isp_twin.experiments.closed_loop.ClosedLoop` runs its samples here when it can
(`available`; no effects on the plant): one call advances many samples,
calling MuJoCo's ``mj_step2`` / ``mj_step1`` itself (by symbol, from the
library the bindings loaded), so a sample costs about one ``mj_step``
instead of ~30 Python calls around it.

Every operation repeats the Python blocks it stands for, in the same order
and with the same floating-point expressions (`Twin.sense`, `Twin.step`,
`Twin._prepare`, `Gyro.read`, `Resolver.read`, `PIController`,
`NotchFilter`, `FrictionFeedForward`, `Bound`, `OuterFollower`), so a run is
bit-identical to the Python path (tests/test_closed_loop_kernel.py compares them);
a change to one of those blocks must be made here too. Eq. 5 itself is not
repeated: the kernels call `isp_twin.model.friction_compiled` (the scalar functions
of `isp_twin.model.friction` compiled from their source), and an edit to friction.py
that the numba cache missed is caught at import (`compiled_law_is_current`). The gyro noise is
drawn before the run from the same generator, in the same order.

State and configuration travel in flat arrays whose layouts are the
constants below; `pack_config` and `initial_state` fill them from the Python
blocks, so the configuration has one source.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from llvmlite import binding as llvm_binding

from isp_twin.model import friction_compiled as law
from isp_twin.model.friction_compiled import law_probe_cases, python_law
from isp_twin.model.twin import MAX_COMMAND, MAX_RATE, REST_RATE, Twin, TwinArrays, mujoco_library

__all__ = [
    "available",
    "KernelConfig",
    "KernelState",
    "pack_config",
    "initial_state",
    "advance",
    "OK",
    "INNER_RATE",
    "INNER_NAN",
    "INNER_SATURATED",
    "TWIN_COMMAND",
    "TWIN_QACC",
    "TWIN_RATE",
    "TWIN_STATE",
    "compiled_law_is_current",
]

_LIB = mujoco_library()


def available(twin: Twin) -> bool:
    """Whether `twin` can be stepped here (MuJoCo's C entry points found, no effects)."""
    return _LIB is not None and not twin.has_effects and hasattr(twin.data, "_address")


# Return codes of `advance` (the Python side turns each into its error message).
OK = 0
INNER_RATE = 1  # err: (axis, omega_1)
INNER_NAN = 2  # err: (axis,)
INNER_SATURATED = 3  # err: (axis,)
TWIN_COMMAND = 4  # err: (slot, command)
TWIN_QACC = 5  # MuJoCo reset the data in mj_step2
TWIN_RATE = 6  # err: (slot, rate)
TWIN_STATE = 7  # MuJoCo reset the data in mj_step1

# Columns of `KernelConfig.inner`, per inner axis.
I_KP, I_KI, I_PI_LIMIT, I_BOUND, I_NOTCH = 0, 1, 2, 3, 4
I_B0, I_B1, I_B2, I_A1, I_A2 = 5, 6, 7, 8, 9
I_NFC, I_GAMMA, I_REST, I_TS, I_TC, I_ALPHA = 10, 11, 12, 13, 17, 21
I_SMOOTH, I_NOISE, I_SCALE, I_SAT_BOUND = 25, 26, 27, 28
I_PI_PARALLEL = 29  # 1.0: parallel PI form (u = kp*e + ki*s), 0.0: series
# Columns of `KernelConfig.outer`, per outer axis.
O_KP, O_KI, O_KD, O_LIMIT = 0, 1, 2, 3
# `KernelConfig.misc`.
M_QUANTUM, M_DT, M_CENTER0, M_CENTER1, M_FOLLOW, M_DIVERGED, M_SAT_LIMIT, M_SAT_SAMPLES = range(8)
# The twin's limits travel as data: numba's cache would keep a stale copy of a constant.
M_MAX_RATE, M_REST_RATE, M_MAX_COMMAND = 8, 9, 10
# `KernelConfig.ints`.
N_SAMPLE_EVERY, N_WINDOW, N_TAPS0, N_TAPS1, N_COL_INNER0, N_COL_INNER1 = range(6)
N_COL_OUTER0, N_COL_OUTER1, N_COL_JOINTS = 6, 7, 8
# Columns of `KernelState.inner`, per inner axis.
S_FILTERED, S_COUNT, S_INTEGRAL, S_Z1, S_Z2, S_SATURATED = range(6)
# `KernelState.ints`.
K_DONE, K_PHASE0, K_PHASE1, K_NFC_POS0, K_NFC_POS1, K_RES_POS, K_DRAW0, K_DRAW1 = range(8)


@dataclass(frozen=True)
class KernelConfig:
    """A closed loop's fixed configuration in flat arrays (layouts: the module constants).

    Attributes:
        inner: shape (2, 32), per inner axis: PI, bound, notch, NFC, gyro (SI,
            digits, counts as in the blocks).
        outer: shape (2, 4), per outer axis: follower kp, ki, kd, limit.
        misc: shape (11,): resolver quantum [rad], dt [s], follower centres
            [rad], follow flag, divergence and saturation limits, the twin's
            `MAX_RATE`, `REST_RATE`, `MAX_COMMAND`.
        ints: shape (9,): gyro sample_every, resolver window, NFC taps, and the
            buffer columns of each axis block and of the joint angles.
    """

    inner: np.ndarray
    outer: np.ndarray
    misc: np.ndarray
    ints: np.ndarray


@dataclass(frozen=True)
class KernelState:
    """A closed loop's mutable state in flat arrays (the kernel writes them in place).

    Attributes:
        inner: shape (2, 8), per inner axis: gyro filter and count, PI
            integral, notch state, saturation average.
        outer: shape (2,), the followers' integrals of the follow error [rad·samples].
        nfc_history: shape (2, max taps), Eq. 12's ring buffers [digits].
        resolver: shape (4, window + 1), the resolvers' past angles [rad].
        command: shape (4,), the commands of the last sample [digits].
        ints: shape (8,), samples done, gyro phases, ring positions, noise draws used.
        twin_ints, twin_floats: the twin's per-step state (`Twin.hot_state`).
        noise: shape (2, draws), the gyros' standard normal deviates in draw order.
        err: shape (2,), details of a failure (see the return codes).
    """

    inner: np.ndarray
    outer: np.ndarray
    nfc_history: np.ndarray
    resolver: np.ndarray
    command: np.ndarray
    ints: np.ndarray
    twin_ints: np.ndarray
    twin_floats: np.ndarray
    noise: np.ndarray
    err: np.ndarray


def pack_config(
    loops, gyros, resolvers, followers, follow, centers, sat_bounds, layout, limits
) -> KernelConfig:
    """The configuration of the Python blocks, packed (`KernelConfig`).

    Args:
        loops: the two `InnerRateLoop`.
        gyros: the two `Gyro`.
        resolvers: the four `Resolver` (same quantum and window).
        followers: the two `OuterFollower`.
        follow: whether the outer gimbals follow the inner ones.
        centers: follower centres [rad], (2,).
        sat_bounds: |command| counted as saturated [digits], (2,).
        layout: the `SignalTable` of the buffer.
        limits: (diverged rate [rad/s], saturation limit, saturation samples).
    """
    inner = np.zeros((2, 32))
    for i, (loop, gyro) in enumerate(zip(loops, gyros)):
        row = inner[i]
        row[I_KP], row[I_KI], row[I_PI_LIMIT] = loop.pi.kp, loop.pi.ki, loop.pi.limit
        row[I_PI_PARALLEL] = float(loop.pi.form == "parallel")
        row[I_BOUND] = loop.bound.limit
        if loop.notch is not None:
            n = loop.notch
            row[I_NOTCH] = 1.0
            row[I_B0 : I_A2 + 1] = (n.b0, n.b1, n.b2, n.a1, n.a2)
        if loop.nfc is not None:
            f = loop.nfc
            row[I_NFC], row[I_GAMMA], row[I_REST] = 1.0, f.gamma, f.rest_rate
            row[I_TS : I_TS + 4] = f.static_digits
            row[I_TC : I_TC + 4] = f.coulomb_digits
            row[I_ALPHA : I_ALPHA + 4] = f.alpha
        row[I_SMOOTH], row[I_NOISE], row[I_SCALE] = gyro.smoothing, gyro.noise, gyro.scale
        row[I_SAT_BOUND] = sat_bounds[i]
    outer = np.array([[f.kp, f.ki, f.kd, f.limit] for f in followers], dtype=float)
    r = resolvers[0]
    if any(x.quantum != r.quantum or x.window != r.window or x.dt != r.dt for x in resolvers):
        raise ValueError("the compiled loop needs one resolver model for the four gimbals")
    misc = np.array(
        [r.quantum, r.dt, centers[0], centers[1], float(follow), *limits]
        + [MAX_RATE, REST_RATE, MAX_COMMAND],
        dtype=float,
    )
    ints = np.array(
        [
            gyros[0].sample_every,
            r.window,
            loops[0].nfc.taps if loops[0].nfc is not None else 1,
            loops[1].nfc.taps if loops[1].nfc is not None else 1,
            layout.block(layout.inner_axes[0]).start,
            layout.block(layout.inner_axes[1]).start,
            layout.block(layout.outer_axes[0]).start,
            layout.block(layout.outer_axes[1]).start,
            layout.joint_columns.start,
        ],
        dtype=np.int64,
    )
    if gyros[1].sample_every != gyros[0].sample_every:
        raise ValueError("the compiled loop needs one gyro sample rate")
    return KernelConfig(inner=inner, outer=outer, misc=misc, ints=ints)


def initial_state(config: KernelConfig, twin: Twin, resolvers, gyros, n: int) -> KernelState:
    """The state after `ClosedLoop.reset` (twin, resolvers and gyros already reset).

    Draws each gyro's noise for `n` samples from its generator, in the order
    `Gyro.read` would.
    """
    every = int(config.ints[N_SAMPLE_EVERY])
    draws = -(-n // every)
    noise = np.zeros((2, draws))
    for i, g in enumerate(gyros):
        if g.noise:
            noise[i] = g.rng.standard_normal(draws)
    taps = int(max(config.ints[N_TAPS0], config.ints[N_TAPS1]))
    resolver = np.array([list(r.past) for r in resolvers], dtype=float)
    twin_ints, twin_floats = twin.hot_state()
    return KernelState(
        inner=np.zeros((2, 8)),
        outer=np.zeros(2),
        nfc_history=np.zeros((2, taps)),
        resolver=resolver,
        command=np.zeros(4),
        ints=np.zeros(8, dtype=np.int64),
        twin_ints=twin_ints,
        twin_floats=twin_floats,
        noise=noise,
        err=np.zeros(2),
    )


def advance(
    stop: int,
    n: int,
    twin_arrays: TwinArrays,
    config: KernelConfig,
    state: KernelState,
    targets: np.ndarray,
    buffer: np.ndarray,
) -> int:
    """Samples ``state.ints[K_DONE]`` .. stop-1, as `ClosedLoop._advance` runs them.

    Args:
        stop: first sample not to run.
        n: samples of the run (the last one is recorded but not stepped from).
        twin_arrays: the twin's buffers (`Twin.arrays`).
        config, state: from `pack_config` and `initial_state`; `state` advances.
        targets: turntable targets [rad], shape (n, 3): row k for the step to t_{k+1}.
        buffer: the run's rows, shape (n, `CLOSED_LOOP_SIGNALS.width`).

    Returns:
        `OK`, or the code of the failure (details in ``state.err``); the
        samples done are ``state.ints[K_DONE]`` either way.
    """
    a, c, s = twin_arrays, config, state
    return _advance(
        stop,
        n,
        a.model_address,
        a.data_address,
        a.qpos,
        a.qvel,
        a.sensordata,
        a.qfrc_constraint,
        a.qfrc_applied,
        a.ctrl,
        a.site_xmat,
        a.xaxis,
        a.warning_number,
        a.frictionloss,
        a.index,
        a.friction_table,
        c.inner,
        c.outer,
        c.misc,
        c.ints,
        s.inner,
        s.outer,
        s.nfc_history,
        s.resolver,
        s.command,
        s.ints,
        s.twin_ints,
        s.twin_floats,
        s.noise,
        s.err,
        targets,
        buffer,
    )


# Offsets into `TwinArrays.index` (`Twin.INDEX`), spelled out here because
# numba's cache would keep a stale copy of values imported from elsewhere;
# checked against the twin's layout at import.
X_DOF_LO, X_ACT_LO, X_GYRO_AZ, X_GYRO_EL, X_GYRO_TABLE, X_TABLE_SITE = range(6)
X_INNER_JIDS, X_TABLE_Q, X_TABLE_ACT, X_SLOT, X_GIMBAL_OF_SLOT = 6, 8, 11, 14, 18
_EXPECTED = {
    "dof_lo": (X_DOF_LO, 1),
    "act_lo": (X_ACT_LO, 1),
    "gyro_az": (X_GYRO_AZ, 1),
    "gyro_el": (X_GYRO_EL, 1),
    "gyro_table": (X_GYRO_TABLE, 1),
    "table_site": (X_TABLE_SITE, 1),
    "inner_jids": (X_INNER_JIDS, 2),
    "table_q": (X_TABLE_Q, 3),
    "table_act": (X_TABLE_ACT, 3),
    "slot": (X_SLOT, 4),
    "gimbal_of_slot": (X_GIMBAL_OF_SLOT, 4),
}
if dict(Twin.INDEX) != _EXPECTED:
    raise ImportError("closed_loop_kernel: Twin.INDEX changed; update the X_* offsets here")

# Columns of `TwinArrays.friction_table` (per regime: 4 columns; per side: 2).
F_GAIN, F_VISCOUS, F_TS, F_TC, F_ALPHA, F_REST_F, F_REST_B = 0, 4, 8, 12, 16, 20, 22

# Warnings MuJoCo raises when it resets the data (mjtWarning).
_BADQPOS, _BADQVEL, _BADQACC = 3, 4, 5


if _LIB is not None:
    # Called by symbol name, resolved in the library the bindings loaded (not
    # through a ctypes pointer, whose address would stop numba caching the kernel).
    llvm_binding.load_library_permanently(_LIB)
    _STEP_SIGNATURE = numba.types.void(numba.types.uintp, numba.types.uintp)
    _mj_step1 = numba.types.ExternalFunction("mj_step1", _STEP_SIGNATURE)
    _mj_step2 = numba.types.ExternalFunction("mj_step2", _STEP_SIGNATURE)

    _F1, _F2, _I1 = numba.float64[::1], numba.float64[:, ::1], numba.int64[::1]

    @numba.njit(
        numba.int64(_F1, _F1, _F1, numba.int64, _F2, _I1, _F1, _F1, _F1),
        cache=True,
    )
    def _prepare(qpos, qvel, frictionloss, lo, table, tw_i, tw_f, err, misc) -> int:
        """`Twin._prepare`: frictionloss, bias and push from the state; 0 or TWIN_RATE."""
        max_rate, rest_rate = misc[M_MAX_RATE], misc[M_REST_RATE]
        for s in range(4):
            w = qvel[lo + s]
            if not -max_rate < w < max_rate:
                err[0], err[1] = s, w
                return TWIN_RATE
            side = law.side_of(qpos[lo + s], w)
            if w > rest_rate or w < -rest_rate:
                r = law.regime_of(side, w)
                frictionloss[lo + s] = law.stribeck(
                    abs(w), table[s, F_TS + r], table[s, F_TC + r], table[s, F_ALPHA + r]
                )
                tw_f[4 + s] = -table[s, F_VISCOUS + r] * w  # push
                tw_f[s] = 0.0  # bias
                tw_i[s] = r
            else:
                frictionloss[lo + s] = table[s, F_REST_F + side]
                tw_f[s] = table[s, F_REST_B + side]
                tw_f[4 + s] = table[s, F_REST_B + side]
                tw_i[s] = -1 - side
        return OK

    # Compiled (or loaded from the cache) at import, not at the first run: a
    # Ctrl-C during numba's loading would leave its state inconsistent.
    # One long function on purpose (tests/test_architecture.py LONG_FUNCTIONS):
    # numba compiles it whole, and the per-sample state stays in locals.
    @numba.njit(
        numba.int64(
            *(numba.int64, numba.int64, numba.int64, numba.int64),
            *(_F1, _F1, _F1, _F1, _F1, _F1, _F2, _F2, numba.int32[:], _F1),
            *(_I1, _F2, _F2, _F2, _F1, _I1),
            *(_F2, _F1, _F2, _F2, _F1, _I1, _I1, _F1, _F2, _F1),
            *(_F2, _F2),
        ),
        cache=True,
    )
    def _advance(
        stop,
        n,
        m_addr,
        d_addr,
        qpos,
        qvel,
        sd,
        qfrc_constraint,
        qfrc_applied,
        ctrl,
        site_xmat,
        xaxis,
        warning,
        frictionloss,
        idx,
        table,
        cin,
        cout,
        misc,
        cint,
        sin,
        sout,
        hist,
        res,
        command,
        sint,
        tw_i,
        tw_f,
        noise,
        err,
        targets,
        buf,
    ) -> int:
        lo, alo = idx[X_DOF_LO], idx[X_ACT_LO]
        g_az, g_el = idx[X_GYRO_AZ], idx[X_GYRO_EL]
        g_tab, site = idx[X_GYRO_TABLE], idx[X_TABLE_SITE]
        quantum, dt = misc[M_QUANTUM], misc[M_DT]
        follow = misc[M_FOLLOW] != 0.0
        diverged, sat_limit, sat_samples = misc[M_DIVERGED], misc[M_SAT_LIMIT], misc[M_SAT_SAMPLES]
        max_command = misc[M_MAX_COMMAND]
        every, window = cint[N_SAMPLE_EVERY], cint[N_WINDOW]
        col_joints = cint[N_COL_JOINTS]
        nres = window + 1
        angle = np.empty(4)
        w1 = np.empty(2)
        meas_q = np.empty(4)
        meas_r = np.empty(4)
        for k in range(sint[K_DONE], stop):
            row = buf[k]
            # --- Twin.sense
            w1[0], w1[1] = sd[g_az], sd[g_el]
            x0 = site_xmat[site, 0] * sd[g_tab] + site_xmat[site, 1] * sd[g_tab + 1]
            x1 = site_xmat[site, 3] * sd[g_tab] + site_xmat[site, 4] * sd[g_tab + 1]
            x2 = site_xmat[site, 6] * sd[g_tab] + site_xmat[site, 7] * sd[g_tab + 1]
            x0 += site_xmat[site, 2] * sd[g_tab + 2]
            x1 += site_xmat[site, 5] * sd[g_tab + 2]
            x2 += site_xmat[site, 8] * sd[g_tab + 2]
            for i in range(4):
                angle[i] = qpos[lo + idx[X_SLOT + i]]
            # --- the four resolvers (Resolver.read), one shared ring position
            pos = sint[K_RES_POS]
            for i in range(4):
                q = (np.rint(angle[i] / quantum) + 0.0) * quantum
                res[i, pos] = q
                meas_q[i] = q
            pos = (pos + 1) % nres
            sint[K_RES_POS] = pos
            for i in range(4):
                meas_r[i] = (meas_q[i] - res[i, pos]) / (window * dt)
            # --- the inner rate loops
            for i in range(2):
                w = w1[i]
                if not -diverged < w < diverged:
                    err[0], err[1] = i, w
                    sint[K_DONE] = k
                    return INNER_RATE
                p = cin[i]
                st = sin[i]
                # Gyro.read
                st[S_FILTERED] += p[I_SMOOTH] * (w - st[S_FILTERED])
                if sint[K_PHASE0 + i] == 0:
                    if p[I_NOISE] != 0.0:
                        noisy = st[S_FILTERED] + p[I_NOISE] * noise[i, sint[K_DRAW0 + i]]
                        sint[K_DRAW0 + i] += 1
                    else:
                        noisy = st[S_FILTERED] + 0.0
                    st[S_COUNT] = np.rint(noisy * p[I_SCALE]) + 0.0
                sint[K_PHASE0 + i] = (sint[K_PHASE0 + i] + 1) % every
                counts = st[S_COUNT]
                # PIController.step(-counts)
                e = -counts
                s_new = st[S_INTEGRAL] + e
                parallel = p[I_PI_PARALLEL] != 0.0
                if parallel:
                    u_pi = p[I_KP] * e + p[I_KI] * s_new
                else:
                    u_pi = p[I_KP] * (e + p[I_KI] * s_new)
                if abs(u_pi) > p[I_PI_LIMIT] and u_pi * e > 0.0:
                    if parallel:
                        u_pi = p[I_KP] * e + p[I_KI] * st[S_INTEGRAL]
                    else:
                        u_pi = p[I_KP] * (e + p[I_KI] * st[S_INTEGRAL])
                else:
                    st[S_INTEGRAL] = s_new
                # NotchFilter.step
                if p[I_NOTCH] != 0.0:
                    y = p[I_B0] * u_pi + st[S_Z1]
                    st[S_Z1] = p[I_B1] * u_pi - p[I_A1] * y + st[S_Z2]
                    st[S_Z2] = p[I_B2] * u_pi - p[I_A2] * y
                    u_fb = y
                else:
                    u_fb = u_pi
                # FrictionFeedForward.step(omega2, u_pi, angle)
                if p[I_NFC] != 0.0:
                    om, ang = meas_r[i], meas_q[i]
                    if abs(om) > p[I_REST]:
                        r = law.regime_of(law.side_of(ang, om), om)
                        u1 = law.sliding(om, p[I_TS + r], p[I_TC + r], p[I_ALPHA + r])
                    else:
                        r = law.regime_of(law.side_of(ang, u_pi), u_pi)
                        u1 = law.stiction(u_pi, p[I_TS + r])
                    taps = cint[N_TAPS0 + i]
                    hist[i, sint[K_NFC_POS0 + i]] = u1
                    sint[K_NFC_POS0 + i] = (sint[K_NFC_POS0 + i] + 1) % taps
                    total = 0.0
                    for j in range(taps):
                        total += hist[i, j]
                    u_nfc = p[I_GAMMA] * total / taps
                else:
                    u_nfc = 0.0
                # Bound.step
                u = u_fb + u_nfc
                lim = p[I_BOUND]
                u = lim if u > lim else (-lim if u < -lim else u)
                if u != u:
                    err[0] = i
                    sint[K_DONE] = k
                    return INNER_NAN
                st[S_SATURATED] += (
                    (1.0 if abs(u) >= p[I_SAT_BOUND] else 0.0) - st[S_SATURATED]
                ) / sat_samples
                if st[S_SATURATED] > sat_limit:
                    err[0] = i
                    sint[K_DONE] = k
                    return INNER_SATURATED
                command[i] = u
                c0 = cint[N_COL_INNER0 + i]
                jid = idx[X_INNER_JIDS + i]
                wc = xaxis[jid, 0] * x0 + xaxis[jid, 1] * x1
                wc += xaxis[jid, 2] * x2
                slot = idx[X_SLOT + i]
                row[c0] = wc
                row[c0 + 1] = w
                row[c0 + 2] = qvel[lo + slot]
                row[c0 + 3] = counts / p[I_SCALE]
                row[c0 + 4] = u
                row[c0 + 5] = -(qfrc_constraint[lo + slot] + tw_f[8 + slot])
                row[c0 + 6] = u_nfc
                row[c0 + 7] = tw_i[4 + slot]
            # --- the outer followers (OuterFollower.step)
            for j in range(2):
                if follow:
                    e = meas_q[j] - misc[M_CENTER0 + j]
                    true_err = angle[j] - misc[M_CENTER0 + j]
                else:
                    e = -meas_q[2 + j]
                    true_err = -angle[2 + j]
                p = cout[j]
                s_new = sout[j] + e
                u = p[O_KP] * e + p[O_KI] * s_new - p[O_KD] * meas_r[2 + j]
                lim = p[O_LIMIT]
                if abs(u) > lim:
                    if u * e <= 0.0:
                        sout[j] = s_new
                    u = lim if u > 0 else -lim
                else:
                    sout[j] = s_new
                command[2 + j] = u
                c0 = cint[N_COL_OUTER0 + j]
                row[c0] = true_err
                row[c0 + 1] = u
            for i in range(3):
                row[col_joints + i] = qpos[idx[X_TABLE_Q + i]]
            for i in range(4):
                row[col_joints + 3 + i] = angle[i]
            sint[K_DONE] = k + 1
            if k + 1 >= n:
                break
            # --- Twin.step(command, targets[k])
            for s in range(4):
                u = command[idx[X_GIMBAL_OF_SLOT + s]]
                if not -max_command < u < max_command:
                    err[0], err[1] = s, u
                    return TWIN_COMMAND
                r = tw_i[s]
                if r < 0:
                    r = law.regime_of(-1 - r, u)
                tw_i[4 + s] = r
                ctrl[alo + s] = table[s, F_GAIN + r] * u
            for i in range(3):
                ctrl[idx[X_TABLE_ACT + i]] = targets[k, i]
            for s in range(4):
                qfrc_applied[lo + s] = tw_f[4 + s]
                tw_f[8 + s] = tw_f[s]
            # MuJoCo resets the data on a bad state and counts a warning; the
            # reset zeroes the counters before counting, so only a counter
            # cleared before the step tells a new reset from an old one.
            warning[_BADQACC] = 0
            _mj_step2(m_addr, d_addr)
            if warning[_BADQACC] != 0:
                return TWIN_QACC
            code = _prepare(qpos, qvel, frictionloss, lo, table, tw_i, tw_f, err, misc)
            if code != OK:
                return code
            warning[_BADQPOS] = 0
            warning[_BADQVEL] = 0
            _mj_step1(m_addr, d_addr)
            if warning[_BADQPOS] != 0 or warning[_BADQVEL] != 0:
                return TWIN_STATE
        return OK

    @numba.njit(numba.float64[:, ::1](numba.float64[:, ::1]), cache=True)
    def _law_probe(cases):
        """`friction_compiled.probe`, cached with these kernels (stale with them)."""
        return law.probe(cases)


def compiled_law_is_current() -> bool:
    """Whether the compiled kernels agree bit for bit with `isp_twin.model.friction` on the probe.

    numba's cache checks only this file's time stamp: an edit to friction.py
    alone would leave the cached kernels on the old law. The probe is
    compiled and cached with them, so it goes stale with them.
    """
    cases = law_probe_cases()
    return bool(np.array_equal(_law_probe(cases), python_law(cases)))


if _LIB is not None and not compiled_law_is_current():
    # Stale cache: compile the kernels afresh (this rewrites the cache).
    for _kernel in (_law_probe, _prepare, _advance):
        _kernel.recompile()
    if not compiled_law_is_current():
        raise ImportError("closed_loop_kernel: the compiled friction law differs from friction.py")
