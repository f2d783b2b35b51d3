"""MonopedResidualForward-v0: the monoped hops forward at target_speed (0.4 m/s in its YAML), a deep agent's action
added to the hopping controller's joint targets (issue 27, "learned hopping, deep", the residual mode).

Action, observation, termination, truncation, info and params: MonopedResidualInPlace-v0's (residual_in_place.py),
    with this task's YAML (config/residual_forward.yaml): target_speed 0.4 m/s along world +x.
Reward: the sum of the terms, each in info as reward_<term>
    alive  alive_reward per second of sim time the hop lasted (alive_reward x duration)
    speed  -speed_weight x the magnitude of the velocity error (world, m/s) at the decision point
    fall   done_reward, alone, on the step that ends the episode by a fall
Metrics: MonopedResidualInPlace-v0's; the headline is forward_speed (m/s along +x over the last 5 s).
"""
from __future__ import annotations

from .residual_in_place import MonopedResidualInPlaceEnv, residual_task

RESIDUAL_FORWARD = residual_task("residual_forward", "MonopedResidualForward-v0",
                                 f"{__name__}:MonopedResidualForwardEnv", "forward_speed")


class MonopedResidualForwardEnv(MonopedResidualInPlaceEnv):
    task = RESIDUAL_FORWARD
