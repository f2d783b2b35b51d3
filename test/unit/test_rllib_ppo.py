"""Agent rllib_ppo without a Ray cluster: its YAML to RLlib's PPOConfig, an unknown key refused in one line, the
order the runners' episodes go into episodes.csv, and the numpy policy (what evaluate.py plays) against the torch
RLModule RLlib builds from the same config, and its weights file checked by sha256."""
import dataclasses
import re
import types

import gymnasium
import numpy as np
import pytest

from moving_cube_training.envs.one_disk_walk import ONE_DISK_WALK
from robot_rl import AGENTS, ParamError, RunFileError, find_agent
from robot_rl.agents.rllib.params import RllibPpoParams, ppo_config
from robot_rl.agents.rllib.policy import NumpyPpoPolicy, load_weights, save_weights
from robot_rl.agents.rllib.runners import in_order
from robot_rl.agents.rllib.trainer import sampled_count
from robot_rl.agents.sb3.params import NetworkParams
from robot_rl.params import DeepAgentParams

pytestmark = [pytest.mark.deep, pytest.mark.ray]  # RLlib (requirements-distributed.txt) on torch

AGENT = find_agent("rllib_ppo")


def config(params=None, envs=3, action_space=None):
    params = params or AGENT.load_params()
    action_space = action_space or gymnasium.spaces.Discrete(5)
    return ppo_config(params, "robot_rl_task", {"x": 1}, gymnasium.spaces.Box(-1.0, 1.0, (6,), np.float32),
                      action_space, envs, gamma=0.95, seed=7)


def test_the_yaml_becomes_rllib_s_ppo_config_on_the_new_api_stack():
    params = AGENT.load_params()
    assert isinstance(params, RllibPpoParams) and AGENT.config_for(ONE_DISK_WALK) == AGENT.config_path
    c = config(params.with_changes("test", rollout_fragment_length=200, batch_size=50, n_epochs=3, ent_coef=0.01))
    assert c.enable_rl_module_and_learner and c.enable_env_runner_and_connector_v2, "the new API stack"
    assert (c.num_env_runners, c.num_envs_per_env_runner, c.num_cpus_per_env_runner) == (3, 1, 1)
    assert c.num_learners == 0, "the learner on the driver"
    assert (c.rollout_fragment_length, c.train_batch_size_per_learner, c.minibatch_size, c.num_epochs) == \
        (200, 600, 50, 3), "one fragment of each runner per update"
    assert (c.gamma, c.lr, c.lambda_, c.clip_param, c.entropy_coeff, c.vf_loss_coeff, c.grad_clip) == \
        (0.95, params.learning_rate, params.gae_lambda, params.clip_range, 0.01, params.vf_coef, params.max_grad_norm)
    assert not c.use_kl_loss, "SB3's PPO has no KL penalty"
    model = c.model_config
    assert model["fcnet_hiddens"] == [params.hidden_units] * params.hidden_layers
    assert (model["fcnet_activation"], model["head_fcnet_hiddens"], model["vf_share_layers"]) == ("tanh", [], False)
    assert (c.seed, c.env, c.env_config) == (7, "robot_rl_task", {"x": 1})
    assert c.restart_failed_env_runners and c.max_num_env_runner_restarts == params.max_runner_restarts


def test_envs_per_runner_puts_that_many_envs_in_each_runner_s_vector_env(tmp_path):
    path = tmp_path / "rllib_ppo.yaml"
    path.write_text(AGENT.config_path.read_text().replace("envs_per_runner: 1 ", "envs_per_runner: 2 "))
    params = AGENT.load_params(path).with_changes("test", rollout_fragment_length=200)
    assert params.envs_per_runner == 2
    c = config(params, envs=6)
    assert (c.num_env_runners, c.num_envs_per_env_runner, c.gym_env_vectorize_mode) == (3, 2, "sync")
    assert (c.rollout_fragment_length, c.train_batch_size_per_learner) == (200, 1200), \
        "a fragment of every env per update, as SB3's n_steps x n_envs"
    with pytest.raises(ParamError, match=r"^agent rllib_ppo: envs:=3 is not a multiple of envs_per_runner 2$"):
        params.check_envs(3, False, "agent rllib_ppo")
    with pytest.raises(ParamError, match=r"envs_per_runner 2 needs backend:=direct"):
        params.check_envs(2, True, "agent rllib_ppo")
    params.check_envs(4, False, "agent rllib_ppo")
    spaces = {"action_space": gymnasium.spaces.Discrete(3),
              "observation_space": gymnasium.spaces.Box(-1.0, 1.0, (6,), np.float32)}
    envs = types.SimpleNamespace(num_envs=3, **spaces, **{f"single_{name}": space for name, space in spaces.items()})
    with pytest.raises(ParamError, match=r"^agent rllib_ppo on T: envs:=3 is not a multiple of envs_per_runner 2$"):
        AGENT.check_fit(envs, params, "agent rllib_ppo on T")  # the training node's check, before a run folder
    AGENT.check_fit(envs, AGENT.load_params(), "agent rllib_ppo on T")
    AGENT.load_params().check_envs(3, True, "agent rllib_ppo")  # one env per runner: any N, over ROS too
    path.write_text(AGENT.config_path.read_text().replace("envs_per_runner: 1 ", "envs_per_runner: 0 "))
    with pytest.raises(ParamError, match="envs_per_runner"):
        AGENT.load_params(path)


def test_an_unknown_key_or_a_bad_value_is_refused_in_one_line(tmp_path):
    path = tmp_path / "rllib_ppo.yaml"
    path.write_text(AGENT.config_path.read_text() + "num_env_runners: 4\n")
    with pytest.raises(ParamError, match=rf"^{re.escape(str(path))}: unknown parameter 'num_env_runners' "
                                         r"\(known: hidden_layers, "):
        AGENT.load_params(path)
    path.write_text(AGENT.config_path.read_text().replace("fragment_length: 1024", "fragment_length: 0"))
    with pytest.raises(ParamError, match="rollout_fragment_length") as error:
        AGENT.load_params(path)
    assert "\n" not in str(error.value)
    with pytest.raises(ParamError, match=r"batch_size 64 is more than the train batch \(rollout_fragment_length 16 x "
                                         r"2 envs\)$"):
        AGENT.load_params().with_changes("t", rollout_fragment_length=16).check_batch(2, "agent rllib_ppo")
    with pytest.raises(ParamError, match="acts in Discrete or Box spaces"):
        AGENT.load_params().check_action_space(gymnasium.spaces.MultiBinary(3), "agent rllib_ppo")


@pytest.mark.parametrize("agent", ["rllib_ppo", "ppo", "dqn", "sac"])
def test_the_network_keys_are_declared_once_for_rllib_and_sb3_with_the_same_bounds(tmp_path, agent):
    shared = ["hidden_layers", "hidden_units", "learning_rate", "reward_scale"]
    assert [f.name for f in dataclasses.fields(DeepAgentParams)] == shared
    spec = find_agent(agent)
    params = spec.load_params()
    assert isinstance(params, DeepAgentParams) and isinstance(params, RllibPpoParams | NetworkParams)
    assert [f.name for f in dataclasses.fields(params)][:4] == shared, "the YAML's keys, in their order"
    for f in dataclasses.fields(params)[:4]:
        assert f.metadata == next(g.metadata for g in dataclasses.fields(DeepAgentParams) if g.name == f.name), \
            f"{agent}'s {f.name}: the base's bounds and doc"
    path = tmp_path / f"{agent}.yaml"
    for key, value, expected in (("hidden_layers", 9, r"\[1, 8\]"), ("hidden_units", 0, r"\[1, 4096\]"),
                                 ("learning_rate", 0.0, r"\(0.0, 1.0\]"), ("reward_scale", 0.0, r"\(0.0, 1000000.0\]")):
        path.write_text(repr(params.to_mapping() | {key: value}).replace("'", '"'))
        with pytest.raises(ParamError, match=rf"^{re.escape(str(path))}: parameter '{key}' = {value!r} out of range "
                                             rf"{expected}$"):
            spec.load_params(path)


def test_the_agent_is_registered_with_weights_only_checkpoints():
    from robot_rl.agents.registry import main
    assert "rllib_ppo" in AGENTS and AGENT.needs_deep and AGENT.own_envs and AGENT.needs_ray
    assert [main(["needs-ray", name]) for name in ("rllib_ppo", "ppo", "x")] == [0, 1, 1], "./ws installs Ray for it"
    assert AGENT.results_name(ONE_DISK_WALK) == "moving_cube-rllib_ppo" and AGENT.checkpoint_name == "agent.json"


def ended(runner, steps):
    return {"runner": runner, "env": runner - 1, "node": "127.0.0.1", "node_id": "n", "steps": steps,
            "return_": float(steps), "terminated": False, "duration": 0.1, "info": {}}


def test_episodes_go_in_by_runner_each_runner_s_in_the_order_they_ended():
    batches = [[ended(2, 5), ended(2, 3)], [ended(1, 7), ended(1, 2)], [], [ended(3, 1)]]  # one batch per runner
    order = [(e.runner, e.steps) for e in in_order(batches)]
    assert order == [(1, 7), (1, 2), (2, 5), (2, 3), (3, 1)]
    assert [(e.runner, e.steps) for e in in_order(batches[::-1])] == order, \
        "the order the runners' answers arrive in changes nothing"


def torch_module(action_space):
    c = config(envs=1, action_space=action_space)
    spec = dataclasses.replace(c.get_default_rl_module_spec(), observation_space=c.observation_space,
                               action_space=action_space, model_config=c.model_config)
    return spec.build()


@pytest.mark.parametrize("action_space", [gymnasium.spaces.Discrete(5),
                                          gymnasium.spaces.Box(np.array([-2.0, 0.0], np.float32),
                                                               np.array([2.0, 1.0], np.float32))],
                         ids=["discrete", "box"])
def test_the_numpy_policy_acts_as_rllib_s_module_greedily(tmp_path, action_space):
    import torch
    module = torch_module(action_space)
    weights = {k: v.detach().numpy() for k, v in module.state_dict().items()}
    digest = save_weights(tmp_path / "rllib_module.npz", weights)
    policy = NumpyPpoPolicy(load_weights(tmp_path / "rllib_module.npz", digest, tmp_path / "agent.json"),
                            action_space, "test")
    rng = np.random.default_rng(0)
    for _ in range(20):
        observation = rng.uniform(-1.0, 1.0, 6).astype(np.float32)
        with torch.no_grad():
            out = module.forward_inference({"obs": torch.as_tensor(observation[None])})["action_dist_inputs"][0]
        if isinstance(action_space, gymnasium.spaces.Discrete):
            assert policy(observation) == int(torch.argmax(out))
        else:
            mean = np.clip(out[:2].numpy(), -1.0, 1.0)
            expected = action_space.low + (mean + 1.0) * (action_space.high - action_space.low) / 2.0
            action = policy(observation)
            assert action_space.contains(action) and np.allclose(action, expected, atol=1e-5)


@pytest.mark.parametrize("action_space", [gymnasium.spaces.Discrete(5),
                                          gymnasium.spaces.Box(np.array([-2.0, 0.0], np.float32),
                                                               np.array([2.0, 1.0], np.float32))],
                         ids=["discrete", "box"])
def test_the_runners_module_samples_its_own_actions_from_the_distribution_ppo_s_loss_uses(action_space):
    import torch
    from ray.rllib.core.columns import Columns

    from robot_rl.agents.rllib.module import LeanPPOTorchRLModule
    c = config(envs=1, action_space=action_space)
    runner_side = c.get_rl_module_spec(inference_only=True).build()
    assert isinstance(runner_side, LeanPPOTorchRLModule), "the config gives the runners the lean module"
    learner_side = torch_module(action_space)  # RLlib's default PPO module, the same layers
    learner_side.load_state_dict(runner_side.state_dict(), strict=False)
    observations = torch.as_tensor(np.random.default_rng(0).uniform(-1.0, 1.0, (4, 6)).astype(np.float32))
    torch.manual_seed(0)
    out = runner_side.forward_exploration({Columns.OBS: observations})
    inputs = out[Columns.ACTION_DIST_INPUTS]
    assert torch.allclose(inputs, learner_side.forward_exploration({Columns.OBS: observations})
                          [Columns.ACTION_DIST_INPUTS]), "the same forward pass as RLlib's module"
    distribution = learner_side.get_train_action_dist_cls().from_logits(inputs)
    assert torch.allclose(out[Columns.ACTION_LOGP], distribution.logp(out[Columns.ACTIONS]), atol=1e-5), \
        "the log-probability PPO's loss divides by is the one its distribution gives"
    draws = torch.stack([runner_side.forward_exploration({Columns.OBS: observations[:1]})[Columns.ACTIONS][0]
                         for _ in range(4000)])
    if isinstance(action_space, gymnasium.spaces.Discrete):
        frequencies = torch.bincount(draws, minlength=action_space.n).float() / len(draws)
        assert torch.allclose(frequencies, torch.softmax(inputs[0], -1), atol=0.03)
    else:
        mean, log_std = inputs[0].chunk(2)
        assert torch.allclose(draws.mean(0), mean, atol=0.06) and torch.allclose(draws.std(0), log_std.exp(),
                                                                                 rtol=0.06)


def test_a_weights_file_that_is_not_the_recorded_one_is_refused(tmp_path):
    path = tmp_path / "rllib_module.npz"
    digest = save_weights(path, {"a": np.zeros(3)})
    with pytest.raises(RunFileError, match="its sha256 differs"):
        load_weights(path, "0" * 64, tmp_path / "agent.json")
    with pytest.raises(RunFileError, match="records no weights_sha256"):
        load_weights(path, None, tmp_path / "agent.json")
    path.write_bytes(path.read_bytes()[:20])
    with pytest.raises(RunFileError, match="its sha256 differs"):
        load_weights(path, digest, tmp_path / "agent.json")
    with pytest.raises(RunFileError, match="no actor of RLlib's PPO module"):
        NumpyPpoPolicy({"a": np.zeros(3)}, gymnasium.spaces.Discrete(2), "test")


def gradients_with(rng, special=None):
    """Gradient-like tensors of a few shapes; `special` puts nan or inf into the second one."""
    import torch
    tensors = [torch.as_tensor(rng.normal(0.0, scale, shape).astype(np.float32))
               for scale, shape in ((3.0, (6, 4)), (0.5, (4,)), (2.0, (4, 2)))]
    if special is not None:
        tensors[1][2] = special
    return tensors


@pytest.mark.parametrize("special", [None, float("nan"), float("inf")], ids=["finite", "nan", "inf"])
@pytest.mark.parametrize("grad_clip", [0.5, 1000.0], ids=["clipped", "unclipped"])
def test_the_fused_clipping_gives_rllib_s_norm_and_gradients(special, grad_clip):
    import torch
    from ray.rllib.utils.torch_utils import clip_gradients

    from robot_rl.agents.rllib.learner import clip_by_global_norm
    ours, theirs = ({i: g for i, g in enumerate(gradients_with(np.random.default_rng(1), special))} for _ in range(2))
    norm = clip_by_global_norm(ours, grad_clip=grad_clip, grad_clip_by="global_norm")
    assert torch.allclose(norm, clip_gradients(theirs, grad_clip=grad_clip, grad_clip_by="global_norm"))
    for i in theirs:
        assert torch.allclose(ours[i], theirs[i], equal_nan=True, rtol=1e-5), f"gradient {i}"


@pytest.mark.parametrize("special", [None, float("nan"), float("inf")], ids=["finite", "nan", "inf"])
def test_the_learner_clips_and_applies_gradients_as_rllib_s_ppo_learner_does(special):
    import torch
    from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner

    from robot_rl.agents.rllib.learner import LeanPPOTorchLearner
    c = config(envs=1)
    ours = c.build_learner()
    assert type(ours) is LeanPPOTorchLearner, "the config gives the driver the lean learner"
    theirs = c.copy(copy_frozen=False).learners(learner_class=PPOTorchLearner).build_learner()
    module = next(iter(ours.module.keys()))
    theirs.module[module].load_state_dict(ours.module[module].state_dict())
    for learner in (ours, theirs):
        rng = np.random.default_rng(2)
        gradients = {}
        for pid, parameter in learner._params.items():
            parameter.grad = torch.as_tensor(rng.normal(0.0, 2.0, tuple(parameter.shape)).astype(np.float32))
            gradients[pid] = parameter.grad
        if special is not None:
            next(iter(gradients.values())).view(-1)[3] = special
        learner.apply_gradients(learner.postprocess_gradients(gradients))
    for (name, a), b in zip(ours.module[module].named_parameters(), theirs.module[module].parameters()):
        assert torch.isfinite(a).all() and torch.allclose(a, b, atol=1e-6), f"{name} after one Adam step"


def test_the_module_runs_exploration_in_eval_mode_training_in_train_mode_and_refuses_dropout():
    import torch
    from ray.rllib.core.columns import Columns

    from robot_rl.agents.rllib.module import LeanPPOTorchRLModule
    spec = config(envs=1).get_rl_module_spec()
    module = spec.build()
    observations = torch.zeros((2, 6))
    module.forward_exploration({Columns.OBS: observations})
    assert not any(layer.training for layer in module.modules()), "exploration in eval mode, every layer"
    module.forward_train({Columns.OBS: observations})
    assert all(layer.training for layer in module.modules()), "training in train mode, every layer"

    class WithDropout(LeanPPOTorchRLModule):
        def setup(self):
            self.noise = torch.nn.Dropout(0.1)
            super().setup()
    with pytest.raises(ValueError, match=r"cannot hold \['Dropout'\]"):
        dataclasses.replace(spec, module_class=WithDropout).build()


def test_an_update_s_steps_count_as_0_when_rllib_reports_nan_after_a_lost_runner():
    assert sampled_count(4096.0) == 4096 and sampled_count(0) == 0 and sampled_count(float("nan")) == 0
