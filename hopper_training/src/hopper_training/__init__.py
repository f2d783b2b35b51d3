"""The monoped hopper's training: MonopedState and JointPub (seed 001), Monoped-v0, Q-learning.

Importing this package registers Monoped-v0 with gymnasium:
`gymnasium.make("Monoped-v0", backend="ros" | "direct")`.
"""
import gymnasium

ENV_ID = "Monoped-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="hopper_training.monoped_env:MonopedEnv")
