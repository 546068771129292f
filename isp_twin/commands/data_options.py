"""The measured-data options shared by `identify` and `diagnose`: how a file's
own columns map onto t, u, omega, theta."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from isp_twin.errors import DataError
from isp_twin.measured import DataMapping, load_data_description, mapping_from_options

__all__ = ["add_data_options", "check_initial_angle", "mapping_from_args"]


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


def check_initial_angle(args: argparse.Namespace) -> None:
    """--initial-angle must be a finite angle."""
    if not math.isfinite(args.initial_angle):
        raise DataError(f"--initial-angle must be a finite angle [deg], got {args.initial_angle}")


def mapping_from_args(args: argparse.Namespace) -> DataMapping | None:
    """The mapping the options describe; None for canonical CSV."""
    if args.describe is not None:
        return load_data_description(args.describe)
    if args.map:
        return mapping_from_options(args.map, initial_angle_deg=args.initial_angle)
    if args.initial_angle:
        return DataMapping(initial_angle_deg=args.initial_angle)
    return None
