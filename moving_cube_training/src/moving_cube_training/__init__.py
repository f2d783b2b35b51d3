"""The moving cube's training: CubeRLUtils (seed 000), the MovingCubeOneDiskWalk-v0 env, Q-learning.

Importing this package registers MovingCubeOneDiskWalk-v0 with gymnasium:
`gymnasium.make("MovingCubeOneDiskWalk-v0", backend="ros" | "direct")`.
"""
import gymnasium

ENV_ID = "MovingCubeOneDiskWalk-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="moving_cube_training.one_disk_walk:MovingCubeOneDiskWalkEnv")
