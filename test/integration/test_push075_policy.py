"""The shipped Q-table trained with 0.75 m/s pushes (hopper_training/policies/hop_in_place_push075: the table the
checks kept, training seed 0) against the best constant placement, through evaluate.py on the direct backend, on
evaluation seed 1000 (20 episodes of 10 s, leaning starts): issue 39's tabular line, at least 60 % upright the whole
10 s and 20 points above the constant +2 cm."""
import json
import subprocess

from workspace_tools.paths import REPO

POLICY = REPO / "hopper_training" / "policies" / "hop_in_place_push075"
EVALUATION = ["--seed", "1000", "--push", "0.75", "--episodes", "20"]


def evaluate(*args):
    result = subprocess.run([str(REPO / "ws"), "exec", "rosrun", "hopper_training", "evaluate.py", *args, *EVALUATION],
                            capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_the_pushed_table_keeps_up_20_points_more_than_the_best_constant():
    learned = evaluate("--run", str(POLICY))
    constant = evaluate("--policy", "constant", "--action", "2", "--task", "hop_in_place")
    assert (learned["push"], learned["horizon_s"], constant["push"]) == (0.75, 10.0, 0.75)
    learned_rate = learned["greedy"]["upright_whole_horizon_rate"]
    constant_rate = constant["constant"]["upright_whole_horizon_rate"]
    assert learned_rate >= 0.6 and learned_rate >= constant_rate + 0.2, (learned_rate, constant_rate)
    assert learned["random"]["upright_whole_horizon_rate"] < learned_rate
