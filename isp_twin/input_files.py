"""Reading the text files a user gives: scenarios, parameter files, data
descriptions, CSV data.

One place turns what can go wrong with a file on disk into a one-line
`IspTwinError`: missing, a directory, not readable (permissions), not UTF-8
(a binary or Latin-1 file). A UTF-8 byte-order mark (Excel's "CSV UTF-8")
is dropped. YAML is read with PyYAML's safe loader, extended so that numbers
in scientific notation without a decimal point (``1e4``, ``1e-9``), which
YAML 1.1 reads as strings, are numbers.
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path
from typing import Any

from isp_twin.errors import IspTwinError, ResourceNotFound

__all__ = ["read_text", "load_yaml"]

_BOM = "\ufeff"


def read_text(path: str | Path, what: str, error: type[IspTwinError]) -> str:
    """The text of a UTF-8 file, without a byte-order mark.

    Args:
        path: the file.
        what: what the file is, for messages ("scenario file", "data file").
        error: the error raised for an unreadable file.

    Raises:
        ResourceNotFound: the file does not exist.
        error: a directory, no read permission, not UTF-8 text, other OS error.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ResourceNotFound(f"{path}: {what} not found") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, expected a {what}") from None
    except PermissionError:
        raise error(f"{path}: cannot read the {what} (permission denied)") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        kind = "binary" if b"\0" in raw[:4096] else "not UTF-8"
        raise error(
            f"{path}: line {line}: {kind}: byte 0x{raw[exc.start]:02x} is not UTF-8 text "
            f"(save the {what} as UTF-8)"
        ) from None
    if "\0" in text:
        raise error(f"{path}: binary file (NUL byte), expected a {what} as UTF-8 text")
    return text.removeprefix(_BOM)


@cache
def _yaml_loader():
    import yaml

    class Loader(yaml.SafeLoader):
        """SafeLoader that also reads ``1e4`` / ``-2E-9`` as floats (YAML 1.2 style)."""

    # YAML 1.1 (PyYAML) needs a '.' in a float; YAML 1.2 and users do not.
    Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float",
        re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
        list("-+0123456789"),
    )
    return Loader


def load_yaml(path: str | Path, what: str, error: type[IspTwinError]) -> tuple[Any, str]:
    """The parsed YAML document of a file, and its text.

    Raises:
        ResourceNotFound: the file does not exist.
        error: unreadable file (see `read_text`) or invalid YAML (with the line).
    """
    import yaml

    text = read_text(path, what, error)
    try:
        return yaml.load(text, Loader=_yaml_loader()), text
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        raise error(f"{path}:{line} not valid YAML ({exc.__class__.__name__})") from None
