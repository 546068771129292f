"""Writing a recording: the stream saved atomically, Ctrl-C held, a viewer fed.

`write_recording` saves a Rerun stream to a temporary file beside the target
*before* anything is logged, closes it (which writes the footer) and only then
renames it onto the target (inside a command's output transaction, with the
command's other files). An interrupted or failed recording leaves the target
as it was and no temporary file behind. A Ctrl-C during the fraction of a
second the file takes is held until the file is complete. A viewer (spawned,
or one listening at a URL) gets a second stream with the same recording id
after the file is in place, so an unreachable viewer cannot cost the file.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from urllib.parse import urlsplit

import rerun as rr
import rerun.blueprint as rrb

from isp_twin.errors import ResourceNotFound
from isp_twin.output.files import after_commit, staged_path

__all__ = ["APPLICATION_ID", "DEFAULT_VIEWER_URL", "write_recording"]

APPLICATION_ID = "isp_twin"
#: Default viewer URL for ``connect=""`` (Rerun's documented default).
DEFAULT_VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"
_SPAWN_PORT = 9876
#: How long to wait for a viewer to take the data before giving up [s].
_VIEWER_TIMEOUT_S = 10.0

#: What a recording logs into a stream (called once for the file, once per viewer).
LogFn = Callable[[rr.RecordingStream], None]


def write_recording(
    path: Path, log: LogFn, blueprint: rrb.Blueprint, *, spawn: bool, connect: str | None
) -> Path:
    """Save to a temporary file beside `path`, log, close, rename; then feed a viewer.

    The file and the viewer get separate streams with the same recording id, so
    an unreachable viewer can neither block nor spoil the file.
    """
    recording_id = str(uuid.uuid4())
    # A Ctrl-C here would cost the whole recording of a finished run: the
    # file (a fraction of a second) is completed first, then the interrupt raised.
    with _sigint_deferred(), staged_path(path) as tmp:
        stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
        try:
            # Saved before anything is logged, so the file holds everything.
            stream.save(tmp, default_blueprint=blueprint)
            log(stream)
            stream.flush()
        finally:
            # Closing writes the footer; also on error, before staged_path removes tmp.
            stream.disconnect()
        _make_readable(tmp)
    if spawn or connect is not None:
        # After the file is in place (the whole command's outputs, inside a
        # transaction): a viewer that fails then cannot cost the file.
        after_commit(
            lambda: _send_to_viewer(
                path, log, blueprint, recording_id, spawn=spawn, connect=connect
            )
        )
    return path


@contextmanager
def _sigint_deferred() -> Iterator[None]:
    """Hold SIGINT until the block ends, then raise KeyboardInterrupt.

    Only in the main thread with Python's default handler installed;
    elsewhere the block runs unchanged.
    """
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return
    received: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if received:
        raise KeyboardInterrupt


def _send_to_viewer(
    path: Path,
    log: LogFn,
    blueprint: rrb.Blueprint,
    recording_id: str,
    *,
    spawn: bool,
    connect: str | None,
) -> None:
    url = connect or DEFAULT_VIEWER_URL
    if not spawn:
        _check_reachable(url, path)
    stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    try:
        if spawn:
            stream.spawn(port=_SPAWN_PORT, default_blueprint=blueprint)
        else:
            stream.connect_grpc(url, default_blueprint=blueprint)
        log(stream)
        stream.flush(timeout_sec=_VIEWER_TIMEOUT_S)
    except (RuntimeError, OSError) as exc:
        where = "a spawned viewer" if spawn else f"the viewer at {url}"
        raise ResourceNotFound(
            f"could not stream to {where} ({str(exc).splitlines()[0]}); "
            f"the recording was saved to '{path}'"
        ) from None
    finally:
        stream.disconnect()


def _check_reachable(url: str, path: Path) -> None:
    """Fail fast when nothing listens at the viewer URL.

    Rerun's client otherwise retries for several seconds before giving up.
    """
    try:
        parts = urlsplit(url)
        host, port = parts.hostname, parts.port
    except ValueError:
        host = port = None
    if host is None or port is None:
        return
    try:
        socket.create_connection((host, port), timeout=_VIEWER_TIMEOUT_S).close()
    except OSError as exc:
        raise ResourceNotFound(
            f"no Rerun viewer at {url} ({exc.strerror or exc}); "
            f"start one with 'rerun', or omit --connect; the recording was saved to '{path}'"
        ) from None


def _make_readable(path: Path) -> None:
    """Give the file the usual permissions (the temporary file is created 0600)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)
