"""The reference benchmark stores with every axis the code that made it
(`benchmarks/identify_reference.py`, `code_version`, `code_lines`).

Its SQLite file resumes across sessions: a table that pools axes of
different commits must say so, and an axis run on uncommitted changes to
the product or the benchmark must not pass for the commit's.
"""

from __future__ import annotations

import subprocess

from reference_benchmark import reference_benchmark


def _git(root, *args):
    subprocess.run(["git", "-C", str(root), *args], check=True, capture_output=True)


def _repo(tmp_path):
    root = tmp_path / "checkout"
    (root / "isp_twin").mkdir(parents=True)
    (root / "isp_twin" / "model.py").write_text("A = 1\n")
    _git(root, "init", "-q")
    _git(root, "add", ".")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "first")
    return root


def test_the_version_is_the_commit_and_says_when_the_code_was_changed(tmp_path):
    root = _repo(tmp_path)
    version = reference_benchmark().code_version(root)
    head = subprocess.run(
        ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    assert len(version) == 12 and head.startswith(version)
    (root / "notes.txt").write_text("an untracked file is not the code\n")
    assert reference_benchmark().code_version(root) == version
    (root / "isp_twin" / "model.py").write_text("A = 2\n")
    assert reference_benchmark().code_version(root) == version + "+modified"


def test_outside_a_checkout_the_version_is_unknown(tmp_path):
    assert reference_benchmark().code_version(tmp_path) == "unknown"


def test_a_table_of_one_commit_names_it():
    lines = reference_benchmark().code_lines([{"code": "abc"}, {"code": "abc"}])
    assert lines == ["code: abc (2 axes)"]


def test_a_table_pooling_commits_says_so():
    records = [{"code": "abc"}, {"code": "def+modified"}, {}]
    (line,) = reference_benchmark().code_lines(records)
    assert "pools records of 3 code versions" in line
    assert "abc (1 axes)" in line and "def+modified (1 axes)" in line
    assert "not recorded (1 axes)" in line
