"""The attitude assist, Track B's curriculum as sim options (issue 39): pybullet_sim's World.set_attitude_assist,
the env's params attitude_assist, the curriculum that takes it away (robot_rl.runs.curriculum) with its state in
the run's checkpoint, and evaluate.py --assist. Direct backend, no ROS (over ROS: test_attitude_assist_over_ros)."""
import json
import math

import numpy as np
import pytest

from hopper_training.envs.end_to_end import END_TO_END
from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import Episode, ParamError, RunDirectory, RunLedger, TrainingHooks, TrainingState, make_env
from robot_rl.evaluation import main as evaluate_main
from robot_rl.evaluation import with_assist
from robot_rl.params import AttitudeAssist
from robot_rl.runs.curriculum import AssistCurriculum

CROUCH = np.zeros(3, np.float32)  # the end-to-end action: every joint at its crouch target


def assisted(stiffness, damping, **changes):
    return END_TO_END.default_params().with_changes(
        "test", attitude_assist={"stiffness": stiffness, "damping": damping, **changes})


def time_up(env, seed, episodes=3):
    """Mean seconds the crouch stays up from the task's leaning starts (evaluation seed `seed`)."""
    ups = []
    for i in range(episodes):
        env.reset(seed=seed + i)
        steps, done = 0, False
        while not done:
            _, _, terminated, truncated, _ = env.step(CROUCH)
            steps, done = steps + 1, terminated or truncated
        ups.append(steps * env.unwrapped.running_step)
    return float(np.mean(ups))


# -- the sim option ------------------------------------------------------------------------------

def test_the_assist_holds_the_crouch_up_for_the_whole_episode_and_without_it_the_crouch_falls():
    for gains, check in (((20.0, 1.0), lambda up: up == pytest.approx(10.0)), ((0.0, 0.0), lambda up: up < 2.0)):
        env = make_env(END_TO_END, params=assisted(*gains), backend="direct", seed=1000)
        try:
            assert env.unwrapped.backend.world.attitude_assist == gains
            assert check(time_up(env, 1000)), gains
        finally:
            env.close()


def test_a_quarter_of_the_assist_is_too_little_and_the_scale_multiplies_both_gains():
    env = make_env(END_TO_END, params=assisted(20.0, 1.0, scale=0.25), backend="direct", seed=1000)
    try:
        assert env.unwrapped.backend.world.attitude_assist == (5.0, 0.25)
        assert time_up(env, 1000) < 3.0  # the monoped topples at ~6 N m/rad about its foot
        env.unwrapped.set_assist_scale(1.0)
        assert env.unwrapped.backend.world.attitude_assist == (20.0, 1.0)
        with pytest.raises(ValueError, match="scale must be from 0 to 1, got 1.5"):
            env.unwrapped.set_assist_scale(1.5)
    finally:
        env.close()


def test_the_torque_turns_the_base_back_towards_upright():
    tilts = []
    for gains in ((0.0, 0.0), (20.0, 0.0)):
        env = make_env(END_TO_END, params=assisted(*gains) if gains[0] else END_TO_END.default_params(),
                       backend="direct", seed=7)
        try:
            env.reset(seed=7)
            for _ in range(40):  # 0.2 s
                env.step(CROUCH)
            orientation = env.unwrapped.backend.world.model_state().orientation
            tilts.append(2.0 * math.asin(min(1.0, math.hypot(orientation[0], orientation[1]))))
        finally:
            env.close()
    assert tilts[1] < 0.02 < tilts[0], tilts


def test_the_world_refuses_a_bad_gain_keeps_the_last_and_resets_keep_it():
    env = make_env(END_TO_END, params=assisted(3.0, 0.5), backend="direct", seed=0)
    world = env.unwrapped.backend.world
    try:
        for stiffness, damping, name in ((math.nan, 0.0, "stiffness"), (-1.0, 0.0, "stiffness"),
                                         (0.0, 1e5, "damping"), (0.0, math.inf, "damping")):
            with pytest.raises(ValueError, match=f"attitude assist {name} must be a finite number from 0 to 10000"):
                world.set_attitude_assist(stiffness, damping)
        assert world.attitude_assist == (3.0, 0.5)
        world.reset_world()
        world.reset_simulation()
        assert world.attitude_assist == (3.0, 0.5)
    finally:
        env.close()


def test_a_replayed_start_with_the_assist_is_the_stepped_one():
    """The World remembers the first steps after a reset (starts.py): with the assist they must be taken with it."""
    env = make_env(END_TO_END, params=assisted(20.0, 1.0), backend="direct", seed=3)
    try:  # the second reset's start is remembered, the third replays it
        observations = [env.reset(seed=3)[0] for _ in range(3)]
    finally:
        env.close()
    fresh = make_env(END_TO_END, params=assisted(20.0, 1.0), backend="direct", seed=3)
    try:
        stepped, _ = fresh.reset(seed=3)
    finally:
        fresh.close()
    assert all(np.array_equal(o, stepped) for o in observations)


# -- the params ------------------------------------------------------------------------------------

def test_the_params_refuse_a_curriculum_of_no_assist_and_thresholds_that_cannot_hold():
    with pytest.raises(ParamError, match="'attitude_assist/adapt_every' \\(20\\) adapts an assist that is off"):
        assisted(0.0, 0.0, adapt_every=20)
    with pytest.raises(ParamError, match="lower_at_most \\(5\\) < raise_at_least \\(5\\) <= adapt_every \\(20\\)"):
        assisted(20.0, 1.0, adapt_every=20, raise_at_least=5)
    with pytest.raises(ParamError, match="factor"):
        assisted(20.0, 1.0, factor=1.0)
    with pytest.raises(ParamError, match="'attitude_assist/free_share' \\(0.25\\) mixes .* it needs adapt_every > 0"):
        assisted(20.0, 1.0, free_share=0.25)
    assert not END_TO_END.default_params().attitude_assist.active


# -- the curriculum --------------------------------------------------------------------------------

ADAPT = AttitudeAssist(stiffness=20.0, damping=1.0, adapt_every=4, lower_at_most=1, raise_at_least=3, factor=0.5,
                       floor=0.1)


def windows(curriculum, *falls_per_window):
    """The scale after each window of 4 episodes with that many falls, and whether each window changed it."""
    seen, episode = [], 0
    for falls in falls_per_window:
        changed = [curriculum.episode_ended(episode := episode + 1, i < falls) for i in range(4)]
        assert not any(changed[:3])
        seen.append((curriculum.scale, changed[3]))
    return seen


def test_the_scale_goes_down_while_few_fall_up_when_many_do_and_stays_between():
    curriculum = AssistCurriculum(ADAPT)
    assert windows(curriculum, 0, 1, 2, 3, 4, 4) == [(0.5, True), (0.25, True), (0.25, False), (0.5, True),
                                                     (1.0, True), (1.0, False)]


def test_under_the_floor_the_scale_is_0_and_a_raise_starts_again_from_the_floor():
    curriculum = AssistCurriculum(ADAPT, scale=0.15)
    assert windows(curriculum, 0, 0, 3) == [(0.0, True), (0.0, False), (0.2, True)]


def test_free_episodes_are_the_share_asked_for_spread_evenly_and_do_not_count_while_there_is_an_assist():
    curriculum = AssistCurriculum(AttitudeAssist(stiffness=20.0, adapt_every=4, free_share=0.25))
    free = [curriculum.free(episode) for episode in range(1, 1001)]
    assert abs(sum(free) - 250) <= 1 and all(1 <= sum(free[i:i + 8]) <= 3 for i in range(0, 1000, 8))
    assert [curriculum.scale_of(episode) for episode in range(1, 9)] == [1.0 * (not f) for f in free[:8]]
    assert not AssistCurriculum(ADAPT).free(1) and not any(map(AssistCurriculum(ADAPT).free, range(1, 100)))
    free_numbers = [episode for episode in range(1, 41) if curriculum.free(episode)]
    assert not any(curriculum.episode_ended(episode, True) for episode in free_numbers) and curriculum.window == []
    curriculum.scale = 0.0  # no assist left: a free episode is like any other, its fall counts
    curriculum.episode_ended(free_numbers[0], True)
    assert curriculum.window == [1]


def test_a_fixed_assist_never_changes_and_a_state_that_does_not_fit_is_refused():
    fixed = AssistCurriculum(AttitudeAssist(stiffness=20.0, scale=0.3))
    assert not any(fixed.episode_ended(episode, True) for episode in range(1, 51)) and fixed.scale == 0.3
    for scale, window in ((1.5, []), (0.5, [0, 2]), (0.5, [0, 0, 0, 0])):
        with pytest.raises(ValueError, match="does not fit its params"):
            AssistCurriculum(ADAPT, scale, window)


# -- in the run's ledger and checkpoint ------------------------------------------------------------

class Learner:
    def __init__(self, run, state):
        self.run, self.state = run, state

    def save_checkpoint(self):
        self.run.checkpoint({"format": "test", "task": ONE_DISK_WALK.env_id, "episode": self.state.episode,
                             "state": vars(self.state)})

    def episode_label(self, epsilon):
        return "test"

    def exploration_label(self):
        return ""

    def summary_fields(self):
        return {}

    def closing_lines(self, summary, last):
        return []


def ledger_for(run, state, assist, set_assist, log):
    ledger = RunLedger(run, ONE_DISK_WALK, 100, state, Learner(run, state),
                       TrainingHooks(log=log.append, checkpoint_every=3, progress_every_s=0.0), assist=assist,
                       set_assist=set_assist)
    ledger.start()
    return ledger


def ended(ledger, fell):
    ledger.episode_done(Episode(steps=2, return_=1.0, terminated=fell, duration=0.2, info={"y_distance": 0.0,
                                                                                           "success": False}),
                        highest=1.0, epsilon=0.0)


def test_the_ledger_hands_each_new_scale_to_the_env_logs_it_and_a_resume_goes_on_from_the_checkpoint(tmp_path):
    run = RunDirectory.create(tmp_path, "moving_cube", {}, ONE_DISK_WALK.metric_names, "run")
    told, log = [], []
    ledger = ledger_for(run, TrainingState(), ADAPT, told.append, log)
    assert told == [1.0]  # the start's scale, also for a run that starts afresh
    for fell in (0, 0, 0, 0, 1, 1, 1, 0, 1, 1):
        ended(ledger, fell)
    assert told == [1.0, 0.5, 1.0]
    assert "attitude assist: scale 0.5 -> 1 after episode 8 (3 of the last 4 episodes fell)" in log
    ledger.log_progress_if_due()
    assert log[-1].endswith(", attitude assist scale 1")
    ledger.checkpoint()  # after episode 10: two episodes of the next window, both fell
    saved = json.loads(run.checkpoint_json.read_text())["state"]
    assert (saved["assist_scale"], saved["assist_window"]) == (1.0, [1, 1])

    state = TrainingState.from_dict(saved)
    told.clear()
    resumed = ledger_for(run, state, ADAPT, told.append, log)
    assert told == [1.0]
    for fell in (0, 0):  # the window under way ends with 2 of 4 fallen: no change
        ended(resumed, fell)
    assert told == [1.0] and resumed.state.assist_window == []


def test_the_ledger_gives_free_episodes_no_assist_and_adapts_on_the_assisted_ones_alone(tmp_path):
    run = RunDirectory.create(tmp_path, "moving_cube", {}, ONE_DISK_WALK.metric_names, "run")
    assist = AttitudeAssist(**{**ADAPT.to_mapping(), "free_share": 0.25})
    curriculum, told, log = AssistCurriculum(assist), [], []
    ledger = ledger_for(run, TrainingState(), assist, told.append, log)
    free = [curriculum.free(episode) for episode in range(1, 9)]
    assert free == [False, True, False, False, True, False, False, False]
    for fell in free:  # every free episode falls, every assisted one keeps up: the scale goes down
        ended(ledger, fell)
    # episodes 2 and 5 free (0); the window of the assisted episodes 1, 3, 4 and 6 ends at 6: 0.5 from 7 on
    assert told == [1.0, 0.0, 1.0, 0.0, 1.0, 0.5]
    assert "attitude assist: scale 1 -> 0.5 after episode 6 (0 of the last 4 assisted episodes fell)" in log
    assert ledger.state.assist_window == [0, 0]  # episodes 7 and 8


def test_a_trainer_that_cannot_change_its_envs_assist_is_refused_before_it_trains(tmp_path):
    run = RunDirectory.create(tmp_path, "moving_cube", {}, ONE_DISK_WALK.metric_names, "run")
    with pytest.raises(ValueError, match="needs the one env in the trainer's process: envs:=1 and an agent"):
        RunLedger(run, ONE_DISK_WALK, 10, TrainingState(), Learner(run, TrainingState()), TrainingHooks(),
                  n_envs=2, assist=ADAPT)
    RunLedger(run, ONE_DISK_WALK, 10, TrainingState(), Learner(run, TrainingState()), TrainingHooks(), n_envs=2,
              assist=AttitudeAssist(stiffness=20.0))  # a fixed assist: every env sets it itself
    assert TrainingState.from_dict({"episode": 3}).assist_scale is None  # a checkpoint from before the assist


# -- evaluation ------------------------------------------------------------------------------------

def test_evaluation_holds_the_assist_it_is_asked_for_and_none_by_default():
    params = assisted(20.0, 1.0, adapt_every=20, scale=0.6, free_share=0.25)
    held = with_assist(params, 0.05).attitude_assist
    assert (held.stiffness, held.damping, held.scale, held.adapt_every, held.free_share) == (20.0, 1.0, 0.05, 0, 0.0)
    assert not with_assist(params, 0.0).attitude_assist.active
    with pytest.raises(ParamError, match="--assist: the run has no attitude assist"):
        with_assist(END_TO_END.default_params(), 0.1)


def test_evaluate_refuses_an_assist_out_of_range_or_where_there_is_none_in_one_line(capsys):
    import hopper_training
    from hopper_training.scripted_policies import POLICIES
    for value, message in (("2", "--assist must be a scale from 0 to 1, got 2.0"),
                           ("nan", "--assist must be a scale from 0 to 1, got nan"),
                           ("0.5", "evaluate.py: --assist: the run has no attitude assist")):
        with pytest.raises(SystemExit) as exit_:
            evaluate_main(["--policy", "controller", "--task", "end_to_end", "--assist", value],
                          hopper_training.TASKS, "evaluate_test", POLICIES)
        assert exit_.value.code == 2 and message in capsys.readouterr().err


# -- a deep run with the curriculum, resumed -------------------------------------------------------

@pytest.mark.deep
def test_a_ppo_run_adapts_the_assist_and_its_resume_sets_the_checkpoints_scale_before_it_trains(tmp_path):
    from robot_rl.agents.registry import find_agent
    from robot_rl.agents.sb3.trainer import DeepTrainer
    ppo = find_agent("ppo")
    # leaning 0.3 rad at the start and a tenth of what holds the crouch: every episode falls, each window raises
    params = assisted(2.0, 0.1, scale=0.25, adapt_every=2, lower_at_most=0, raise_at_least=2, factor=0.5).with_changes(
        "test", initial_tilt={"low": 0.3, "high": 0.35}, nsteps=400)
    agent_params = ppo.load_params().with_changes("test", n_steps=64, batch_size=32, hidden_units=16)

    def train(nepisodes, resume):
        run = RunDirectory.latest(tmp_path, "hopper-ppo", ppo.checkpoint_name) if resume else RunDirectory.create(
            tmp_path, "hopper-ppo", params.to_mapping(), END_TO_END.metric_names, checkpoint_name=ppo.checkpoint_name)
        env, log = make_env(END_TO_END, params=params, backend="direct", seed=0), []
        try:
            trainer = DeepTrainer(env, END_TO_END, params.with_changes("test", nepisodes=nepisodes), ppo,
                                  agent_params, run, TrainingHooks(log=log.append, checkpoint_every=2), resume=resume)
            world = env.unwrapped.backend.world
            gains_at_start = world.attitude_assist
            summary = trainer.train()
            return run, summary, log, gains_at_start, world.attitude_assist
        finally:
            env.close()

    run, summary, log, at_start, at_end = train(4, resume=False)
    assert summary["completed"] and at_start == (0.5, 0.025) and summary["attitude_assist_scale"] == 1.0
    assert [line for line in log if line.startswith("attitude assist")] == [
        "attitude assist: scale 0.25 -> 0.5 after episode 2 (2 of the last 2 episodes fell)",
        "attitude assist: scale 0.5 -> 1 after episode 4 (2 of the last 2 episodes fell)"]
    assert at_end == (2.0, 0.1)
    state = json.loads(run.checkpoint_json.read_text())["state"]
    assert (state["assist_scale"], state["assist_window"]) == (1.0, [])

    _, summary, log, _, at_end = train(6, resume=True)
    assert summary["completed"] and summary["episodes"] == 6
    assert at_end == (2.0, 0.1)  # the checkpoint's scale (1), not the params' start (0.25), and capped at 1
    assert not [line for line in log if line.startswith("attitude assist")]
