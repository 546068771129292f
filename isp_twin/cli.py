"""The `isp-twin` command line.

Each subcommand lives in `isp_twin.commands.<name>` with ``add_parser(sub)`` and
``execute(args) -> int``. Only this module chooses exit codes: any
`IspTwinError` becomes one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from isp_twin import __version__
from isp_twin.errors import IspTwinError

__all__ = ["main", "build_parser"]

SUBCOMMANDS = ("run", "identify", "diagnose", "generate", "campaign", "report", "sweep")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="isp-twin",
        description=(
            "Digital twin of a two-axis, four-gimbal inertially stabilized platform "
            "on a 3-axis flight turntable, with the improved Stribeck friction model "
            "and friction feed-forward of Cong et al."
        ),
    )
    parser.add_argument("--version", action="version", version=f"isp-twin {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"isp_twin.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"isp_twin.commands.{name}":
                continue
            raise
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.execute(args) or 0)
    except IspTwinError as exc:
        print(f"isp-twin {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"isp-twin {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
