"""./ws's commands: one table of command -> function, one usage text (the `ws` script sets up the workspace).

  python -m workspace_tools.cli COMMAND [ARGS...]        run COMMAND, inside the workspace environment
  python -m workspace_tools.cli needs COMMAND [ARGS...]  what COMMAND needs first, one line each: `apt PACKAGE`,
                                                         `requirements FILE`, `private-master` (ws provides it)

A command's arguments are checked once, by its parser, in both; a wrong one exits 1 with one line
("[ws] error: ..."), an unknown command prints the usage and exits 1 (no command: 2).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from workspace_tools.lint import lint
from workspace_tools.live_runs import RECORD_VARIABLE, LiveRun, join_line, live_runs, run_master_uri, runs_folder
from workspace_tools.paths import REPO
from workspace_tools.pytest_markers import requirements_of
from workspace_tools.robots import DEFAULT_ROBOT, DEMO_ROBOT, ROBOTS, UnknownRobot, find_robot
from workspace_tools.ws_messages import WsError, log

USAGE = """\
The workspace's one entry script. Every command first makes sure the workspace is set up (Debian's
ROS 1 packages, a venv from /usr/bin/python3 with the pinned requirements, the catkin build) and
does only what is missing, so a second run starts in seconds.

  ./ws run [cube|hopper] [NAME:=VALUE ...]  set up, then train (roslaunch <robot's package> main.launch);
                              rviz:=true also installs rviz (Debian's) and shows the robot in it;
                              agent:=NAME of a deep agent (robot_rl.agents) also installs requirements-deep.txt;
                              cluster:=ray|ADDRESS (env workers as Ray actors) also installs requirements-distributed.txt
  ./ws rviz [cube|hopper] [NAME:=VALUE ...] set up with rviz, then the robot moving in its sim, seen in rviz
                              (the monoped hopping under hop_controller, at real_time_factor 0.25)
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
  ./ws demo [cube|hopper] [policy:=NAME|run:=RUN_FOLDER] [push:=V] [seed:=N] [VIDEO.mp4]  a shipped policy
                              (<package>/policies/NAME, default demo), or a run of yours, plays one episode, recorded
                              to VIDEO.mp4 (never overwritten; default demos/demo_<robot>.mp4, or demos/<run>.mp4,
                              a new name if it exists), then evaluate.py's JSON (an SB3 agent's policy also installs
                              requirements-deep.txt); push:=V kicks the base at V m/s (evaluate.py --push);
                              seed:=N seeds the episode (evaluate.py --seed, default 0)
  ./ws setup [deep|distributed]  only the set-up (deep: also torch and stable-baselines3; distributed: also Ray)
  ./ws help                   this text and the arguments of every launch file ./ws run starts
"""  # noqa: E501 (the usage's lines are as wide as its commands)

DEEP, DISTRIBUTED, DEV = "requirements-deep.txt", "requirements-distributed.txt", "requirements-dev.txt"
RVIZ_APT, PLOT_APT, TEST_APT = ["rviz"], ["python3-tk"], ["xvfb"]  # Debian's, installed only when asked for
PRIVATE_MASTER = "private-master"  # a master on a free port unless the caller set ROS_MASTER_URI
RESULTS = REPO / "training_results"
DEMOS = REPO / "demos"  # ./ws demo's videos (ignored by git)
WS_RUN_VARIABLE = "WS_RUN"  # robot_rl.runs.next_steps's (not imported: ./ws starts without numpy)
WS_RESULTS_VARIABLE = "WS_RUN_RESULTS"  # next_steps's too: ./ws run's default results_dir, not repeated in its hints
CALLER_MASTER = "WS_CALLER_MASTER"  # ws sets it to the caller's ROS_MASTER_URI ("" if none): the caller's wins
# The robots' rviz configs (package, file), for ./ws rviz on a run that is going on (robot_rl's watch.launch).
RVIZ_CONFIGS = {"cube": ("moving_cube_description", "rviz/moving_cube.rviz"),
                "hopper": ("hopper_description", "rviz/monoped.rviz")}


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
    """requirements-deep.txt when agent:=NAME names a deep agent, and requirements-distributed.txt when it needs Ray
    (RLlib's) (robot_rl.agents says)."""
    agent = _last(args, "agent")
    if not agent:
        return []
    needs = [file for file, question in ((DEEP, "needs-deep"), (DISTRIBUTED, "needs-ray"))
             if subprocess.run([sys.executable, "-m", "robot_rl.agents", question, agent]).returncode == 0]
    return _requirements(*needs) if needs else []


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
    # Quiet unless quiet:=false: the EP: lines and the tutorial's closing lines at debug level, roslaunch's own
    # lines (its parameter dump, each process's start and end) in its log folder.
    quiet = not re.fullmatch(r"(?i)false|0", _last(args, "quiet"))
    command = " ".join(["./ws run", robot.name, *args])
    return Plan(needs, ["rosrun", "workspace_tools", "roslaunch_checked.py", *(["--quiet"] if quiet else []),
                        *robot.training_launch, f"results_dir:={RESULTS}", *([] if _last(args, "quiet") else
                                                                              ["quiet:=true"]), *args],
                before=lambda: _run_master(command, robot.name))


def _caller_chose_master() -> bool:
    return bool(os.environ.get(CALLER_MASTER))


def _run_master(command: str, robot: str) -> None:
    """A new run's master: the caller's ROS_MASTER_URI, else 11311 if free, else a free port; one line says which.
    roslaunch_checked.py records the run for ./ws plot, rviz and exec (workspace_tools.live_runs)."""
    if _caller_chose_master():
        log(f"this run's ROS master: {os.environ['ROS_MASTER_URI']} (your ROS_MASTER_URI)")
    else:
        os.environ["ROS_MASTER_URI"], line = run_master_uri()
        log(line)
    os.environ[RECORD_VARIABLE] = json.dumps({"folder": str(runs_folder()), "command": command, "robot": robot})
    os.environ[WS_RUN_VARIABLE] = f"./ws run {robot}"  # the training node's end block gives ./ws commands
    os.environ[WS_RESULTS_VARIABLE] = str(RESULTS)


def _join_run() -> LiveRun | None:
    """The newest run ./ws run has going (its master set as ROS_MASTER_URI, one line saying which), unless the
    caller set ROS_MASTER_URI or no run is going (then ROS_MASTER_URI stays as ws set it: 11311)."""
    if _caller_chose_master():
        return None
    runs = live_runs()
    if not runs:
        return None
    os.environ["ROS_MASTER_URI"] = runs[0].master_uri
    log(join_line(runs))
    return runs[0]


def _join() -> None:
    _join_run()


def rviz(args: list[str]) -> Plan:
    name = args.pop(0) if args and ":=" not in args[0] else DEFAULT_ROBOT
    robot = ROBOTS[_robot(name)]
    _display("rviz")
    todo = Plan(_apt(RVIZ_APT), ["roslaunch", *robot.show, "rviz:=true", "paused:=false", *args])

    def join() -> None:  # a run going on: rviz on its sim, not a second sim on its master
        joined = _join_run()
        if joined is not None:
            watched = ROBOTS.get(joined.robot, robot)
            package, config = RVIZ_CONFIGS[watched.name]
            namespace = watched.namespace
            todo.argv = ["roslaunch", "robot_rl", "watch.launch", f"joint_states:=/{namespace}/joint_states",
                         f"rviz_config:={_package_path(package)}/{config}"]
    todo.before = join
    return todo


def _package_path(package: str) -> str:
    return subprocess.run(["rospack", "find", package], capture_output=True, text=True, check=True).stdout.strip()


def plot(args: list[str]) -> Plan:
    return Plan(_apt(PLOT_APT), ["rosrun", "robot_rl", "plot_rewards.py", *args], before=_join)


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


DEMO_USAGE = "usage: ./ws demo [cube|hopper] [policy:=NAME|run:=RUN_FOLDER] [push:=V] [seed:=N] [VIDEO.mp4]"


def demo(args: list[str]) -> Plan:
    name = DEMO_ROBOT
    if args and not args[0].endswith(".mp4") and ":=" not in args[0]:
        name = args.pop(0)
    given: dict[str, str] = {}
    for arg in [a for a in args if ":=" in a]:  # NAME:=V in any order, each once
        key, _, value = arg.partition(":=")
        if key not in ("policy", "run", "push", "seed") or key in given:
            raise WsError(DEMO_USAGE)
        given[key] = value
        args.remove(arg)
    if "policy" in given and "run" in given:
        raise WsError(DEMO_USAGE)
    policy, run_path = given.get("policy", "demo"), given.get("run", "")
    push, seed = given.get("push", ""), given.get("seed", "")
    if "push" in given and not re.fullmatch(r"\d+(\.\d*)?|\.\d+", push):
        raise WsError(f"push:={push}: the kicks' speed in m/s, a number of 0 or more (e.g. push:=0.75)")
    if "seed" in given and not re.fullmatch(r"\d+", seed):  # evaluate.py checks its range
        raise WsError(f"seed:={seed}: the episode's seed, a whole number of 0 or more (e.g. seed:=1000)")
    robot = ROBOTS[_robot(name)]
    if len(args) > 1:
        raise WsError(DEMO_USAGE)
    if args and (not args[0].endswith(".mp4") or os.path.isdir(args[0])):
        folder = " (a folder)" if os.path.isdir(args[0]) else ""
        raise WsError(f"the video must be an .mp4 file, got '{args[0]}'{folder}")
    if run_path:
        played = Path(run_path).resolve()
        if not played.is_dir():
            raise WsError(f"run:={run_path}: no such run folder (a training_results/<task>/<run>/ folder)")
        default_name = f"{played.name}.mp4"
    else:
        shipped = REPO / robot.package / "policies"
        if not re.fullmatch(r"[A-Za-z0-9_-]+", policy) or not (shipped / policy).is_dir():
            known = ", ".join(sorted(path.name for path in shipped.iterdir())) if shipped.is_dir() else ""
            raise WsError(f"no shipped policy '{policy}' for {name} (known: {known})")
        played = shipped / policy
        default_name = f"demo_{name}.mp4" if policy == "demo" else f"demo_{name}_{policy}.mp4"
    if args and Path(args[0]).exists():  # a video named by the caller is never overwritten
        raise WsError(f"{args[0]} exists: give another name (or delete it)")
    # SB3's model.zip needs torch to play; a bc_dagger student (student.npz) plays in numpy
    needs = _requirements(DEEP) if (played / "model.zip").is_file() else []
    todo = Plan(needs, ["rosrun", robot.package, "evaluate.py", "--run", str(played), "--episodes", "1", "--video",
                        os.path.realpath(args[0]) if args else "", "--video-episodes", "1",
                        *(["--push", push] if push else []), *(["--seed", seed] if seed else [])])

    def default_video() -> None:  # chosen when it runs (not in `needs`): demos/, a new name if taken
        if not args:
            DEMOS.mkdir(exist_ok=True)
            assert todo.argv is not None
            todo.argv[todo.argv.index("--video") + 1] = str(_new_video(DEMOS / default_name))
    todo.before = default_video
    return todo


def _new_video(path: Path) -> Path:
    """`path`, or the first of PATH-2.mp4, PATH-3.mp4, ... that does not exist (one line says so)."""
    if not path.exists():
        return path
    number = 2
    while (other := path.with_name(f"{path.stem}-{number}{path.suffix}")).exists():
        number += 1
    log(f"{path.parent.name}/{path.name} exists: this video goes to {other.parent.name}/{other.name}")
    return other


def python(args: list[str]) -> Plan:
    return Plan([], ["python", *args])


def exec_command(args: list[str]) -> Plan:
    if not args:
        raise WsError("usage: ./ws exec CMD [ARGS...]")
    return Plan([], args, before=_join)


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
        todo.before()  # may change argv (./ws rviz on a run going on)
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
