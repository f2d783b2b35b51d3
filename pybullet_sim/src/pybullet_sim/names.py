"""The names the sim node serves and its clients call: services and topics, in one place."""
from __future__ import annotations

STEP_SERVICE = "/pybullet_sim/step"
STEP_PACKED_SERVICE = "/pybullet_sim/step_packed"
RESET_SERVICE = "/pybullet_sim/reset"
RENDER_SERVICE = "/pybullet_sim/render"
ATTITUDE_ASSIST_SERVICE = "/pybullet_sim/set_attitude_assist"
PHYSICS_SERVICE = "/gazebo/get_physics_properties"
GAZEBO_SERVICES = ("/gazebo/pause_physics", "/gazebo/unpause_physics", "/gazebo/reset_world",
                   "/gazebo/reset_simulation")
SIM_NODE = "/pybullet_sim"  # the sim node's name: its private params hold the robot's sim config
CONTACT_MARKERS_TOPIC = "/pybullet_sim/contact_markers"
