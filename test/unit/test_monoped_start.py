"""Unit tests for the monoped's start (no ROS master): the leg kinematics read from the URDF against PyBullet's,
the crouched start pose of the YAMLs (foot under the centre of mass, on the ground), and the perturbed start
(initial_tilt: within its range, about the foot, reproducible from the reset seed), on the direct backend.

How the YAMLs' hip angle was derived, runnable by anyone:
    ./ws test --quick test/unit/test_monoped_start.py -k hip
"""
import math

import gymnasium
import numpy as np
import pybullet as p
import pytest
from tf.transformations import quaternion_matrix

from hopper_training.envs.hop import HOP
from hopper_training.envs.stay_up import STAY_UP
from hopper_training.kinematics import FOOT_LINK, leg_kinematics, tilt_rotation
from hopper_training.robot import JOINTS, MONOPED

KINEMATICS = leg_kinematics(MONOPED.urdf_path)


@pytest.fixture(scope="module")
def bullet():
    """The URDF in PyBullet (no gravity, base at the origin), and its client id."""
    cid = p.connect(p.DIRECT)
    body = p.loadURDF(str(MONOPED.urdf_path), [0, 0, 0], flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
    yield body, cid
    p.disconnect(cid)


def bullet_foot_and_com(bullet, angles):
    body, cid = bullet
    for index in range(p.getNumJoints(body, physicsClientId=cid)):
        name = p.getJointInfo(body, index, physicsClientId=cid)[1].decode()
        if name in JOINTS:
            p.resetJointState(body, index, angles[name], physicsClientId=cid)
    links = range(-1, p.getNumJoints(body, physicsClientId=cid))
    masses = [p.getDynamicsInfo(body, link, physicsClientId=cid)[0] for link in links]
    centres = [p.getBasePositionAndOrientation(body, physicsClientId=cid)[0] if link == -1 else
               p.getLinkState(body, link, computeForwardKinematics=1, physicsClientId=cid)[0] for link in links]
    foot = p.getLinkState(body, len(masses) - 2, computeForwardKinematics=1, physicsClientId=cid)[4]
    com = sum(m * np.array(c) for m, c in zip(masses, centres)) / sum(masses)
    return np.array(foot), com


@pytest.mark.parametrize("haa, hfe, kfe", [(0.0, 0.0, 0.0), (0.0, 0.476, -0.9), (0.3, -0.5, -1.4), (-0.2, 1.0, -0.3)])
def test_foot_and_centre_of_mass_match_pybullets(bullet, haa, hfe, kfe):
    angles = dict(zip(JOINTS, (haa, hfe, kfe)))
    foot, com = bullet_foot_and_com(bullet, angles)
    assert KINEMATICS.foot(angles) == pytest.approx(foot, abs=1e-6)
    assert KINEMATICS.centre_of_mass(angles) == pytest.approx(com, abs=1e-6)
    assert KINEMATICS.foot_radius == 0.02


def test_the_yamls_hip_angle_puts_the_foot_under_the_centre_of_mass(bullet):
    """start_pose/hfe is the hip angle, solved from the URDF, that puts the foot under the CoM for the knee."""
    for task in (STAY_UP, HOP):
        pose = task.default_params().start_pose
        hip = KINEMATICS.balanced_hip_angle("hfe_joint", "kfe_joint", pose.kfe, (0.0, 1.6))
        assert pose.hfe == pytest.approx(hip, abs=5e-4)
        assert -1.0 <= pose.kfe <= -0.8 and pose.haa == 0.0
        foot, com = bullet_foot_and_com(bullet, dict(zip(JOINTS, (pose.haa, pose.hfe, pose.kfe))))
        assert foot[:2] == pytest.approx(com[:2], abs=1e-3)


def test_a_tilt_leans_the_top_towards_its_heading():
    for heading in (0.0, 1.0, -2.5):
        up = tilt_rotation(0.1, heading) @ np.array([0.0, 0.0, 1.0])
        assert up == pytest.approx([math.sin(0.1) * math.cos(heading), math.sin(0.1) * math.sin(heading),
                                    math.cos(0.1)])


def start(seed, **changes):
    """The first observation and the robot (base tilt from the IMU, foot centre, contact) after a seeded reset."""
    params = STAY_UP.default_params().with_changes("test", **changes)
    env = gymnasium.make(STAY_UP.env_id, backend="direct", params=params).unwrapped
    try:
        observation, _ = env.reset(seed=seed)
        world = env.backend.world
        rotation = quaternion_matrix(env.readings.imu("gazebo_ros_imu_controller").orientation)
        tilt = math.acos(min(1.0, rotation[2, 2]))
        foot = world.link_state(FOOT_LINK).position
        return observation, tilt, foot, env.readings.joints.position
    finally:
        env.close()


def test_the_crouched_start_stands_on_its_foot_under_the_spawn_point():
    observation, tilt, foot, joints = start(0)
    pose = STAY_UP.default_params().start_pose
    assert joints == pytest.approx((pose.haa, pose.hfe, pose.kfe), abs=1e-3)
    assert tilt == pytest.approx(0.0, abs=1e-6)
    assert foot == pytest.approx((0.0, 0.0, KINEMATICS.foot_radius), abs=1e-3)


def test_the_tilted_start_is_in_range_about_the_foot_and_repeats_with_its_seed():
    tilts, headings = [], []
    for seed in range(6):
        observation, tilt, foot, _ = start(seed, initial_tilt={"low": 0.02, "high": 0.05})
        assert 0.02 - 1e-4 <= tilt <= 0.05 + 1e-4
        assert foot == pytest.approx((0.0, 0.0, KINEMATICS.foot_radius), abs=1e-3)  # leaned about the foot
        tilts.append(tilt)
        headings.append(math.atan2(-observation[1], observation[2]))  # from roll and pitch: where it leans
        again, *_ = start(seed, initial_tilt={"low": 0.02, "high": 0.05})
        assert again.tolist() == observation.tolist()
    assert len({round(t, 6) for t in tilts}) == 6 and np.ptp(headings) > 1.0  # seeds differ, in every direction


def test_tutorial_mode_starts_straight_in_the_air_unless_tilted():
    _, tilt, foot, joints = start(0, action_mode="tutorial")
    assert joints == pytest.approx((0.0, 0.0, 0.0)) and tilt == 0.0
    assert foot[2] == pytest.approx(1.0 - 0.93, abs=1e-3)  # the spawn pose: 5 cm above the ground
    _, tilt, foot, _ = start(1, action_mode="tutorial", initial_tilt={"low": 0.03, "high": 0.03})
    assert tilt == pytest.approx(0.03, abs=1e-4) and foot == pytest.approx((0.0, 0.0, 0.07), abs=1e-3)
