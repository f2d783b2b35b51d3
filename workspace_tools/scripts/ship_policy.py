#!/usr/bin/env python3
"""Ship a trained run into the repository: its checkpoint, params and results, a deep run's model.zip with
its weights only or a bc_dagger run's student (workspace_tools.ship): loaded back before it replaces the destination
folder whole.

  ship_policy.py RUN DESTINATION
  e.g. ./ws exec rosrun workspace_tools ship_policy.py training_results/residual_forward-sac/sac_s0 \
           hopper_training/policies/residual_forward_sac
       ./ws exec rosrun workspace_tools ship_policy.py training_results/end_to_end-bc_dagger/s0 \
           hopper_training/policies/end_to_end
       ./ws exec rosrun workspace_tools ship_policy.py training_results/hop_in_place/s0/qtable_best.json \
           hopper_training/policies/hop_in_place_push075    # the table the checks kept (params' selection)
"""
import argparse
import sys
from pathlib import Path

from workspace_tools.ship import ship_run


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("run", type=Path, help="a run folder (training_results/<task>/<run>) or its latest link; a "
                        "tabular run's qtable_best.json: the table its checks kept")
    parser.add_argument("destination", type=Path, help="the folder to write, e.g. <package>/policies/<name>")
    args = parser.parse_args(argv)
    try:
        names = ship_run(args.run, args.destination)
    except (OSError, ValueError) as error:
        print(f"ship_policy.py: {error}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as error:  # a deep run is loaded back before it ships: torch and SB3
        print(f"ship_policy.py: loading the policy back needs {error.name}: ./ws setup deep", file=sys.stderr)
        return 1
    print(f"wrote {', '.join(names)} to {args.destination}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
