"""The `isp-twin` command line.

Each subcommand lives in `isp_twin.commands.<name>` with ``add_parser(sub)`` and
``execute(args) -> int``. Only this module chooses exit codes: any
`IspTwinError` (or file-system error) becomes one line on stderr and exit
code 2; a closed standard output (``| head``) ends the command quietly.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from isp_twin import __version__
from isp_twin.commands import (
    calibrate,
    campaign,
    diagnose,
    generate,
    identify,
    report,
    run,
    sweep,
)
from isp_twin.errors import IspTwinError
from isp_twin.output.files import is_stdout, stdout_for_outputs

__all__ = ["main", "build_parser"]

#: The subcommands, in the order of ``isp-twin --help``.
SUBCOMMANDS = (run, identify, diagnose, generate, campaign, report, calibrate, sweep)


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
    for command in SUBCOMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with stdout_for_outputs(is_stdout(getattr(args, "json", None))):
            code = int(args.execute(args) or 0)
            sys.stdout.flush()
        return code
    except IspTwinError as exc:
        return _error(args.command, str(exc))
    except BrokenPipeError:
        # `isp-twin run ... | head -1`: the reader is gone; stop quietly.
        _silence_stdout()
        return 128 + 13  # as if killed by SIGPIPE, the shell convention
    except OSError as exc:  # a file-system failure no check foresaw
        where = f"{exc.filename}: " if exc.filename else ""
        return _error(args.command, f"{where}{exc.strerror or exc}")
    except KeyboardInterrupt:
        print(f"isp-twin {args.command}: interrupted", file=sys.stderr)
        return 130


def _error(command: str, message: str) -> int:
    """One line on stderr (a message naming a file with a newline stays one line)."""
    one_line = message.replace("\r", "\\r").replace("\n", "\\n")
    print(f"isp-twin {command}: error: {one_line}", file=sys.stderr)
    return 2


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # no real file descriptor (tests)
        pass


if __name__ == "__main__":
    sys.exit(main())
