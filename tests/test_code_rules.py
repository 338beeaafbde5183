"""The rules the code follows are checked, not only written: ruff (lint and format) on the whole
tree and the import contracts (import-linter, ``[tool.importlinter]`` in pyproject.toml: the layers
cli > experiments > launch > sim | vehicle | groundstation > bus)."""

import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _tool(name: str) -> str:
    found = shutil.which(name, path=str(BIN)) or shutil.which(name)
    if found is None:
        pytest.fail(f"{name} is not installed: it is a dev dependency (pip install -e '.[dev]')")
    return found


def _run(*command: str) -> subprocess.CompletedProcess:
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_ruff_lint_passes():
    result = _run(_tool("ruff"), "check", "--no-cache", ".")
    assert result.returncode == 0, result.stdout + result.stderr


def test_ruff_format_is_applied():
    result = _run(_tool("ruff"), "format", "--check", "--no-cache", ".")
    assert result.returncode == 0, "run `ruff format .`:\n" + result.stdout + result.stderr


def test_import_contracts_are_kept():
    result = _run(_tool("lint-imports"), "--no-cache")
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr


KEY_PATTERN = re.compile(r"(^|/|})(v/[^ ]*/|ctl/|alive/)|/truth\b")
PRODUCT = ("bus", "sim", "vehicle", "groundstation", "launch", "experiments", "cli")


def _key_literals(path: Path) -> list[str]:
    """String literals (f-strings included) in ``path`` that look like zenoh keys of the swarm."""
    with path.open("rb") as source:
        tokens = tokenize.tokenize(source.readline)
        return [
            f"{path.relative_to(ROOT)}:{tok.start[0]}: {tok.string}"
            for tok in tokens
            if tok.type == tokenize.STRING and KEY_PATTERN.search(tok.string.strip("\"'frb")) and "\n" not in tok.string
        ]


def test_key_strings_are_built_only_in_bus_keys():
    found = [
        hit
        for package in PRODUCT
        for path in sorted((ROOT / package).rglob("*.py"))
        if path != ROOT / "bus" / "keys.py"
        for hit in _key_literals(path)
    ]
    assert not found, "key strings outside bus/keys.py:\n" + "\n".join(found)


def test_the_key_check_finds_a_key_literal(tmp_path):
    planted = ROOT / "bus" / "_planted_for_test.py"
    try:
        planted.write_text('KEY = f"{prefix}/ctl/clock"\n')
        assert _key_literals(planted)
    finally:
        planted.unlink()
