"""The code version a result names: the commit, and `+dirty` only when a source that decides results
differs from it."""

from __future__ import annotations

import subprocess
from pathlib import Path

from atr.provenance import source_commit


def _git(root: Path, *args: str) -> None:
    subprocess.run(["git", *args], cwd=root, check=True, capture_output=True)


def test_only_a_changed_source_makes_the_version_dirty(tmp_path: Path) -> None:
    (tmp_path / "atr").mkdir()
    (tmp_path / "docs").mkdir()
    (tmp_path / "atr" / "step.py").write_text("X = 1\n")
    (tmp_path / "docs" / "page.md").write_text("text\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "first")
    clean = source_commit(tmp_path)
    assert len(clean) == 40 and not clean.endswith("+dirty")
    (tmp_path / "docs" / "page.md").write_text("other text\n")
    assert source_commit(tmp_path) == clean  # not a source: results do not depend on it
    (tmp_path / "atr" / "step.py").write_text("X = 2\n")
    assert source_commit(tmp_path) == clean + "+dirty"
