"""``isp-twin generate --reference``: runs of a random axis of the independent reference simulator.

Writes ``train1.csv``, ``train2.csv`` (Eq. 7-style cosines), ``heldout.csv``
(multisine or random steps) as canonical CSV and ``truth.yaml`` (the drawn
parameters, their Eq. 6 rate form, the effect in the project's names, the
noise sigma). See docs/reference_simulator.md.
"""

from __future__ import annotations

import argparse

from isp_twin.errors import ParameterError, nearest
from isp_twin.identification.measured import MeasuredData, save_measured
from isp_twin.output.files import write_text_atomic

__all__ = ["add_reference_options", "execute_reference"]


def add_reference_options(p: argparse.ArgumentParser) -> None:
    """Add --reference and --effect to `generate` (--seed and --out are shared)."""
    p.add_argument(
        "--reference",
        action="store_true",
        help="draw a random axis of the independent reference simulator (with --seed, --effect) "
        "and write train1.csv, train2.csv, heldout.csv and truth.yaml",
    )
    p.add_argument(
        "--effect",
        default=None,
        metavar="NAME",
        help="with --reference: one library effect on the drawn axis, or none (default)",
    )
    p.add_argument(
        "--held-out",
        default=None,
        metavar="DESIGN",
        help="with --reference: free (default; drawn like the training runs, may go faster "
        "than they do) or covered (within the training speeds in each regime)",
    )


def execute_reference(args: argparse.Namespace) -> int:
    import yaml

    from isp_twin.reference import EFFECT_NAMES, HELD_OUT_DESIGNS, RUN_NAMES, design_experiment

    if not args.reference:
        given = "--effect" if args.effect is not None else "--held-out"
        raise ParameterError(
            f"{given} needs --reference (it sets up the reference simulator's experiment)"
        )
    effect = args.effect or "none"
    if effect != "none" and effect not in EFFECT_NAMES:
        raise ParameterError(
            f"--effect '{effect}'{nearest(effect, ('none', *EFFECT_NAMES))}; "
            f"expected none or one of {', '.join(EFFECT_NAMES)}"
        )
    if args.seed < 0:
        raise ParameterError(f"--seed must be >= 0 with --reference, got {args.seed}")
    held_out = args.held_out or "free"
    if held_out not in HELD_OUT_DESIGNS:
        raise ParameterError(
            f"--held-out '{held_out}'{nearest(held_out, HELD_OUT_DESIGNS)}; "
            f"expected one of {', '.join(HELD_OUT_DESIGNS)}"
        )
    experiment = design_experiment(args.seed, effect, held_out=held_out)
    truth = experiment.truth()
    paths = []
    for name in RUN_NAMES:
        run = experiment.runs[name]
        data = MeasuredData(
            name, run.t, run.u, run.omega, run.theta, None, experiment.excitations[name].dt
        )
        paths.append(save_measured(data, args.out / f"{name}.csv"))
    header = (
        f"# Truth of reference axis seed {args.seed}, effect {effect}: isp_twin.reference "
        "(docs/reference_simulator.md). SI unless the key names a unit.\n"
    )
    paths.append(
        write_text_atomic(
            args.out / "truth.yaml", header + yaml.safe_dump(truth, sort_keys=False, width=100)
        )
    )
    if not args.quiet:
        print(
            f"reference axis seed {args.seed}, effect {effect}: noise "
            f"{truth['noise_sigma_deg_s']:.4g} deg/s, time constant "
            f"{truth['physical']['time_constant_s'] * 1e3:.4g} ms"
        )
        for path in paths:
            print(f"wrote {path}")
    return 0
