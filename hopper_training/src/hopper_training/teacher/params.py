"""The params of agent bc_dagger (config/agents/end_to_end.bc_dagger.yaml): the student's network, the behaviour
cloning data and epochs, and the DAgger rounds' beta schedule."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium

from robot_rl import MAX_COUNT, ParamError, Params, param


@dataclass(frozen=True, kw_only=True)
class BcDaggerParams(Params):
    hidden_layers: int = param(low=1, high=8, doc="hidden layers of the student's MLP (tanh)")
    hidden_units: int = param(low=1, high=4096, doc="units per hidden layer")
    bc_episodes: int = param(low=1, high=MAX_COUNT, doc="teacher episodes for behaviour cloning")
    bc_noise: float = param(low=0.0, high=1.0, doc="the largest Ornstein-Uhlenbeck noise on the teacher's "
                                                    "actions (in action units): episode i of bc_episodes gets "
                                                    "bc_noise x (i / bc_episodes), so the first ones are clean")
    bc_epochs: int = param(low=1, high=MAX_COUNT, doc="epochs of behaviour cloning")
    learning_rate: float = param(low=0.0, low_open=True, high=1.0, doc="Adam's step size in behaviour cloning")
    batch_size: int = param(low=1, high=MAX_COUNT, doc="samples per gradient step")
    dagger_rounds: int = param(low=0, high=MAX_COUNT, doc="DAgger rounds after behaviour cloning")
    dagger_episodes: int = param(low=1, high=MAX_COUNT, doc="student episodes collected per round")
    dagger_epochs: int = param(low=1, high=MAX_COUNT, doc="epochs of training on the aggregate data per round")
    dagger_learning_rate: float = param(low=0.0, low_open=True, high=1.0, doc="Adam's step size in DAgger rounds")
    beta_start: float = param(low=0.0, high=1.0, doc="round 0's chance per step that the teacher's action is taken")
    beta_decay: float = param(low=0.0, high=1.0, doc="beta of round r: beta_start x beta_decay^r")
    horizon_s: float = param(low=0.0, low_open=True, high=1e6, doc="sim seconds per collected episode at most")
    refit_epochs: int = param(low=0, high=MAX_COUNT, default=0,
                              doc="after the last round, a new student trained from its first weights on the whole "
                                  "aggregate for this many epochs at learning_rate (0: the last round's student)")

    def stages(self) -> int:
        """The run's stages: behaviour cloning, the DAgger rounds, and the refit when refit_epochs > 0."""
        return 1 + self.dagger_rounds + (1 if self.refit_epochs else 0)

    def episodes(self) -> int:
        """The episodes a run collects: behaviour cloning's, then every DAgger round's (the task's nepisodes is not
        used)."""
        return self.bc_episodes + self.dagger_rounds * self.dagger_episodes

    def beta(self, round_: int) -> float:
        """Round `round_`'s chance per step that the teacher acts instead of the student."""
        return self.beta_start * self.beta_decay ** round_

    def check_action_space(self, space: gymnasium.spaces.Space[Any], source: str) -> None:
        """ParamError unless the actions are the monoped's three joint targets (the teacher's): Box(3)."""
        if not (isinstance(space, gymnasium.spaces.Box) and space.shape == (3,)):
            raise ParamError(f"{source}: bc_dagger's teacher sets the monoped's three joint targets (task "
                             f"end_to_end, Box(3)); this task's actions are {space}")


def episode_budget(agent_params: Params | None) -> int:
    """The agent registry's episode count of agent bc_dagger: its params' own (BcDaggerParams.episodes)."""
    if not isinstance(agent_params, BcDaggerParams):
        raise ValueError(f"agent bc_dagger needs BcDaggerParams, got {type(agent_params).__name__}")
    return agent_params.episodes()
