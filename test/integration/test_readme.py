"""The documentation as a newcomer reads and pastes it: README.md, docs/**/*.md, pybullet_sim/README.md, CHANGELOG.md.

Every command line of their code blocks names an existing ./ws command, launch file, launch argument,
script, option and test file; the quick ones run; their code excerpts are the code's; every relative
link points to a file of the repository (and a heading of it); every repository path they name exists;
the README stays a front page that lists every page."""
from __future__ import annotations

import functools
import re
import shlex
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pytest
import rospkg
from PIL import Image

from workspace_tools.paths import REPO
from workspace_tools.processes import Processes
from workspace_tools.robots import ROBOTS
from workspace_tools.sweep_spec import parse_sweep

README = REPO / "README.md"
PAGES = [README, REPO / "CHANGELOG.md", REPO / "pybullet_sim" / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
IMAGES = REPO / "docs" / "images"
README_MAX_LINES = 250
WS_COMMANDS = {"run", "help", "python", "exec", "test", "lint", "bench", "rviz", "plot", "setup", "cluster", "sweep",
               "demo"}
ROBOT_LAUNCH = {name: robot.training_launch for name, robot in ROBOTS.items()}
SIM_LAUNCH = {name: robot.sim for name, robot in ROBOTS.items()}
REWARD_NAMESPACES = {f"/{robot.namespace}" for robot in ROBOTS.values()}
COMMAND_START = re.compile(r"(\./ws|\$WS/ws|roslaunch|rosrun|rostest|catkin_make|evaluate\.py) ")
FENCE = re.compile(r"^ *```[a-z]*\n(.*?)^ *```", re.M | re.S)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")


def page_id(page: Path) -> str:
    return str(page.relative_to(REPO))


def code_blocks(text: str) -> list[str]:
    return [textwrap.dedent(block) for block in FENCE.findall(text)]


def command_lines(page: Path) -> list[list[str]]:
    """Every line of the page's code blocks that starts with a command we document, split as bash would."""
    lines = []
    for block in code_blocks(page.read_text()):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.strip()
            if COMMAND_START.match(line) and "-c '" not in line:
                lines.append(shlex.split(line, comments=True))
    return lines


COMMANDS = [(page, words) for page in PAGES for words in command_lines(page)]


def launch_args(package: str, launch_file: str) -> set[str]:
    path = Path(rospkg.RosPack().get_path(package)) / "launch" / launch_file
    assert path.is_file(), f"{package}/launch/{launch_file} does not exist"
    # an <arg value=...> is a constant of the file, not an argument roslaunch takes
    return {str(arg.get("name")) for arg in ElementTree.parse(path).getroot().iter("arg") if arg.get("value") is None}


def check_script(package: str, script: str) -> None:
    path = Path(rospkg.RosPack().get_path(package)) / "scripts" / script
    assert path.is_file(), f"{package}/scripts/{script} does not exist"


@functools.cache
def script_options(package: str, script: str) -> set[str]:
    """The options a script's --help lists."""
    help_text = subprocess.run(["rosrun", package, script, "--help"], capture_output=True, text=True, timeout=60).stdout
    return set(re.findall(r"--[\w-]+", help_text))


def check_options(package: str, script: str, words: list[str]) -> None:
    check_script(package, script)
    for option in [word.split("=")[0] for word in words if word.startswith("--")]:
        assert option in script_options(package, script), f"{script} has no option {option}"


def check_launch(words: list[str]) -> None:
    package, launch_file, *rest = words
    declared = launch_args(package, launch_file)
    for word in rest:
        if ":=" in word:
            assert word.split(":=")[0] in declared, f"{package} {launch_file} has no argument {word}"


def check_ws(words: list[str]) -> None:
    command, rest = words[1], words[2:]
    assert command in WS_COMMANDS, f"./ws has no command {command}"
    first = rest[0] if rest and ":=" not in rest[0] and not rest[0].startswith("-") else None
    if command in ("run", "rviz"):
        assert (first or "cube") in ROBOT_LAUNCH, f"./ws {command} {first}: no such robot"
    if command == "run":
        check_launch([*ROBOT_LAUNCH[first or "cube"], *rest[1 if first else 0:]])
    elif command == "rviz":
        check_launch([*SIM_LAUNCH[first or "cube"], *rest[1 if first else 0:]])
    elif command == "exec" and rest and rest[0] in ("roslaunch", "rosrun", "rostest"):
        check_command(rest)
    elif command == "test":
        for before, word in zip(["", *rest], rest):
            if not word.startswith("-") and before != "-k":
                assert (REPO / word.split("::")[0]).exists(), f"./ws test {word}: no such test file or folder"
    elif command == "bench":
        check_options("workspace_tools", "bench.py", rest)
    elif command == "plot":
        assert first is None or first in REWARD_NAMESPACES, f"./ws plot {first}: not a reward namespace"
        check_options("robot_rl", "plot_rewards.py", rest)
    elif command == "setup":
        assert rest in ([], ["deep"], ["distributed"]), f"./ws setup takes only 'deep' or 'distributed', got {rest}"
    elif command == "cluster":
        assert first in ("start", "join", "stop", "status"), f"./ws cluster has no command {first}"
    elif command == "sweep" and "--help" not in rest:
        parse_sweep(rest)  # the sweep's grammar: SweepError names a bad argument
    elif command == "demo":
        robot = first if first and not first.endswith(".mp4") else "hopper"
        package = ROBOT_LAUNCH[robot][0]
        assert (REPO / package / "policies" / "demo").is_dir(), f"./ws demo {robot}: {package} ships no policies/demo"


def check_command(words: list[str]) -> None:
    if words[0] in ("./ws", "$WS/ws"):
        check_ws(words)
    elif words[0] == "roslaunch":
        check_launch(words[2:] if words[1] == "--ros-args" else words[1:])
    elif words[0] == "rosrun" and words[1:3] == ["workspace_tools", "roslaunch_checked.py"]:
        check_launch(words[3:])
    elif words[0] == "rosrun":
        check_options(words[1], words[2], words[3:])
    elif words[0] == "rostest":
        assert words[1] == "workspace_tests", words
        assert (REPO / "test" / "rostest" / words[2]).is_file(), f"no rostest file test/rostest/{words[2]}"
    elif words[0] == "evaluate.py":
        check_options("moving_cube_training", "evaluate.py", words[1:])


def is_quick(words: list[str]) -> bool:
    """Commands that only list or check something: they run in seconds, with no master."""
    return "--ros-args" in words or words[-1] in ("--help", "--check")


QUICK = sorted({tuple(words) for _, words in COMMANDS if is_quick(words)})


def test_the_pages_document_enough_commands_to_check():
    assert len(COMMANDS) >= 60, COMMANDS
    assert len([page for page, _ in COMMANDS if page == README]) >= 12
    assert QUICK, "no quick command to run"


@pytest.mark.parametrize("page,words", COMMANDS, ids=[f"{page_id(p)}: {' '.join(w)[:60]}" for p, w in COMMANDS])
def test_every_command_names_what_exists(page, words):
    check_command(words)


@pytest.mark.parametrize("words", QUICK, ids=[" ".join(w)[:70] for w in QUICK])
def test_the_quick_commands_run(words):
    result = subprocess.run(list(words), cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]


def test_help_lists_every_training_argument(tmp_path):
    result = subprocess.run([str(REPO / "ws"), "help"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    for package, launch_file in ROBOT_LAUNCH.values():
        for arg in launch_args(package, launch_file) - {"sim_launch", "node_name"}:
            assert f"  {arg} (default " in result.stdout, f"./ws help does not list {arg}"


def test_the_python_snippet_runs_as_pasted():
    snippet = re.search(r"^(\./ws python -c '\n.*?\n')$", README.read_text(), re.M | re.S)
    assert snippet, "the README's ./ws python snippet"
    result = subprocess.run(["bash", "-c", snippet.group(1)], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "reward_distance" in result.stdout and "reward_speed" in result.stdout


def python_programs(page: Path) -> list[str]:
    """The page's ```python blocks meant to be run: those with an import statement, excerpts of the code aside
    (architecture.md's other block is one line of a registry, not a program)."""
    blocks = re.findall(r"(<!-- excerpt: \S+ -->\n)? *```python\n(.*?)^ *```", page.read_text(), re.M | re.S)
    return [textwrap.dedent(code) for excerpt, code in blocks
            if not excerpt and re.search(r"^(import|from) \w", textwrap.dedent(code), re.M)]


PROGRAMS = [(page, code) for page in PAGES for code in python_programs(page)]


def test_the_pages_have_programs_to_run():
    assert len(PROGRAMS) >= 2, "docs/guide/training.md's vector env and frames snippets"


@pytest.mark.parametrize("page,code", PROGRAMS, ids=[f"{page_id(p)}: {c.splitlines()[0][:50]}" for p, c in PROGRAMS])
def test_every_python_program_runs_saved_to_a_file(page, code, tmp_path):
    """Each program saved as a file and run with python, from an empty folder, as a user would; a picture it
    writes that docs/images/ shows too must be that picture."""
    program = tmp_path / "program" / "snippet.py"
    program.parent.mkdir()
    program.write_text(code)
    runner = Processes(tmp_path, cwd=program.parent)
    try:
        result = runner.run([sys.executable, program.name], timeout=300)
    finally:
        runner.close()
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-3000:]
    assert "Traceback" not in result.stderr, result.stderr[-3000:]
    for picture in program.parent.glob("*.png"):
        shown = IMAGES / picture.name
        assert shown.exists(), f"{page_id(page)}: the program writes {picture.name}, not in docs/images/"
        made, committed = (np.asarray(Image.open(path).convert("RGB"), dtype=int) for path in (picture, shown))
        assert made.shape == committed.shape, f"{picture.name}: {made.shape} made, docs/images/: {committed.shape}"
        differing = (np.abs(made - committed).max(axis=2) > 32).mean()
        assert differing < 0.002, f"{picture.name}: {differing:.1%} of its pixels differ from {shown}"


def test_the_code_excerpts_are_the_code():
    """A block after `<!-- excerpt: PATH -->` is a verbatim part of the repository's file PATH."""
    excerpts = [(page, path, code) for page in PAGES for path, code in re.findall(
        r"<!-- excerpt: (\S+) -->\n *```python\n(.*?)^ *```", page.read_text(), re.M | re.S)]
    assert len(excerpts) >= 2, "the architecture page's excerpts of hop.py"
    for page, path, code in excerpts:
        source = (REPO / path).read_text()
        assert textwrap.dedent(code).strip() in source, f"{page_id(page)}: excerpt not in {path}:\n{code}"


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text())
    return {slug(heading) for heading in re.findall(r"^#+ (.*)$", text, re.M)}


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_relative_link_points_into_the_repository(page):
    for target in LINK.findall(FENCE.sub("", page.read_text())):
        if re.match(r"[a-z]+:", target):
            continue
        path_text, _, anchor = target.partition("#")
        path = (page.parent / path_text).resolve() if path_text else page
        assert path.is_relative_to(REPO), f"{page_id(page)}: {target} leaves the repository"
        assert path.exists(), f"{page_id(page)}: {target} does not exist"
        if anchor and path.suffix == ".md":
            assert anchor in anchors(path), f"{page_id(page)}: {target}: no such heading"


def repository_paths(page: Path) -> list[str]:
    """Paths in `code` to a file (a name with an extension) or a folder (a trailing /) under a folder of the
    repository's packages, tests or docs; not ROS names such as `pybullet_sim/Step`."""
    folders = {p.parent.name for p in REPO.glob("*/package.xml")} | {"docs"}
    return [token for token in re.findall(r"`([^`\s]+)`", page.read_text())
            if "/" in token and token.split("/")[0] in folders and not re.search(r"[*{}<>$]|\.\.\.", token)
            and ("." in token.split("::")[0].rsplit("/", 1)[-1] or token.endswith("/"))]


@pytest.mark.parametrize("page", PAGES, ids=page_id)
def test_every_repository_path_named_exists(page):
    for token in repository_paths(page):
        path = token.split("::")[0].rstrip("/")
        package, _, rest = path.partition("/")
        candidates = [REPO / path, REPO / package / "src" / package / rest, REPO / package / "scripts" / rest]
        assert any(candidate.exists() for candidate in candidates), f"{page_id(page)}: `{token}` does not exist"


def test_the_readme_is_a_front_page_that_lists_every_page():
    text = README.read_text()
    assert len(text.splitlines()) <= README_MAX_LINES, f"README.md has {len(text.splitlines())} lines"
    assert "\n./ws run " in text and "\n./ws test " in text
    for page in PAGES[1:]:
        assert f"]({page_id(page)})" in text, f"README.md does not link {page_id(page)}"
