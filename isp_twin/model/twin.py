"""The MuJoCo digital twin: the four-gimbal ISP on its turntable, with friction injected.

The only module that imports `mujoco`. Physics (inertia, gyroscopic coupling,
the turntable's reaction, the ±4 deg stops) is MuJoCo's; the friction law of
Eq. 5 (the regime choice and the Stribeck magnitude of `isp_twin.model.friction`)
is written into the model every step from the parameter set, mapped from
the rate form of Eq. 6 to torques by `PhysicalAxis.from_rate_params` (the
derivation is in docs/axis_model.md).

Per step and gimbal (Eq. 5, regime = side of the angle x direction):

* moving (|rate| > `REST_RATE`): frictionloss = Stribeck magnitude of the
  current regime at |rate|, no bias; the frictionloss constraint (made hard by
  noslip) brings the axis exactly to rest instead of reversing it, so
  reversals pass through stick and never chatter;
* at rest: frictionloss F = (Ts+ + Ts-)/2 of the side, plus a constant bias
  torque (Ts- - Ts+)/2, so that the breakaway is Ts+ in + and Ts- in -
  (MuJoCo's constraint solver plays Eq. 5's stiction test, `friction.stiction`);
* viscous torque −eta[r]·ω (explicit, in ``qfrc_applied``, so the friction
  constraint sees it; see the integrator note in the model), drive
  drive_gain[r]·u through the gimbal's motor.

Stepping is split as ``mj_step2`` then ``mj_step1``: after `Twin.step` the
positions, velocities, sensors and kinematics all belong to the same instant,
so gyro = carrier rate + relative rate holds sample by sample.
"""

from __future__ import annotations

import copy
import ctypes
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

from isp_twin.errors import (
    ParameterError,
    ResourceNotFound,
    ScenarioError,
    SimulationDiverged,
    nearest,
)
from isp_twin.model.effects import Effect, make_effect
from isp_twin.model.friction import regime_of, side_of, stribeck
from isp_twin.model.parameters import ParameterSet, RateParams
from isp_twin.resources import model_path as default_model_path
from isp_twin.vocabulary import GIMBAL_AXES as GIMBALS
from isp_twin.vocabulary import INNER_AXES, TABLE_JOINTS

__all__ = [
    "GIMBALS",
    "TABLE_JOINTS",
    "REST_RATE",
    "MAX_RATE",
    "MAX_COMMAND",
    "PhysicalAxis",
    "TwinState",
    "TwinArrays",
    "Twin",
    "mujoco_library",
]

# GIMBALS (the vocabulary's GIMBAL_AXES) orders every (4,) array of the twin
# (commands and state); TABLE_JOINTS orders `table_target`, `table_angle`,
# `table_rate`.
#: |rate| at or below this counts as rest [rad/s] (5.7e-4 deg/s). Noslip holds
#: a stuck joint to < 1e-7 rad/s, but a stop leaves up to ~1e-4 of the
#: previous step's rate (< 3e-6 rad/s) with either sign; friction cannot
#: reverse a motion, so that residue is rest, not a reversal.
REST_RATE = 1e-5
#: Any |joint rate| above this is a runaway [rad/s] (the ISP moves < 1 rad/s).
MAX_RATE = 100.0
#: Any |command| above this is a runaway controller [digits] (the paper's are < 1000).
MAX_COMMAND = 1e9


@dataclass(frozen=True)
class PhysicalAxis:
    """Continuous physical model of one gimbal: J·dω/dt = drive_gain·u − η·ω − T_f.

    All per-regime arrays have shape (4,), `REGIMES` order R+, R-, L+, L-.

    Attributes:
        inertia: J [kg·m²].
        viscous: η [N·m·s/rad].
        drive_gain: motor torque per amplifier digit [N·m/digit].
        static: breakaway torque Ts [N·m].
        coulomb: Coulomb torque Tc [N·m].
        alpha: Stribeck curve factor [s/rad].
    """

    inertia: float
    viscous: np.ndarray
    drive_gain: np.ndarray
    static: np.ndarray
    coulomb: np.ndarray
    alpha: np.ndarray

    @classmethod
    def from_rate_params(
        cls, rate: RateParams, inertia: float, dt: float, discretization: str = "zoh"
    ) -> PhysicalAxis:
        """Map Eq. 6's per-sample rate form to torques.

        ``"zoh"``, the continuous-time meaning (exact zero-order hold):
        a = exp(−η·dt/J) gives η = −J·ln(a)/dt; a torque held over one sample
        changes the rate by g = (1 − a)/η per N·m.
        ``"euler"``, what a simulator stepping by explicit Euler with step dt
        must use to reproduce Eq. 6 sample for sample: a = 1 − η·dt/J, so
        η = J·(1 − a)/dt, and g = dt/J (the paper's own "b = 1/J").
        Either way drive_gain = gain/g, static = static_rate/g,
        coulomb = coulomb_rate/g; alpha is unchanged.

        Args:
            rate: one axis's rate-form parameters, arrays (4,).
            inertia: J about the joint axis [kg·m²].
            dt: the sample period the rate form refers to [s].
            discretization: "zoh" or "euler".
        """
        if not inertia > 0.0:
            raise ParameterError(f"inertia must be positive, got {inertia}")
        pole = np.asarray(rate.pole, dtype=float)
        if pole.shape != (4,) or np.any((pole <= 0.0) | (pole >= 1.0)):
            raise ParameterError(f"pole a must be 4 values in (0, 1), got {pole}")
        if discretization == "zoh":
            viscous = -inertia * np.log(pole) / dt
            g = (1.0 - pole) / viscous
        elif discretization == "euler":
            viscous = inertia * (1.0 - pole) / dt
            g = np.full(4, dt / inertia)
        else:
            raise ParameterError(f"discretization must be 'zoh' or 'euler', got {discretization!r}")
        return cls(
            inertia=float(inertia),
            viscous=viscous,
            drive_gain=np.asarray(rate.gain, dtype=float) / g,
            static=np.asarray(rate.static, dtype=float) / g,
            coulomb=np.asarray(rate.coulomb, dtype=float) / g,
            alpha=np.asarray(rate.alpha, dtype=float).copy(),
        )


@dataclass(frozen=True)
class TwinState:
    """A snapshot of the twin after a step; SI units, gimbal arrays in `GIMBALS` order.

    Attributes:
        t: simulation time [s].
        angle: relative gimbal angles [rad], shape (4,).
        rate: relative gimbal rates ω2 [rad/s], shape (4,).
        gyro: inertial rate ω1 of inner_az and inner_el about their own joint
            axes [rad/s], shape (2,), after the effects' ``measure()``, no noise.
        carrier_rate: inertial rate of the turntable top projected on the
            inner_az and inner_el joint axes (ω of Eq. 10) [rad/s], shape (2,).
        table_angle: turntable joint angles [rad], shape (3,), `TABLE_JOINTS` order.
        table_rate: turntable joint rates [rad/s], shape (3,).
        friction: friction torque applied during the last step [N·m], shape (4,),
            sign of the motion it opposes (includes the end-stop force while a
            gimbal is pressed against its stop).
        drive: motor torque applied during the last step [N·m], shape (4,)
            (after the motor's ±200 N·m limit).
        regime: regime index used for the last step (0 R+, 1 R-, 2 L+, 3 L-), shape (4,).
    """

    t: float
    angle: np.ndarray
    rate: np.ndarray
    gyro: np.ndarray
    carrier_rate: np.ndarray
    table_angle: np.ndarray
    table_rate: np.ndarray
    friction: np.ndarray
    drive: np.ndarray
    regime: np.ndarray

    def all_joint_angles(self) -> dict[str, float]:
        """All seven joint angles [rad] by joint name (for the 3D view)."""
        out = dict(zip(TABLE_JOINTS, self.table_angle.tolist()))
        out.update(zip(GIMBALS, self.angle.tolist()))
        return out


def _load_model(path: Path) -> mujoco.MjModel:
    if not path.is_file():
        raise ResourceNotFound(f"{path}: model file not found")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "compile error"
        raise ParameterError(f"{path}: MuJoCo cannot compile the model: {first}") from None


@lru_cache(maxsize=1)
def mujoco_library() -> str | None:
    """Path of the MuJoCo shared library the `mujoco` package loaded, or None.

    For compiled code (`isp_twin.experiments.closed_loop_kernel`) that calls ``mj_step1``
    and ``mj_step2`` without a Python call per step; it is the same file the
    bindings use, so the same library instance. None when it cannot be found
    or loaded, or pointers do not fit a ``size_t`` (the compiled code passes
    ``mjModel*`` and ``mjData*`` as such).
    """
    folder = Path(mujoco.__file__).parent
    libs = sorted(folder.glob("libmujoco.so*")) + sorted(folder.glob("libmujoco*.dylib"))
    if not libs or ctypes.sizeof(ctypes.c_void_p) != ctypes.sizeof(ctypes.c_size_t):
        return None
    try:
        lib = ctypes.CDLL(str(libs[0]))
    except OSError:
        return None
    return str(libs[0]) if hasattr(lib, "mj_step1") and hasattr(lib, "mj_step2") else None


@lru_cache(maxsize=4)
def _compiled_model(path: str, mtime_ns: int) -> mujoco.MjModel:
    """The compiled model of a file (cached per process and file version; callers copy it)."""
    return _load_model(Path(path))


@dataclass(frozen=True)
class TwinArrays:
    """What compiled code needs to step the twin (views into MuJoCo's buffers).

    Attributes:
        model_address, data_address: the ``mjModel*`` and ``mjData*``.
        qpos, qvel, sensordata, qfrc_constraint, qfrc_applied, ctrl, site_xmat,
            xaxis, warning_number: views of the `mujoco.MjData` fields.
        frictionloss: view of ``model.dof_frictionloss``.
        index: int64 indices, layout `Twin.INDEX` (gimbal slots, sensors,
            turntable joints and actuators).
        friction_table: shape (4, 24), per slot: drive gain (4), viscous (4),
            Ts (4), Tc (4), alpha (4), rest frictionloss R/L (2), rest bias
            R/L (2), SI (see `PhysicalAxis`).
    """

    model_address: int
    data_address: int
    qpos: np.ndarray
    qvel: np.ndarray
    sensordata: np.ndarray
    qfrc_constraint: np.ndarray
    qfrc_applied: np.ndarray
    ctrl: np.ndarray
    site_xmat: np.ndarray
    xaxis: np.ndarray
    warning_number: np.ndarray
    frictionloss: np.ndarray
    index: np.ndarray
    friction_table: np.ndarray


def _joint_id(m: mujoco.MjModel, name: str, path: Path) -> int:
    """A joint's id; a missing one names the file and the nearest joint name."""
    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
    if jid < 0:
        names = [m.joint(i).name for i in range(m.njnt)]
        raise ParameterError(f"{path}: no joint '{name}'{nearest(name, names)}")
    return jid


def _sensor_adr(m: mujoco.MjModel, name: str, path: Path) -> int:
    """Where a sensor's values start in ``sensordata``."""
    sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, name)
    if sid < 0:
        raise ParameterError(f"{path}: no sensor '{name}'")
    return int(m.sensor_adr[sid])


def _actuator_id(m: mujoco.MjModel, name: str, path: Path) -> int:
    aid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, name)
    if aid < 0:
        raise ParameterError(f"{path}: no actuator '{name}'")
    return aid


class Twin:
    """The simulated ISP: MuJoCo physics plus Eq. 5 friction from a parameter set.

    Attributes:
        model, data: the MuJoCo model and data (read them; the twin writes
            friction, damping, ctrl and qfrc_applied every step).
        dt: model timestep [s].
        params: the parameter set.
        axes: `PhysicalAxis` per gimbal name.
    """

    GIMBALS = GIMBALS
    TABLE_JOINTS = TABLE_JOINTS
    #: Layout of `TwinArrays.index`: name -> (offset, length).
    INDEX = {
        "dof_lo": (0, 1),
        "act_lo": (1, 1),
        "gyro_az": (2, 1),
        "gyro_el": (3, 1),
        "gyro_table": (4, 1),
        "table_site": (5, 1),
        "inner_jids": (6, 2),
        "table_q": (8, 3),
        "table_act": (11, 3),
        "slot": (14, 4),
        "gimbal_of_slot": (18, 4),
    }

    def __init__(self, params: ParameterSet, model_path: Path | str | None = None):
        path = Path(model_path) if model_path is not None else default_model_path()
        try:
            mtime = path.stat().st_mtime_ns
        except OSError:
            mtime = 0  # _load_model names the missing file
        # A copy of the cached compiled model: the twin writes its frictionloss.
        self.model = copy.copy(_compiled_model(str(path), mtime))
        self.data = mujoco.MjData(self.model)
        self.params = params
        self.dt = float(self.model.opt.timestep)
        dofs = self._find_gimbal_slots(path)
        self._find_table_and_sensors(path)
        self._build_axes(params, dofs)
        self._build_effects(params)
        self._bind_buffers()
        self.reset()

    def _find_gimbal_slots(self, path: Path) -> list[int]:
        """Joint ids, and the gimbals' dof and motor slots; returns the gimbals' dofs.

        Raises:
            ParameterError: a joint or motor is missing, or the gimbals are not
                consecutive hinges with their motors in the same order.
        """
        m = self.model
        self._jid = {n: _joint_id(m, n, path) for n in TABLE_JOINTS + GIMBALS}
        dofs = [int(m.jnt_dofadr[self._jid[n]]) for n in GIMBALS]
        qadr = [int(m.jnt_qposadr[self._jid[n]]) for n in GIMBALS]
        motors = [_actuator_id(m, f"motor_{n}", path) for n in GIMBALS]
        # The hot loop works on contiguous slices in dof order ("slots"): the
        # gimbal hinges are consecutive dofs, their motors consecutive
        # actuators in the same order (as in the shipped model).
        lo = min(dofs)
        self._lo, self._hi = lo, lo + 4
        mlo = min(motors)
        self._mlo = mlo
        if (
            sorted(dofs) != list(range(lo, lo + 4))
            or qadr != dofs
            or [a - mlo for a in motors] != [d - lo for d in dofs]
        ):
            raise ParameterError(
                f"{path}: the four gimbal joints must be consecutive hinges, and their "
                "motors consecutive actuators in the same order"
            )
        #: GIMBALS index -> slot; slot -> GIMBALS index.
        self._slot = np.array([d - lo for d in dofs])
        self._gimbal_of_slot = [int(np.flatnonzero(self._slot == s)[0]) for s in range(4)]
        self._slots = self._slot.tolist()
        return dofs

    def _find_table_and_sensors(self, path: Path) -> None:
        """The turntable's joints and actuators, the gyros, the joint ranges.

        Raises:
            ParameterError: an actuator, sensor or the ``gyro_table`` site is missing.
        """
        m = self.model
        self._table_q = np.array([int(m.jnt_qposadr[self._jid[n]]) for n in TABLE_JOINTS])
        self._table_v = np.array([int(m.jnt_dofadr[self._jid[n]]) for n in TABLE_JOINTS])
        self._table_act = np.array([_actuator_id(m, n, path) for n in TABLE_JOINTS])
        self._gyro_az = _sensor_adr(m, "gyro_inner_az", path) + 2  # z: the inner_az joint axis
        self._gyro_el = _sensor_adr(m, "gyro_inner_el", path) + 1  # y: the inner_el joint axis
        self._gyro_table = _sensor_adr(m, "gyro_table", path)
        sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "gyro_table")
        if sid < 0:
            raise ParameterError(f"{path}: no site 'gyro_table'")
        self._table_site = sid
        self._inner_jids = np.array([self._jid[n] for n in INNER_AXES])
        self._ranges = {n: tuple(m.jnt_range[self._jid[n]]) for n in TABLE_JOINTS + GIMBALS}

    def _build_axes(self, params: ParameterSet, dofs: list[int]) -> None:
        """`PhysicalAxis` per gimbal, and the per-slot friction table of the hot loop."""
        m = self.model
        # Effective inertia about each gimbal axis at qpos0 (dof_M0: the
        # diagonal of the joint-space inertia), so the twin and Eq. 6 agree.
        # The twin steps by explicit Euler (docs/axis_model.md); when its step
        # is the parameters' sample period, the Euler map makes every twin
        # step an Eq. 6 step; otherwise the continuous-time (ZOH) map applies.
        same_step = abs(self.dt - params.sample_time_s) <= 1e-12
        self.axes: dict[str, PhysicalAxis] = {}
        for n, d in zip(GIMBALS, dofs):
            self.axes[n] = PhysicalAxis.from_rate_params(
                params.axis(n).rate_params(),
                float(m.dof_M0[d]),
                params.sample_time_s,
                "euler" if same_step else "zoh",
            )
        # Per slot, plain Python lists: the per-step loop is scalar and lean.
        tab = []
        for s in range(4):
            ax = self.axes[GIMBALS[self._gimbal_of_slot[s]]]
            ts = ax.static.tolist()
            tab.append(
                (
                    ax.drive_gain.tolist(),
                    ax.viscous.tolist(),
                    ts,
                    ax.coulomb.tolist(),
                    ax.alpha.tolist(),
                    # at rest, per side (R = 0, L = 1): frictionloss and bias
                    ((ts[0] + ts[1]) / 2, (ts[2] + ts[3]) / 2),
                    ((ts[1] - ts[0]) / 2, (ts[3] - ts[2]) / 2),
                )
            )
        self._tab = tab
        self._inertia = [self.axes[GIMBALS[g]].inertia for g in self._gimbal_of_slot]

    def _build_effects(self, params: ParameterSet) -> None:
        """Each slot's effects, sorted by the hook they override (command, acceleration, gyro)."""
        effects = [
            [make_effect(spec, self.dt) for spec in params.axis(GIMBALS[g]).effects]
            for g in self._gimbal_of_slot
        ]
        self._effects = effects
        self._cmd_fx = [[e for e in fx if type(e).command is not Effect.command] for fx in effects]
        self._acc_fx = [
            [e for e in fx if type(e).acceleration is not Effect.acceleration] for fx in effects
        ]
        self._meas_fx = [
            [e for e in effects[int(self._slot[g])] if type(e).measure is not Effect.measure]
            for g in (0, 1)  # inner_az, inner_el carry the gyros
        ]
        self._any_cmd = any(self._cmd_fx)
        self._any_acc = any(self._acc_fx)
        self._any_meas = any(self._meas_fx)

    def _bind_buffers(self) -> None:
        """Views into MuJoCo's buffers (stable for the lifetime of model/data)."""
        m, d = self.model, self.data
        lo, mlo = self._lo, self._mlo
        self._qpos_g = d.qpos[lo : lo + 4]
        self._qvel_g = d.qvel[lo : lo + 4]
        self._fl_g = m.dof_frictionloss[lo : lo + 4]
        self._applied_g = d.qfrc_applied[lo : lo + 4]
        self._ctrl_g = d.ctrl[mlo : mlo + 4]
        self._constraint_g = d.qfrc_constraint[lo : lo + 4]
        self._force_g = d.actuator_force[mlo : mlo + 4]

    # ------------------------------------------------------------ internals

    def _prepare(self) -> None:
        """From the current qpos/qvel: moving or not, frictionloss, bias, viscous torque.

        All of it depends on the state only, so it is written before
        ``mj_step1`` builds the constraint rows; what depends on the command's
        sign (at rest) is decided in `step`.
        """
        q = self._qpos_g.tolist()
        v = self._qvel_g.tolist()
        fl = [0.0] * 4
        bias = [0.0] * 4
        push = [0.0] * 4
        moving = self._moving
        tab = self._tab
        for s in range(4):
            w = v[s]
            if not -MAX_RATE < w < MAX_RATE:
                raise self.rate_diverged(s, w)
            _, visc, ts, tc, al, rest_f, rest_b = tab[s]
            side = side_of(q[s], w)
            if w > REST_RATE or w < -REST_RATE:
                r = regime_of(side, w)
                fl[s] = stribeck(abs(w), ts[r], tc[r], al[r])
                push[s] = -visc[r] * w
                moving[s] = r
            else:
                fl[s] = rest_f[side]
                bias[s] = push[s] = rest_b[side]
                moving[s] = -1 - side
        self._fl_g[:] = fl
        self._q = q
        self._v = v
        self._bias = bias
        self._push = push

    def _carrier_rate(self) -> list[float]:
        """The turntable top's inertial rate on the inner_az and inner_el axes [rad/s].

        Written out in a fixed order (not numpy's ``@``, whose rounding
        depends on the BLAS kernel, e.g. with or without FMA) so the compiled
        closed loop (`isp_twin.experiments.closed_loop_kernel`) gets the same bits.
        """
        d = self.data
        g = self._gyro_table
        w0, w1, w2 = d.sensordata[g : g + 3].tolist()
        m = d.site_xmat[self._table_site].tolist()
        # the table's rate in world axes: site_xmat (row-major 3x3) @ body-frame rate
        x0 = m[0] * w0 + m[1] * w1 + m[2] * w2
        x1 = m[3] * w0 + m[4] * w1 + m[5] * w2
        x2 = m[6] * w0 + m[7] * w1 + m[8] * w2
        return [a0 * x0 + a1 * x1 + a2 * x2 for a0, a1, a2 in d.xaxis[self._inner_jids].tolist()]

    def _measured_gyro(self) -> list[float]:
        sd = self.data.sensordata
        gyro = [float(sd[self._gyro_az]), float(sd[self._gyro_el])]
        for i in range(2):
            for e in self._meas_fx[i]:
                gyro[i] = e.measure(gyro[i])
        return gyro

    # ---------------------------------------------- errors (both step paths)

    def rate_diverged(self, slot: int, rate: float) -> SimulationDiverged:
        """The error for a runaway gimbal rate [rad/s] found after a step."""
        return SimulationDiverged(
            f"twin diverged at t={self.data.time:.4f} s: "
            f"{GIMBALS[self._gimbal_of_slot[slot]]} rate = {rate} rad/s "
            f"(allowed |rate| < {MAX_RATE})"
        )

    def command_diverged(self, slot: int, command: float) -> SimulationDiverged:
        """The error for a runaway command [digits]."""
        return SimulationDiverged(
            f"twin diverged at t={self.data.time:.4f} s: {GIMBALS[self._gimbal_of_slot[slot]]} "
            f"command = {command} digits (allowed |command| < {MAX_COMMAND:g})"
        )

    @staticmethod
    def mujoco_rejected(t_before: float, what: str) -> SimulationDiverged:
        """The error for a step MuJoCo refused (it resets the data instead)."""
        return SimulationDiverged(
            f"twin diverged at t={t_before:.4f} s: MuJoCo rejected the {what}"
        )

    # ---------------------------------------------------- compiled stepping

    @property
    def has_effects(self) -> bool:
        """Whether any effect hooks into the step (the compiled path has none)."""
        return self._any_cmd or self._any_acc or self._any_meas

    def arrays(self) -> TwinArrays:
        """The buffers, indices and friction table for compiled stepping (`TwinArrays`).

        Compiled code reproduces `step` and `sense` operation for operation
        on these; `set_hot_state` hands its per-step state back.
        """
        m, d = self.model, self.data
        index = np.zeros(22, dtype=np.int64)
        lay = self.INDEX
        values = {
            "dof_lo": [self._lo],
            "act_lo": [self._mlo],
            "gyro_az": [self._gyro_az],
            "gyro_el": [self._gyro_el],
            "gyro_table": [self._gyro_table],
            "table_site": [self._table_site],
            "inner_jids": self._inner_jids.tolist(),
            "table_q": self._table_q.tolist(),
            "table_act": self._table_act.tolist(),
            "slot": self._slots,
            "gimbal_of_slot": self._gimbal_of_slot,
        }
        for name, (off, n) in lay.items():
            index[off : off + n] = values[name]
        table = np.array(
            [
                [*gain, *visc, *ts, *tc, *al, *rest_f, *rest_b]
                for gain, visc, ts, tc, al, rest_f, rest_b in self._tab
            ]
        )
        return TwinArrays(
            model_address=int(m._address),
            data_address=int(d._address),
            qpos=d.qpos,
            qvel=d.qvel,
            sensordata=d.sensordata,
            qfrc_constraint=d.qfrc_constraint,
            qfrc_applied=d.qfrc_applied,
            ctrl=d.ctrl,
            site_xmat=d.site_xmat,
            xaxis=d.xaxis,
            warning_number=d.warning.number,
            frictionloss=m.dof_frictionloss,
            index=index,
            friction_table=table,
        )

    def hot_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The per-step state compiled stepping carries: (ints (8,), floats (12,)).

        ints: moving (4), regime (4), per slot; floats: bias, push, bias
        used in the last step (4 each) [N·m], per slot.
        """
        ints = np.array(self._moving + self._regime, dtype=np.int64)
        floats = np.array(self._bias + self._push + self._bias_used, dtype=float)
        return ints, floats

    def set_hot_state(self, ints: np.ndarray, floats: np.ndarray) -> None:
        """Take back the state compiled stepping advanced (layout of `hot_state`)."""
        i, f = ints.tolist(), floats.tolist()
        self._moving, self._regime = i[:4], i[4:8]
        self._bias, self._push, self._bias_used = f[:4], f[4:8], f[8:12]
        self._q = self._qpos_g.tolist()
        self._v = self._qvel_g.tolist()

    # ------------------------------------------------------------ public API

    def reset(self, angles: dict[str, float] | None = None) -> None:
        """Back to t = 0: given joint angles [rad] (others 0), zero rates, effects reset.

        Args:
            angles: joint name -> angle [rad]; gimbal or turntable joints.

        Raises:
            ScenarioError: unknown joint name or an angle outside the joint's range.
        """
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        known = TABLE_JOINTS + GIMBALS
        for name, value in (angles or {}).items():
            if name not in self._jid:
                raise ScenarioError(
                    f"initial angle for unknown joint '{name}'{nearest(name, known)}; "
                    f"joints: {', '.join(known)}"
                )
            lo, hi = self._ranges[name]
            value = float(value)
            if not lo <= value <= hi:
                raise ScenarioError(
                    f"initial angle of '{name}' = {value:.6g} rad is outside its range "
                    f"[{lo:.6g}, {hi:.6g}] rad"
                )
            d.qpos[m.jnt_qposadr[self._jid[name]]] = value
            if name in TABLE_JOINTS:
                d.ctrl[self._table_act[TABLE_JOINTS.index(name)]] = value
        for fx in self._effects:
            for e in fx:
                e.reset()
        self._moving = [-1] * 4
        self._regime = [0] * 4
        self._prepare()
        self._applied_g[:] = self._push
        self._bias_used = self._bias
        mujoco.mj_forward(m, d)
        self._gyro = self._measured_gyro()

    def step(self, command_digits, table_target=None) -> None:
        """Advance one timestep `dt`.

        Args:
            command_digits: amplifier commands [digits], shape (4,), `GIMBALS`
                order, held over the step (zero-order hold).
            table_target: turntable position targets [rad], shape (3,),
                `TABLE_JOINTS` order; None keeps the previous targets (0 after
                `reset`, unless given there).

        Raises:
            SimulationDiverged: a state went non-finite or a rate ran away.
        """
        m, d = self.model, self.data
        u_all = (
            command_digits.tolist()
            if isinstance(command_digits, np.ndarray)
            else [float(x) for x in command_digits]
        )
        drive = [0.0] * 4
        regime = self._regime
        moving = self._moving
        tab = self._tab
        for s in range(4):
            u = u_all[self._gimbal_of_slot[s]]
            if self._any_cmd:
                for e in self._cmd_fx[s]:
                    u = e.command(u)
            if not -MAX_COMMAND < u < MAX_COMMAND:
                raise self.command_diverged(s, u)
            r = moving[s]
            if r < 0:  # at rest: the drive's sign picks the direction (Eq. 5)
                r = regime_of(-1 - r, u)
            regime[s] = r
            drive[s] = tab[s][0][r] * u
        self._ctrl_g[:] = drive
        if table_target is not None:
            d.ctrl[self._table_act] = table_target
        if self._any_acc:
            applied = list(self._push)
            for s in range(4):
                for e in self._acc_fx[s]:
                    applied[s] += self._inertia[s] * e.acceleration(self._q[s], self._v[s])
            self._applied_g[:] = applied
        else:
            self._applied_g[:] = self._push
        self._bias_used = self._bias
        t_before = d.time
        mujoco.mj_step2(m, d)
        if d.time <= t_before:  # MuJoCo resets the data on a bad qacc
            raise self.mujoco_rejected(t_before, "accelerations (non-finite qacc)")
        self._prepare()
        mujoco.mj_step1(m, d)
        if d.time <= t_before:
            raise self.mujoco_rejected(t_before, "state (non-finite qpos or qvel)")
        if self._any_meas:
            self._gyro = self._measured_gyro()

    def state(self) -> TwinState:
        """The current state (see `TwinState`); consistent at time `t`."""
        d = self.data
        sd = d.sensordata
        gyro = self._gyro if self._any_meas else [sd[self._gyro_az], sd[self._gyro_el]]
        slot = self._slot
        # frictionloss constraint (plus a stop's force if pressed) + the bias
        friction = -(self._constraint_g + self._bias_used)
        return TwinState(
            t=float(d.time),
            angle=self._qpos_g[slot],
            rate=self._qvel_g[slot],
            gyro=np.array(gyro, dtype=float),
            carrier_rate=np.array(self._carrier_rate()),
            table_angle=d.qpos[self._table_q],
            table_rate=d.qvel[self._table_v],
            friction=friction[slot],
            drive=self._force_g[slot],
            regime=np.array(self._regime, dtype=np.intp)[slot],
        )

    def sense(self) -> tuple[list[float], ...]:
        """What the closed loop reads each sample, as lists (the per-step fast path of `state`).

        Returns:
            (angle (4,), rate (4,), gyro (2,), carrier_rate (2,), friction (4,),
            regime (4,), table_angle (3,)), the same numbers as the `TwinState`
            fields of those names, gimbal lists in `GIMBALS` order.
        """
        d = self.data
        sd = d.sensordata
        gyro = (
            self._gyro if self._any_meas else [float(sd[self._gyro_az]), float(sd[self._gyro_el])]
        )
        slot = self._slots
        q, v = self._qpos_g.tolist(), self._qvel_g.tolist()
        c, b = self._constraint_g.tolist(), self._bias_used
        regime = self._regime
        return (
            [q[s] for s in slot],
            [v[s] for s in slot],
            list(gyro),
            self._carrier_rate(),
            [-(c[s] + b[s]) for s in slot],
            [regime[s] for s in slot],
            d.qpos[self._table_q].tolist(),
        )

    def __repr__(self) -> str:
        return f"Twin(params={self.params.name!r}, dt={self.dt})"
