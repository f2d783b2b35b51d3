"""docs/reference/architecture.md's module tables name every first-party module of the tree, and nothing else:
under "## Modules", one "### `<package>`" table per package, its first column the module's path below
<package>/src/<package>/ (package __init__.py files are the packages themselves, not listed)."""
import re

import pytest

from workspace_tools.paths import REPO

PAGE = REPO / "docs" / "reference" / "architecture.md"
PACKAGES = ["pybullet_sim", "robot_rl", "hopper_training", "moving_cube_training", "workspace_tools"]


def documented_modules() -> dict[str, list[str]]:
    """The first column of each package's table in the Modules section, in the page's order."""
    section = PAGE.read_text().split("\n## Modules\n", 1)[1].split("\n## ", 1)[0]
    tables: dict[str, list[str]] = {}
    for block in re.split(r"^### ", section, flags=re.M)[1:]:
        heading, _, body = block.partition("\n")
        package = heading.strip().strip("`")
        tables[package] = re.findall(r"^\| `([^`]+)` \|", body, flags=re.M)
    return tables


def modules_in_tree(package: str) -> set[str]:
    root = REPO / package / "src" / package
    return {path.relative_to(root).as_posix() for path in root.rglob("*.py") if path.name != "__init__.py"}


def test_the_modules_section_has_a_table_per_package():
    assert list(documented_modules()) == PACKAGES


@pytest.mark.parametrize("package", PACKAGES)
def test_a_packages_table_names_its_modules(package):
    listed = documented_modules()[package]
    assert len(listed) == len(set(listed)), f"{package}: a module listed twice"
    in_tree = modules_in_tree(package)
    assert not in_tree - set(listed), f"{PAGE.name} does not name {sorted(in_tree - set(listed))} of {package}"
    assert not set(listed) - in_tree, f"{PAGE.name} names {sorted(set(listed) - in_tree)}, not in {package}"
