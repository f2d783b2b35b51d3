"""Scripted checks of the monoped's action interface on the direct backend (no ROS; about 10 s):

  ./ws python hopper_training/scripts/leg_check.py

- hold: action_mode accumulate, the hold action every step from the crouched start: does the knee carry
  the robot (knee angle, base height at 0.5 s) and how long does it stay up;
- tutorial_rule: the same crouch with the tutorial's rule (targets = measured positions every step): the
  knee gives way;
- tutorial_still: action_mode tutorial, straight start, kfe+ every step (which the knee's limit turns into
  no motion: the "hold still" its Q-learning learned): the passive fall time;
- thrust: action_mode targets, the crouch for 0.2 s, then knee straight and hip at 0 (foot under the hip)
  until lift-off, then the crouch again: the hop's apex (noise-free, from the sim) and the env's metrics.
Prints one JSON object. Base heights are the sim's (noise-free); the env's metrics read the odometry.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
from tf.transformations import quaternion_matrix

from hopper_training.actions import HOLD
from hopper_training.envs.stay_up import STAY_UP
from hopper_training.robot import CONTROLLERS, JOINTS, joint_positions
from robot_rl import make_env

HORIZON_STEPS = 500  # 10 s at 20 ms


def env_of(**changes):
    return make_env(STAY_UP, params=STAY_UP.default_params().with_changes("leg_check", **changes),
                    backend="direct", max_episode_steps=HORIZON_STEPS).unwrapped


def base(env) -> tuple[float, float]:
    """(height, tilt) of the base, noise-free from the sim."""
    state = env.backend.world.model_state()
    return state.position[2], math.acos(min(1.0, quaternion_matrix(state.orientation)[2, 2]))


def time_upright(env, action_of_step) -> tuple[float, dict]:
    """Sim seconds until the fall (or the horizon), and samples of the knee and the base at 0.5 s and 1 s."""
    env.reset(seed=0)
    samples = {}
    for step in range(1, HORIZON_STEPS + 1):
        *_, terminated, _, info = env.step(action_of_step(step))
        if step in (25, 50):
            samples[f"at_{step * 0.02:.1f}_s"] = {"kfe": round(joint_positions(env.readings)[2], 4),
                                                  "base_height": round(base(env)[0], 4)}
        if terminated:
            return step * env.running_step, samples
    return HORIZON_STEPS * env.running_step, samples


def tutorial_rule_on_the_crouch() -> dict:
    """The crouched start, then every step each joint commanded to its measured position (the tutorial's
    rule without an increment): the knee and base height at 0.2 s and 0.5 s."""
    env = env_of()
    try:
        env.reset(seed=0)
        figures = {}
        for step in range(1, 26):
            for controller, position in zip(CONTROLLERS, joint_positions(env.readings)):
                env.backend.set_command(controller, position)
            env.readings = env.backend.step(env.physics_steps)
            if step in (10, 25):
                figures[f"at_{step * 0.02:.1f}_s"] = {"kfe": round(joint_positions(env.readings)[2], 4),
                                                      "base_height": round(base(env)[0], 4)}
        return figures
    finally:
        env.close()


def thrust() -> dict:
    env = env_of(action_mode="targets")
    try:
        env.reset(seed=0)
        start_height = base(env)[0]
        crouch = np.zeros(3, np.float32)
        pose = env.params.start_pose
        extend = np.array([0.0, -pose.hfe / env.params.target_range, 1.0], np.float32)  # hip 0, knee straight
        top, lift_off, landing, landing_tilt, steps, info, in_air = start_height, None, None, 0.0, 0, {}, False
        for step in range(1, 101):
            if step <= 10:
                action = crouch
            elif lift_off is None:
                action = extend
            else:
                action = crouch
            *_, terminated, _, info = env.step(action)
            touching = bool(env.readings.contact("lowerleg_contactsensor_sensor").contacts)
            height, tilt = base(env)
            top = max(top, height)
            if not touching and lift_off is None and step > 10:
                lift_off, in_air = step * env.running_step, True
            if touching and in_air and landing is None:
                landing, landing_tilt = step * env.running_step, tilt
                in_air = False
            steps = step
            if terminated:
                break
        return {"start_height_m": round(start_height, 4), "apex_rise_m": round(top - start_height, 4),
                "lift_off_s": lift_off, "landing_s": landing,
                "flight_s": None if landing is None or lift_off is None else round(landing - lift_off, 3),
                "tilt_at_landing_rad": None if landing is None else round(landing_tilt, 4),
                "metrics": {"hops": info.get("hops"), "apex_height": round(info.get("apex_height", 0.0), 4)},
                "steps": steps, "fell": bool(info.get("fell"))}
    finally:
        env.close()


def main() -> None:
    report: dict[str, Any] = {}
    for name, changes, action in (("hold", {}, lambda _: HOLD),
                                  ("tutorial_still", {"action_mode": "tutorial"}, lambda _: 4)):
        env = env_of(**changes)
        try:
            seconds, samples = time_upright(env, action)
        finally:
            env.close()
        report[name] = {"time_upright_s": round(seconds, 2), **samples}
    report["tutorial_rule"] = tutorial_rule_on_the_crouch()
    report["thrust"] = thrust()
    report["joints"] = list(JOINTS)
    print(json.dumps(report))


if __name__ == "__main__":
    main()
