"""`isp-twin calibrate`: fit the rig's declared knobs on its declared cells, then label every cell."""

from __future__ import annotations

import argparse

from isp_twin.commands.report import add_common_options, run_evaluation

__all__ = ["add_parser", "execute"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="fit the rig's calibrated knobs on the cells the rig declares, then run every cell",
        description=(
            "Fit only the rig knobs that carry a `fit` block (models/rigs/paper_rig.yaml: the "
            "gyro scale), only on the paper cells the block names, by scanning its values with "
            "N seeds each (least squared error against the paper). Then run every paper cell "
            "with the fitted values and print one table whose columns separate fitted cells, "
            "repeats of a run, cells that shaped a hand-chosen setting, and validation cells. "
            "The rig file is not changed."
        ),
    )
    add_common_options(p)
    p.set_defaults(execute=execute)


def execute(args: argparse.Namespace) -> int:
    return run_evaluation(args, fit=True, what="calibration")
