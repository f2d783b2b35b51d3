"""The README's commands as a newcomer pastes them: every command line of its code blocks names an existing
./ws command, launch file, launch argument, script and option; the quick ones run; its code excerpts
are the code's."""
from __future__ import annotations

import re
import shlex
import subprocess
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
import rospkg

from workspace_tools.paths import REPO

README = (REPO / "README.md").read_text()
BLOCKS = re.findall(r"^```[a-z]*\n(.*?)^```", README, re.M | re.S)
WS_COMMANDS = {"run", "help", "python", "exec", "test", "lint", "bench", "rviz", "plot", "setup"}
ROBOT_LAUNCH = {"cube": ("moving_cube_training", "main.launch"), "hopper": ("hopper_training", "main.launch")}


def command_lines() -> list[list[str]]:
    """Every line of a code block that starts with a command we document, split as bash would."""
    lines = []
    for block in BLOCKS:
        joined = block.replace("\\\n", " ")
        for line in joined.splitlines():
            line = line.strip()
            if re.match(r"(\./ws|\$WS/ws|roslaunch|rosrun|rostest|catkin_make) ", line) and "-c '" not in line:
                lines.append(shlex.split(line, comments=True))
    return lines


COMMANDS = command_lines()


def launch_args(package: str, launch_file: str) -> set[str]:
    path = Path(rospkg.RosPack().get_path(package)) / "launch" / launch_file
    assert path.is_file(), f"{package}/launch/{launch_file} does not exist"
    return {str(arg.get("name")) for arg in ElementTree.parse(path).getroot().iter("arg")}


def script_options(package: str, script: str) -> str:
    path = Path(rospkg.RosPack().get_path(package)) / "scripts" / script
    assert path.is_file(), f"{package}/scripts/{script} does not exist"
    if script not in ("evaluate.py", "compare_agents.py"):  # the scripts with options in the README
        return ""
    return subprocess.run(["rosrun", package, script, "--help"], capture_output=True, text=True, timeout=60).stdout


def check_launch(words: list[str]) -> None:
    package, launch_file, *rest = words
    declared = launch_args(package, launch_file)
    for word in rest:
        if ":=" in word:
            assert word.split(":=")[0] in declared, f"{package} {launch_file} has no argument {word}"


def check_command(words: list[str]) -> None:
    if words[0] in ("./ws", "$WS/ws"):
        assert words[1] in WS_COMMANDS, f"./ws has no command {words[1]}"
        if words[1] == "run":
            robot = words[2] if len(words) > 2 and ":=" not in words[2] and not words[2].startswith("-") else "cube"
            check_launch([*ROBOT_LAUNCH[robot], *words[2:]])
        elif words[1] == "exec" and words[2] in ("roslaunch", "rosrun"):
            check_command(words[2:])
        return
    if words[0] == "roslaunch" and words[1] != "--ros-args":
        check_launch(words[1:])
    elif words[0] == "rosrun":
        help_text = script_options(words[1], words[2])
        for word in words[3:]:
            if word.startswith("--"):
                assert word in help_text, f"{words[2]} has no option {word}"
    elif words[0] == "rostest":
        assert (REPO / "test" / "rostest" / words[2]).is_file() and words[1] == "workspace_tests", words


def test_the_readme_documents_enough_commands_to_check():
    assert len(COMMANDS) >= 20, COMMANDS


@pytest.mark.parametrize("words", COMMANDS, ids=[" ".join(w)[:60] for w in COMMANDS])
def test_every_command_names_what_exists(words):
    check_command(words)


def test_help_lists_every_training_argument(tmp_path):
    result = subprocess.run([str(REPO / "ws"), "help"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    for package, launch_file in ROBOT_LAUNCH.values():
        for arg in launch_args(package, launch_file) - {"sim_launch", "node_name"}:
            assert f"  {arg} (default " in result.stdout, f"./ws help does not list {arg}"


def test_the_python_snippet_runs_as_pasted():
    snippet = re.search(r"^(\./ws python -c '\n.*?\n')$", README, re.M | re.S)
    assert snippet, "the README's ./ws python snippet"
    result = subprocess.run(["bash", "-c", snippet.group(1)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "reward_distance" in result.stdout and "reward_speed" in result.stdout


def test_the_hop_excerpts_are_the_code():
    source = (REPO / "hopper_training" / "src" / "hopper_training" / "hop.py").read_text()
    for excerpt in re.findall(r"   ```python\n(.*?)   ```", README, re.S):
        code = "\n".join(line[3:] for line in excerpt.splitlines())
        assert code.strip() in source, f"README excerpt not in hop.py:\n{code}"
