"""An older commit of this repository, checked out beside it and installed in a virtual environment
of its own, so that a benchmark can run it and today's code side by side in one sitting (a speed
target is a ratio measured in one run, never a number carried over from another day). Cached under
``~/.cache/swarmloc/baseline/<commit>``; built once, in a minute or two."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = Path.home() / ".cache" / "swarmloc" / "baseline"
A0FCCEE = "a0fccee"  # before the redesign and the work that followed it (the speed targets' yardstick)


def swarm_of(python: Path | str) -> str:
    """The `swarm` command installed beside a Python (what a user types; a0fccee had no `cli` package)."""
    return str(Path(python).parent / "swarm")


def checkout_of(python: Path | str) -> Path:
    """The checkout a Python runs the code of: its baseline worktree, or this repository. `python -m
    cli` imports the package of the working directory first, so a baseline must run from its own."""
    path = Path(python)
    return path.parents[2] if CACHE in path.parents else ROOT


def baseline_python(commit: str = A0FCCEE) -> Path:
    """The Python of a virtual environment with ``commit`` of this repository installed (built here
    on first use)."""
    full = subprocess.run(["git", "rev-parse", commit], cwd=ROOT, capture_output=True, text=True, check=True)
    work = CACHE / full.stdout.strip()[:12]
    python = work / ".venv" / "bin" / "python"
    if python.exists() and (work / ".venv" / ".installed").exists():
        return python
    if not work.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        subprocess.run(["git", "worktree", "add", "--detach", "--force", str(work), commit], cwd=ROOT, check=True)
    subprocess.run([sys.executable, "-m", "venv", str(work / ".venv")], check=True)
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", "-e", str(work)], check=True)
    (work / ".venv" / ".installed").touch()
    return python
