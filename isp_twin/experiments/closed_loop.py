"""Run a closed-loop scenario on the twin: the product's main job.

Per 1 ms sample k (the paper's T, zero-order hold on every command):

1. read the sensors of the twin's state at t_k: the inner gyros (through the
   `Gyro` model: lag, noise, sampling, counts) and the resolvers;
2. the inner rate loops (PI + notch + NFC + bound) give the inner commands,
   the outer followers the outer commands (the inner resolver angle is the
   follow error);
3. record the signals at t_k, then step the twin to t_{k+1} with the
   turntable driven to its target angle at t_{k+1}.

The controllers see sensor readings only, never the true state.

The samples run compiled (`isp_twin.experiments.closed_loop_kernel`, numba) whenever
numba is there and the plant has no effects; the Python blocks of
`isp_twin.control` and `Twin.step` are the reference it reproduces bit for
bit, and run the rest.

Signals of the `RunResult` (SI, shape (N,)): per inner axis
``omega_carrier`` (omega of Eq. 10), ``omega_inertial`` (true omega_1),
``omega_relative`` (omega_2), ``gyro`` (the reading, rad/s), ``command``
[digits], ``friction`` [N·m], ``nfc`` [digits], ``regime``; per outer axis
``follow_error`` [rad] (the true inner gimbal angle minus its centre; with
the follower off, minus the outer gimbal's own angle) and ``command`` [digits].
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from isp_twin.control.bound import Bound
from isp_twin.control.follower import OuterFollower
from isp_twin.control.gyro import Gyro
from isp_twin.control.nfc import FrictionFeedForward
from isp_twin.control.notch import NotchFilter
from isp_twin.control.pi import PIController
from isp_twin.control.rate_loop import InnerRateLoop
from isp_twin.control.resolver import Resolver
from isp_twin.errors import IspTwinError, ScenarioError, SimulationDiverged
from isp_twin.experiments.metrics import run_metrics
from isp_twin.experiments.results import RunResult
from isp_twin.experiments.scenario import Motion, Scenario
from isp_twin.experiments.signals import CLOSED_LOOP_SIGNALS
from isp_twin.model.parameters import ParameterSet, load_parameters
from isp_twin.units import DEG
from isp_twin.vocabulary import INNER_AXES, OUTER_AXES, TABLE_JOINTS

__all__ = [
    "DIVERGED_RATE",
    "table_angles",
    "build_rate_loop",
    "ClosedLoop",
    "run_scenario",
    "load_kernel",
]

#: An inner inertial rate above this is a runaway [rad/s]: the carrier moves at
#: a few deg/s and the inner gimbals have +-4 deg of travel, so 60 deg/s means
#: the loop is unstable (absurd gains), not isolating.
DIVERGED_RATE = 60.0 * DEG

#: A loop whose command sits on its bound for this fraction of the time
#: (exponential average over `SATURATION_SAMPLES`) is unstable, not working:
#: in a working loop the command stays far inside its bound.
SATURATION_LIMIT = 0.9
SATURATION_SAMPLES = 500

#: Progress is reported every this many samples.
PROGRESS_EVERY = 500


def table_angles(motion: Motion, t: np.ndarray) -> np.ndarray:
    """Turntable angle [rad] of one axis at times `t`: the integral from 0 of its rate."""
    amp = motion.rate_amplitude
    if amp == 0.0:
        return np.zeros_like(t)
    w = 2 * math.pi * motion.freq_hz
    phase = math.radians(motion.phase_deg)
    if motion.waveform == "sine":
        return amp / w * (math.cos(phase) - np.cos(w * t + phase))
    return amp / w * (np.sin(w * t + phase) - math.sin(phase))


def build_rate_loop(
    scenario: Scenario, axis: str, nfc_params: ParameterSet, dt: float
) -> InnerRateLoop:
    """The inner rate loop of `axis` as the scenario configures it."""
    cfg = scenario.controller.axis(axis)
    gains = cfg.gains
    notch = (
        NotchFilter(cfg.notch.freq_hz, cfg.notch.q, cfg.notch.depth, dt)
        if cfg.notch.enabled
        else None
    )
    nfc = (
        FrictionFeedForward(
            nfc_params.axis(axis).rate_params(),
            gamma=cfg.nfc.gamma,
            taps=cfg.nfc.taps,
            rest_rate=cfg.nfc.rest_rate_deg_s * DEG,
        )
        if cfg.nfc.enabled
        else None
    )
    return InnerRateLoop(
        PIController(
            gains.kp_digit_per_count, gains.ki_digit_per_count, cfg.bound_digits, cfg.pi_form
        ),
        Bound(cfg.bound_digits),
        notch,
        nfc,
    )


class ClosedLoop:
    """One closed-loop run on the twin, sample by sample.

    Holds the twin, the sensors, the controllers and the per-sample buffer
    (layout `CLOSED_LOOP_SIGNALS`). `reset` returns to t = 0 with the noise
    seeded afresh, `step` advances one sample, `run` to the end; `result`
    packs what has run into a `RunResult`.

    Args:
        scenario: a ``kind: closed_loop`` scenario.
        params: the twin's parameter set (default: the scenario's file).
        seed: noise seed (default: the scenario's).
        nfc_params: the model the NFC compensates with (default: the
            scenario's `nfc_parameters`: its file, or `params` for 'plant').
        compiled: run the samples in `isp_twin.experiments.closed_loop_kernel` (same
            numbers, ~4x faster); None: whenever it can (numba importable,
            no effects on the plant); False: the Python blocks.

    Raises:
        ScenarioError: the scenario is not a closed-loop one.
    """

    def __init__(
        self,
        scenario: Scenario,
        params: ParameterSet | None = None,
        seed: int | None = None,
        nfc_params: ParameterSet | None = None,
        compiled: bool | None = None,
    ):
        if scenario.kind != "closed_loop":
            raise ScenarioError(
                f"{scenario.source or scenario.name}: kind: '{scenario.kind}' cannot be run "
                "closed loop (expected 'closed_loop')"
            )
        self.scenario = scenario
        nfc_params = self._load_models(scenario, params, nfc_params)
        self.seed = scenario.seed if seed is None else int(seed)
        self._build_plant(scenario)
        self._build_blocks(scenario, nfc_params)
        self._choose_path(compiled)
        self.reset()

    def _load_models(
        self, scenario: Scenario, params: ParameterSet | None, nfc_params: ParameterSet | None
    ) -> ParameterSet:
        """The plant's parameters (`params`, `params_path`) and the NFC's model, returned."""
        if params is None:
            self.params_path: Path | None = scenario.parameters_path
            params = load_parameters(self.params_path)
        else:
            self.params_path = params.path
        self.params = params
        if nfc_params is None:
            nfc_path = scenario.nfc_parameters_path
            nfc_params = params if nfc_path is None else load_parameters(nfc_path)
        #: What the NFC compensates with, for the record.
        self.nfc_parameters = (
            "plant"
            if nfc_params is params
            else str(nfc_params.path or nfc_params.name or "given in code")
        )
        return nfc_params

    def _build_plant(self, scenario: Scenario) -> None:
        """The twin, the sample times and the turntable's targets."""
        from isp_twin.model.twin import Twin  # mujoco only where the twin lives

        self.twin = twin = Twin(self.params)
        dt = twin.dt
        #: Samples of the run (t_0 .. t_{n-1}).
        self.n = n = int(round(scenario.duration_s / dt)) + 1
        self.t = np.arange(n) * dt
        motions = scenario.turntable.motions()
        # Targets for t_1 .. t_n: step k drives the table to its angle at t_{k+1}.
        targets = np.stack([table_angles(motions[a], self.t + dt) for a in TABLE_JOINTS], axis=1)
        self._targets_array = targets
        #: One row per sample (`CLOSED_LOOP_SIGNALS` layout), written as the run goes.
        self.buffer = np.zeros((n, CLOSED_LOOP_SIGNALS.width))

    def _build_blocks(self, scenario: Scenario, nfc_params: ParameterSet) -> None:
        """Sensors, the inner rate loops, the outer followers and their settings."""
        dt = self.twin.dt
        g = scenario.gyro
        self._gyro_model = g
        self.gyros: list[Gyro] = []
        r = scenario.resolver
        self.resolvers = [Resolver(r.resolution_deg, r.rate_window, dt) for _ in range(4)]
        self.loops = [build_rate_loop(scenario, a, nfc_params, dt) for a in INNER_AXES]
        f = scenario.follower
        self.followers = [
            OuterFollower(
                f.kp_digit_per_deg / DEG,
                f.ki_digit_per_deg / DEG,
                f.kd_digit_per_deg_s / DEG,
                f.bound_digits,
            )
            for _ in OUTER_AXES
        ]
        self._follow = f.enabled
        self._centers = [f.inner_az_center_deg * DEG, f.inner_el_center_deg * DEG]
        self._initial = {
            a: v * DEG for a, v in scenario.initial_angles_deg.as_dict().items() if v != 0.0
        }
        self._bounds = [0.999 * scenario.controller.axis(a).bound_digits for a in INNER_AXES]

    def _choose_path(self, compiled: bool | None) -> None:
        """The compiled kernel when asked for or possible, else the Python blocks."""
        self._kernel = _kernel_for(self.twin) if compiled is not False else None
        if compiled and self._kernel is None:
            raise IspTwinError(
                "closed loop: the compiled path needs numba and a plant without effects"
            )
        if self._kernel is not None:
            self._twin_arrays = self.twin.arrays()
        else:
            self._targets = self._targets_array.tolist()  # plain floats for the Python loop

    @property
    def compiled(self) -> bool:
        """Whether the samples run in the compiled kernel."""
        return self._kernel is not None

    @property
    def done(self) -> int:
        """Samples recorded so far."""
        return self._k

    def reset(self) -> None:
        """Back to t = 0: twin at the initial angles, controllers cleared, noise re-seeded."""
        dt = self.twin.dt
        g = self._gyro_model
        rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(self.seed).spawn(2)]
        self.gyros = [
            Gyro(g.scale_count_per_deg_s, g.noise_deg_s, g.bandwidth_hz, g.sample_every, dt, rng)
            for rng in rngs
        ]
        self.twin.reset(self._initial or None)
        for res, a in zip(self.resolvers, INNER_AXES + OUTER_AXES):
            res.reset(self._initial.get(a, 0.0))
        for block in self.loops + self.followers:
            block.reset()
        self._command = [0.0, 0.0, 0.0, 0.0]
        self._saturated = [0.0, 0.0]
        self._k = 0
        if self._kernel is not None:
            kernel = self._kernel
            self._kernel_config = kernel.pack_config(
                self.loops,
                self.gyros,
                self.resolvers,
                self.followers,
                self._follow,
                self._centers,
                self._bounds,
                CLOSED_LOOP_SIGNALS,
                (DIVERGED_RATE, SATURATION_LIMIT, SATURATION_SAMPLES),
            )
            self._kernel_state = kernel.initial_state(
                self._kernel_config, self.twin, self.resolvers, self.gyros, self.n
            )

    def step(self) -> None:
        """One sample: sense, control, record row k, advance the twin to t_{k+1}.

        Raises:
            SimulationDiverged: the loop ran away (names the time and signal);
                also when called after the last sample.
        """
        self._advance(self._k + 1)

    def run(self, on_progress: Callable[[float, float], None] | None = None) -> bool:
        """Run to the end (or until Ctrl-C).

        Args:
            on_progress: called as ``on_progress(t, duration_s)`` [s] every
                `PROGRESS_EVERY` samples and at the end.

        Returns:
            True when interrupted by Ctrl-C (the samples so far are kept).
        """
        n, t_end = self.n, self.t[-1]
        try:
            if on_progress is None:
                self._advance(n)
            while self._k < n:
                # report after each sample k with k % PROGRESS_EVERY == 0
                k = -(-self._k // PROGRESS_EVERY) * PROGRESS_EVERY
                self._advance(min(n, k + 1))
                if k + 1 < n:
                    on_progress(self.t[k], t_end)
        except KeyboardInterrupt:
            return True
        if on_progress is not None:
            on_progress(t_end, t_end)
        return False

    def _advance(self, stop: int) -> None:
        """Samples k .. stop-1; locals hoisted: this is the per-step hot loop."""
        n = self.n
        if stop > n:
            raise SimulationDiverged(f"closed loop: the run ends at sample {n}")
        if self._kernel is not None:
            self._advance_compiled(stop)
            return
        twin, buf, t, targets = self.twin, self.buffer, self.t, self._targets
        gyros, resolvers, loops, followers = self.gyros, self.resolvers, self.loops, self.followers
        follow, centers, bounds = self._follow, self._centers, self._bounds
        command, saturated = self._command, self._saturated
        layout = CLOSED_LOOP_SIGNALS
        inner = [layout.block(a) for a in INNER_AXES]
        outer = [layout.block(a) for a in OUTER_AXES]
        table_cols = slice(layout.joint_columns.start, layout.joint_columns.start + 3)
        gimbal_cols = slice(table_cols.stop, layout.joint_columns.stop)
        row = [0.0] * layout.width
        for k in range(self._k, stop):
            angle, rate, w1, wc, friction, regime, table_angle = twin.sense()
            meas = [res.read(angle[i]) for i, res in enumerate(resolvers)]
            for i in range(2):
                if not -DIVERGED_RATE < w1[i] < DIVERGED_RATE:
                    raise _rate_runaway(t[k], i, w1[i])
                counts = gyros[i].read(w1[i])
                u, _, u_nfc = loops[i].step(counts, meas[i][0], meas[i][1])
                if u != u:
                    raise _command_nan(t[k], i)
                saturated[i] += ((abs(u) >= bounds[i]) - saturated[i]) / SATURATION_SAMPLES
                if saturated[i] > SATURATION_LIMIT:
                    raise _saturated(t[k], i, bounds[i])
                command[i] = u
                # INNER_SIGNALS order
                row[inner[i]] = (
                    wc[i],
                    w1[i],
                    rate[i],
                    gyros[i].to_rate(counts),
                    u,
                    friction[i],
                    u_nfc,
                    regime[i],
                )
            for j in range(2):
                # outer_az follows inner_az, outer_el follows inner_el; with the
                # follower off the outer gimbal holds its own zero instead.
                if follow:
                    err, true_err = meas[j][0] - centers[j], angle[j] - centers[j]
                else:
                    err, true_err = -meas[2 + j][0], -angle[2 + j]
                uo = followers[j].step(err, meas[2 + j][1])
                command[2 + j] = uo
                row[outer[j]] = (true_err, uo)  # OUTER_SIGNALS order
            row[table_cols] = table_angle
            row[gimbal_cols] = angle
            buf[k] = row
            self._k = k + 1
            if k + 1 < n:
                twin.step(command, targets[k])

    def _advance_compiled(self, stop: int) -> None:
        """`_advance` in the kernel; its return code becomes the Python path's error."""
        kernel, state, twin = self._kernel, self._kernel_state, self.twin
        code = kernel.advance(
            stop,
            self.n,
            self._twin_arrays,
            self._kernel_config,
            state,
            self._targets_array,
            self.buffer,
        )
        k = int(state.ints[kernel.K_DONE])
        self._k = k
        twin.set_hot_state(state.twin_ints, state.twin_floats)
        self._command = state.command.tolist()
        if code == kernel.OK:
            return
        i, value = int(state.err[0]), float(state.err[1])
        t = self.t
        if code == kernel.INNER_RATE:
            raise _rate_runaway(t[k], i, value)
        if code == kernel.INNER_NAN:
            raise _command_nan(t[k], i)
        if code == kernel.INNER_SATURATED:
            raise _saturated(t[k], i, self._bounds[i])
        if code == kernel.TWIN_COMMAND:
            raise twin.command_diverged(i, value)
        if code == kernel.TWIN_RATE:
            raise twin.rate_diverged(i, value)
        what = (
            "accelerations (non-finite qacc)"
            if code == kernel.TWIN_QACC
            else ("state (non-finite qpos or qvel)")
        )
        raise twin.mujoco_rejected(t[k - 1], what)

    def metrics(self) -> dict:
        """The run's metrics (`isp_twin.experiments.metrics.run_metrics`) from every sample so far.

        What `result` reports, without copying the series (a sweep needs only these).
        """
        done = self._k
        buf = self.buffer[:done]
        signals = {name: buf[:, c] for c, name in enumerate(CLOSED_LOOP_SIGNALS.signals)}
        return run_metrics(self.t[:done], signals, self.scenario.skip_s)

    def result(self, interrupted: bool = False) -> RunResult:
        """The samples run so far as a `RunResult`, with metrics from every sample.

        The series are decimated by the scenario's ``record.decimation``.
        """
        scenario = self.scenario
        done = self._k
        buf = self.buffer[:done]
        layout = CLOSED_LOOP_SIGNALS
        signals = {name: buf[:, c].copy() for c, name in enumerate(layout.signals)}
        j0 = layout.joint_columns.start
        joint_angles = {name: buf[:, j0 + c].copy() for c, name in enumerate(layout.joints)}
        t = self.t[:done]
        metrics = self.metrics()
        step = scenario.record.decimation
        if step > 1:
            # The metrics above saw every sample; the record keeps every n-th.
            t = t[::step]
            signals = {k: v[::step] for k, v in signals.items()}
            joint_angles = {k: v[::step] for k, v in joint_angles.items()}
        params_path = self.params_path
        return RunResult(
            scenario=scenario.name,
            scenario_text=scenario.text,
            parameters_file=str(params_path) if params_path is not None else self.params.name,
            parameters_text=_read_text(params_path),
            rig=scenario.rig,
            rig_text=_read_text(scenario.rig_path),
            nfc_parameters=self.nfc_parameters,
            seed=self.seed,
            t=t,
            signals=signals,
            joint_angles=joint_angles,
            metrics=metrics,
            interrupted=interrupted,
            view_start_s=scenario.skip_s,
        )


def run_scenario(
    scenario: Scenario,
    params: ParameterSet | None = None,
    seed: int | None = None,
    on_progress: Callable[[float, float], None] | None = None,
    nfc_params: ParameterSet | None = None,
) -> RunResult:
    """Simulate a closed-loop scenario on the MuJoCo twin (a whole `ClosedLoop` run).

    Args:
        scenario: a ``kind: closed_loop`` scenario.
        params: the twin's parameter set (default: the scenario's file).
        seed: noise seed (default: the scenario's).
        on_progress: called as ``on_progress(t, duration_s)`` [s] every
            0.5 s of simulated time and at the end.
        nfc_params: the model the NFC compensates with (default: the
            scenario's `nfc_parameters`: its file, or `params` for 'plant').

    Returns:
        The `RunResult` with metrics (see `isp_twin.experiments.metrics`, computed from
        every sample) and the series decimated by ``record.decimation``; on
        Ctrl-C the partial result with ``interrupted=True``.

    Raises:
        ScenarioError: the scenario is not a closed-loop one.
        SimulationDiverged: the loop ran away (names the time and signal).
    """
    loop = ClosedLoop(scenario, params=params, seed=seed, nfc_params=nfc_params)
    interrupted = loop.run(on_progress)
    return loop.result(interrupted)


def _rate_runaway(t: float, axis: int, rate: float) -> SimulationDiverged:
    return SimulationDiverged(
        f"closed loop diverged at t={t:.3f} s: {INNER_AXES[axis]}/omega_inertial "
        f"= {rate / DEG:.1f} deg/s (limit {DIVERGED_RATE / DEG:.0f} deg/s; "
        "check the controller gains)"
    )


def _command_nan(t: float, axis: int) -> SimulationDiverged:
    return SimulationDiverged(
        f"closed loop diverged at t={t:.3f} s: {INNER_AXES[axis]}/command is NaN"
    )


def _saturated(t: float, axis: int, bound: float) -> SimulationDiverged:
    return SimulationDiverged(
        f"closed loop unstable at t={t:.3f} s: {INNER_AXES[axis]}/command has "
        f"been at its bound (+-{bound / 0.999:g} digits) "
        f"{100 * SATURATION_LIMIT:.0f} % of the time; check the controller gains"
    )


def load_kernel():
    """The compiled loop's module (`isp_twin.experiments.closed_loop_kernel`), or None without numba."""
    try:
        from isp_twin.experiments import closed_loop_kernel
    except ImportError:  # numba missing or broken: the Python blocks do the same
        return None
    return closed_loop_kernel


def _kernel_for(twin):
    """The compiled-kernel module if it can step `twin`, else None."""
    kernel = load_kernel()
    return kernel if kernel is not None and kernel.available(twin) else None


def _read_text(path: Path | None) -> str:
    if path is None:
        return ""
    try:
        return Path(path).read_text()
    except OSError:
        return ""
