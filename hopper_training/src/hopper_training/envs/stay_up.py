"""Monoped-v0: the hopper learns to stay up (seed 001's MonopedEnv, on the gymnasium 1.x API).

Actions: chosen by the params' action_mode (hopper_training/actions.py)
    accumulate  Discrete(7) (config/stay_up.yaml, config/hop.yaml)
                0/1  haa target +/- joint_increment_value (rad)
                2/3  hfe target +/- joint_increment_value
                4/5  kfe target +/- joint_increment_value
                6    hold: the three targets as they are
                Each step adds to the last *commanded* targets (start_pose at reset), clamped to the URDF
                limits, and publishes all three: the PD controllers hold them, so the leg stays stiff and a
                bent knee carries the robot (as The Construct's later jumping code did).
    tutorial    Discrete(6): actions 0-5 as above, but from the *measured* joint positions, the other two
                joints commanded to stay where they are (the tutorial's rule); the robot starts straight,
                its foot 5 cm above the ground (the sim's spawn pose), and start_pose is not used. Its leg is
                limp: the P term asks for at most p x joint_increment_value = 0.5 N m.
    targets     Box(3) in [-1, 1]: absolute haa, hfe, kfe targets start_pose + action * target_range (rad),
                clamped to the URDF limits (for PPO and SAC, and for controllers).
Start: except in action_mode tutorial, the joints start at start_pose (a crouch with the foot under the
    centre of mass, hopper_training/kinematics.py) with their targets there, and the foot's sphere touches
    the ground under the spawn point. With initial_tilt {low, high} the whole robot then leans about its
    foot by an angle drawn uniformly from [low, high] towards a uniformly drawn heading (the env's
    np_random, seeded by reset(seed=...)); the first observation comes one physics step later.
Observation: Box(10,) float32 (the tutorial's 8 in its order, then the tilt rates); with observation:
    extended Box(23,)
    0  distance of the base from desired_pose (m)
    1  roll, 2 pitch, 3 yaw of the base (rad, from the IMU)
    4  foot contact force (N, 0 in the air)
    5  haa, 6 hfe, 7 kfe positions (rad)
    8  roll rate, 9 pitch rate (rad/s: the IMU's angular velocity about the base's x and y axes)
    extended:
    10-12  haa, hfe, kfe velocities (rad/s)
    13-15  base linear velocity (m/s, world frame, odometry)
    16-18  base angular velocity (rad/s, base frame, IMU)
    19     foot contact (1 touching, 0 in the air)
    20-22  the last commanded haa, hfe, kfe targets (rad): the last action's effect (start_pose at reset)
State key (Q-learning; the params' state_key)
    tilt      (config/stay_up.yaml) forward or backward (the sign of pitch), how far the base leans
              (max(abs(roll), abs(pitch)) in decades, 1e-6 .. 0.1 rad), how fast (max of the abs tilt
              rates in decades, 1e-6 .. 1 rad/s), the knee (edges -0.3, -0.02 rad) and the foot's contact
              (force > 0): 2 x 7 x 8 x 3 x 2 keys (hopper_training/state.py: TiltStateKey)
    tutorial  the tutorial's: observations 0-7 in 10 linspace bins each (TutorialStateKey)
Reward: the sum of the terms, each in info as reward_<term>
    alive           alive_reward
    joint_position  -weight_r1 * sum of abs(joint positions)
    joint_effort    -weight_r2 * sum of abs(joint efforts)
    contact_force   -weight_r3 * abs(abs(contact force) - desired_force)
    orientation     -weight_r4 * (abs(roll) + abs(pitch) + abs(yaw - desired_yaw))
    distance        -weight_r5 * distance from desired_pose
    fall            done_reward, alone, on the step that ends the episode by a fall
Terminated: base height outside [min_height, max_height), or abs(roll) or abs(pitch) >= max_incl.
Truncated: after nsteps steps (gymnasium's TimeLimit; registered with 500: 10 s at 20 ms).
Step: the three joint targets are published and the sim advances running_step of sim time, in lockstep.
Info: fell, base_height (m), x_travelled (m of the base along +x since the episode started), hops,
    apex_height, forward_speed, lateral_drift (hopper_training/hop_metrics.py defines them), the reward
    terms, sim_time.
Metrics: time_upright_s (sim seconds until the fall or the end), upright_whole_horizon (no fall), fell,
    x_distance (x_travelled at the end), hops (flights of at least 0.06 s), apex_height (m above the start
    height, mean over hops), forward_speed (m/s along +x over the last 5 s), lateral_drift (m).
Arguments: backend ("ros", "direct" or a Backend), params (MonopedParams; default config/stay_up.yaml),
    seed (the direct sim's noise), ros_timeout (s, every wait on the sim).

Fixes over the tutorial: an observation_space (gymnasium's env checker failed on its absence), the
5-tuple step and reset(seed=, options=), no time.sleep(running_step) of wall time between unpause
and pause (the sim advances exactly running_step), no gravity switching during reset, a TimeLimit
that matches nsteps (the tutorial registered 50 steps), the contact force drops to 0 when the foot
leaves the ground (the tutorial kept the last value), and joint targets stay inside the URDF limits.
"""
from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from robot_rl import Readings, StepOutcome, TaskSpec

from ..params import MonopedParams
from ..robot import MONOPED, ODOMETRY_SENSOR, base_rpy, contact_force
from ..state import monoped_state_key
from .base import MonopedBaseEnv, monoped_metrics

STAY_UP = TaskSpec(
    name="stay_up", env_id="Monoped-v0", entry_point=f"{__name__}:MonopedEnv", package="hopper_training",
    robot=MONOPED, params_type=MonopedParams, params_namespace="/", state_key=monoped_state_key,
    results_name="stay_up", reward_topic="/monoped/reward", episode_reward_topic="/monoped/episode_reward",
    publish_cumulated_reward=True, max_episode_steps=500, metrics=monoped_metrics,
    headline_metric="time_upright_s", eval_horizon_s=10.0, curve_metrics=("hops",))


class MonopedEnv(MonopedBaseEnv):
    task: ClassVar[TaskSpec[Any]] = STAY_UP

    def _reward_and_termination(self, observation: np.ndarray, readings: Readings) -> StepOutcome:
        p = self.params
        roll, pitch, yaw = base_rpy(readings)
        position = readings.odometry(ODOMETRY_SENSOR).position
        self.hop_tracker.add(readings.stamp, position, contact_force(readings) > 0.0)
        height_ok = p.min_height <= position[2] < p.max_height
        fell = not (height_ok and abs(roll) < p.max_incl and abs(pitch) < p.max_incl)
        info: dict[str, Any] = {"fell": fell, "base_height": position[2], "x_travelled": position[0] - self.start_x,
                                **self.hop_tracker.summary()}
        if fell:
            return {"fall": p.done_reward}, True, info
        terms = {"alive": p.alive_reward,
                 "joint_position": -p.weight_r1 * sum(abs(q) for q in readings.joints.position),
                 "joint_effort": -p.weight_r2 * sum(abs(e) for e in readings.joints.effort),
                 "contact_force": -p.weight_r3 * abs(contact_force(readings) - p.desired_force),
                 "orientation": -p.weight_r4 * (abs(roll) + abs(pitch) + abs(yaw - p.desired_yaw)),
                 "distance": -p.weight_r5 * self._distance_from_desired_pose(readings)}
        return terms, False, info
