"""ros_control's controller manager over a World: list, load, unload and switch controllers. No ROS here.

The sim node serves these as <robot_namespace>/controller_manager/{list,load,unload,switch}_controller(s).
The controllers are those of config/<robot>_sim.yaml; at start every one is loaded and running, as the
tutorials' spawner leaves them. Semantics of ros_control noetic-devel (controller_manager.cpp):

- load: a configured controller that is not loaded becomes "initialized" (loaded, not running); loading
  a loaded one or an unknown name fails. unload: only a loaded controller that is not running.
- switch: strictness 0 means BEST_EFFORT (with a warning). STRICT fails the whole switch, changing
  nothing, on an unknown name, on stopping a controller that is not running, or on starting one that is
  running; BEST_EFFORT skips those. A controller in both lists (after those checks) and two running
  controllers on one joint fail under either strictness. Then the stops happen, then the starts: every
  controller in the start list is (re)started, a running one too, unless start_asap is set (then only the
  ones not running). start_asap and timeout have nothing to wait for here: the switch happens at once,
  between two physics steps, paused or not.
- A stopped or unloaded effort controller applies no effort and ignores commands (World.stop_controller);
  a stopped joint_state_controller publishes no joint_states (the node asks joint_states_running).
  Note: real gazebo_ros_control keeps applying a stopped effort controller's last effort (its
  DefaultRobotHWSim holds the last command; effort_controllers have no stopping()); here it is zero, so
  a stopped wheel coasts.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

from .config import JOINT_STATE_CONTROLLER, RobotConfig
from .world import World

BEST_EFFORT, STRICT = 1, 2  # controller_manager_msgs/SwitchController's constants
ECHO_NAMES = 3              # names a message repeats of a request's list at most
ECHO_CHARS = 60             # characters of one name a message repeats at most


def _name(name: str) -> str:
    """A name of a request, quoted, cut at ECHO_CHARS characters (a caller may send megabytes)."""
    return repr(name) if len(name) <= ECHO_CHARS else f"{name[:ECHO_CHARS]!r}... ({len(name)} characters)"


def _names(names: Sequence[str]) -> str:
    """Names of a request for a message: all of a few, else their count and the first ECHO_NAMES."""
    if len(names) <= ECHO_NAMES:
        return ", ".join(map(_name, names))
    return f"{len(names)} names, the first {ECHO_NAMES}: {', '.join(map(_name, names[:ECHO_NAMES]))}, ..."
EFFORT_INTERFACE = "hardware_interface::EffortJointInterface"
JOINT_STATE_INTERFACE = "hardware_interface::JointStateInterface"


@dataclass(frozen=True)
class ControllerInfo:
    """One loaded controller as list_controllers reports it (controller_manager_msgs/ControllerState)."""

    name: str
    type: str
    state: str  # "initialized" (loaded, never started), "running" or "stopped"
    hardware_interface: str
    resources: tuple[str, ...]  # the joints it claims


class Result(NamedTuple):
    ok: bool
    message: str  # why it failed; when ok, what was skipped or assumed ("" if nothing)


class ControllerManager:
    """The loaded controllers of one robot and their states; effort controllers run in the World."""

    def __init__(self, config: RobotConfig, world: World):
        self._world = world
        self._namespace = config.robot_namespace
        self._specs: dict[str, tuple[str, str, tuple[str, ...]]] = {  # name -> type, interface, claimed joints
            config.joint_state_controller: (JOINT_STATE_CONTROLLER, JOINT_STATE_INTERFACE, ())}
        for controller in config.controllers:
            self._specs[controller.name] = (controller.type, EFFORT_INTERFACE, (controller.joint,))
        self._joint_state_controller = config.joint_state_controller
        self._states: dict[str, str] = {name: "running" for name in self._specs}  # loaded ones, in load order

    @property
    def joint_states_running(self) -> bool:
        return self._states.get(self._joint_state_controller) == "running"

    def infos(self) -> list[ControllerInfo]:
        infos = []
        for name, state in self._states.items():
            controller_type, interface, joints = self._specs[name]
            infos.append(ControllerInfo(name, controller_type, state, interface, joints))
        return infos

    def load(self, name: str) -> Result:
        if name in self._states:
            return Result(False, f"a controller named {_name(name)} is already loaded in {self._namespace}")
        if name not in self._specs:
            return Result(False, f"could not load {_name(name)}: the sim's configuration has no such controller "
                                 f"(configured: {', '.join(self._specs)})")
        self._states[name] = "initialized"
        return Result(True, "")

    def unload(self, name: str) -> Result:
        if name not in self._states:
            return Result(False, f"could not unload {_name(name)}: no controller with this name is loaded")
        if self._states[name] == "running":
            return Result(False, f"could not unload {name!r}: it is still running (stop it first)")
        del self._states[name]
        return Result(True, "")

    def switch(self, start: Sequence[str], stop: Sequence[str], strictness: int, start_asap: bool = False) -> Result:
        """Stop then start controllers, all between two physics steps; nothing changes when it fails."""
        notes = []
        if strictness not in (BEST_EFFORT, STRICT):
            notes.append(f"strictness {strictness} is neither BEST_EFFORT ({BEST_EFFORT}) nor STRICT ({STRICT}): "
                         f"BEST_EFFORT, as ros_control does")
        strict = strictness == STRICT
        unknown = [name for name in (*stop, *start) if name not in self._states]
        if unknown:
            message = f"no controller named {_names(unknown)} is loaded in {self._namespace}"
            if strict:
                return Result(False, f"STRICT switch refused: {message}")
            notes.append(f"skipped: {message}")
        stops = [name for name in dict.fromkeys(stop) if name in self._states]
        starts = [name for name in dict.fromkeys(start) if name in self._states]
        for name, state in self._states.items():
            running, in_stop, in_start = state == "running", name in stops, name in starts
            if in_stop and not running:
                if strict:
                    return Result(False, f"STRICT switch refused: could not stop {name!r}, it is not running")
                in_stop = False
                stops.remove(name)
            if running and in_start and not in_stop and strict:
                return Result(False, f"STRICT switch refused: {name!r} is already running")
            if in_stop and in_start:
                return Result(False, f"could not start or stop {name!r}: it is in both lists")
        conflict = self._conflict([name for name, state in self._states.items()
                                   if (state == "running" and name not in stops) or name in starts])
        if conflict:
            return Result(False, conflict)
        for name in stops:
            self._set_running(name, False)
        for name in starts:
            if not (start_asap and self._states[name] == "running"):
                self._set_running(name, True)
        return Result(True, "; ".join(notes))

    def _conflict(self, running: list[str]) -> str:
        """ros_control's RobotHW::checkForConflict: one joint claimed by two running controllers."""
        owner: dict[str, str] = {}
        for name in running:
            for joint in self._specs[name][2]:
                if joint in owner:
                    return f"could not switch: {owner[joint]!r} and {name!r} would both control {joint}"
                owner[joint] = name
        return ""

    def _set_running(self, name: str, running: bool) -> None:
        self._states[name] = "running" if running else "stopped"
        if name == self._joint_state_controller:
            return
        if running:
            self._world.start_controller(name)
        else:
            self._world.stop_controller(name)
