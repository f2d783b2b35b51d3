"""./ws's commands: one table of command -> function, one usage text (the `ws` script sets up the workspace).

  python -m workspace_tools.cli COMMAND [ARGS...]        run COMMAND, inside the workspace environment
  python -m workspace_tools.cli needs COMMAND [ARGS...]  what COMMAND needs first, one line each: `apt PACKAGE`,
                                                         `requirements FILE`, `private-master` (ws provides it)

A command's arguments are checked once, by its parser, in both; a wrong one exits 1 with one line
("[ws] error: ..."), an unknown command prints the usage and exits 1 (no command: 2).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from workspace_tools.lint import lint
from workspace_tools.paths import REPO
from workspace_tools.pytest_markers import requirements_of
from workspace_tools.robots import DEFAULT_ROBOT, DEMO_ROBOT, ROBOTS, UnknownRobot, find_robot
from workspace_tools.ws_messages import WsError

USAGE = """\
The workspace's one entry script. Every command first makes sure the workspace is set up (Debian's
ROS 1 packages, a venv from /usr/bin/python3 with the pinned requirements, the catkin build) and
does only what is missing, so a second run starts in seconds.

  ./ws run [cube|hopper] [NAME:=VALUE ...]  set up, then train (roslaunch <robot's package> main.launch);
                              rviz:=true also installs rviz (Debian's) and shows the robot in it;
                              agent:=NAME of a deep agent (robot_rl.agents) also installs requirements-deep.txt;
                              cluster:=ray|ADDRESS (env workers as Ray actors) also installs requirements-distributed.txt
  ./ws rviz [cube|hopper] [NAME:=VALUE ...] set up with rviz, then the robot's sim running, seen in rviz
  ./ws plot [NAMESPACE] [--output PNG]      a live plot of the reward topics (rqt_plot is not in Debian 12)
  ./ws test [PYTEST ARGS]     set up, then the linters and every test (pytest + rostest)
  ./ws test --quick [PYTEST ARGS]  pytest alone: no linters, no display packages, the deep agents' only if the tests use them
  ./ws lint                   set up, then only the linters (ruff, mypy, catkin_lint, roslaunch-check)
  ./ws bench [--reps N] [--sections S,...] [--running-step ROBOT=S] [--markdown]  set up (with the deep agents), then the benchmark (--markdown: also docs/reference/performance.md)
  ./ws python [ARGS...]       python inside the workspace environment (the venv, the devel space)
  ./ws exec CMD [ARGS...]     CMD inside the workspace environment
  ./ws sweep [cube|hopper] [seeds:=0-9] [NAME:=V1,V2 ...] [max_steps:=N] [name:=SWEEP] [resume:=true] [cluster:=ray|ADDRESS]
                              many training runs on Ray Tune, a table and a plot (installs requirements-distributed.txt)
  ./ws cluster start|join ADDRESS|stop|status  this machine's Ray node (installs requirements-distributed.txt)
  ./ws demo [cube|hopper] [policy:=NAME] [VIDEO.mp4]  a shipped trained policy (<package>/policies/NAME,
                              default demo) plays one episode, recorded to VIDEO.mp4 (default ./demo_<robot>.mp4),
                              then evaluate.py's JSON (a deep agent's policy also installs requirements-deep.txt)
  ./ws setup [deep|distributed]  only the set-up (deep: also torch and stable-baselines3; distributed: also Ray)
  ./ws help                   this text and the arguments of every launch file ./ws run starts
"""  # noqa: E501 (the usage's lines are as wide as its commands)

DEEP, DISTRIBUTED, DEV = "requirements-deep.txt", "requirements-distributed.txt", "requirements-dev.txt"
RVIZ_APT, PLOT_APT, TEST_APT = ["rviz"], ["python3-tk"], ["xvfb"]  # Debian's, installed only when asked for
PRIVATE_MASTER = "private-master"  # a master on a free port unless the caller set ROS_MASTER_URI
RESULTS = REPO / "training_results"


@dataclass
class Plan:
    """What a command needs installed (`needs`) and then runs (`argv`, exec'd; None: it is done in Python)."""

    needs: list[str] = field(default_factory=list)
    argv: list[str] | None = None
    chdir: Path | None = None            # where argv runs (default: the caller's folder)
    before: Callable[[], None] | None = None  # Python run before argv (or instead of it)


def _requirements(*files: str) -> list[str]:
    return [f"requirements {file}" for file in files]


def _apt(packages: Sequence[str]) -> list[str]:
    return [f"apt {package}" for package in packages]


def _last(args: Sequence[str], name: str) -> str:
    """The value of the last `name:=VALUE` among args ("" if none)."""
    values = [arg.split(":=", 1)[1] for arg in args if arg.startswith(f"{name}:=")]
    return values[-1] if values else ""


def _agent_needs(args: Sequence[str]) -> list[str]:
    """requirements-deep.txt when agent:=NAME names a deep agent (robot_rl.agents says)."""
    agent = _last(args, "agent")
    if agent and subprocess.run([sys.executable, "-m", "robot_rl.agents", "needs-deep", agent]).returncode == 0:
        return _requirements(DEEP)
    return []


def _robot(name: str, hint: str = "") -> str:
    try:
        return find_robot(name).name
    except UnknownRobot as error:
        raise WsError(f"{str(error)[:-1]}{hint})") from None


def _display(what: str) -> None:
    if not os.environ.get("DISPLAY"):
        raise WsError(f"{what} needs a display (DISPLAY is not set)")


def run(args: list[str]) -> Plan:
    name = DEFAULT_ROBOT
    if args and ":=" not in args[0] and not args[0].startswith("-"):
        name = args.pop(0)
    for arg in args:
        if arg in ("-h", "--help"):
            return help_command([])
        if ":=" not in arg:
            raise WsError(f"'{arg}' is not a launch argument NAME:=VALUE (see ./ws help)")
    robot = ROBOTS[_robot(name, "; see ./ws help")]
    needs = _agent_needs(args)
    if any(re.match(r"cluster:=.", arg) for arg in args):
        needs += _requirements(DISTRIBUTED)
    if any(re.fullmatch(r"rviz:=(true|1)", arg, re.IGNORECASE) for arg in args):
        _display("rviz:=true")
        needs += _apt(RVIZ_APT)
    return Plan([*needs, PRIVATE_MASTER], ["rosrun", "workspace_tools", "roslaunch_checked.py", *robot.training_launch,
                                           f"results_dir:={RESULTS}", *args])


def rviz(args: list[str]) -> Plan:
    name = args.pop(0) if args and ":=" not in args[0] else DEFAULT_ROBOT
    robot = ROBOTS[_robot(name)]
    _display("rviz")
    return Plan(_apt(RVIZ_APT), ["roslaunch", *robot.sim, "rviz:=true", "paused:=false", *args])


def plot(args: list[str]) -> Plan:
    return Plan(_apt(PLOT_APT), ["rosrun", "robot_rl", "plot_rewards.py", *args])


def help_text() -> str:
    """The usage, then each training launch file's arguments, as roslaunch itself lists them."""
    parts = [USAGE]
    for robot in ROBOTS.values():
        launch = " ".join(robot.training_launch)
        parts.append(f"\n./ws run {robot.name} = roslaunch {launch}, arguments (NAME:=VALUE):\n")
        listed = subprocess.run(["roslaunch", "--ros-args", *robot.training_launch], capture_output=True, text=True,
                                check=True).stdout
        # roslaunch files an argument whose default is "" under "Required": it is not, show its default.
        lines = [line if "(default " in line else re.sub(r"^(  [^:]*):", r'\1 (default ""):', line)
                 for line in listed.splitlines() if line.startswith("  ")]
        parts.append(subprocess.run(["sort"], input="".join(f"{line}\n" for line in lines), capture_output=True,
                                    text=True, check=True).stdout)
    parts.append(f"\nResults go to {REPO}/training_results/ (results_dir:=...).\n")
    return "".join(parts)


def help_command(args: list[str]) -> Plan:
    return Plan(before=lambda: print(help_text(), end=""))


def lint_command(args: list[str]) -> Plan:
    return Plan(_requirements(DEV), before=lambda: lint(REPO))


def test(args: list[str]) -> Plan:
    quick = bool(args) and args[0] == "--quick"
    if quick:
        args.pop(0)
    # The whole test folder unless the arguments name test files or folders themselves.
    named = [path for path in (REPO / arg.split("::")[0] for arg in args if not arg.startswith("-")) if path.exists()]
    paths = [] if named else ["test"]
    if quick:  # pytest alone: no linters, no display packages; the optional packages the chosen tests' markers ask
        needs = _requirements(*requirements_of(named or [REPO / "test"]))
    else:
        needs = [*_apt(RVIZ_APT + PLOT_APT + TEST_APT), *_requirements(DEEP, DISTRIBUTED, DEV)]
    return Plan([*needs, PRIVATE_MASTER], [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args, *paths],
                chdir=REPO, before=None if quick else lambda: lint(REPO))


def bench(args: list[str]) -> Plan:
    return Plan([*_requirements(DEEP, DISTRIBUTED), PRIVATE_MASTER], ["rosrun", "workspace_tools", "bench.py", *args],
                chdir=REPO)


def sweep(args: list[str]) -> Plan:
    if any(arg in ("-h", "--help") for arg in args):
        return Plan([], [sys.executable, "-m", "workspace_tools.sweep", "--help"])
    # Results go where ./ws run puts them unless results_dir:= says otherwise.
    default = [] if any(arg.startswith("results_dir:=") for arg in args) else [f"results_dir:={RESULTS}"]
    return Plan([*_agent_needs(args), *_requirements(DISTRIBUTED)],
                [sys.executable, "-m", "workspace_tools.sweep", *args, *default])


def cluster(args: list[str]) -> Plan:
    action = args[0] if args else ""
    if action in ("start", "stop", "status"):
        if len(args) != 1 and action != "start":
            raise WsError(f"usage: ./ws cluster {action}")
    elif action == "join":
        if len(args) < 2:
            raise WsError("usage: ./ws cluster join ADDRESS (HOST:PORT of the head)")
    else:
        raise WsError("usage: ./ws cluster start|join ADDRESS|stop|status")
    return Plan(_requirements(DISTRIBUTED), [sys.executable, "-m", "robot_rl.workers.cluster", *args])


def demo(args: list[str]) -> Plan:
    name, policy = DEMO_ROBOT, "demo"
    if args and not args[0].endswith(".mp4") and not args[0].startswith("policy:="):
        name = args.pop(0)
    if args and args[0].startswith("policy:="):
        policy = args.pop(0).removeprefix("policy:=")
    robot = ROBOTS[_robot(name)]
    if len(args) > 1:
        raise WsError("usage: ./ws demo [cube|hopper] [policy:=NAME] [VIDEO.mp4]")
    shipped = REPO / robot.package / "policies"
    if not re.fullmatch(r"[A-Za-z0-9_-]+", policy) or not (shipped / policy).is_dir():
        known = ", ".join(sorted(path.name for path in shipped.iterdir())) if shipped.is_dir() else ""
        raise WsError(f"no shipped policy '{policy}' for {name} (known: {known})")
    video = os.path.realpath(args[0] if args else f"demo_{name}.mp4")
    if not video.endswith(".mp4") or os.path.isdir(video):
        raise WsError(f"the video must be an .mp4 file, got '{args[0]}'{' (a folder)' if os.path.isdir(video) else ''}")
    needs = _requirements(DEEP) if (shipped / policy / "agent.json").is_file() else []
    return Plan(needs, ["rosrun", robot.package, "evaluate.py", "--run", str(shipped / policy), "--episodes", "1",
                        "--video", video, "--video-episodes", "1"])


def python(args: list[str]) -> Plan:
    return Plan([], ["python", *args])


def exec_command(args: list[str]) -> Plan:
    if not args:
        raise WsError("usage: ./ws exec CMD [ARGS...]")
    return Plan([], args)


def setup(args: list[str]) -> Plan:
    if args not in ([], ["deep"], ["distributed"]):
        raise WsError("usage: ./ws setup [deep|distributed]")
    return Plan(_requirements(f"requirements-{args[0]}.txt") if args else [])


COMMANDS: dict[str, Callable[[list[str]], Plan]] = {
    "run": run, "rviz": rviz, "plot": plot, "help": help_command, "-h": help_command, "--help": help_command,
    "lint": lint_command, "test": test, "bench": bench, "sweep": sweep, "cluster": cluster, "demo": demo,
    "python": python, "exec": exec_command, "setup": setup,
}


def plan(argv: Sequence[str]) -> Plan:
    """The plan of `./ws ARGV`; WsError if it cannot run, SystemExit(2) with the usage when no command is given."""
    command, *args = argv or [""]
    if command not in COMMANDS:
        print(USAGE, end="", file=sys.stderr)
        if not command:
            raise SystemExit(2)
        raise WsError(f"unknown command '{command}'")
    return COMMANDS[command](list(args))


def execute(todo: Plan) -> int:
    """Run a plan's Python, then exec its argv (this process becomes it: its exit code is the command's)."""
    if todo.chdir:
        os.chdir(todo.chdir)
    if todo.before:
        todo.before()
    if todo.argv is None:
        return 0
    os.execvp(todo.argv[0], todo.argv)
    return 127  # not reached: execvp returns only by raising


def main(argv: Sequence[str]) -> int:
    try:
        if argv and argv[0] == "needs":
            for line in plan(argv[1:]).needs:
                print(line)
            return 0
        return execute(plan(argv))
    except WsError as error:
        print(f"[ws] error: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
