"""Run by hopper_sim_node.py as its own process (own caller id, so the test node's lockstep counts
stay intact): what the env does around a reset (the init pose, then the first action, with no step
in between), as it happens on a loaded machine.

rospy's queued publishers (queue_size=N) yield once per publish (time.sleep(0)) so that their send
thread takes the message; under load that thread is often not scheduled before the next publish,
and queue_size=1 then drops the older message although the caller counted it. Here the send thread
is never scheduled between two publishes (no yield, no GIL switch): the race made deterministic.
With synchronous publishers (queue_size=None) it cannot happen. Prints "stepped" on success."""
import sys

import rospy
import rospy.impl.tcpros_pubsub as tcpros_pubsub

from pybullet_sim.ros.client import CommandPublisher, SimConnection


class NoYield:
    @staticmethod
    def sleep(seconds):
        pass


def main():
    rospy.init_node("hopper_command_burst")
    sim = SimConnection(timeout=10.0)
    publishers = [CommandPublisher(f"/monoped/{joint}_position_controller/command")
                  for joint in ("haa_joint", "hfe_joint", "kfe_joint")]
    for publisher in publishers:
        publisher.wait_for_subscriber(10.0)
    real_time, tcpros_pubsub.time = tcpros_pubsub.time, NoYield
    sys.setswitchinterval(5.0)
    for target in (0.0, 0.1):  # MonopedEnv: reset -> init pose, then step -> action targets
        for publisher in publishers:
            publisher.publish(target)
    tcpros_pubsub.time = real_time
    sys.setswitchinterval(0.005)
    sim.step(1, publishers)
    print("stepped")


if __name__ == "__main__":
    main()
