"""./ws lint: every linter the tests rely on (ruff, mypy, catkin_lint, roslaunch-check, import-linter), in
that order; the first that complains ends it (WsError)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from workspace_tools.robots import ROBOTS
from workspace_tools.ws_messages import WsError, log

ROSLAUNCH_CHECK = "/usr/share/roslaunch/scripts/roslaunch-check"
IMPORT_CONTRACTS = ".importlinter"  # lint-imports' config at the repository root, checked when it is there


def launch_files(root: Path) -> list[Path]:
    """The launch files roslaunch-check checks: each robot's sim and training, the cube's systems test and the
    rostest files."""
    return [*(root / robot.sim_package / "launch" / robot.sim_launch for robot in ROBOTS.values()),
            *(root / robot.package / "launch" / robot.main_launch for robot in ROBOTS.values()),
            root / "moving_cube_training" / "launch" / "systems_test.launch",
            *sorted((root / "test" / "rostest").glob("*.test"))]


def lint(root: Path) -> None:
    """Run the linters in `root` (the repository); WsError names the first that found problems."""
    def passes(*command: str) -> bool:
        return subprocess.run(command, cwd=root).returncode == 0

    log("ruff")
    if not passes("ruff", "check", "--quiet", "."):
        raise WsError("ruff found problems (fix them, or 'ruff check --fix .')")
    log("mypy")
    if not passes("mypy", "--no-error-summary"):
        raise WsError("mypy found type errors")
    log("catkin_lint")
    result = subprocess.run(["catkin_lint", "--quiet", "."], cwd=root, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    problems = [line for line in result.stdout.splitlines()
                if line.strip() and "rosdep" not in line and "unknown dependencies" not in line]
    if problems:
        print("\n".join(problems), file=sys.stderr)
        raise WsError("catkin_lint found problems")
    log("roslaunch-check")
    report = root / ".ws" / "roslaunch-check.xml"
    for launch_file in launch_files(root):
        relative = launch_file.relative_to(root)
        check = subprocess.run(["python3", ROSLAUNCH_CHECK, "-o", str(report), str(relative)], cwd=root,
                               capture_output=True, text=True)
        if not any(line.startswith("passed") for line in check.stdout.splitlines()):
            raise WsError(f"roslaunch-check: {relative} has problems (see {report})")
    if (root / IMPORT_CONTRACTS).is_file():
        log("import-linter")
        # The packages' sources, not the devel space's relays to them (import-linter reads the files it finds).
        sources = [str(path) for path in sorted(root.glob("*/src")) if path.is_dir()]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([*sources, os.environ.get("PYTHONPATH", "")])}
        checked = subprocess.run(["lint-imports", "--no-cache", IMPORT_CONTRACTS], cwd=root, env=env,
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if checked.returncode != 0:
            print(checked.stdout.split("Broken contracts", 1)[-1].strip("\n-"), file=sys.stderr)
            raise WsError("import-linter found imports its contracts forbid (.importlinter)")
