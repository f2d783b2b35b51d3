"""Shared fixtures for the unit tests: the moving cube's sim YAML and URDF."""
import copy
import tempfile

import pytest
import yaml

from moving_cube_training.robot import MOVING_CUBE

_CUBE_PARAMS = yaml.safe_load(MOVING_CUBE.sim_config_path.read_text())
_CUBE_URDF_TEXT = MOVING_CUBE.urdf_path.read_text()


@pytest.fixture
def cube_params():
    """A fresh, freely mutable copy of moving_cube_description/config/moving_cube_sim.yaml as a dict."""
    return copy.deepcopy(_CUBE_PARAMS)


@pytest.fixture
def cube_urdf():
    """The moving cube's URDF text."""
    return _CUBE_URDF_TEXT


@pytest.fixture(autouse=True)
def temporary_files_in_tmp_path(tmp_path, monkeypatch):
    """Temporary folders a test leaves on purpose (a failed vector env keeps its workers' logs) go to
    pytest's tmp_path, not /tmp."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
