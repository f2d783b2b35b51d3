"""Agent bc_dagger's training (issue 39, Track A): the hopping controller teaches MonopedEndToEnd-v0's student.

1. Behaviour cloning: `bc_episodes` episodes of the teacher acting (the later ones with Ornstein-Uhlenbeck noise
   on its actions, so that the data holds recoveries from states it would not visit itself; the labels are always
   its clean actions), then `bc_epochs` epochs of mean squared error on (observation, label).
2. DAgger rounds: the student acts, except that with probability beta (beta_start x beta_decay^round) a step
   takes the teacher's action; the teacher, shadow-run on the visited states (teacher.py), labels every one; the
   new samples join the aggregate and the student trains `dagger_epochs` more epochs on it.
3. The refit (when `refit_epochs` > 0): a new student, from the same first weights as the run's, trains
   `refit_epochs` epochs at `learning_rate` on the whole aggregate and is the run's student. A student that went
   through every round, fine-tuned on data that grew round by round, imitates worse than one fitted once on all of it
   (docs/guide/end_to_end.md, "Pushes in training").
Every collected episode is a row of episodes.csv (its epsilon column is the chance the teacher acted: 1 for a
behaviour cloning episode, beta for a round's). Episode i of the run resets with seed 10000 x (seed + 1) + i.
The run's checkpoint is agent.json (the counters, the rounds' figures, the teacher's gains, the sha256 of the
weights and the RNGs' states) beside student.npz and student.json (student.py) and the aggregate data,
dagger_data.npz (observations and labels, numpy arrays read with allow_pickle=False), all as they were at the end
of the last finished stage (BC, a DAgger round, the refit): each stage's end writes the data, then the checkpoint,
each file whole. resume:=true goes on from there, with the teacher it recorded (other gains are refused): the
episodes of a stage under way at the stop are dropped from episodes.csv and collected anew (with the same seeds
and RNG states: a resumed run is the uninterrupted one). Needs torch
(requirements-deep.txt); trains on one env (envs:=1), over ROS or direct.
"""
from __future__ import annotations

import base64
import dataclasses
import hashlib
import io
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from robot_rl import (
    DEFAULT_HOOKS,
    AgentSpec,
    Episode,
    EpisodeRecord,
    RunDirectory,
    RunFileError,
    RunLedger,
    TaskParams,
    TaskSpec,
    TrainingHooks,
    TrainingState,
    assist_setter,
    restored_state,
    write_bytes_atomic,
)

from .params import BcDaggerParams
from .student import CHECKPOINT_FORMAT, RESUME_ENTRIES, NumpyStudent
from .teacher import Teacher

Actor = Callable[[np.ndarray], np.ndarray]
class StopRequested(Exception):
    """The run's hooks asked to stop (Ctrl-C through the training node): the episodes so far are saved."""


OU_DECAY, OU_SCALE = 0.8, 0.6  # the noise's correlation (~20 ms at 5 ms steps: long enough for the PD to feel it)
DATA_FILE = "dagger_data.npz"  # the aggregate (observations, labels) at the last finished stage's end


def data_digest(observations: np.ndarray, labels: np.ndarray) -> str:
    """The sha256 of the aggregate's bytes (float32, C order): what the checkpoint records of dagger_data.npz."""
    digest = hashlib.sha256(np.ascontiguousarray(observations, np.float32).tobytes())
    digest.update(np.ascontiguousarray(labels, np.float32).tobytes())
    return digest.hexdigest()


def load_data(path: Path, samples: int, sha256: str) -> tuple[np.ndarray, np.ndarray]:
    """The first `samples` rows of dagger_data.npz, whose digest must be `sha256` (a later stage's file holds the
    checkpoint's rows first: the aggregate only grows); RunFileError naming the file if not."""
    try:
        with np.load(path, allow_pickle=False) as arrays:
            observations = arrays["observations"][:samples].astype(np.float32)
            labels = arrays["labels"][:samples].astype(np.float32)
    except (OSError, ValueError, KeyError) as error:
        raise RunFileError(f"{path}: not the run's aggregate data ({error})") from None
    if len(observations) != samples or len(labels) != samples or data_digest(observations, labels) != sha256:
        raise RunFileError(f"{path}: not the data the checkpoint recorded ({samples} samples, sha256 {sha256[:12]}"
                           f"...): the run cannot resume; train a new run")
    return observations, labels


class StudentNet(nn.Module):
    """The MLP: normalised observation -> tanh hidden layers -> tanh output (the action, in [-1, 1])."""

    mean: torch.Tensor
    std: torch.Tensor

    def __init__(self, sizes: Sequence[int]):
        super().__init__()
        layers: list[nn.Module] = []
        for m, n in zip(sizes, sizes[1:]):
            layers += [nn.Linear(m, n), nn.Tanh()]
        self.net = nn.Sequential(*layers)
        self.register_buffer("mean", torch.zeros(sizes[0]))
        self.register_buffer("std", torch.ones(sizes[0]))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net((x - self.mean) / self.std)

    def set_normaliser(self, observations: np.ndarray) -> None:
        """The inputs' mean and standard deviation (+ 1e-3, so a constant input divides by no zero)."""
        self.mean.copy_(torch.as_tensor(observations.mean(axis=0)))
        self.std.copy_(torch.as_tensor(observations.std(axis=0) + 1e-3))

    def load_student(self, student: NumpyStudent) -> None:
        """The weights and normaliser of a saved student (float32 as trained: the round trip is exact)."""
        linears = [layer for layer in self.net if isinstance(layer, nn.Linear)]
        if len(linears) != len(student.layers):
            raise ValueError(f"the saved student has {len(student.layers)} layers, this run's {len(linears)}")
        with torch.no_grad():
            for layer, (weights, bias) in zip(linears, student.layers):
                layer.weight.copy_(torch.as_tensor(weights, dtype=torch.float32))
                layer.bias.copy_(torch.as_tensor(bias, dtype=torch.float32))
            self.mean.copy_(torch.as_tensor(student.mean, dtype=torch.float32))
            self.std.copy_(torch.as_tensor(student.std, dtype=torch.float32))

    def numpy_student(self) -> NumpyStudent:
        linears = [layer for layer in self.net if isinstance(layer, nn.Linear)]
        return NumpyStudent([(layer.weight.detach().numpy().astype(np.float64),
                              layer.bias.detach().numpy().astype(np.float64)) for layer in linears],
                            self.mean.numpy().astype(np.float64), self.std.numpy().astype(np.float64))


def fit(net: StudentNet, observations: np.ndarray, labels: np.ndarray, epochs: int, learning_rate: float,
        batch_size: int, generator: torch.Generator) -> float:
    """`epochs` epochs of Adam on the mean squared error (cosine learning rate); returns the last epoch's error."""
    optimiser = torch.optim.Adam(net.parameters(), lr=learning_rate)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, epochs)
    x, y = torch.as_tensor(observations), torch.as_tensor(labels)
    total = 0.0
    for _ in range(epochs):
        total = 0.0
        for batch in torch.randperm(len(x), generator=generator).split(batch_size):
            loss = ((net(x[batch]) - y[batch]) ** 2).mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(batch)
        schedule.step()
    return total / len(x)


def rollout(env: Any, teacher: Teacher, seed: int, max_steps: int, rng: np.random.Generator,
            student: Actor | None = None, beta: float = 1.0, noise: float = 0.0
            ) -> tuple[np.ndarray, np.ndarray, Episode]:
    """One episode from reset(seed=seed), at most `max_steps` steps: the student acts (None: the teacher), the
    teacher's action taken instead with probability `beta` per step (with OU noise of scale `noise` when the
    teacher acts throughout). Returns the observations, the teacher's labels for them and the Episode."""
    observation, _ = env.reset(seed=seed)
    teacher.reset()
    observations, labels = [], []
    total, steps, terminated, info, eps = 0.0, 0, False, {}, np.zeros(3)
    while steps < max_steps:
        label = teacher.label(observation)
        observations.append(observation)
        labels.append(label)
        if student is None or rng.random() < beta:
            action = label
            if noise > 0.0:
                eps = OU_DECAY * eps + OU_SCALE * noise * rng.standard_normal(3)
                action = np.clip(label + eps, -1.0, 1.0).astype(np.float32)
        else:
            action = student(observation)
        observation, reward, terminated, truncated, info = env.step(action)
        total += reward
        steps += 1
        if terminated or truncated:
            break
    episode = Episode(steps=steps, return_=total, terminated=terminated,
                      duration=steps * env.unwrapped.running_step, info=info)
    return np.array(observations, np.float32), np.array(labels, np.float32), episode


class BcDaggerTrainer:
    """Trains the student of `env` (one MonopedEndToEnd-v0 env) from the controller and writes `run`."""

    def __init__(self, env: Any, task: TaskSpec[Any], params: TaskParams, agent: AgentSpec,
                 agent_params: BcDaggerParams, run: RunDirectory, hooks: TrainingHooks = DEFAULT_HOOKS,
                 agent_config: Path | None = None, resume: bool = False):
        if not hasattr(env, "unwrapped") or not hasattr(env.unwrapped, "readings"):
            raise ValueError("agent bc_dagger trains on one env whose readings its teacher reads: envs:=1")
        agent_params.check_action_space(env.action_space, f"agent {agent.name} on {task.env_id}")
        torch.set_num_threads(1)
        self.env, self.task, self.params, self.agent, self.p, self.run = env, task, params, agent, agent_params, run
        self.agent_config = None if agent_config is None else str(agent_config)
        self.log, self.should_stop = hooks.log, hooks.should_stop
        run.checkpoint_name = agent.checkpoint_name
        self.net = self._first_net()
        self.generator = torch.Generator().manual_seed(params.seed)
        self.rng = np.random.default_rng(params.seed)
        self.teacher = Teacher(env)
        self.max_steps = max(1, round(agent_params.horizon_s / env.unwrapped.running_step))
        self.rounds: list[dict[str, Any]] = []
        self.beta = 1.0
        self.observations = np.zeros((0, int(np.prod(env.observation_space.shape))), np.float32)
        self.labels = np.zeros((0, 3), np.float32)
        self.state = TrainingState()
        self.saved = self._snapshot(None)  # what the checkpoint holds: the last finished stage's end (none yet)
        self.resuming = ""
        if resume:
            self.state = run.prepare_resume(self._restore)
            self.resuming = (f"Resuming {run.path} after stage {len(self.rounds)} of {agent_params.stages()} "
                             f"(episode {self.state.episode}); a stage under way at the stop is collected anew")
        self.ledger = RunLedger(run, task, agent_params.episodes(), self.state, self, hooks,
                                assist=params.attitude_assist, set_assist=assist_setter(env))

    def _first_net(self) -> StudentNet:
        """The student as the run begins it: its weights drawn from the training seed alone."""
        torch.manual_seed(self.params.seed)
        size = int(np.prod(self.env.observation_space.shape))
        return StudentNet([size, *[self.p.hidden_units] * self.p.hidden_layers, 3])

    # -- the Learner's side (RunLedger) --
    def save_checkpoint(self) -> None:
        """agent.json as at the last finished stage's end (the student changes only there: its weights are that
        stage's), whenever the ledger saves (every 10 episodes, on a stop, at the end)."""
        sha256 = self.net.numpy_student().save(self.run.path)
        self.run.checkpoint({"format": CHECKPOINT_FORMAT, "agent": self.agent.name, "task": self.task.env_id,
                             "agent_params": self.p.to_mapping(), "agent_config": self.agent_config,
                             "teacher_gains": self.teacher.gains(), "weights_sha256": sha256, **self.saved})

    def _snapshot(self, data: dict[str, Any] | None) -> dict[str, Any]:
        """The checkpoint's counters, rounds and RNG states now (a stage's end), with its data file's record."""
        return {"episode": self.state.episode, "state": dataclasses.asdict(self.state),
                "rounds": [dict(r) for r in self.rounds], "stages_done": len(self.rounds), "data": data,
                "rng": self.rng.bit_generator.state,
                "torch_generator": base64.b64encode(self.generator.get_state().numpy().tobytes()).decode("ascii")}

    def _restore(self, checkpoint: dict[str, Any]) -> TrainingState:
        """The run as at its checkpoint's stage end: counters, rounds, RNGs, the student and the aggregate data
        (ValueError/KeyError/TypeError naming what is wrong; RunFileError naming another file of the run)."""
        state = restored_state(checkpoint, CHECKPOINT_FORMAT, self.task)
        if checkpoint["agent"] != self.agent.name:
            raise ValueError(f"it is of agent {checkpoint['agent']!r}, this run trains {self.agent.name!r}")
        if "stages_done" not in checkpoint:
            raise ValueError("it is from before bc_dagger runs could resume (no stages_done): train a new run")
        missing = [key for key in RESUME_ENTRIES if key not in checkpoint]
        if missing:
            raise ValueError(f"it has no {', '.join(missing)}: a shipped student (its weights only, ship_policy.py) "
                             f"does not resume; train a new run")
        self.p.require_saved(checkpoint["agent_params"])
        today = self.teacher.gains()  # a run from before the gains were recorded resumes with today's teacher
        changed = [f"{key} {there} there, {today.get(key)} here"
                   for key, there in checkpoint.get("teacher_gains", {}).items() if there != today.get(key)]
        if changed:
            raise ValueError(f"its teacher's gains differ from today's ({', '.join(changed)}): train a new run")
        stages, rounds = checkpoint["stages_done"], checkpoint["rounds"]
        if not (isinstance(stages, int) and isinstance(rounds, list) and len(rounds) == stages
                and 0 <= stages <= self.p.stages()):
            raise ValueError(f"stages_done {stages!r} does not fit its {len(rounds)} rounds")
        if stages:
            data = checkpoint["data"]
            self.observations, self.labels = load_data(self.run.path / DATA_FILE, int(data["samples"]),
                                                       str(data["sha256"]))
            self.net.load_student(NumpyStudent.load(self.run.path, checkpoint["weights_sha256"]))
        self.rng.bit_generator.state = checkpoint["rng"]
        generator = np.frombuffer(base64.b64decode(checkpoint["torch_generator"]), np.uint8)
        self.generator.set_state(torch.as_tensor(generator.copy()))
        self.rounds = [dict(r) for r in rounds]
        self.state = state
        self.saved = {key: checkpoint[key] for key in
                      ("episode", "state", "rounds", "stages_done", *RESUME_ENTRIES)}
        return state

    def episode_label(self, epsilon: float) -> str:
        return f"teacher share {epsilon:.3f}"

    def exploration_label(self) -> str:
        return f", teacher share {self.beta:.3f}"

    def summary_fields(self) -> dict[str, Any]:
        return {"agent": self.agent.name, "agent_config": self.agent_config, "teacher": "hopper_training.controller",
                "rounds": self.rounds}

    def closing_lines(self, summary: dict[str, Any], last: Sequence[EpisodeRecord]) -> list[str]:
        return [f"stage {r['stage']}: {self._collected(r)}{r['samples']} samples, training error {r['train_mse']:.5f}"
                for r in self.rounds]

    @staticmethod
    def _collected(stage: dict[str, Any]) -> str:
        if not stage["episodes"]:
            return "a new student, "
        return f"teacher share {stage['beta']:.3f}, collected upright {stage['collect_upright']:.2f}, "

    # -- training --
    def _collect(self, episodes: int, student: Actor | None, beta: float, noise: Callable[[int], float]
                 ) -> tuple[list[np.ndarray], list[np.ndarray], list[Episode]]:
        xs, ys, collected = [], [], []
        for i in range(episodes):
            if self.should_stop():
                raise StopRequested
            seed = 10_000 * (self.params.seed + 1) + self.state.episode
            x, y, episode = rollout(self.env, self.teacher, seed, self.max_steps, self.rng, student, beta, noise(i))
            xs.append(x)
            ys.append(y)
            collected.append(episode)
            self.ledger.episode_done(episode, episode.return_, beta)
            self.ledger.log_progress_if_due()
        return xs, ys, collected

    def _train_stage(self, stage: str, xs: list[np.ndarray], ys: list[np.ndarray], epochs: int,
                     learning_rate: float, collected: list[Episode]) -> None:
        """Join the stage's samples to the aggregate, train on it, then save the stage: the data, then the
        checkpoint (a resume goes on from here). No samples: the refit, a new student on the aggregate."""
        self.observations = np.concatenate([self.observations, *xs])
        self.labels = np.concatenate([self.labels, *ys])
        observations, labels = self.observations, self.labels
        if not self.rounds or not collected:
            if self.rounds:
                self.net = self._first_net()
            self.net.set_normaliser(observations)
        started = time.monotonic()
        mse = fit(self.net, observations, labels, epochs, learning_rate, self.p.batch_size, self.generator)
        self.rounds.append({"stage": stage, "beta": self.beta if collected else 0.0, "episodes": len(collected),
                            "collect_upright": float(np.mean([not e.terminated for e in collected])) if collected
                            else None,
                            "samples": len(observations), "epochs": epochs, "train_mse": mse,
                            "train_wall_s": time.monotonic() - started})
        self.log(f"{stage}: {len(observations)} samples, training error {mse:.5f}")
        buffer = io.BytesIO()
        np.savez(buffer, observations=observations, labels=labels)
        write_bytes_atomic(self.run.path / DATA_FILE, buffer.getvalue())
        self.saved = self._snapshot({"file": DATA_FILE, "samples": len(observations),
                                     "sha256": data_digest(observations, labels)})
        self.ledger.checkpoint()

    def train(self) -> dict[str, Any]:
        p = self.p
        if self.resuming:
            self.log(self.resuming)
        self.ledger.start()
        try:
            with self.ledger.saved_on_stop():
                if not self.rounds:
                    xs, ys, collected = self._collect(p.bc_episodes, None, 1.0,
                                                      lambda i: p.bc_noise * i / p.bc_episodes)
                    self._train_stage("bc", xs, ys, p.bc_epochs, p.learning_rate, collected)
                for round_ in range(len(self.rounds) - 1, p.dagger_rounds):
                    self.beta = p.beta(round_)
                    student = self.net.numpy_student()
                    xs, ys, collected = self._collect(p.dagger_episodes, student, self.beta, lambda i: 0.0)
                    self._train_stage(f"dagger {round_}", xs, ys, p.dagger_epochs, p.dagger_learning_rate,
                                      collected)
                if len(self.rounds) < p.stages():
                    self._train_stage("refit", [], [], p.refit_epochs, p.learning_rate, [])
        except StopRequested:  # saved_on_stop saved the checkpoint and an "interrupted" summary
            return self.ledger.finish(stopped="interrupted")
        return self.ledger.close(done=True)


def make_trainer(spec: AgentSpec, env: Any, task: TaskSpec[Any], params: TaskParams, run: RunDirectory,
                 hooks: TrainingHooks, resume: bool = False, agent_params: Any = None, max_steps: int | None = None,
                 agent_config: Path | None = None) -> BcDaggerTrainer:
    """The agent registry's entry point of agent bc_dagger."""
    if max_steps is not None:
        raise ValueError("agent bc_dagger's budget is its episodes (bc_episodes, dagger_rounds x dagger_episodes), "
                         "not max_steps")
    if not isinstance(agent_params, BcDaggerParams):
        raise ValueError(f"agent bc_dagger needs BcDaggerParams, got {type(agent_params).__name__}")
    return BcDaggerTrainer(env, task, params, spec, agent_params, run, hooks, agent_config, resume)
