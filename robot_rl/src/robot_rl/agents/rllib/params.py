"""Agent rllib_ppo's params (robot_rl/config/rllib_ppo.yaml) and RLlib's PPOConfig they make.

Named as Stable-Baselines3 PPO's where the two mean the same (hidden_layers, hidden_units, learning_rate,
reward_scale, gae_lambda, ent_coef, n_epochs, batch_size, clip_range), so that the two agents compare at equal
settings; `rollout_fragment_length` is SB3's n_steps: each env runner returns a fragment of that many env steps
per call of each of its envs, and one PPO update trains on one fragment of every env (train batch = fragment x
envs). `envs_per_runner` envs share a runner (RLlib's num_envs_per_env_runner, a sync vector env: the policy acts
for them in one batched forward pass); envs:=N makes N / envs_per_runner runners. Only `ppo_config` imports Ray (a
config is checked and mapped without it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium

from ...params import MAX_COUNT, DeepAgentParams, ParamError, Params, param


@dataclass(frozen=True, kw_only=True)
class RllibPpoParams(DeepAgentParams):
    """RLlib PPO's settings (gamma and the seed are the task's; the MLPs' and the learning rate's are
    DeepAgentParams', as SB3's; the MLPs are tanh); see robot_rl/config/rllib_ppo.yaml."""

    rollout_fragment_length: int = param(low=1, high=MAX_COUNT, doc="env steps of each env per update (SB3's "
                                                                    "n_steps); the train batch is this x envs")
    batch_size: int = param(low=1, high=MAX_COUNT, doc="minibatch size")
    n_epochs: int = param(low=1, high=MAX_COUNT, doc="passes over each train batch")
    gae_lambda: float = param(low=0.0, high=1.0, doc="GAE lambda")
    clip_range: float = param(low=0.0, low_open=True, doc="PPO's clip range")
    ent_coef: float = param(low=0.0, doc="entropy bonus weight")
    vf_coef: float = param(low=0.0, default=0.5, doc="value loss weight (SB3's default 0.5; RLlib's own is 1.0)")
    max_grad_norm: float = param(low=0.0, low_open=True, default=0.5, doc="gradient clipping by global norm")
    sample_timeout_s: float = param(low=1.0, high=3600.0, default=120.0,
                                    doc="s for the runners' fragments of one update (a late runner's are dropped)")
    envs_per_runner: int = param(low=1, high=64, default=1,
                                 doc="envs each env runner steps together (RLlib's num_envs_per_env_runner: one "
                                     "batched forward pass for them); envs:=N makes N / this runners; direct backend "
                                     "only when over 1")
    max_runner_restarts: int = param(low=0, high=MAX_COUNT, default=10,
                                     doc="times RLlib restarts a lost env runner over the run")

    def check_action_space(self, space: gymnasium.spaces.Space[Any], source: str) -> None:
        """ParamError in one line unless the policy can act in `space` (Discrete or a Box)."""
        if not isinstance(space, (gymnasium.spaces.Discrete, gymnasium.spaces.Box)):
            raise ParamError(f"{source}: rllib_ppo acts in Discrete or Box spaces, the task has {space}")

    def train_batch_size(self, envs: int) -> int:
        return self.rollout_fragment_length * envs

    def runners(self, envs: int) -> int:
        """The env runners `envs` envs make (check_envs first)."""
        return envs // self.envs_per_runner

    def check_envs(self, envs: int, over_ros: bool, source: str) -> None:
        """ParamError unless `envs` envs fill whole runners of envs_per_runner (each one process: over ROS one env,
        as a process holds one rospy node)."""
        if envs % self.envs_per_runner:
            raise ParamError(f"{source}: envs:={envs} is not a multiple of envs_per_runner {self.envs_per_runner}")
        if over_ros and self.envs_per_runner > 1:
            raise ParamError(f"{source}: envs_per_runner {self.envs_per_runner} needs backend:=direct (over ROS a "
                             f"runner's process holds one env: one rospy node)")

    def check_batch(self, envs: int, source: str) -> None:
        """ParamError when a minibatch would not fit in one train batch."""
        if self.batch_size > self.train_batch_size(envs):
            raise ParamError(f"{source}: batch_size {self.batch_size} is more than the train batch "
                             f"(rollout_fragment_length {self.rollout_fragment_length} x {envs} envs)")


def check_fit(action_space: gymnasium.spaces.Space[Any], observation_space: gymnasium.spaces.Space[Any], n_envs: int,
              agent_params: Params | None, source: str) -> None:
    """The agent registry's fit check of rllib_ppo, before a run folder is made (ParamError in one line): its actions'
    kind, envs:=N in whole runners of envs_per_runner, a minibatch within the train batch. (Over ROS, envs_per_runner
    > 1 is refused by the trainer, which knows the backend.)"""
    assert isinstance(agent_params, RllibPpoParams)
    agent_params.check_action_space(action_space, source)
    agent_params.check_envs(n_envs, False, source)
    agent_params.check_batch(n_envs, source)


def ppo_config(p: RllibPpoParams, env_name: str, env_config: dict[str, Any], observation_space: Any,
               action_space: Any, envs: int, gamma: float, seed: int) -> Any:
    """RLlib's PPOConfig for these params: `envs` envs in envs / envs_per_runner remote env runners (one CPU each, a
    sync vector env of envs_per_runner envs) on env `env_name` (registered with tune.register_env), the learner on the
    driver (num_learners=0), failed runners restarted; the module LeanPPOTorchRLModule (runners sample their own
    actions), the learner LeanPPOTorchLearner (gradients clipped and applied in fused calls)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    from .learner import LeanPPOTorchLearner
    from .module import LeanPPOTorchRLModule
    network = [p.hidden_units] * p.hidden_layers
    return (PPOConfig()
            .framework("torch")
            .environment(env_name, env_config=env_config, observation_space=observation_space,
                         action_space=action_space, disable_env_checking=True)
            .env_runners(num_env_runners=p.runners(envs), num_envs_per_env_runner=p.envs_per_runner,
                         num_cpus_per_env_runner=1, gym_env_vectorize_mode="sync",
                         rollout_fragment_length=p.rollout_fragment_length, batch_mode="truncate_episodes",
                         sample_timeout_s=p.sample_timeout_s)
            .learners(num_learners=0, num_cpus_per_learner=0, learner_class=LeanPPOTorchLearner)
            .training(gamma=gamma, lr=p.learning_rate, train_batch_size_per_learner=p.train_batch_size(envs),
                      minibatch_size=p.batch_size, num_epochs=p.n_epochs, lambda_=p.gae_lambda,
                      clip_param=p.clip_range, entropy_coeff=p.ent_coef, vf_loss_coeff=p.vf_coef,
                      grad_clip=p.max_grad_norm, grad_clip_by="global_norm", use_kl_loss=False,
                      vf_clip_param=float("inf"))
            .rl_module(rl_module_spec=RLModuleSpec(module_class=LeanPPOTorchRLModule),
                       model_config=DefaultModelConfig(fcnet_hiddens=network, fcnet_activation="tanh",
                                                       head_fcnet_hiddens=[], vf_share_layers=False))
            .debugging(seed=seed, log_level="ERROR")
            .fault_tolerance(restart_failed_env_runners=True, max_num_env_runner_restarts=p.max_runner_restarts)
            .reporting(metrics_num_episodes_for_smoothing=1))
