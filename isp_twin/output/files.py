"""Command outputs: every destination checked before the work starts, all of a
command's files written as one transaction after it.

A command first calls `check_outputs` with each output option and the input
files: a destination that is a directory, one of the inputs, read-only, in a
folder that cannot be written (permissions, read-only file system) or that is
a socket or block device fails at once, in one line, before any simulation.
The writing then happens inside ``with transaction():``: each file is written
to a temporary ``.NAME.XXXX.part`` beside its target and, once every file of
the command is complete, all are renamed onto their targets. On any error
(Ctrl-C included) the temporaries are removed, folders made for the outputs
are removed again, and no target is touched.

Special destinations:

- ``-`` (only where a command allows it, e.g. ``--json -``): standard output.
- a symbolic link: the file it points to is replaced, the link kept.
- a character device (``/dev/null``, ``/dev/full``) or a FIFO: written
  through (a FIFO needs a reader, else the command fails rather than hangs).

Outside a transaction `staged_path` commits its one file at once;
`write_text_atomic` writes one text file that way.

Known limit: renames are done one after the other; a rename failing after an
earlier one succeeded (a disk removed mid-commit) leaves the earlier file.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from isp_twin.errors import OutputError

__all__ = [
    "STDOUT",
    "after_commit",
    "check_outputs",
    "check_folder",
    "is_stdout",
    "stdout_for_outputs",
    "staged_path",
    "transaction",
    "write_text_atomic",
]

#: The path that means standard output.
STDOUT = "-"

_transaction: ContextVar[_Transaction | None] = ContextVar("isp_twin_output_tx", default=None)
_stdout: ContextVar[TextIO | None] = ContextVar("isp_twin_stdout", default=None)


def is_stdout(path: str | Path | None) -> bool:
    """True when `path` is ``-`` (standard output)."""
    return path is not None and str(path) == STDOUT


# ------------------------------------------------------------------ checks


def _writable(path: Path) -> bool:
    """Write permission for the effective user (as a setuid or seteuid process has it)."""
    return os.access(path, os.W_OK, effective_ids=os.access in os.supports_effective_ids)


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):
        return False


def _nearest_existing(folder: Path) -> Path:
    folder = Path(os.path.abspath(folder))
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return folder


def _probe_writable(folder: Path, option: str, shown: Path) -> None:
    """Fail unless a file can be created in `folder` (the nearest existing ancestor)."""
    existing = _nearest_existing(folder)
    if not existing.is_dir():
        raise OutputError(f"{option} {shown}: {existing} is not a directory")
    try:
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".isp-twin-probe.", suffix=".part")
    except OSError as exc:
        raise OutputError(
            f"{option} {shown}: cannot write in {existing} ({exc.strerror or exc})"
        ) from None
    os.close(fd)
    os.unlink(probe)


def _check_one(option: str, path: Path, inputs: list[Path], allow_stdout: bool) -> None:
    if is_stdout(path):
        if not allow_stdout:
            raise OutputError(f"{option} -: standard output is not possible here (a file is)")
        return
    if str(path) in ("", "."):
        raise OutputError(f"{option}: empty path")
    try:
        target = path.resolve() if path.is_symlink() else path
    except (OSError, RuntimeError):
        raise OutputError(f"{option} {path}: symbolic link loop") from None
    for inp in inputs:
        if _same_file(target, inp):
            raise OutputError(
                f"{option} {path}: is one of the inputs ({inp}); choose another output path"
            )
    try:
        st = target.stat()
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise OutputError(f"{option} {path}: {exc.strerror or exc}") from None
    if st is not None:
        mode = st.st_mode
        if stat.S_ISDIR(mode):
            raise OutputError(f"{option} {path}: is a directory; give a file name")
        if stat.S_ISCHR(mode) or stat.S_ISFIFO(mode):
            if not _writable(target):
                raise OutputError(f"{option} {path}: cannot write to it (permission denied)")
            return
        if not stat.S_ISREG(mode):
            raise OutputError(f"{option} {path}: is a socket or block device; give a regular file")
        if not _writable(target):
            raise OutputError(f"{option} {path}: exists and is read-only")
    _probe_writable(target.parent, option, path)


def check_outputs(
    outputs: Mapping[str, str | Path | None],
    inputs: Iterable[str | Path] = (),
    stdout_ok: Iterable[str] = ("--json",),
) -> None:
    """Check every output file of a command before its work starts.

    Args:
        outputs: option name (as shown to the user) -> path; None entries skipped.
        inputs: the command's input files (none may be overwritten).
        stdout_ok: options that accept ``-`` for standard output.

    Raises:
        OutputError: a destination cannot be written, is an input, or two
            options name the same file.
    """
    given = {k: Path(v) for k, v in outputs.items() if v is not None}
    ins = [Path(p) for p in inputs]
    for option, path in given.items():
        _check_one(option, path, ins, option in set(stdout_ok))
    seen: dict[Path, str] = {}
    for option, path in given.items():
        if is_stdout(path):
            continue
        key = Path(os.path.abspath(path))
        if key in seen:
            raise OutputError(f"{seen[key]} and {option} both name {path}; give two files")
        seen[key] = option


def check_folder(option: str, folder: str | Path) -> None:
    """Check that files can be written in `folder` (made if missing).

    Raises:
        OutputError: it is a file, or it (or its nearest existing parent)
            cannot be written.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{option} {folder}: exists and is not a folder")
    _probe_writable(folder, option, folder)


@contextmanager
def stdout_for_outputs(redirect: bool) -> Iterator[None]:
    """With `redirect`, send the command's own prints to stderr, so that
    standard output carries only the ``-`` output (e.g. ``--json -``)."""
    if not redirect:
        yield
        return
    token = _stdout.set(sys.stdout)
    saved = sys.stdout
    sys.stdout = sys.stderr
    try:
        yield
    finally:
        sys.stdout = saved
        _stdout.reset(token)


# ------------------------------------------------------------------ writing


@dataclass
class _Staged:
    """A temporary file waiting for its rename (or copy) onto `target`."""

    shown: Path
    target: Path
    tmp: Path
    kind: str  # "file", "special" or "stdout"

    def finish(self) -> None:
        try:
            if self.kind == "file":
                os.replace(self.tmp, self.target)
            elif self.kind == "stdout":
                stream = _stdout.get() or sys.stdout
                stream.write(self.tmp.read_text())
                stream.flush()
            else:
                _write_through(self.tmp, self.target)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OutputError(f"{self.shown}: cannot write ({exc.strerror or exc})") from None
        finally:
            self.tmp.unlink(missing_ok=True)


def _write_through(tmp: Path, target: Path) -> None:
    """Copy `tmp` into a character device or FIFO without replacing it."""
    flags = os.O_WRONLY
    if stat.S_ISFIFO(target.stat().st_mode):
        flags |= os.O_NONBLOCK  # no reader -> ENXIO instead of a hang
    try:
        fd = os.open(target, flags)
    except OSError as exc:
        if exc.errno == errno.ENXIO:
            raise OSError(exc.errno, "a FIFO with no reader") from None
        raise
    os.set_blocking(fd, True)
    with os.fdopen(fd, "wb") as out, tmp.open("rb") as src:
        shutil.copyfileobj(src, out)


@dataclass
class _Transaction:
    staged: list[_Staged] = field(default_factory=list)
    made_dirs: list[Path] = field(default_factory=list)
    then: list[Callable[[], None]] = field(default_factory=list)

    def mkdirs(self, folder: Path) -> None:
        missing = []
        p = Path(os.path.abspath(folder))
        while not p.exists() and p != p.parent:
            missing.append(p)
            p = p.parent
        for d in reversed(missing):
            d.mkdir()
            self.made_dirs.append(d)

    def commit(self) -> None:
        # Devices, FIFOs and stdout can fail on write (/dev/full, no reader):
        # they go first, so that such a failure leaves every file untouched.
        order = sorted(self.staged, key=lambda s: s.kind == "file")
        try:
            for s in order:
                s.finish()
        except BaseException:
            self.abort()
            raise
        self.staged.clear()
        self.made_dirs.clear()
        then, self.then = self.then, []
        for action in then:
            action()

    def abort(self) -> None:
        for s in self.staged:
            s.tmp.unlink(missing_ok=True)
        self.staged.clear()
        for d in reversed(self.made_dirs):
            try:
                d.rmdir()
            except OSError:
                pass
        self.made_dirs.clear()
        self.then.clear()


def after_commit(action: Callable[[], None]) -> None:
    """Run `action` once the current transaction's files are all in place (at
    once outside a transaction); e.g. streaming to a viewer, whose failure
    must not undo the files."""
    tx = _transaction.get()
    if tx is None:
        action()
    else:
        tx.then.append(action)


def _stage(tx: _Transaction, path: Path) -> _Staged:
    umask = os.umask(0)
    os.umask(umask)
    if is_stdout(path):
        kind, target, folder = "stdout", path, None
    else:
        target = path.resolve() if path.is_symlink() else path
        special = target.exists() and not target.is_file() and not target.is_dir()
        kind = "special" if special else "file"
        folder = None if special else target.parent
    try:
        if folder is not None:
            tx.mkdirs(folder)
        fd, tmp = tempfile.mkstemp(
            dir=folder, prefix=f".{target.name or 'stdout'}.", suffix=".part"
        )
    except OSError as exc:
        raise OutputError(f"{path}: cannot write ({exc.strerror or exc})") from None
    os.close(fd)
    # mkstemp makes the file private (0600); outputs get the usual mode.
    os.chmod(tmp, 0o666 & ~umask)
    return _Staged(shown=path, target=target, tmp=Path(tmp), kind=kind)


@contextmanager
def staged_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write `path`'s content to.

    Inside `transaction` the file reaches `path` when the transaction
    commits; outside one, when the block ends. On an exception in the
    block the temporary file is removed and `path` is left as it was.
    """
    tx = _transaction.get()
    own = tx is None
    if own:
        tx = _Transaction()
    staged = _stage(tx, Path(path))
    try:
        yield staged.tmp
    except BaseException:
        staged.tmp.unlink(missing_ok=True)
        if own:
            tx.abort()
        raise
    tx.staged.append(staged)
    if own:
        tx.commit()


@contextmanager
def transaction() -> Iterator[None]:
    """Write every `staged_path` of the block, or none of them."""
    if _transaction.get() is not None:  # nested: the outer one commits
        yield
        return
    tx = _Transaction()
    token = _transaction.set(tx)
    try:
        yield
    except BaseException:
        tx.abort()
        raise
    finally:
        _transaction.reset(token)
    tx.commit()


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write `text` (UTF-8) to `path` whole or not at all (a `staged_path`)."""
    with staged_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
