"""Helper of test_sim_node.py: the lockstep step (~step, ~step_packed) and reset answered with every sensor's
message, or packed.

Subscribes to every sensor topic of the hopper's sim, then resets and steps with commands in the
request (and once with a bad request), and prints one JSON object: whether each answer's messages are
the very messages published on the topics, whether each packed answer holds exactly the readings of the
messages published on the topics, the errors of the bad requests, and the joint positions the commands
moved."""
import dataclasses
import json
from typing import Any

import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, JointState

from gazebo_msgs.msg import ContactsState
from pybullet_sim.ros import messages
from pybullet_sim.ros.client import SensorSubscriber, SimConnection, SimConnectionError
from pybullet_sim.sensors import unpack_readings

TIMEOUT = 10.0
TOPICS = {"joint_states": ("/monoped/joint_states", JointState), "odometry": ("/odom", Odometry),
          "imu": ("/monoped/imu/data", Imu), "contacts": ("/lowerleg_contactsensor_state", ContactsState)}
# The hopper's sensors in the order of its sim config (hopper_description/config/hopper_sim.yaml).
SENSOR_FIELDS = (("imu", messages.imu_reading), ("contacts", messages.contact_reading),
                 ("odometry", messages.odometry_reading))


def same_as_published(readings, subscribers, marks) -> dict:
    """Per field of the answer: its message equals the one that arrived on the topic (stamp included)."""
    result = {}
    for (field, subscriber), mark in zip(subscribers.items(), marks):
        published = subscriber.wait_newer(mark, TIMEOUT)
        answered = readings.joint_states if field == "joint_states" else getattr(readings, field)[0]
        result[field] = answered == published
    return result


def same_readings_as_published(packed, subscribers, marks) -> dict:
    """Per sensor: the packed answer's reading equals the reading of the message that arrived on its topic
    (stamps within a nanosecond: a message stamp is whole nanoseconds); and how many contact points it has."""
    joints, sensors = unpack_readings(packed.values, packed.names, ("imu", "contact", "p3d"))
    answered: dict[str, Any] = {"joint_states": joints, **{field: r for (field, _), r in zip(SENSOR_FIELDS, sensors)}}
    convert: dict[str, Any] = {"joint_states": messages.joint_state_reading, **dict(SENSOR_FIELDS)}
    result: dict[str, Any] = {}
    for (field, subscriber), mark in zip(subscribers.items(), marks):
        published = convert[field](subscriber.wait_newer(mark, TIMEOUT))
        reading = answered[field]
        result[field] = (abs(reading.stamp - published.stamp) < 1e-9
                         and dataclasses.replace(reading, stamp=published.stamp) == published)
    result["contact_points"] = len(answered["contacts"].contacts)
    return result


def main() -> None:
    rospy.init_node("readings_client")
    sim = SimConnection(timeout=TIMEOUT)
    subscribers = {field: SensorSubscriber(topic, kind, lambda msg: msg) for field, (topic, kind) in TOPICS.items()}
    for subscriber in subscribers.values():
        subscriber.wait_for_connection(TIMEOUT)
    sim.pause()
    marks = [s.count for s in subscribers.values()]
    reset = same_as_published(sim.reset(restart_time=True), subscribers, marks)
    marks = [s.count for s in subscribers.values()]
    controllers = ["haa_joint_position_controller", "hfe_joint_position_controller", "kfe_joint_position_controller"]
    answer = sim.step_with(200, controllers, [0.3, -0.2, -0.4])
    step = same_as_published(answer.readings, subscribers, marks)
    # Steps of 50 ms until one answers with a contact point (the foot bounces a little).
    packed_steps: list[dict[str, Any]] = []
    packed_stamps = []
    while len(packed_steps) < 40 and not any(packed["contact_points"] for packed in packed_steps):
        marks = [s.count for s in subscribers.values()]
        packed = sim.step_packed(50, controllers, [0.0, 0.0, 0.0])
        packed_stamps.append(packed.values[0])
        packed_steps.append(same_readings_as_published(packed, subscribers, marks))
    marks = [s.count for s in subscribers.values()]
    packed_reset = same_readings_as_published(sim.reset_packed(restart_time=False), subscribers, marks)
    errors = []
    for step_call in (sim.step_with, sim.step_packed):
        for names, values in ((["no_such_controller"], [1.0]), (controllers, [0.0])):
            try:
                step_call(1, names, values)
            except SimConnectionError as error:
                errors.append(str(error))
    print(json.dumps({"reset": reset, "step": step, "packed_steps": packed_steps, "packed_reset": packed_reset,
                      "stamp": answer.stamp.to_sec(), "packed_stamps": packed_stamps,
                      "positions": list(answer.readings.joint_states.position), "errors": errors}))


if __name__ == "__main__":
    main()
