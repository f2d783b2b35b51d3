"""docs/guide/tutorials.md's recipes as a user types them: every venv the pages make, in a shell whose first python3
is not Debian's; and the commands that run the tutorials' own training scripts, on a layout of the tutorials'
packages of our own making (stand-ins for their entry points that find their package as theirs do), with a
folder beside the packages that rospkg cannot parse."""
import re
import sys
from pathlib import Path

from workspace_tools.paths import REPO
from workspace_tools.processes import Processes, RosMaster

TUTORIALS_PAGE = REPO / "docs" / "guide" / "tutorials.md"
PAGES = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
VENV_COMMAND = re.compile(r"([^\s`]+) -m venv ([^&`\n]*)")
GYM_ERA = "/tmp/gym-era"
GYM_ERA_PYTHON = f"{GYM_ERA}/bin/python"


def entry_point(script: str, node: str, package: str, namespace: str) -> str:
    """Stand-in for a tutorial's training script: its node, its params, its output folder found as theirs."""
    return f'''#!/usr/bin/env python
"""Stand-in for the tutorial's {script}: its node, its params, its output folder."""
import os
import rospkg
import rospy

rospy.init_node('{node}', anonymous=True, log_level=rospy.WARN)
outdir = rospkg.RosPack().get_path('{package}') + '/training_results'
if not os.path.exists(outdir):
    os.makedirs(outdir)
with open(os.path.join(outdir, 'params.txt'), 'w') as out:
    out.write('alpha %s nepisodes %s\\n' % (rospy.get_param('{namespace}alpha'),
                                           rospy.get_param('{namespace}nepisodes')))
'''


HOPPER_ENTRY_POINT = entry_point("start_training_v2.py", "monoped_gym", "my_hopper_training", "/")
CUBE_ENTRY_POINT = entry_point("oldway_start_training.py", "movingcube_gym", "moving_cube_training_pkg",
                               "/moving_cube/")
CUBE_SYSTEMS_TEST = '''"""Stand-in for the cube tutorial's cube_rl_utils.py as a script (the real one needs the sim)."""
import rospy

rospy.init_node('cube_rl_systems_test_node', anonymous=True, log_level=rospy.WARN)
print('Done==>False')
'''


def lay_out_the_tutorials(root: Path) -> None:
    """The two tutorial packages as published (the hopper's without a package.xml, the cube's named otherwise
    than its script looks it up), and beside them a folder with a package.xml that is not XML."""
    files = {
        "my_hopper_training/src/start_training_v2.py": HOPPER_ENTRY_POINT,
        "my_hopper_training/config/qlearn_params.yaml": "alpha: 0.1\ngamma: 0.8\nnepisodes: 1000\n",
        "moving_cube_training_pkg/package.xml":
            '<?xml version="1.0"?>\n<package format="2">\n  <name>my_moving_cube_training_pkg</name>\n'
            '  <version>0.0.0</version>\n  <description>The my_moving_cube_training_pkg package</description>\n'
            '  <maintainer email="user@todo.todo">user</maintainer>\n  <license>TODO</license>\n'
            '  <buildtool_depend>catkin</buildtool_depend>\n</package>\n',
        "moving_cube_training_pkg/script/oldway_start_training.py": CUBE_ENTRY_POINT,
        "moving_cube_training_pkg/script/cube_rl_utils.py": CUBE_SYSTEMS_TEST,
        "moving_cube_training_pkg/config/one_disk_walk_openai_params.yaml":
            "moving_cube:\n  alpha: 0.2\n  nepisodes: 1000\n",
        "notes/package.xml": "a draft, not XML yet <package\n",
    }
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)


def recipe_paragraphs() -> list[list[str]]:
    """The lines of the tutorials page's block that runs their training scripts, by paragraph (one per
    robot), without the sims' lines (terminal 1)."""
    blocks = [block for block in re.findall(r"^```\n(.*?)^```", TUTORIALS_PAGE.read_text(), re.M | re.S)
              if "start_training_v2.py" in block]
    assert len(blocks) == 1, "docs/guide/tutorials.md's block that runs the tutorials' training scripts"
    return [[line for line in paragraph.splitlines() if not line.startswith("./ws exec roslaunch")]
            for paragraph in blocks[0].strip().split("\n\n")]


def test_the_recipe_runs_the_tutorials_entry_points_in_their_packages(tmp_path):
    tutorials = tmp_path / "tutorials"
    lay_out_the_tutorials(tutorials)
    paragraphs = recipe_paragraphs()
    assert len(paragraphs) == 2 and any("cd my_hopper_training/src" in line for line in paragraphs[0]), paragraphs
    script = "set -e\n" + "".join(f"cd {tutorials}\n" + "\n".join(paragraph) + "\n" for paragraph in paragraphs)
    # The gym-era venv needs gym 0.10.5 from PyPI; the stand-ins need only rospy and rospkg.
    script = script.replace(GYM_ERA_PYTHON, "python3")
    master = RosMaster(tmp_path)
    master.env["WS"] = str(REPO)
    try:
        result = master.run(["bash", "-c", script], timeout=300)
    finally:
        master.close()
    assert result.returncode == 0, f"{script}\n{result.stdout[-2000:]}\n{result.stderr[-3000:]}"
    hopper = tutorials / "my_hopper_training" / "training_results" / "params.txt"
    cube = tutorials / "moving_cube_training_pkg" / "training_results" / "params.txt"
    assert hopper.read_text() == "alpha 0.1 nepisodes 5\n", result.stderr[-3000:]
    assert cube.read_text() == "alpha 0.2 nepisodes 5\n", result.stderr[-3000:]
    assert "Done==>False" in result.stdout, result.stdout


def venv_commands() -> list[str]:
    """Every `python -m venv ...` the pages give, in code blocks or inline, up to its `&&`."""
    return sorted({match.group(0).strip() for page in PAGES for match in VENV_COMMAND.finditer(page.read_text())})


def test_every_venv_of_the_pages_is_made_from_debians_python_and_finds_ros(tmp_path):
    """The recipes' venvs, made as written (HOME and /tmp/gym-era moved into the test's folder) in a shell
    whose first python3 is not Debian's (one that has no rospy; here a python3 that fails), then asked for
    rospy, catkin_pkg and a message package."""
    commands = venv_commands()
    assert any("~/rl-venv" in command for command in commands), commands
    assert any(GYM_ERA in command for command in commands), commands
    home, fake_bin = tmp_path / "home", tmp_path / "bin"
    home.mkdir()
    fake_bin.mkdir()
    (fake_bin / "python3").write_text("#!/bin/sh\necho 'not the python3 of Debian: no rospy here' >&2\nexit 1\n")
    (fake_bin / "python3").chmod(0o755)
    venv_bin = str(Path(sys.executable).parent)
    runner = Processes(tmp_path, cwd=tmp_path)
    runner.env = {**{k: v for k, v in runner.env.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")},
                  "HOME": str(home),
                  "PATH": ":".join([str(fake_bin), *(p for p in runner.env["PATH"].split(":") if p != venv_bin)])}
    try:
        for command in commands:
            typed = command.replace(GYM_ERA, str(home / "gym-era"))
            venv = Path(typed.split()[-1].replace("~", str(home), 1))
            made = runner.run(["bash", "-c", typed], timeout=120)
            assert made.returncode == 0, f"{command}: {made.stderr[-2000:]}"
            imports = runner.run([str(venv / "bin" / "python"), "-c", "import rospy, catkin_pkg, std_msgs.msg"],
                                 timeout=60)
            assert imports.returncode == 0, f"the venv of `{command}` has no ROS: {imports.stderr[-2000:]}"
    finally:
        runner.close()
