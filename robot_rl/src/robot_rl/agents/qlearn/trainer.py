"""The tutorials' Q-learning loop, shared by every task, with results on disk and resume: the "qlearn" agent.

Per episode, as in the tutorials' start_training scripts: decay epsilon (while above epsilon_min, the
tutorials' 0.05), reset, then up to nsteps of chooseAction -> env.step -> learn, and one log line
"EP: ...". Past the tutorials: terminal transitions do not bootstrap, the step cap is gymnasium
truncation, and the run's bookkeeping (episodes.csv, progress lines, checkpoints, summary.json) is its
RunLedger's. A checkpoint (qtable.json: Q-table, epsilon, RNG, counters; JSON, atomic) lets a run
resume: episodes logged after it are dropped and re-run, never repeated. When an episode cannot
finish (Ctrl-C, the sim gone), the Q-learner goes back to where that episode started before the
ledger saves the run: nothing completed is lost, and resuming repeats exactly what the uninterrupted
run would have done. With the params' `selection` on, the greedy table is checked every few episodes and the
best kept (robot_rl.agents.qlearn.selection). With N envs the trainer is robot_rl.agents.qlearn.vector_trainer's,
whose `make_trainer` and robot_rl.agents.qlearn.policy's `greedy_policy` are the agent registry's entry points.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import gymnasium

from ...envs.base import assist_setter
from ...params import ParamError, Params, TaskParams, load_yaml_file
from ...runs.ledger import DEFAULT_HOOKS, Learner, RunLedger, TrainingHooks, TrainingState, restored_state
from ...runs.results import EpisodeRecord, RunDirectory
from ...task import Episode, TaskSpec, episode_duration
from .qlearn import QLearn
from .selection import BEST_CHECKPOINT, SelectionLog, SelectionState, check_due, play_greedy, score, training_reseed

CHECKPOINT_FORMAT = "robot_rl.training_checkpoint/2"


def check_fit(action_space: gymnasium.spaces.Space[Any], observation_space: gymnasium.spaces.Space[Any], n_envs: int,
              agent_params: Params | None, source: str) -> None:
    """The agent registry's fit check of tabular Q-learning: Discrete actions (ParamError in one line)."""
    if not isinstance(action_space, gymnasium.spaces.Discrete):
        raise ParamError(f"{source}: tabular Q-learning needs Discrete actions, the task has {action_space} "
                         f"(try agent:=sac or ppo; the monoped's action_mode targets is for the deep agents)")


def _listed(mapping: dict[str, Any]) -> str:
    return ", ".join(f"{key} {value!r}" for key, value in sorted(mapping.items()))


class QLearningTrainer(Learner):
    """Runs the loop on `env`, an instance of `task` made with `params`, and writes `run`."""

    def __init__(self, env: gymnasium.Env[Any, Any], task: TaskSpec[Any], params: TaskParams, run: RunDirectory,
                 hooks: TrainingHooks = DEFAULT_HOOKS, resume: bool = False):
        self.env, self.task, self.params, self.run = env, task, params, run
        self.on_step, self.should_stop = hooks.on_step, hooks.should_stop
        self.state_key = task.state_key(params)
        # A vector env's single_action_space: the action space of one of its envs.
        space = getattr(env, "single_action_space", env.action_space)
        if not isinstance(space, gymnasium.spaces.Discrete):
            raise ValueError(f"tabular Q-learning needs Discrete actions, {task.env_id} has {space} (the monoped's "
                             f"action_mode targets is for the deep agents)")
        self.n_actions = int(space.n)
        self.running_step = params.running_step
        self._hooks, self._resuming = hooks, ""
        self.selection, self.selection_log = SelectionState(), SelectionLog(run.path)
        self._reset_seed: int | None = None  # the next training reset's seed, after a check
        if resume:
            self.qlearn, self.state, self.initial_epsilon = run.prepare_resume(self._restore)
            self.selection_log.keep_until(self.state.episode)
            self._resuming = (f"Resuming {run.path} after episode {self.state.episode} "
                              f"(epsilon {self.qlearn.epsilon:.4f})")
        else:
            self.qlearn = QLearn(actions=range(self.n_actions), epsilon=params.epsilon, alpha=params.alpha,
                                 gamma=params.gamma, seed=params.seed, exploration=params.exploration,
                                 q_init=params.q_init, first_visit=params.first_visit,
                                 step_size=params.step_size)
            self.state = TrainingState()
            self.initial_epsilon = params.epsilon
        self.ledger = RunLedger(run, task, params.nepisodes, self.state, self, hooks,
                                n_envs=getattr(env, "num_envs", 1), assist=params.attitude_assist,
                                set_assist=assist_setter(env))

    def _restore(self, checkpoint: dict[str, Any]) -> tuple[QLearn, TrainingState, float]:
        """Everything a checkpoint holds, checked against this run (ValueError/KeyError/TypeError if not)."""
        state = restored_state(checkpoint, CHECKPOINT_FORMAT, self.task)
        if checkpoint["state_key"] != self.state_key.to_dict():
            raise ValueError("its state key differs from the one this code makes from the params")
        qlearn = QLearn.from_dict(checkpoint["qlearn"])
        if qlearn.actions != list(range(self.n_actions)):
            raise ValueError(f"its actions {qlearn.actions} are not the env's {self.n_actions}")
        initial_epsilon = checkpoint["initial_epsilon"]
        if not isinstance(initial_epsilon, (int, float)):
            raise ValueError(f"initial_epsilon {initial_epsilon!r} is not a number")
        self._check_learning_params(qlearn, float(initial_epsilon))
        if "selection" in checkpoint:
            self.selection = SelectionState.from_dict(checkpoint["selection"])
            there, here = checkpoint["selection"]["params"], self.params.selection.to_mapping()
            if self.selection.checked_at and there != here:
                raise ValueError(f"its table checks ran with selection ({_listed(there)}), this run's is "
                                 f"({_listed(here)}): a best table is picked on the same episodes throughout; resume "
                                 "with the params the run began with")
        return qlearn, state, float(initial_epsilon)

    def _check_learning_params(self, qlearn: QLearn, initial_epsilon: float) -> None:
        """ValueError naming each learning param whose value differs from the run's, as DeepTrainer refuses changed
        agent params: the checkpoint's Q-learner's (alpha, gamma, the initial epsilon, ...) and params.yaml's
        epsilon_discount and epsilon_min. nepisodes (a run trained further) and the rest may change."""
        params = self.params
        there: dict[str, Any] = {"alpha": qlearn.alpha, "gamma": qlearn.gamma, "epsilon": initial_epsilon,
                                 "exploration": qlearn.exploration, "q_init": qlearn.q_init,
                                 "first_visit": qlearn.first_visit, "step_size": qlearn.step_size}
        try:
            began = load_yaml_file(self.run.params_yaml)
        except ParamError:
            began = {}
        there.update({key: began[key] for key in ("epsilon_discount", "epsilon_min") if key in began})
        differ = ", ".join(f"{key} {value!r} there, {getattr(params, key)!r} here" for key, value in there.items()
                           if value != getattr(params, key))
        if differ:
            raise ValueError(f"its learning params differ from this run's ({differ}): resume with the params the run "
                             "began with")

    def _checkpoint_state(self) -> dict[str, Any]:
        return {"format": CHECKPOINT_FORMAT, "task": self.task.env_id, "episode": self.state.episode,
                "qlearn": self.qlearn.to_dict(), "state_key": self.state_key.to_dict(),
                "initial_epsilon": self.initial_epsilon, "state": dataclasses.asdict(self.state),
                "selection": {**self.selection.to_dict(), "params": self.params.selection.to_mapping()}}

    def save_checkpoint(self) -> None:
        self.run.checkpoint(self._checkpoint_state())

    def episode_label(self, epsilon: float) -> str:
        return f"alpha: {round(self.qlearn.alpha, 2)} - gamma: {round(self.qlearn.gamma, 2)} - epsilon: " \
               f"{round(epsilon, 2)}"

    def exploration_label(self) -> str:
        return f", epsilon {self.qlearn.epsilon:.3f}"

    def summary_fields(self) -> dict[str, Any]:
        lengths = sorted(self.state.last_time_steps)
        return {"overall_score": sum(lengths) / len(lengths) if lengths else None,
                "best_100_score": sum(lengths[-100:]) / len(lengths[-100:]) if lengths else None,
                "q_table_entries": len(self.qlearn.q), "final_epsilon": self.qlearn.epsilon,
                **({"selection": self.selection.to_dict()} if self.params.selection.every else {})}

    def closing_lines(self, summary: dict[str, Any], last: Sequence[EpisodeRecord]) -> list[str]:
        """The tutorials' closing lines, without their reduce and division-by-zero bugs."""
        def fmt(v: float | None) -> str:
            return "n/a (no episode ended by termination)" if v is None else f"{v:0.2f}"
        return [f"\n|{self.params.nepisodes}|{self.qlearn.alpha}|{self.qlearn.gamma}|{self.initial_epsilon}*"
                f"{self.params.epsilon_discount}|{self.state.highest_reward}| PICTURE |",
                f"Overall score: {fmt(summary['overall_score'])}", f"Best 100 score: {fmt(summary['best_100_score'])}"]

    def decay_epsilon(self) -> None:
        if self.qlearn.epsilon > self.params.epsilon_min:
            self.qlearn.epsilon *= self.params.epsilon_discount

    def _episode(self, first: bool) -> tuple[Episode, float]:
        """One episode: (the episode, the highest cumulated reward within it). Changes only the Q-learner."""
        qlearn, env = self.qlearn, self.env
        self.decay_epsilon()
        # The first episode of a (resumed) run restarts sim time and sensor noise from the seeds.
        observation, _ = env.reset(seed=self.params.seed if first else self._reset_seed)
        self._reset_seed = None
        state = self.state_key.key(observation)
        cumulated, highest = 0.0, -math.inf
        steps = 0
        terminated = False
        info: dict[str, Any] = {}
        for i in range(self.params.nsteps):
            action = qlearn.chooseAction(state)
            observation, step_reward, terminated, truncated, info = env.step(action)
            reward = float(step_reward)
            steps = i + 1
            cumulated += reward
            highest = max(highest, cumulated)
            next_state = self.state_key.key(observation)
            qlearn.learn(state, action, reward, next_state, terminal=terminated)
            self.on_step(reward, cumulated)
            if terminated or truncated:
                break
            state = next_state
        return Episode(steps=steps, return_=cumulated, terminated=terminated,
                       duration=episode_duration(info, steps, self.running_step), info=info), highest

    def _back_to_episode_start(self) -> None:
        """The Q-learner as it was when the episode that could not finish started."""
        self.qlearn.q, self.qlearn.visits, self.qlearn.epsilon, rng_state = self._episode_start
        self.qlearn.rng.setstate(rng_state)

    def train(self) -> dict[str, Any]:
        """Run the remaining episodes; returns the summary written to summary.json."""
        params, state, ledger = self.params, self.state, self.ledger
        if self._resuming:  # said when training starts: a resume of a complete run trains nothing
            self._hooks.log(self._resuming)
        ledger.start()
        first = True
        while not self.should_stop():
            if check_due(params.selection, self.selection, state.episode, params.nepisodes):
                with ledger.saved_on_stop():
                    self._check_table()
            if state.episode >= params.nepisodes:
                break
            self._episode_start = (dict(self.qlearn.q), dict(self.qlearn.visits), self.qlearn.epsilon,
                                   self.qlearn.rng.getstate())
            with ledger.saved_on_stop(rollback=self._back_to_episode_start):
                episode, highest = self._episode(first)
            first = False
            ledger.episode_done(episode, highest, self.qlearn.epsilon)
            ledger.log_progress_if_due()
        return ledger.close(done=state.episode >= params.nepisodes)

    def _check_table(self) -> None:
        """Play the greedy table on the check's episodes (after a checkpoint of it), log its score, keep it as
        qtable_best.json if it beats every earlier one, and checkpoint the result (selection.py)."""
        selection, state, checked = self.params.selection, self.selection, self.state.episode
        self.ledger.checkpoint()
        episodes = play_greedy(self.env, self.qlearn, self.state_key, selection, self.params.nsteps,
                               self.running_step)
        table_score, mean_return = score(episodes, self.task)
        better = table_score > state.best_score
        state.checked_at = checked
        if better:
            state.best_score, state.best_episode = table_score, checked
            RunDirectory(self.run.path, BEST_CHECKPOINT).checkpoint({**self._checkpoint_state(), "selected": {
                "episode": checked, "score": table_score, "metric": self.task.headline_metric,
                "episodes": selection.episodes, "seed": selection.seed}})
        self.selection_log.append([checked, f"{table_score:.6g}", f"{mean_return:.6g}", f"{state.best_score:.6g}",
                                   state.best_episode])
        self._reset_seed = training_reseed(self.params.seed, checked)
        self.ledger.checkpoint()
        self._hooks.log(f"table check after episode {checked}: {self.task.headline_metric} {table_score:.3g} over "
                        f"{selection.episodes} greedy episodes from seed {selection.seed}"
                        f"{' (the best so far: ' + BEST_CHECKPOINT + ')' if better else ''}; best "
                        f"{state.best_score:.3g} after episode {state.best_episode}")
