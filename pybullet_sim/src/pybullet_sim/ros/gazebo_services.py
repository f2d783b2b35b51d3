"""Gazebo's physics, world and model services and ros_control's controller manager services, on the sim node.

An adapter: each handler turns a gazebo_msgs or controller_manager_msgs request into World or
ControllerManager calls (under the node's World lock) and the result into Gazebo's answer. What it needs
of the node is the SimHost protocol below. Services:
/gazebo/{get,set}_physics_properties, get_world_properties, {get,set}_model_state, set_model_configuration,
get_link_state, and <robot_namespace>/controller_manager/{switch,list,load,unload}_controller(s). Bad
requests get success false (ok false) and change nothing.
"""
from __future__ import annotations

from contextlib import AbstractContextManager
from typing import Any, Protocol

import rospy
from geometry_msgs.msg import Vector3

from controller_manager_msgs.srv import (
    ListControllers,
    ListControllersResponse,
    LoadController,
    LoadControllerResponse,
    SwitchController,
    SwitchControllerResponse,
    UnloadController,
    UnloadControllerResponse,
)
from gazebo_msgs.msg import LinkState
from gazebo_msgs.srv import (
    GetLinkState,
    GetLinkStateResponse,
    GetModelState,
    GetModelStateResponse,
    GetPhysicsProperties,
    GetPhysicsPropertiesResponse,
    GetWorldProperties,
    GetWorldPropertiesResponse,
    SetModelConfiguration,
    SetModelConfigurationResponse,
    SetModelState,
    SetModelStateResponse,
    SetPhysicsProperties,
    SetPhysicsPropertiesResponse,
)

from ..config import RobotConfig
from ..controller_manager import ControllerManager
from ..physics_properties import OdeConfig, PhysicsProperties, solver_settings
from ..physics_properties import check as physics_problem
from ..physics_properties import not_honoured as ode_not_honoured
from ..physics_properties import real_time_factor as physics_real_time_factor
from ..transforms import absolute_state, relative_state
from ..world import SolverSettings, World
from .messages import controller_state_msg, frame_state, ode_config, ode_physics_msg, pose_twist_msgs

WORLD_FRAMES = ("", "world", "map", "/map")  # the names gazebo_ros takes for the world frame


class SimHost(Protocol):
    """What the services need of the sim node: its World, controllers and config, its lock and run state."""

    world: World
    controllers: ControllerManager
    config: RobotConfig
    gui: bool
    real_time_factor: float

    @property
    def paused(self) -> bool: ...

    def exclusive(self) -> AbstractContextManager[Any]: ...  # hold the World lock from a service thread

    def stamp(self) -> rospy.Time: ...

    def set_physics(self, time_step: float, gravity, solver: SolverSettings, real_time_factor: float) -> None: ...


class GazeboServices:
    """Serves Gazebo's physics, world and model services and the controller manager for `node`."""

    def __init__(self, node: SimHost):
        self.node = node
        self._ode = OdeConfig()  # the last accepted ode_config, for get_physics_properties
        self._said_not_honoured: set[str] = set()  # ode_config fields already logged as not honoured
        for name, srv_type, handler in (
                ("get_physics_properties", GetPhysicsProperties, self._handle_get_physics),
                ("set_physics_properties", SetPhysicsProperties, self._handle_set_physics),
                ("get_world_properties", GetWorldProperties, self._handle_get_world),
                ("get_model_state", GetModelState, self._handle_get_model_state),
                ("set_model_state", SetModelState, self._handle_set_model_state),
                ("set_model_configuration", SetModelConfiguration, self._handle_set_model_configuration),
                ("get_link_state", GetLinkState, self._handle_get_link_state)):
            rospy.Service(f"/gazebo/{name}", srv_type, handler)
        manager = f"{node.config.robot_namespace}/controller_manager"
        rospy.Service(f"{manager}/switch_controller", SwitchController, self._handle_switch_controller)
        rospy.Service(f"{manager}/list_controllers", ListControllers, self._handle_list_controllers)
        rospy.Service(f"{manager}/load_controller", LoadController, self._handle_load_controller)
        rospy.Service(f"{manager}/unload_controller", UnloadController, self._handle_unload_controller)

    # -- Gazebo's physics, world and model services ---------------------------------------------
    def _handle_get_physics(self, _request):
        node = self.node
        with node.exclusive():
            world = node.world
            return GetPhysicsPropertiesResponse(
                time_step=world.time_step, pause=node.paused, max_update_rate=node.real_time_factor / world.time_step,
                gravity=Vector3(*world.gravity), ode_config=ode_physics_msg(self._ode), success=True,
                status_message="GetPhysicsProperties: got properties")

    def _handle_set_physics(self, request):
        node = self.node
        gravity = request.gravity
        wanted = PhysicsProperties(request.time_step, request.max_update_rate, (gravity.x, gravity.y, gravity.z),
                                   ode_config(request.ode_config))
        problem = physics_problem(wanted)
        if problem:
            message = f"SetPhysicsProperties refused, nothing changed: {problem}"
            return SetPhysicsPropertiesResponse(success=False, status_message=message)
        node.set_physics(wanted.time_step, wanted.gravity, solver_settings(wanted.ode),
                         physics_real_time_factor(wanted.max_update_rate, wanted.time_step))
        self._ode = wanted.ode
        not_honoured = ode_not_honoured(wanted.ode)
        new = [reason for name, reason in not_honoured.items() if name not in self._said_not_honoured]
        if new:
            self._said_not_honoured.update(not_honoured)
            rospy.logwarn("pybullet_sim: /gazebo/set_physics_properties: PyBullet cannot honour ode_config %s; "
                          "the rest is applied (said once per setting)", "; ".join(new))
        status = "physics engine updated"
        if not_honoured:
            status += f"; PyBullet cannot honour ode_config {', '.join(not_honoured)} (kept, without effect)"
        return SetPhysicsPropertiesResponse(success=True, status_message=status)

    def _handle_get_world(self, _request):
        node = self.node
        with node.exclusive():
            return GetWorldPropertiesResponse(sim_time=node.world.time, model_names=[node.world.robot_name],
                                              rendering_enabled=node.gui, success=True,
                                              status_message="GetWorldProperties: got properties")

    def _frame(self, name: str):
        """The world-frame state of a Gazebo reference frame name, None for the world itself (ValueError if unknown)."""
        return None if name in WORLD_FRAMES else self.node.world.entity_state(name)

    def _handle_get_model_state(self, request):
        node = self.node
        response = GetModelStateResponse()
        if request.model_name != node.world.robot_name:
            response.status_message = (f"GetModelState: model [{request.model_name}] does not exist (models: "
                                       f"{node.world.robot_name})")
            return response
        with node.exclusive():
            try:
                frame = self._frame(request.relative_entity_name)
            except ValueError as error:
                response.status_message = f"GetModelState: relative_entity_name not found: {error}"
                return response
            state = node.world.model_state()
            response.header.stamp = node.stamp()  # rospy numbers header.seq itself
        response.header.frame_id = request.relative_entity_name
        state = state if frame is None else relative_state(state, frame)
        response.pose, response.twist = pose_twist_msgs(state)
        response.success, response.status_message = True, "GetModelState: got properties"
        return response

    def _handle_set_model_state(self, request):
        node = self.node
        wanted = request.model_state
        if wanted.model_name != node.world.robot_name:
            message = f"SetModelState: model [{wanted.model_name}] does not exist (models: {node.world.robot_name})"
            return SetModelStateResponse(success=False, status_message=message)
        with node.exclusive():
            try:
                frame = self._frame(wanted.reference_frame)
                state = frame_state(wanted.pose, wanted.twist)
                node.world.set_model_state(state if frame is None else absolute_state(state, frame))
            except ValueError as error:
                return SetModelStateResponse(success=False,
                                             status_message=f"SetModelState refused, nothing changed: {error}")
        return SetModelStateResponse(success=True, status_message="SetModelState: set model state done")

    def _handle_set_model_configuration(self, request):
        node = self.node
        if request.model_name != node.world.robot_name:
            message = (f"SetModelConfiguration: model [{request.model_name}] does not exist (models: "
                       f"{node.world.robot_name})")
            return SetModelConfigurationResponse(success=False, status_message=message)
        if len(request.joint_names) != len(request.joint_positions):
            message = (f"SetModelConfiguration refused, nothing changed: {len(request.joint_names)} joint names "
                       f"but {len(request.joint_positions)} positions")
            return SetModelConfigurationResponse(success=False, status_message=message)
        with node.exclusive():
            try:
                node.world.set_joint_positions(dict(zip(request.joint_names, request.joint_positions)))
            except ValueError as error:
                return SetModelConfigurationResponse(
                    success=False, status_message=f"SetModelConfiguration refused, nothing changed: {error}")
        return SetModelConfigurationResponse(success=True, status_message="SetModelConfiguration: success")

    def _handle_get_link_state(self, request):
        node = self.node
        with node.exclusive():
            try:
                state = node.world.link_state(node.world.link_name(request.link_name))
                frame = self._frame(request.reference_frame)
            except ValueError as error:
                return GetLinkStateResponse(success=False, status_message=f"GetLinkState: {error}")
        pose, twist = pose_twist_msgs(state if frame is None else relative_state(state, frame))
        return GetLinkStateResponse(link_state=LinkState(link_name=request.link_name, pose=pose, twist=twist,
                                                         reference_frame=request.reference_frame),
                                    success=True, status_message="GetLinkState: got state")

    # -- ros_control's controller manager -------------------------------------------------------
    def _answer(self, service: str, result) -> bool:
        """Log a controller manager result as ros_control does (errors as errors), return its ok."""
        if not result.ok:
            rospy.logerr("pybullet_sim: %s/controller_manager/%s: %s", self.node.config.robot_namespace, service,
                         result.message)
        elif result.message:
            rospy.logwarn("pybullet_sim: %s/controller_manager/%s: %s", self.node.config.robot_namespace, service,
                          result.message)
        return result.ok

    def _handle_switch_controller(self, request):
        node = self.node
        with node.exclusive():
            result = node.controllers.switch(request.start_controllers, request.stop_controllers, request.strictness,
                                             request.start_asap)
        return SwitchControllerResponse(ok=self._answer("switch_controller", result))

    def _handle_list_controllers(self, _request):
        node = self.node
        with node.exclusive():
            return ListControllersResponse(controller=[controller_state_msg(info)
                                                       for info in node.controllers.infos()])

    def _handle_load_controller(self, request):
        node = self.node
        with node.exclusive():
            result = node.controllers.load(request.name)
        return LoadControllerResponse(ok=self._answer("load_controller", result))

    def _handle_unload_controller(self, request):
        node = self.node
        with node.exclusive():
            result = node.controllers.unload(request.name)
        return UnloadControllerResponse(ok=self._answer("unload_controller", result))
