"""Record /monoped/reward and /monoped/episode_reward as node reward_recorder: one
"<reward|episode_reward> <repr(value)>" line per message on stdout, until ended."""
import sys
import threading

import rospy
from std_msgs.msg import Float64


def main():
    rospy.init_node("reward_recorder")
    lock = threading.Lock()  # the two subscriptions call back from two threads

    def record(name):
        def callback(msg):
            with lock:
                sys.stdout.write(f"{name} {msg.data!r}\n")
                sys.stdout.flush()
        return callback
    rospy.Subscriber("/monoped/reward", Float64, record("reward"))
    rospy.Subscriber("/monoped/episode_reward", Float64, record("episode_reward"))
    rospy.spin()


if __name__ == "__main__":
    main()
