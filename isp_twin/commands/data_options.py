"""The options shared by `identify` and `diagnose`: how a file's own columns
map onto t, u, omega, theta, how much data is accepted, and how the model
integrates a sample (``--substeps``, or a parameter file's ``fitted_with``)."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

from isp_twin.errors import DataError, ParameterError
from isp_twin.identification.measured import (
    DataMapping,
    load_data_description,
    mapping_from_options,
)
from isp_twin.identification.read_out import Timing, recorded_model
from isp_twin.model.parameters import MAX_SUBSTEPS, AxisParams
from isp_twin.model.substep_model import DEFAULT_INTEGRATION, EQ6, Integration

__all__ = [
    "MAX_SAMPLES",
    "add_data_options",
    "check_initial_angle",
    "check_sample_budget",
    "integration_from_args",
    "mapping_from_args",
    "model_from_file",
]

#: Default limit on the samples of one identify/diagnose call (all runs together):
#: about 8 times the 2 x 6000 samples of the issue 8 benchmark, a few minutes of
#: work on 2 cores. Every trial parameter set simulates every sample.
MAX_SAMPLES = 100_000


def add_data_options(p: argparse.ArgumentParser) -> None:
    """Add --map, --describe and --initial-angle to a subcommand."""
    p.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="KEY=SOURCE[*SCALE]",
        help="column mapping, e.g. t=data:0 u=data:4 omega=data:3*rad/s theta=data:2*rad",
    )
    p.add_argument(
        "--describe", type=Path, default=None, help="YAML data description (instead of --map)"
    )
    p.add_argument(
        "--initial-angle",
        type=float,
        default=0.0,
        metavar="DEG",
        help="angle at the first sample [deg] for rate-only data (the angle is integrated)",
    )
    p.add_argument(
        "--max-samples",
        type=int,
        default=MAX_SAMPLES,
        metavar="N",
        help=f"refuse data with more samples than this in all runs together (default {MAX_SAMPLES})",
    )
    p.add_argument(
        "--substeps",
        type=int,
        default=None,
        metavar="M",
        help="the model integrates each sample in M sub-steps (1: the paper's Eq. 6, friction "
        "held over the sample; default: diagnose: the parameter file's fitted_with block, "
        f"identify and files without the block: {DEFAULT_INTEGRATION.substeps})",
    )
    p.add_argument(
        "--split-sides",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="a sub-step in which the angle crosses 0 takes each side's regime for its part "
        'of it (docs/diagnosis.md "Stop 34", default since "Stop 38"; diagnose: the '
        "parameter file's fitted_with block says whether its parameters were fitted so; "
        "a file without the block: the default)",
    )


def integration_from_args(args: argparse.Namespace) -> Integration:
    """The model integration ``--substeps`` and ``--split-sides`` /
    ``--no-split-sides`` ask for (1: Eq. 6 exactly, its regime switched at the
    crossing only with ``--split-sides``; not given: the default)."""
    m = DEFAULT_INTEGRATION.substeps if args.substeps is None else args.substeps
    if m < 1 or m > MAX_SUBSTEPS:
        raise ParameterError(f"--substeps must be between 1 and {MAX_SUBSTEPS}, got {m}")
    integration = EQ6 if m == 1 else replace(DEFAULT_INTEGRATION, substeps=m)
    if args.split_sides is None:
        return integration
    return replace(integration, split_sides=bool(args.split_sides))


def model_from_file(
    args: argparse.Namespace, axis: AxisParams, where: str
) -> tuple[Integration, Timing | None, str | None]:
    """The model integration and read-out timing to simulate an axis with.

    The axis' ``fitted_with`` block (`FittedWith`) unless ``--substeps`` asks
    for another sub-step count; without the block, ``--substeps`` or the
    default, and the timing is chosen from the data (None). Returns also a
    line stating an override (None when there is none); `where` names the
    block in it (file and axis).
    """
    record = axis.fitted_with
    if record is None:
        return integration_from_args(args), None, None
    same_steps = args.substeps is None or args.substeps == record.substeps
    same_split = args.split_sides is None or bool(args.split_sides) == record.split_sides
    if same_steps and same_split:
        integration, timing = recorded_model(record)
        return integration, timing, None
    if same_steps:  # --split-sides / --no-split-sides against the file's
        integration = replace(recorded_model(record)[0], split_sides=bool(args.split_sides))
        flag = "--split-sides" if args.split_sides else "--no-split-sides"
        what = f"{flag} overrides {where}.fitted_with.split_sides {str(record.split_sides).lower()}"
    else:  # another sub-step count; the file's split stays unless asked
        integration = integration_from_args(args)
        split = record.split_sides if args.split_sides is None else bool(args.split_sides)
        integration = replace(integration, split_sides=split)
        what = (
            f"--substeps {args.substeps} overrides {where}.fitted_with.substeps {record.substeps}"
        )
    return (
        integration,
        None,
        f"{what}: the parameters were fitted with another model; the read-out timing is chosen "
        "again from the data",
    )


def check_initial_angle(args: argparse.Namespace) -> None:
    """--initial-angle must be a finite angle."""
    if not math.isfinite(args.initial_angle):
        raise DataError(f"--initial-angle must be a finite angle [deg], got {args.initial_angle}")


def check_sample_budget(runs, args: argparse.Namespace) -> None:
    """Refuse, before any work, data longer than --max-samples (all runs together)."""
    limit = args.max_samples
    if limit < 20:
        raise DataError(f"--max-samples must be >= 20, got {limit}")
    total = sum(len(r) for r in runs)
    if total > limit:
        longest = max(runs, key=len)
        raise DataError(
            f"{total:,} samples in {len(runs)} run(s) (longest {longest.name}: {len(longest):,}) "
            f"exceed the limit of {limit:,} (--max-samples): every trial parameter set simulates "
            "every sample; cut the log to the segments that excite the axis, or resample it, or "
            "raise --max-samples"
        )


def mapping_from_args(args: argparse.Namespace) -> DataMapping | None:
    """The mapping the options describe; None for canonical CSV."""
    if args.describe is not None:
        return load_data_description(args.describe)
    if args.map:
        return mapping_from_options(args.map, initial_angle_deg=args.initial_angle)
    if args.initial_angle:
        return DataMapping(initial_angle_deg=args.initial_angle)
    return None
