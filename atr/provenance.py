"""What identifies the code that made a result: the source tree's git commit and a hash of its sources,
and the SHA-256 of a file. One definition for the recorder's provenance record (bus/provenance.py) and the
regression baselines (atr/regression/corpus.py).
"""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# What decides a result: the code, the message contract and the layouts.
SOURCE_GLOBS = (
    "atr/**/*.py",
    "bus/**/*.py",
    "cli/**/*.py",
    "services/**/*.py",
    "schemas/*.json",
    "compose/**/*.yml",
    "compose/**/*.json5",
)


def source_commit(root: Path = REPO) -> str:
    """The git commit of the source tree, with `+dirty` when a source that decides a result
    (`SOURCE_GLOBS`) has uncommitted changes; empty outside a git checkout.

    Other files (docs, the regression baselines a `--update` is writing) leave it clean.
    """
    if not (root / ".git").exists():
        return ""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10
        )
        dirty = subprocess.run(
            [
                "git",
                "status",
                "--porcelain",
                "--untracked-files=no",
                "--",
                *(f":(glob){pattern}" for pattern in SOURCE_GLOBS),
            ],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return ""
    if head.returncode != 0:
        return ""
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def source_sha256(root: Path = REPO) -> str:
    """SHA-256 over the project's source files (path and bytes, in path order): the same sources
    give the same hash on any machine, installed or checked out.
    """
    digest = hashlib.sha256()
    files = sorted({p for pattern in SOURCE_GLOBS for p in root.glob(pattern)})
    for path in files:
        if "__pycache__" in path.parts or not path.is_file():
            continue
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file, read in 16 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1 << 24):
            digest.update(block)
    return digest.hexdigest()
