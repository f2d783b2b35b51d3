#!/usr/bin/env python3
"""roslaunch a file; end when its required nodes end, and exit with their exit code.

  roslaunch_checked.py [--quiet] [PACKAGE] LAUNCH_FILE [NAME:=VALUE ...]

What plain roslaunch does not: a required node (here: a training node) that fails makes the command
fail (roslaunch exits 0 whatever its nodes did), a required node that finishes cleanly ends the
launch without roslaunch's red "REQUIRED process has died" banner, and Ctrl-C exits 130. Starts a
master if none is running, as roslaunch does. Nothing it started outlives it, however it ends (kill -9
included: workspace_tools.launch_reaper). A YAML file with rosparam's !radians tag, which rosparam
evaluates with eval(), is refused before anything in it runs. A relative or ~ results_dir:= is made
absolute against the folder it runs in.

--quiet (what ./ws run passes unless quiet:=false): roslaunch's own screen lines (the parameter summary, the
master's and each process's start and end) go to roslaunch-screen.log in the launch's log folder
(~/.ros/log/RUN_ID/) instead; its errors still go to stderr, and the nodes' own output to the screen. With
$WS_RUN_RECORD set (by ./ws run: {"folder": ..., "command": ...}), the run is recorded there once its master
is up, for ./ws plot, rviz and exec to join (workspace_tools.live_runs), and the record removed when it ends.
"""
import json
import os
import sys
from pathlib import Path
from typing import Any

import rosgraph
import roslaunch
import roslaunch.core
import roslaunch.parent
import roslaunch.pmon
import roslaunch.rlutil
import rosparam  # noqa: F401 (registers its YAML tags, which refuse_evaluated_yaml_tags then replaces)
import rospkg
import yaml

from workspace_tools.launch_reaper import watch_launch
from workspace_tools.live_runs import RECORD_VARIABLE, record, release_default_port

INTERRUPTED = 130  # the shell's code for a command ended by SIGINT


class ExitCodes(roslaunch.pmon.ProcessListener):
    """Records how nodes end; when one of `ends_launch` ends, shuts the launch down as roslaunch would."""

    def __init__(self):
        self.ends_launch = set()
        self.monitor: Any = None
        self.finished = None    # exit code of the first node of ends_launch to end
        self.failures = []      # non-zero exit codes of the other nodes

    def process_died(self, process_name, exit_code):
        if process_name in self.ends_launch and self.finished is None:
            self.finished = exit_code or 0
            self.monitor.is_shutdown = True
        elif exit_code:
            self.failures.append(exit_code)


def refuse_evaluated_yaml_tags() -> None:
    """Make roslaunch refuse !radians (and rad(...)): Debian's rosparam evaluates it as Python with eval()."""
    def refuse(loader, node):
        raise yaml.constructor.ConstructorError(
            None, None, f"{node.tag} {node.value!r} is not allowed in a config (rosparam would evaluate it as "
                        f"Python code): write the number", node.start_mark)
    for loader in (yaml.SafeLoader, yaml.Loader, yaml.FullLoader, yaml.UnsafeLoader):
        loader.add_constructor("!radians", refuse)


PATH_ARGS = ("results_dir",)  # launch arguments that name a folder: relative to where the command runs


def absolute_paths(arg: str) -> str:
    """results_dir:=runs or :=~/runs made absolute here: roslaunch runs its nodes in ROS_HOME (~/.ros), where
    a relative path would land, and ~ is no folder to a node."""
    name, _, value = arg.partition(":=")
    return f"{name}:={os.path.abspath(os.path.expanduser(value))}" if name in PATH_ARGS and value else arg


ROS_INT = (-2**31, 2**31 - 1)  # XML-RPC's int, which carries every integer param


def too_big_for_ros(parent) -> str:
    """", not ...: the params whose integers XML-RPC cannot carry" when the launch has any, else ""."""
    def too_big(value) -> bool:
        if isinstance(value, dict):
            return any(too_big(v) for v in value.values())
        if isinstance(value, list):
            return any(too_big(v) for v in value)
        return isinstance(value, int) and not isinstance(value, bool) and not ROS_INT[0] <= value <= ROS_INT[1]
    params = getattr(getattr(parent, "config", None), "params", {}) or {}
    names = sorted(name for name, p in params.items() if too_big(p.value))
    return f" (a ROS param is a 32-bit int at most: {', '.join(names)})" if names else ""


def screen_to_log(uuid: str) -> None:
    """roslaunch's own screen lines (it prints them to sys.stdout) into roslaunch-screen.log of the launch's log
    folder; the nodes started from now on still write to the terminal (they inherit file descriptor 1)."""
    folder = Path(rospkg.get_log_dir()) / uuid
    folder.mkdir(parents=True, exist_ok=True)
    sys.stdout = open(folder / "roslaunch-screen.log", "a", buffering=1)  # noqa: SIM115 (open until the end)


def record_run(uuid: str, wanted: str) -> Path | None:
    """The run's record for ./ws plot, rviz and exec (if ./ws run asked for one: `wanted`), once the master is up."""
    if not wanted:
        return None
    try:
        request = json.loads(wanted)
        return record(Path(request["folder"]), rosgraph.get_master_uri(), uuid, request["command"],
                      request.get("robot", ""))
    except (OSError, ValueError, KeyError, TypeError) as error:  # the run goes on; only joining it needs the uri
        print(f"roslaunch_checked.py: could not record the run for ./ws plot, rviz and exec: {error}", file=sys.stderr)
        return None


def main(argv) -> int:
    quiet = bool(argv) and argv[0] == "--quiet"
    argv = argv[1:] if quiet else argv
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__, file=sys.stderr)
        return 2
    launch_file = roslaunch.rlutil.resolve_launch_arguments(argv)[0]
    launch_args = [absolute_paths(arg) for arg in argv if ":=" in arg]
    uuid = roslaunch.rlutil.get_or_generate_uuid(None, False)
    wanted_record = os.environ.pop(RECORD_VARIABLE, "")  # not for the nodes this launch starts
    if quiet:
        screen_to_log(uuid)
    roslaunch.configure_logging(uuid)
    refuse_evaluated_yaml_tags()
    watch_launch()
    codes = ExitCodes()
    parent = roslaunch.parent.ROSLaunchParent(uuid, [(launch_file, launch_args)], process_listeners=[codes])
    try:
        parent.start()
    except Exception as error:  # noqa: BLE001 (a launch file, argument or YAML file roslaunch cannot load; an
        # $(eval) of a bad argument raises whatever Python raises; a number XML-RPC cannot carry, OverflowError)
        reason = " ".join(str(error).split())
        if not isinstance(error, roslaunch.core.RLException):
            reason = f"{type(error).__name__}: {reason}{too_big_for_ros(parent)}"
        print(f"roslaunch_checked.py: cannot launch {launch_file}: {reason}", file=sys.stderr)
        parent.shutdown()
        return 1
    # Required nodes end the launch through the listener instead, without the banner.
    codes.monitor = parent.pm
    for process in parent.pm.procs:
        if process.required:
            process.required = False
            codes.ends_launch.add(process.name)
    recorded = record_run(uuid, wanted_record)
    try:
        parent.spin()
    finally:
        if recorded is not None:
            recorded.unlink(missing_ok=True)
            release_default_port(recorded.parent)
        parent.shutdown()
    if codes.finished is not None:
        code = codes.finished or (codes.failures[0] if codes.failures else 0)
    else:
        code = codes.failures[0] if codes.failures else INTERRUPTED
    return 128 - code if code < 0 else code  # a node killed by signal N: 128 + N, as the shell says


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
