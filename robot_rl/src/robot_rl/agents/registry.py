"""The agents a run can train, each an `AgentSpec` in one registry (AGENTS), as tasks are TaskSpecs.

A spec says everything the training node, evaluate.py, compare_agents.py, the bench and `./ws` need:
the params (None: the task's; else a Params type loaded from a YAML: the task's own,
<task package>/config/agents/<task>.<agent>.yaml, where there is one, else robot_rl/config/<agent>.yaml),
the checkpoint file, the results folder, how to make N envs, build the trainer and load a trained run's
greedy policy, and whether it needs requirements-deep.txt. The implementation is named "module:attr"
(as gymnasium's entry points) and imported only when used, so that this module never imports torch.
Adding an agent: one module with its trainer and policy loader, one line in AGENTS.

  python -m robot_rl.agents needs-deep NAME   exit 0 if agent NAME needs requirements-deep.txt (./ws)
  python -m robot_rl.agents needs-ray NAME    exit 0 if agent NAME needs requirements-distributed.txt (./ws)
"""
from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from ..params import ParamError, Params, TaskParams, load_yaml_file
from ..policies import PolicyMaker
from ..runs.ledger import TrainingHooks
from ..runs.loaded import LoadedRun
from ..runs.results import DEEP_CHECKPOINT, QTABLE_CHECKPOINT, RunDirectory
from ..task import TaskSpec, package_path


class Trainer(Protocol):
    """What every agent's trainer offers the training node."""

    @property
    def state(self) -> Any:
        """The run's counters (robot_rl.runs.ledger.TrainingState)."""

    def train(self) -> dict[str, Any]:
        """Train the remaining episodes; returns the summary written to summary.json."""


def _resolve(reference: str) -> Any:
    module, _, attr = reference.partition(":")
    return getattr(importlib.import_module(module), attr)


@dataclass(frozen=True)
class AgentSpec:
    """One agent. The "module:attr" references are imported when used:
    `trainer` -> make_trainer(spec, env, task, params, run, hooks, resume, agent_params, max_steps, agent_config),
    `vector_env` -> a function (task, n, backend=, seed=, params=, ros_timeout=, cluster=) making N envs,
    `policy` -> a function (LoadedRun, its checkpoint) -> PolicyMaker, `params` -> a Params type."""

    name: str
    description: str                 # for the launch files' and the docs' lists of agents
    checkpoint_name: str             # the run folder's checkpoint file
    results_suffix: str              # the results folder is the task's results_name + this
    needs_deep: bool                 # needs requirements-deep.txt (torch, Stable-Baselines3)
    trainer: str
    vector_env: str
    policy: str
    params: str | None = None        # None: the agent's params are the task's
    fit: str = ""                    # "module:attr" of check_fit(action_space, observation_space, n_envs,
                                     # agent_params, source): ParamError when the agent cannot train such envs
    own_envs: bool = False           # its vector_env makes its envs even for envs:=1 (RLlib's env runners)
    needs_ray: bool = False          # needs requirements-distributed.txt (Ray, RLlib) even without cluster:=
    episodes: str = ""               # "module:attr" of episode_budget(agent_params) -> int: the agent trains its
                                     # params' own count of episodes, not the task's nepisodes ("": nepisodes)
    table_checks: bool = False       # plays the task params' `selection` checks (with envs:=1; see
                                     # robot_rl.agents.qlearn.selection); other agents refuse selection/every > 0

    def results_name(self, task: TaskSpec[Any]) -> str:
        return task.results_name + self.results_suffix

    @property
    def config_path(self) -> Path | None:
        """robot_rl/config/<agent>.yaml, the agent's params for any task (None: it has none of its own)."""
        return None if self.params is None else package_path("robot_rl") / "config" / f"{self.name}.yaml"

    def task_config_path(self, task: TaskSpec[Any]) -> Path | None:
        """<task package>/config/agents/<task>.<agent>.yaml, the agent's params tuned for `task` (it may not exist;
        None: the agent has no params of its own)."""
        if self.params is None:
            return None
        return package_path(task.package) / "config" / "agents" / f"{task.name}.{self.name}.yaml"

    def config_for(self, task: TaskSpec[Any]) -> Path | None:
        """The agent's default params file for `task`: its task_config_path if there is one, else config_path
        (rl-baselines3-zoo's practice: hyperparameters per agent and task, a general file for the rest)."""
        tuned = self.task_config_path(task)
        return tuned if tuned is not None and tuned.is_file() else self.config_path

    def load_params(self, path: Path | None = None) -> Params | None:
        """The agent's params from `path` (default: config_path); ParamError names the key (an unknown one too).
        May raise ModuleNotFoundError when the agent needs requirements-deep.txt and it is not installed."""
        default = self.config_path
        if default is None:
            return None
        path = path or default
        return self.load_params_from(load_yaml_file(path), str(path), strict=True)

    def load_params_from(self, values: Any, source: str, strict: bool = False) -> Params | None:
        """The agent's params from a mapping; `strict` (a config file): an unknown key is refused too."""
        return None if self.params is None else _resolve(self.params).from_mapping(values, source, strict=strict)

    def own_episodes(self, agent_params: Params | None) -> int | None:
        """The episodes a run of this agent trains when its params say (bc_dagger's BC and DAgger episodes); None:
        the task's nepisodes."""
        return _resolve(self.episodes)(agent_params) if self.episodes else None

    def check_fit(self, env: Any, agent_params: Params | None, source: str) -> None:
        """ParamError in one line when this agent cannot train `env` (one env or N; its actions' kind, or a buffer
        beyond the memory): asked before a run folder is made, so a misfit writes nothing."""
        if not self.fit:
            return
        action_space = getattr(env, "single_action_space", env.action_space)
        observation_space = getattr(env, "single_observation_space", env.observation_space)
        _resolve(self.fit)(action_space, observation_space, getattr(env, "num_envs", 1), agent_params, source)

    def make_vector_env(self, task: TaskSpec[Any], n: int, backend: str, seed: int, params: TaskParams,
                        ros_timeout: float, cluster: str | None = None) -> Any:
        """N envs of `task` in worker processes (or Ray actors on `cluster`), in the form this agent's trainer takes."""
        return _resolve(self.vector_env)(task, n, backend=backend, seed=seed, params=params, ros_timeout=ros_timeout,
                                         cluster=cluster)

    def make_trainer(self, env: Any, task: TaskSpec[Any], params: TaskParams, run: RunDirectory,
                     hooks: TrainingHooks, resume: bool = False, agent_params: Params | None = None,
                     max_steps: int | None = None, agent_config: Path | None = None) -> Trainer:
        """The trainer of `env` (one env, or N from make_vector_env); `max_steps`: a deep agent's step budget;
        `agent_config`: the file `agent_params` came from (the run's summary.json and checkpoint name it)."""
        make: Callable[..., Trainer] = _resolve(self.trainer)
        return make(self, env, task, params, run, hooks, resume, agent_params, max_steps, agent_config)

    def greedy_policy(self, run: LoadedRun, checkpoint: dict[str, Any]) -> PolicyMaker:
        """The trained run's greedy policy; ValueError if the checkpoint is not this agent's."""
        load: Callable[[LoadedRun, dict[str, Any]], PolicyMaker] = _resolve(self.policy)
        return load(run, checkpoint)


AGENTS: dict[str, AgentSpec] = {spec.name: spec for spec in (
    AgentSpec("qlearn", "tabular Q-learning, the tutorials'", QTABLE_CHECKPOINT, "", needs_deep=False,
              trainer="robot_rl.agents.qlearn.vector_trainer:make_trainer",
              vector_env="robot_rl.workers.vector_env:make_vector_env",
              policy="robot_rl.agents.qlearn.policy:greedy_policy", fit="robot_rl.agents.qlearn.trainer:check_fit",
              table_checks=True),
    AgentSpec("dqn", "Stable-Baselines3's DQN", DEEP_CHECKPOINT, "-dqn", needs_deep=True,
              trainer="robot_rl.agents.sb3.trainer:make_trainer", vector_env="robot_rl.agents.sb3.vec_env:make_vec_env",
              policy="robot_rl.agents.sb3.policy:greedy_policy", params="robot_rl.agents.sb3.params:DqnParams",
              fit="robot_rl.agents.sb3.params:check_fit"),
    AgentSpec("ppo", "Stable-Baselines3's PPO", DEEP_CHECKPOINT, "-ppo", needs_deep=True,
              trainer="robot_rl.agents.sb3.trainer:make_trainer", vector_env="robot_rl.agents.sb3.vec_env:make_vec_env",
              policy="robot_rl.agents.sb3.policy:greedy_policy", params="robot_rl.agents.sb3.params:PpoParams",
              fit="robot_rl.agents.sb3.params:check_fit"),
    AgentSpec("sac", "Stable-Baselines3's SAC, for continuous actions", DEEP_CHECKPOINT, "-sac", needs_deep=True,
              trainer="robot_rl.agents.sb3.trainer:make_trainer", vector_env="robot_rl.agents.sb3.vec_env:make_vec_env",
              policy="robot_rl.agents.sb3.policy:greedy_policy", params="robot_rl.agents.sb3.params:SacParams",
              fit="robot_rl.agents.sb3.params:check_fit"),
    AgentSpec("bc_dagger", "behaviour cloning and DAgger from the monoped's hopping controller, task end_to_end only",
              DEEP_CHECKPOINT, "-bc_dagger", needs_deep=True, trainer="hopper_training.teacher.trainer:make_trainer",
              vector_env="robot_rl.workers.vector_env:make_vector_env",
              policy="hopper_training.teacher.student:greedy_policy",
              params="hopper_training.teacher.params:BcDaggerParams",
              episodes="hopper_training.teacher.params:episode_budget"),
    AgentSpec("ppo_finetune", "Stable-Baselines3's PPO fine-tuning a bc_dagger student, task end_to_end",
              DEEP_CHECKPOINT, "-ppo_finetune", needs_deep=True,
              trainer="hopper_training.teacher.finetune:make_trainer",
              vector_env="robot_rl.agents.sb3.vec_env:make_vec_env", policy="robot_rl.agents.sb3.policy:greedy_policy",
              params="hopper_training.teacher.finetune:FinetuneParams",
              fit="hopper_training.teacher.finetune:check_fit"),
    AgentSpec("rllib_ppo", "RLlib's PPO, its env runners on Ray", DEEP_CHECKPOINT, "-rllib_ppo", needs_deep=True,
              trainer="robot_rl.agents.rllib.trainer:make_trainer",
              vector_env="robot_rl.agents.rllib.runners:make_rllib_envs",
              policy="robot_rl.agents.rllib.policy:greedy_policy", params="robot_rl.agents.rllib.params:RllibPpoParams",
              fit="robot_rl.agents.rllib.params:check_fit", own_envs=True, needs_ray=True),
)}


DEFAULT_AGENT = "qlearn"


def find_agent(name: str) -> AgentSpec:
    try:
        return AGENTS[name]
    except (KeyError, TypeError):
        raise ParamError(f"unknown agent {name!r} (known: {', '.join(AGENTS)})") from None


def checkpoint_of(run_dir: Path) -> Path:
    """The checkpoint file of a run folder: the first agent's in AGENTS' order that is there (none: the first's)."""
    names = dict.fromkeys(spec.checkpoint_name for spec in AGENTS.values())
    return next((run_dir / name for name in names if (run_dir / name).is_file()), run_dir / next(iter(names)))


def agent_of(checkpoint: dict[str, Any]) -> AgentSpec:
    """The agent a checkpoint is of: the one it names ("agent", as deep agents' do), else the tabular one."""
    return find_agent(checkpoint.get("agent", DEFAULT_AGENT))


def main(argv: Sequence[str]) -> int:
    if len(argv) == 2 and argv[0] == "needs-deep":
        return 0 if argv[1] in AGENTS and AGENTS[argv[1]].needs_deep else 1
    if len(argv) == 2 and argv[0] == "needs-ray":
        return 0 if argv[1] in AGENTS and AGENTS[argv[1]].needs_ray else 1
    print("usage: python -m robot_rl.agents needs-deep|needs-ray NAME", file=sys.stderr)
    return 2

