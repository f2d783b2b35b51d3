"""Every test module that needs torch / Stable-Baselines3 or Ray carries its pytest marker (deep, ray), which
`./ws test --quick` reads (workspace_tools.pytest_markers) to install requirements-deep.txt or
requirements-distributed.txt first: a forgotten marker fails here, instead of the test failing to import."""
import ast
import re
from pathlib import Path

import pytest

import robot_rl
from workspace_tools.paths import REPO
from workspace_tools.pytest_markers import REQUIREMENTS, markers_of, module_markers, requirements_of

# What in a test's source needs the optional packages: the deep agents (robot_rl.agents.sb3, SB3, torch) and Ray
# (robot_rl.workers' Ray actors and cluster; RLlib's agent robot_rl.agents.rllib needs both), imported by module, or
# by a name robot_rl's face loads from them.
USES = {"deep": re.compile(r"^ *(import|from) (torch|stable_baselines3)\b|robot_rl\.agents\.(sb3|rllib)", re.M),
        "ray": re.compile(r"^ *(import ray|from ray)|robot_rl\.workers\.(cluster|ray_actors)|ray_cluster"
                          r"|robot_rl\.agents\.rllib", re.M)}
FACE_MODULES = {"deep": ("robot_rl.agents.sb3",), "ray": ("robot_rl.workers.cluster", "robot_rl.workers.ray_actors")}


def face_imports(text: str) -> set[str]:
    """The names a source imports from robot_rl's face (`from robot_rl import ...`)."""
    return {alias.name for node in ast.walk(ast.parse(text))
            if isinstance(node, ast.ImportFrom) and node.module == "robot_rl" and not node.level
            for alias in node.names}


def uses(marker: str, text: str) -> bool:
    lazy = {name for name, reference in robot_rl._LAZY.items() if reference.startswith(FACE_MODULES[marker])}
    return bool(USES[marker].search(text) or face_imports(text) & lazy)


SOURCES = sorted(path for path in (REPO / "test").rglob("*.py") if path != Path(__file__).resolve())


@pytest.mark.parametrize("path", SOURCES, ids=lambda path: str(path.relative_to(REPO)))
def test_a_module_that_uses_optional_packages_carries_their_marker(path):
    text, markers = path.read_text(), module_markers(path)
    for marker in USES:
        if uses(marker, text):
            assert path.name.startswith("test_"), f"{path.name} is not a test module but needs {marker}'s packages: " \
                                                  f"mark the tests that use it"
            assert marker in markers, f"{path.name} uses {marker}'s packages: add `pytestmark = pytest.mark.{marker}`"


def test_markers_are_read_from_the_source_without_importing_it(tmp_path):
    (tmp_path / "test_a.py").write_text("import pytest\nimport torch\npytestmark = [pytest.mark.deep]\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "test_b.py").write_text("import pytest\n@pytest.mark.ray\ndef test_b(): pass\n")
    assert module_markers(tmp_path / "test_a.py") == {"deep"}
    assert markers_of([tmp_path]) == {"deep", "ray"}
    assert requirements_of([tmp_path / "sub"]) == [REQUIREMENTS["ray"]]
    assert requirements_of([tmp_path / "test_a.py"]) == ["requirements-deep.txt"]
