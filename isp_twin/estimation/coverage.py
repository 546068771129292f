"""Whether the held-out runs stay within the speeds the training runs reach.

A fit is determined only where its training runs go. Per friction regime
(side of the angle x direction of motion) the Stribeck law is seen up to
the fastest speed a training run reaches there: above it, the Coulomb level
and the tail of the Stribeck curve are whatever fitted the training runs,
and two parameter sets that fit them to the noise can differ held out by
tens of noise floors. On reference resonance seed 108 (a 0.7 s axis) the
5 Hz cosine training runs reach 6.2 deg/s in regime L-, the held-out
multisine 32 deg/s; with its payload mode held at the truth, `identify`
fits the training runs at 1.00 noise sigmas with L-'s Coulomb level at
0.36 of the truth's, and misses the held-out run by 52 (the truth: 0.98;
docs/identification.md "Stop 37").

`beyond_training` names the regimes where a held-out run goes faster than
the training runs by more than `BEYOND_RATIO`; the verdicts of `identify`
and `diagnose` state them beside an error above the noise, so that a user
reads an experiment that does not cover the held-out run as such, and not
as a fit or an effect to look for.

`thin_training` names the regimes the training runs move in for a small
share of their samples while a held-out run spends `THIN_RATIO` times that
share there: within the training speeds, but fitted from few samples. On
reference axis 305 (docs/diagnosis.md "Stop 45") the training runs move in
regime L- for 5.7 % of their samples, the held-out run for 36 %; with the
right effect found to 0.2 %, the fit of L- is 7-28 % off and misses the
held-out run by 3.6 noise floors, the truth by 1.02.

`untrained_breakaways` names the regimes the fitted model rests against on
a held-out run (the drive pushes that way while it sticks) where it never
breaks away on the training runs. A breakaway under a rising drive
measures a regime's static level (Ts), a rest only bounds it, and at speed
the training runs see the level only through the Stribeck curve, where it
trades with alpha. An Eq. 7 cosine that swings through angle 0 turns back
at its two ends, so from rest it breaks away only towards angle 0 (R- and
L+). On reference clean seed 348 (docs/identification.md "Stop 54")
`identify` fits the training runs at the noise with L-'s static level 9 %
above the truth's; a held-out random step pushes the axis at rest in L-
with a drive between the two levels: the axis breaks away, the fitted
model stays, and the fit misses the run by 20 noise floors (the truth by
1.01).

`first_untrained_rest` marks where on a held-out run the model first
rests against such a regime; the samples before it are the part of the run
the training runs determine as far as breakaways go, and the verdicts
state the held-out error there (`DeterminedPart`) beside the error over the
whole run. On reference LuGre seed 379 (docs/diagnosis.md "Stop 60"),
`identify` with diagnose's LuGre candidate held fits the training runs at
1.11-1.16 noise floors and misses the held-out run by 88; before the
model's first rest against L- (sample 1689 of 6000) it reads 1.05, the
model without LuGre 10.5 (before sample 1693).

Speeds are rad/s inside; the sentence prints deg/s (the paper's unit).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isp_twin.model.friction import regime_index
from isp_twin.units import DEG
from isp_twin.vocabulary import REGIMES

__all__ = [
    "BEYOND_RATIO",
    "DeterminedPart",
    "REACH_QUANTILE",
    "THIN_RATIO",
    "MIN_REST_SAMPLES",
    "RegimeBreakaways",
    "RegimeReach",
    "RegimeShare",
    "beyond_training",
    "breakaway_counts",
    "breakaway_sentence",
    "breakaway_table",
    "first_untrained_rest",
    "rest_counts",
    "untrained_breakaways",
    "reach_sentence",
    "thin_training",
    "thin_sentence",
]

#: The quantile of |rate| over a regime's samples read as the speed the runs
#: reach there: the top one per cent is left out, so a few noise spikes or a
#: single overshoot do not set it.
REACH_QUANTILE = 0.99
#: A held-out run is beyond the training runs in a regime where it reaches
#: more than this times their speed there. Chosen once, not tuned: half as
#: fast again is well outside a Stribeck curve fitted up to the lower speed.
BEYOND_RATIO = 1.5
#: A held-out speed below this many noise floors is not a speed the runs
#: tell apart from rest; such a regime is never called beyond.
MIN_REACH_FLOORS = 10.0
#: Fewer held-out samples than this in a regime do not count (a crossing).
MIN_SAMPLES = 50
#: A regime is thinly trained where the held-out runs move there for more
#: than this times the share of their samples the training runs do. Advice
#: only (it decides nothing); chosen on stop 44's reference axes 302-306
#: (the misses of axis 305: 5.4-6.7; of the 50 effect axes, 7 above 3) and
#: stop 43's clean 280-289 (all below 2.2).
THIN_RATIO = 3.0
#: A breakaway counts where the model rested for at least this many samples
#: before it: a run that opens at rest under a drive above the static level
#: leaves rest at its first step, which bounds the level and does not
#: measure it. Chosen once, not tuned.
MIN_REST_SAMPLES = 2


@dataclass(frozen=True)
class RegimeReach:
    """One regime where the held-out runs go beyond the training runs.

    Attributes:
        regime: its name (`REGIMES`).
        training_rad_s: the speed the training runs reach there [rad/s]
            (`REACH_QUANTILE` of |rate|; 0 where they never go).
        held_out_rad_s: the speed the held-out runs reach there [rad/s].
    """

    regime: str
    training_rad_s: float
    held_out_rad_s: float

    def to_json(self) -> dict:
        return {
            "regime": self.regime,
            "training_reach_deg_s": self.training_rad_s / DEG,
            "held_out_reach_deg_s": self.held_out_rad_s / DEG,
        }


@dataclass(frozen=True)
class RegimeShare:
    """One regime the training runs move in for a small share of their samples.

    Attributes:
        regime: its name (`REGIMES`).
        training_share: share of the training samples moving there.
        held_out_share: share of the held-out samples moving there.
    """

    regime: str
    training_share: float
    held_out_share: float

    def to_json(self) -> dict:
        return {
            "regime": self.regime,
            "training_share_moving": self.training_share,
            "held_out_share_moving": self.held_out_share,
        }


@dataclass(frozen=True)
class RegimeBreakaways:
    """One regime the model rests against on the held-out runs where it
    never breaks away on the training runs.

    Attributes:
        regime: its name (`REGIMES`).
        held_out: the model's rests against it on the held-out runs
            (`rest_counts`).
    """

    regime: str
    held_out: int

    def to_json(self) -> dict:
        return {"regime": self.regime, "training_breakaways": 0, "held_out_rests": self.held_out}


@dataclass(frozen=True)
class DeterminedPart:
    """A held-out run's error before the model first rests against a regime
    where it never breaks away on the training runs (`first_untrained_rest`).

    Attributes:
        run: the held-out run's name.
        samples: the samples before that rest (sample 0 included).
        of_samples: the run's samples.
        rmse: the RMS rate error over samples 1..samples-1 [rad/s] (nan
            where there are none).
    """

    run: str
    samples: int
    of_samples: int
    rmse: float

    def to_json(self, noise_floor: float) -> dict:
        """Its JSON record (nan and inf as they are: the verdicts write it
        through `isp_twin.estimation.verdict.json_safe`)."""
        ratio = self.rmse / noise_floor if noise_floor > 0 else math.inf
        return {
            "run": self.run,
            "samples": self.samples,
            "of_samples": self.of_samples,
            "rmse_deg_s": self.rmse / DEG,
            "rmse_over_noise_floor": ratio,
        }

    def sentence(self, noise_floor: float) -> str:
        """What the advice says of it, with the run's noise floor [rad/s]."""
        if not math.isfinite(self.rmse) or noise_floor <= 0:
            return ""
        return (
            f"Before its first such rest (sample {self.samples} of {self.of_samples}) "
            f"{self.run} reads {self.rmse / noise_floor:.2f} x the noise floor. "
        )


def _pooled(runs) -> tuple[np.ndarray, np.ndarray]:
    """(rate [rad/s], regime index) of every sample of the runs, pooled."""
    omega = np.concatenate([np.asarray(d.omega, float) for d in runs])
    angle = np.concatenate([np.asarray(d.angle, float) for d in runs])
    return omega, regime_index(angle, omega)


def _moving(runs, noise_floor: float) -> tuple[np.ndarray, int]:
    """(per regime index, the runs' samples moving there (faster than
    `MIN_REACH_FLOORS` noise floors); the runs' samples in all, at least 1)."""
    omega, regime = _pooled(runs)
    moving = np.abs(omega) > MIN_REACH_FLOORS * noise_floor
    return np.bincount(regime[moving], minlength=len(REGIMES)), max(omega.size, 1)


def thin_training(
    train: Sequence, held_out: Sequence, noise_floor: float
) -> tuple[RegimeShare, ...]:
    """The regimes where the held-out runs move for more than `THIN_RATIO`
    times the share of samples the training runs do (arguments as
    `beyond_training`; at least `MIN_SAMPLES` held-out samples moving there)."""
    if not train or not held_out:
        return ()
    (seen, n_seen), (held, n_held) = _moving(train, noise_floor), _moving(held_out, noise_floor)
    return tuple(
        RegimeShare(name, float(seen[r] / n_seen), float(held[r] / n_held))
        for r, name in enumerate(REGIMES)
        if held[r] >= MIN_SAMPLES and held[r] / n_held > THIN_RATIO * seen[r] / n_seen
    )


def thin_sentence(thin: Sequence[RegimeShare]) -> str:
    """What the advice says of `thin` ("" when empty)."""
    if not thin:
        return ""
    parts = ", ".join(
        f"{t.regime} ({100 * t.held_out_share:.0f} % of the samples held out, "
        f"{100 * t.training_share:.1f} % in training)"
        for t in thin
    )
    return (
        f"The held-out runs move in regime(s) {parts} far more than the training runs: "
        "fitted from few samples there, the model can miss the held-out runs. Train with a run "
        "that moves there (another offset or starting angle). "
    )


def _reach(runs) -> dict[int, tuple[float, int]]:
    """Per regime index: (speed reached [rad/s], samples), over the runs pooled."""
    omega, regime = _pooled(runs)
    out = {}
    for r in range(len(REGIMES)):
        speed = np.abs(omega[regime == r])
        out[r] = (float(np.quantile(speed, REACH_QUANTILE)) if speed.size else 0.0, speed.size)
    return out


def beyond_training(
    train: Sequence, held_out: Sequence, noise_floor: float
) -> tuple[RegimeReach, ...]:
    """The regimes where the held-out runs reach speeds the training runs do not.

    Args:
        train, held_out: runs with ``omega`` [rad/s] and ``angle`` (its sign
            is the side; the angle as read is close enough for a speed range).
        noise_floor: the rate noise [rad/s] (`MIN_REACH_FLOORS`).

    Returns:
        One `RegimeReach` per such regime, in `REGIMES` order; empty without
        held-out runs.
    """
    if not train or not held_out:
        return ()
    seen, held = _reach(train), _reach(held_out)
    out = []
    for r, name in enumerate(REGIMES):
        speed, n = held[r]
        if n < MIN_SAMPLES or not speed > MIN_REACH_FLOORS * noise_floor:
            continue
        if speed > BEYOND_RATIO * seen[r][0]:
            out.append(RegimeReach(name, seen[r][0], speed))
    return tuple(out)


def reach_sentence(beyond: Sequence[RegimeReach]) -> str:
    """What the advice says of `beyond` ("" when empty)."""
    if not beyond:
        return ""
    parts = ", ".join(
        f"{b.regime} ({b.held_out_rad_s / DEG:.3g} deg/s held out, {b.training_rad_s / DEG:.3g} "
        "in training)"
        for b in beyond
    )
    return (
        f"The held-out runs go faster than the training runs in regime(s) {parts}: there the "
        "training runs do not determine the friction law, and a model that fits them to the "
        "noise can miss the held-out runs. Train with runs that reach those speeds (a slower or "
        "larger cosine), or judge on held-out runs within the training speeds. "
    )


def _rest_episodes(rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first, one-past-last sample) of each stretch of at least
    `MIN_REST_SAMPLES` samples where `rate` is exactly 0."""
    rest = (np.asarray(rate, float) == 0.0).astype(np.int8)
    edges = np.diff(np.concatenate([[0], rest, [0]]))
    first, stop = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    keep = stop - first >= MIN_REST_SAMPLES
    return first[keep], stop[keep]


def breakaway_counts(rates: Sequence[np.ndarray], regimes: Sequence[np.ndarray]) -> np.ndarray:
    """Per regime index (`REGIMES` order), how often a model's rate leaves
    exact rest after at least `MIN_REST_SAMPLES` samples of it.

    Args:
        rates: per run, the model's own rate [rad/s] (0.0 exactly at rest,
            as the sub-stepped model holds it).
        regimes: per run, the regime index of the step into each sample
            (`AxisResponse.regime`; at rest the drive's direction chooses
            it): at the first moving sample, the breakaway's side and
            direction.
    """
    counts = np.zeros(len(REGIMES), dtype=int)
    for w, regime in zip(rates, regimes):
        _, stop = _rest_episodes(w)
        stop = stop[stop < np.size(w)]
        counts += np.bincount(np.asarray(regime)[stop], minlength=len(REGIMES))
    return counts


def rest_counts(rates: Sequence[np.ndarray], regimes: Sequence[np.ndarray]) -> np.ndarray:
    """Per regime index, how many of a model's rests (at least
    `MIN_REST_SAMPLES` samples at exact rest; arguments as
    `breakaway_counts`) the drive pushes towards that regime at some
    sample: the rests whose end depends on that regime's static level."""
    counts = np.zeros(len(REGIMES), dtype=int)
    for w, regime in zip(rates, regimes):
        regime = np.asarray(regime)
        for a, b in zip(*_rest_episodes(w)):
            counts[np.unique(regime[a:b])] += 1
    return counts


def first_untrained_rest(rate: np.ndarray, regime: np.ndarray, untrained: Sequence[int]) -> int:
    """The first sample of the model's first rest on a run (at least
    `MIN_REST_SAMPLES` samples at exact rest) that the drive pushes towards
    one of the `untrained` regime indices at some sample (as `rest_counts`
    reads a rest); the run's length where none does.

    Args:
        rate: the model's own rate on the run [rad/s] (0.0 exactly at rest).
        regime: the regime index of the step into each sample
            (`AxisResponse.regime`).
        untrained: regime indices (`REGIMES` order) where the model never
            breaks away on the training runs.
    """
    regime = np.asarray(regime)
    wanted = np.zeros(len(REGIMES), dtype=bool)
    wanted[list(untrained)] = True
    for a, b in zip(*_rest_episodes(rate)):
        if wanted[regime[a:b]].any():
            return int(a)
    return int(np.size(rate))


def untrained_breakaways(
    train_breakaways: np.ndarray, held_out_rests: np.ndarray
) -> tuple[RegimeBreakaways, ...]:
    """The regimes the held-out runs rest against (`rest_counts`) where the
    training runs never break away (`breakaway_counts`), in `REGIMES` order."""
    return tuple(
        RegimeBreakaways(name, int(held_out_rests[r]))
        for r, name in enumerate(REGIMES)
        if held_out_rests[r] > 0 and train_breakaways[r] == 0
    )


def breakaway_table(
    train_breakaways: np.ndarray, held_out_rests: np.ndarray | None = None
) -> dict[str, dict[str, int]]:
    """The counts per regime name, as the verdicts' JSON holds them:
    "training_breakaways" and (with held-out runs) "held_out_rests"."""
    table = {"training_breakaways": dict(zip(REGIMES, map(int, train_breakaways)))}
    if held_out_rests is not None:
        table["held_out_rests"] = dict(zip(REGIMES, map(int, held_out_rests)))
    return table


def breakaway_sentence(untrained: Sequence[RegimeBreakaways]) -> str:
    """What the advice says of `untrained` ("" when empty)."""
    if not untrained:
        return ""
    parts = ", ".join(f"{b.regime} ({b.held_out} rests)" for b in untrained)
    return (
        f"The held-out runs rest against regime(s) {parts}, where the model never breaks away "
        "on the training runs: whether and when they break away there depends on its static "
        "level, which the training runs do not measure (it trades with alpha along the "
        "Stribeck curve at speed). Train with a run that breaks away there, from rest on that "
        "side in that direction (a cosine whose turning points stay on that side, or a slow "
        "ramp from rest). "
    )
