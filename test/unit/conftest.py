"""Shared fixtures for the unit tests: the moving cube's sim YAML and URDF."""
import copy
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
CUBE_SIM_YAML = ROOT / "config" / "moving_cube_sim.yaml"
CUBE_URDF = ROOT / "moving_cube_description" / "urdf" / "moving_cube.urdf"

_CUBE_PARAMS = yaml.safe_load(CUBE_SIM_YAML.read_text())
_CUBE_URDF_TEXT = CUBE_URDF.read_text()


@pytest.fixture
def cube_params():
    """A fresh, freely mutable copy of config/moving_cube_sim.yaml as a dict."""
    return copy.deepcopy(_CUBE_PARAMS)


@pytest.fixture
def cube_urdf():
    """The moving cube's URDF text."""
    return _CUBE_URDF_TEXT
