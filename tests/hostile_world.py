"""Files for the hostile-input tests: good tiny inputs, bad inputs of every
kind, and per-case folders holding awkward output destinations.

Everything lives under one folder that an unprivileged user can read: when
the tests run as root, each case runs with the effective user `nobody`
(`unprivileged`), so that permission cases (an unreadable file, a
read-only folder) behave as they do for a user.
"""

from __future__ import annotations

import os
import shutil
import socket
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from isp_twin.resources import default_parameters_path

NOBODY = 65534

CLOSED_LOOP = """\
name: tiny_cl
kind: closed_loop
duration_s: 0.06
turntable:
  table_yaw: {amplitude_deg: 3.0, freq_hz: 1.0}
metrics: {skip_s: 0.01}
"""

OPEN_LOOP = """\
name: tiny_ol
kind: open_loop
duration_s: 0.05
open_loop:
  axis: inner_az
  command: {amplitude_digits: 950.0, freq_hz: 0.5, offset_digits: 0.0}
"""

DESCRIPTION = "columns:\n  t: t\n  u: u\n  omega: omega\n  theta: theta\n"

#: Bad versions of a text input: name -> bytes (None: special, made below).
BAD_TEXT: dict[str, bytes | None] = {
    "binary": bytes(range(256)) * 4,
    "latin1": "name: caf\xe9\nduration_s: 1.0\n".encode("latin-1"),
    "utf16": "t,u,omega,theta\n0,1,2,3\n".encode("utf-16"),
    "nul": b"name: x\x00\nkind: open_loop\n",
    "bad_utf8_line3": b"# ok\n# ok\n\xff\xfe broken\n",
    "directory": None,
    "unreadable": None,
}


def good_table(n: int = 200, dt: float = 1e-3) -> np.ndarray:
    t = np.arange(n) * dt
    u = 900 * np.cos(2 * np.pi * 5 * t)
    omega = 10 * np.sin(2 * np.pi * 5 * t)
    theta = np.cumsum(omega) * dt
    return np.column_stack([t, u, omega, theta])


def write_csv(path: Path, table: np.ndarray, header: str = "t,u,omega,theta") -> Path:
    np.savetxt(path, table, delimiter=",", header=header, comments="", fmt="%.10g")
    return path


def build_world(root: Path) -> Path:
    """The shared inputs under `root` (readable by everyone)."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "cl.yaml").write_text(CLOSED_LOOP)
    (root / "ol.yaml").write_text(OPEN_LOOP)
    shutil.copy(default_parameters_path(), root / "params.yaml")
    write_csv(root / "good.csv", good_table())
    (root / "desc.yaml").write_text(DESCRIPTION)
    for name, content in BAD_TEXT.items():
        for ext in ("yaml", "csv"):
            path = root / f"bad_{name}.{ext}"
            if name == "directory":
                path.mkdir()
            else:
                path.write_bytes(content if content is not None else b"t,u,omega,theta\n")
            if name == "unreadable":
                path.chmod(0)
    for p in [root, *root.rglob("*")]:
        if p.name.startswith("bad_unreadable"):
            continue
        p.chmod(0o755 if p.is_dir() else 0o644)
    (root / "cases").mkdir(mode=0o777)
    (root / "cases").chmod(0o777)
    return root


def make_case_dir(world: Path, index: int) -> Path:
    """A fresh folder with every awkward destination a case may aim at.

    ok/ (writable, the working directory), ro/ (read-only), adir/ (a folder),
    afile (a file), rofile.json / rofile.yaml (read-only files), sock (a
    Unix socket), loop (a symbolic link to itself).
    """
    case = world / "cases" / str(index)
    if case.exists():
        release(case)
        shutil.rmtree(case)
    case.mkdir()
    for d in ("ok", "ro", "adir"):
        (case / d).mkdir()
    (case / "afile").write_text("a file\n")
    for ext in ("json", "yaml", "md", "rrd"):
        (case / f"rofile.{ext}").write_text("read-only\n")
        (case / f"rofile.{ext}").chmod(0o444)
    s = socket.socket(socket.AF_UNIX)
    try:
        s.bind(str(case / "sock"))
    finally:
        s.close()
    (case / "loop").symlink_to("loop")
    for d in (case, case / "ok", case / "adir"):
        d.chmod(0o777)
    (case / "ro").chmod(0o555)
    return case


def release(folder: Path) -> None:
    """Make a case folder removable again."""
    for p in [folder, *folder.rglob("*")]:
        if p.is_dir() and not p.is_symlink():
            p.chmod(0o777)


def snapshot(folder: Path) -> dict[str, tuple]:
    """Every entry under `folder` (not following links): kind, size, mtime, mode
    (folders: kind and mode)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            st = p.lstat()
            if stat.S_ISDIR(st.st_mode):  # a probe file may come and go: mtime changes
                out[str(p.relative_to(folder))] = (stat.S_IFMT(st.st_mode), st.st_mode)
            else:
                out[str(p.relative_to(folder))] = (
                    stat.S_IFMT(st.st_mode),
                    st.st_size,
                    st.st_mtime_ns,
                    st.st_mode,
                )
    return out


#: Modules the commands import lazily: imported before a case runs as
#: `nobody`, who may not read the interpreter's site-packages.
LAZY_MODULES = (
    "yaml",
    "scipy.io",
    "scipy.optimize",
    "matplotlib",
    "isp_twin.experiments.campaign",
    "isp_twin.experiments.closed_loop",
    "isp_twin.diagnosis.report",
    "isp_twin.diagnosis.search",
    "isp_twin.identification.experiments",
    "isp_twin.identification.fit",
    "isp_twin.identification.report",
    "isp_twin.input_files",
    "isp_twin.identification.measured",
    "isp_twin.experiments.open_loop",
    "isp_twin.model.parameters",
    "isp_twin.output.readback",
    "isp_twin.output.recording",
    "isp_twin.experiments.scenario",
    "isp_twin.model.twin",
)


def import_lazy_modules() -> None:
    import importlib

    for name in LAZY_MODULES:
        importlib.import_module(name)
    from isp_twin.input_files import _yaml_loader

    _yaml_loader()


@contextmanager
def unprivileged() -> Iterator[None]:
    """Run the block as user `nobody` when the tests run as root (permissions
    are then enforced as for a user); unchanged otherwise."""
    if os.geteuid() != 0:
        yield
        return
    os.setegid(NOBODY)
    os.seteuid(NOBODY)
    try:
        yield
    finally:
        os.seteuid(0)
        os.setegid(0)


@contextmanager
def working_directory(path: Path) -> Iterator[None]:
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)
