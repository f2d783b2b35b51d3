"""pybullet_sim.sensors' packed readings (the lockstep answer of RosBackend) gives back exactly what it packed.

One stamp for all: every reading of a snapshot carries the sim time of the joint states."""
import pytest

from hopper_training.envs.stay_up import STAY_UP
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from pybullet_sim.readings import ContactPoint, ContactReading, ImuReading, JointStateReading, OdometryReading
from pybullet_sim.sensors import pack_readings, unpack_readings
from robot_rl import DirectBackend

JOINTS = JointStateReading(1.25, ("a", "b"), (0.1, -0.2), (1e-300, 3.0), (0.0, -7.5))
ODOMETRY = OdometryReading(1.25, "world", "base", (1.0, 2.0, 3.0), (0.0, 0.0, 0.6, 0.8), (0.1, 0.2, 0.3),
                           (4.0, 5.0, 6.0))
IMU = ImuReading(1.25, "base", (0.0, 0.0, 0.0, 1.0), (0.5, -0.5, 1.0 / 3.0), (0.0, 0.0, 9.81))
POINTS = tuple(ContactPoint("robot::foot::foot_collision", f"ground_plane::link::collision{i}", (1.0, 2.0, float(i)),
                            (0.0, -1.0, 0.5), (0.3, 0.2, 0.0), (0.0, 0.0, 1.0), 1e-4 * i) for i in range(2))
CONTACT = ContactReading(1.25, "foot", POINTS, (2.0, 4.0, 1.0), (0.0, -2.0, 1.0))
IN_THE_AIR = ContactReading(1.25, "foot")


@pytest.mark.parametrize("sensors", [[ODOMETRY, IMU, CONTACT], [IN_THE_AIR, ODOMETRY], [CONTACT, CONTACT], []])
def test_unpack_gives_back_exactly_what_was_packed(sensors):
    types = [{OdometryReading: "p3d", ImuReading: "imu", ContactReading: "contact"}[type(s)] for s in sensors]
    values, names = pack_readings(JOINTS, sensors)
    assert all(isinstance(v, float) for v in values)
    assert unpack_readings(values, names, types) == (JOINTS, sensors)


def test_a_stopped_joint_state_controller_packs_no_joints():
    empty = JointStateReading(IMU.stamp, (), (), (), ())
    assert unpack_readings(*pack_readings(empty, [IMU]), ["imu"]) == (empty, [IMU])


@pytest.mark.parametrize("task", [ONE_DISK_WALK, STAY_UP], ids=["cube", "hopper"])
def test_the_robots_readings_survive_packing(task):
    backend = DirectBackend(task.robot.urdf_path, task.robot.sim_config_path)
    try:
        readings = backend.step(300)  # the hopper stands on its foot: its contact sensor has points
        sensors = [readings.sensors[s.name] for s in backend.config.sensors]
        types = [s.type for s in backend.config.sensors]
        assert unpack_readings(*pack_readings(readings.joints, sensors), types) == (readings.joints, sensors)
    finally:
        backend.close()


@pytest.mark.parametrize("change, message", [
    (lambda v, n: (v[:-1], n), "too short"),
    (lambda v, n: (v + [0.0], n), "1 numbers and 0 names more"),
    (lambda v, n: (v, n + ["x"]), "0 numbers and 1 names more"),
])
def test_packed_readings_that_do_not_fit_the_sensors_are_refused(change, message):
    values, names = pack_readings(JOINTS, [ODOMETRY, CONTACT])
    with pytest.raises(ValueError, match=message):
        unpack_readings(*change(values, names), ["p3d", "contact"])


def test_an_unknown_sensor_type_is_refused():
    with pytest.raises(ValueError, match="unknown sensor type 'lidar'"):
        unpack_readings(*pack_readings(JOINTS, [IMU]), ["lidar"])
