"""The pytest markers of test modules, read from their sources: what `./ws test --quick` must install first.

A module's markers are every `pytest.mark.NAME` its source names (`pytestmark = pytest.mark.deep`, a
decorator). Read without importing: a module whose torch is not installed yet could not be collected.
"""
from __future__ import annotations

import ast
from collections.abc import Iterable
from pathlib import Path

# marker -> the requirements file a test with it needs (the markers are registered in pyproject.toml)
REQUIREMENTS = {"deep": "requirements-deep.txt", "ray": "requirements-distributed.txt"}


def module_markers(path: Path) -> set[str]:
    """The names of the pytest.mark.NAME attributes the Python source at `path` uses."""
    markers = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute) and node.value.attr == "mark"
                and isinstance(node.value.value, ast.Name) and node.value.value.id == "pytest"):
            markers.add(node.attr)
    return markers


def python_files(paths: Iterable[Path]) -> list[Path]:
    """The .py files that `paths` (files and folders) name, folders searched throughout."""
    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            files += sorted(path.rglob("*.py"))
        elif path.suffix == ".py":
            files.append(path)
    return files


def markers_of(paths: Iterable[Path]) -> set[str]:
    """Every marker of the Python files in `paths`."""
    return set().union(*(module_markers(path) for path in python_files(paths)))


def requirements_of(paths: Iterable[Path]) -> list[str]:
    """The requirements files the tests in `paths` need, by their markers (REQUIREMENTS' order)."""
    markers = markers_of(paths)
    return [file for marker, file in REQUIREMENTS.items() if marker in markers]
