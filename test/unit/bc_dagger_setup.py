"""What test_bc_dagger.py and test_bc_dagger_resume.py share: the agent, and the `env` fixture (task end_to_end on
the direct backend, seed 0, closed after the test). A test module takes the fixture by importing
`end_to_end_env`; its tests ask for `env`."""
import pytest

from hopper_training.envs.end_to_end import END_TO_END
from robot_rl import AGENTS, make_env

AGENT = AGENTS["bc_dagger"]


@pytest.fixture(name="env")
def end_to_end_env():
    made = make_env(END_TO_END, backend="direct", seed=0)
    yield made
    made.close()
