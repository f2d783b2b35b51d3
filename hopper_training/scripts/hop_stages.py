#!/usr/bin/env python3
"""The hopping controller's staged validation (docs/guide/hopping.md), in-process on PyBullet, no ROS.

  hop_stages.py [--stage vertical|in_place|forward|push|all] [--episodes 20] [--seed 0] [--duration 10]
                [--speed 0.4] [--push 0.5] [--control-period 0.001] [--apex-target M] [--sim-config PATH]

1 vertical: the base on a vertical slider (the sim config's base_constraint: vertical), one trial:
  apex height mean and spread after the first second. 2 in_place: free 3D hopping from a lean of
  0.02-0.05 rad in a random direction (drawn from --seed), --episodes trials. 3 forward: the same,
  commanded --speed m/s along +x: mean speed over the last 5 s. 4 push: in place, kicked --push m/s in a
  random horizontal direction at 4 s. Each stage prints one line: {"stage": ..., figures}.
"""
import argparse
import json
import sys
from pathlib import Path

from hopper_training.controller.core import HopGains
from hopper_training.controller.trials import StageSettings, stage_free, stage_vertical
from hopper_training.robot import MONOPED

STAGES = ("vertical", "in_place", "forward", "push")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="hop_stages.py", description=__doc__.splitlines()[0])
    parser.add_argument("--stage", choices=(*STAGES, "all"), default="all")
    parser.add_argument("--episodes", type=int, default=20, help="trials of the free stages (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="seeds the starts, kicks and sensor noise (default 0)")
    parser.add_argument("--duration", type=float, default=10.0, help="sim seconds per trial (default 10)")
    parser.add_argument("--speed", type=float, default=0.4, help="the forward stage's commanded m/s (default 0.4)")
    parser.add_argument("--push", type=float, default=0.5, help="the push stage's kick in m/s (default 0.5)")
    parser.add_argument("--control-period", type=float, default=0.001, help="sim s between commands (default 0.001)")
    parser.add_argument("--apex-target", type=float, default=0.0,
                        help="base height at the apex that the thrust adapts to, m (default 0: a fixed thrust)")
    parser.add_argument("--sim-config", type=Path, default=MONOPED.sim_config_path,
                        help="the robot's sim config (default hopper_description/config/hopper_sim.yaml)")
    args = parser.parse_args(argv)
    if args.episodes < 1 or not args.duration > 0.0 or not args.control_period > 0.0:
        parser.error("--episodes must be >= 1, --duration and --control-period > 0")
    if args.apex_target < 0.0:
        parser.error("--apex-target must be >= 0")
    if not args.sim_config.is_file():
        parser.error(f"--sim-config {args.sim_config}: no such file")
    settings = StageSettings(urdf=MONOPED.urdf_path, sim_config=args.sim_config, episodes=args.episodes,
                             duration=args.duration, seed=args.seed, control_period=args.control_period,
                             gains=HopGains(apex_target=args.apex_target))
    for stage in STAGES if args.stage == "all" else (args.stage,):
        if stage == "vertical":
            figures = stage_vertical(settings)
        elif stage == "in_place":
            figures = stage_free(settings)
        elif stage == "forward":
            figures = stage_free(settings, speed=(args.speed, 0.0))
        else:
            figures = stage_free(settings, push=args.push)
        print(json.dumps(figures), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
