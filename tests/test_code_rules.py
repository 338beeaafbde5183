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


def _circles(graph, modules: set[str]) -> list[list[str]]:
    """The import circles among ``modules`` (strongly connected components of two or more, or a module
    importing itself), by Tarjan's algorithm over grimp's direct imports."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []

    def visit(module: str) -> None:  # recursion depth is bounded by the chain length (a few dozen)
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in sorted(graph.find_modules_directly_imported_by(module) & modules):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                component.append(other)
                if other == module:
                    break
            if len(component) > 1 or module in graph.find_modules_directly_imported_by(module):
                circles.append(sorted(component))

    for module in sorted(modules):
        if module not in index:
            visit(module)
    return circles


def _graph():
    import grimp

    return grimp.build_graph(*PRODUCT, "campaign")


def test_no_module_imports_itself_back():
    """No import circle between any two modules (type-checking imports count: a circle is a circle
    whether or not Python trips over it)."""
    graph = _graph()
    modules = {m for m in graph.modules if m.split(".")[0] in (*PRODUCT, "campaign")}
    circles = _circles(graph, modules)
    assert not circles, "import circles:\n" + "\n".join(" <-> ".join(c) for c in circles)


def test_the_circle_check_finds_a_planted_circle():
    graph = _graph()
    graph.add_import(importer="bus.angles", imported="bus.topics")
    graph.add_import(importer="bus.topics", imported="bus.angles")
    assert ["bus.angles", "bus.topics"] in _circles(graph, {"bus.angles", "bus.topics", "bus.keys"})
