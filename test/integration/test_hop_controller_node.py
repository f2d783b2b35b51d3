"""The hop_controller node over ROS on a private master: with the monoped's sim running freely, it keeps the
robot hopping for 3 s of sim time without a fall, judged from the odometry (and the foot's contact topic)."""
import json
import sys

from workspace_tools.paths import REPO
from workspace_tools.processes import RosMaster, launch_args

SIM_SECONDS = 3.0
START_TIMEOUT = 90.0   # wall s for the sim and the node to come up on a busy 2-core machine
RUN_TIMEOUT = 120.0    # wall s for 3 s of sim time at real_time_factor 0.25 (12 s when idle)
# One observer process: waits until hop_controller publishes the three commands and the sim subscribes to
# them, unpauses the sim, then records /odom and the foot's contacts for SIM_SECONDS of sim time.
OBSERVER = """
import json, math, sys, time
import rosgraph, rospy
from nav_msgs.msg import Odometry
from std_srvs.srv import Empty
from gazebo_msgs.msg import ContactsState

SIM_SECONDS, START_TIMEOUT, RUN_TIMEOUT = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
COMMANDS = [f"/monoped/{j}_joint_position_controller/command" for j in ("haa", "hfe", "kfe")]
master = rosgraph.Master("/observer")
deadline = time.monotonic() + START_TIMEOUT
def ready():
    publishers, subscribers, _ = master.getSystemState()
    pub, sub = dict(publishers), dict(subscribers)
    return all("/hop_controller" in pub.get(t, []) and "/pybullet_sim" in sub.get(t, []) for t in COMMANDS) \\
        and "/hop_controller" in sub.get("/monoped/joint_states", [])
while not ready():
    if time.monotonic() > deadline:
        sys.exit(f"hop_controller did not publish {COMMANDS} (with /pybullet_sim subscribed) within "
                 f"{START_TIMEOUT} s: check the node's log")
    time.sleep(0.1)
rospy.init_node("observer")
heights, tilts, stamps, contacts = [], [], [], []
def on_odometry(msg):
    q = msg.pose.pose.orientation
    roll = math.atan2(2 * (q.w * q.x + q.y * q.z), 1 - 2 * (q.x * q.x + q.y * q.y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (q.w * q.y - q.z * q.x))))
    heights.append(msg.pose.pose.position.z)
    tilts.append(max(abs(roll), abs(pitch)))
    stamps.append(msg.header.stamp.to_sec())
rospy.Subscriber("/odom", Odometry, on_odometry, queue_size=100)
rospy.Subscriber("/lowerleg_contactsensor_state", ContactsState,
                 lambda msg: contacts.append((msg.header.stamp.to_sec(), bool(msg.states))), queue_size=100)
rospy.wait_for_service("/gazebo/unpause_physics", START_TIMEOUT)
rospy.ServiceProxy("/gazebo/unpause_physics", Empty)()
deadline = time.monotonic() + RUN_TIMEOUT
while not (stamps and stamps[-1] >= SIM_SECONDS):
    if time.monotonic() > deadline:
        sys.exit(f"/odom reached {stamps[-1] if stamps else 'no'} s of sim time within {RUN_TIMEOUT} s, not "
                 f"{SIM_SECONDS}: is /pybullet_sim running (unpaused)?")
    time.sleep(0.05)
print(json.dumps({"heights": heights, "tilts": tilts, "stamps": stamps, "contacts": contacts}))
"""


def test_the_controller_node_keeps_the_monoped_hopping(tmp_path):
    master = RosMaster(tmp_path, cwd=REPO)
    try:
        master.start(["roslaunch", "hopper_training", "hop_controller.launch",
                      *launch_args(paused="true", real_time_factor=0.25)])
        result = master.run([sys.executable, "-c", OBSERVER, str(SIM_SECONDS), str(START_TIMEOUT), str(RUN_TIMEOUT)],
                            timeout=START_TIMEOUT + RUN_TIMEOUT + 30.0)
    finally:
        master.close()
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    heights = [z for z, t in zip(report["heights"], report["stamps"]) if t <= SIM_SECONDS]
    tilts = [a for a, t in zip(report["tilts"], report["stamps"]) if t <= SIM_SECONDS]
    assert len(heights) > 100, "the observer heard /odom"
    # A fall is the base below 0.5 m or a tilt of 1.57 rad (the tasks' terms); a hopping base stays far above
    # (the crouch at touchdown holds it at ~0.8 m; odometry noise is 0.01 m and 0.01 rad).
    assert min(heights) > 0.7, f"the base sank to {min(heights):.3f} m"
    assert max(tilts) < 0.8, f"the base tilted {max(tilts):.2f} rad"
    # It left the ground several times: lift-offs on the contact topic, each with the base rising after it.
    lift_offs = [t for (t0, was), (t, now) in zip(report["contacts"], report["contacts"][1:]) if was and not now]
    assert len(lift_offs) >= 5, f"{len(lift_offs)} lift-offs in {SIM_SECONDS} s of sim time"
    assert max(heights) - min(heights) > 0.05, "the base moved up and down as it hopped"


def test_the_node_asked_to_start_a_sim_that_is_not_there_ends_with_one_line(tmp_path):
    """~unpause waits (bounded) for the sim's connections; without a sim it says which topics are unconnected."""
    master = RosMaster(tmp_path, cwd=REPO)
    try:
        result = master.run(["rosrun", "hopper_training", "hop_controller.py", "_unpause:=true",
                             "_connect_timeout:=3.0"], timeout=START_TIMEOUT)
    finally:
        master.close()
    assert result.returncode == 1, result.stdout[-2000:] + result.stderr[-2000:]
    output = result.stdout + result.stderr
    assert "hop_controller cannot start the sim: no connection on" in output, output[-2000:]
    assert "/monoped/haa_joint_position_controller/command" in output and "/odom" in output, output[-2000:]
    assert "is the monoped's sim running" in output, output[-2000:]
