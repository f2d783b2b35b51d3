"""docs/reference/tasks.md is generated from the task specs and their env docstrings: it must be what its generator,
workspace_tools/scripts/write_tasks_doc.py, writes now."""
from __future__ import annotations

import difflib
import importlib
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / "docs" / "reference" / "tasks.md"


def load_generator() -> ModuleType:
    return importlib.import_module("workspace_tools.tasks_doc")


def test_the_tasks_page_is_what_its_generator_writes():
    generator = load_generator()
    expected = generator.render(REPO)
    actual = PAGE.read_text()
    diff = "".join(list(difflib.unified_diff(actual.splitlines(True), expected.splitlines(True),
                                             "docs/reference/tasks.md", "generated"))[:40])
    assert actual == expected, f"docs/reference/tasks.md is out of date: run `{generator.REGENERATE}`\n{diff}"


def test_the_tasks_page_has_every_task_with_its_docstring():
    generator = load_generator()
    page = PAGE.read_text()
    for spec in generator.registered_tasks():
        assert f"## {spec.env_id}\n" in page
        module = importlib.import_module(spec.entry_point.split(":")[0])
        assert "Reward:" in (module.__doc__ or ""), f"{module.__name__}'s docstring has no Reward: section"
