#!/usr/bin/env python3
"""Train MonopedEndToEnd-v0's student from the hopping controller (agent bc_dagger: BC, then DAgger) on the
direct backend, no ROS: what `./ws run hopper task:=end_to_end agent:=bc_dagger` does over the sim node.

  rosrun hopper_training train_end_to_end.py [--seed 0] [--run NAME] [--results-dir training_results] [--config YAML]

--config: the task's params, e.g. hopper_training/config/end_to_end_push.yaml (pushes in training) or
end_to_end_forward.yaml (hop forward at 0.4 m/s); default the task's end_to_end.yaml.

The run goes to RESULTS_DIR/end_to_end-bc_dagger/NAME (default: the UTC time); evaluate.py --run plays it.
"""
import argparse
import sys
from pathlib import Path

from hopper_training.envs.end_to_end import END_TO_END
from robot_rl import AGENTS, ParamError, RunDirectory, TrainingHooks, make_env


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seeds the sim, the data collection and the network")
    parser.add_argument("--run", help="the run's folder name (default: the UTC time)")
    parser.add_argument("--results-dir", default="training_results", help="where runs go (default training_results)")
    parser.add_argument("--config", help="the task's params (YAML; default the task's end_to_end.yaml)")
    args = parser.parse_args(argv)
    try:
        params = END_TO_END.load_params(Path(args.config)) if args.config else END_TO_END.default_params()
    except ParamError as e:
        print(f"train_end_to_end.py: {e}", file=sys.stderr)
        return 2
    agent, params = AGENTS["bc_dagger"], params.with_changes("--seed", seed=args.seed)
    env = make_env(END_TO_END, params=params, backend="direct", seed=args.seed)
    try:
        run = RunDirectory.create(args.results_dir, agent.results_name(END_TO_END), params.to_mapping(),
                                  END_TO_END.metric_names, run_name=args.run, checkpoint_name=agent.checkpoint_name)
        print(f"Results go to {run.path}", flush=True)
        hooks = TrainingHooks(log=lambda line: print(line, flush=True))
        trainer = agent.make_trainer(env, END_TO_END, params, run, hooks, agent_params=agent.load_params(),
                                     agent_config=agent.config_path)
        summary = trainer.train()
    finally:
        env.close()
    return 0 if summary["completed"] else 130


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
