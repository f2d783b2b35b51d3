"""One gymnasium for everything: the version pinned in requirements.txt is the one installed, the one RLlib
pins exactly and one that Stable-Baselines3 accepts (docs/guide/training.md, "One gymnasium")."""
import importlib.metadata as metadata
import re
from pathlib import Path

import pytest
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[2]


def pinned(file: str, name: str) -> str:
    for line in (ROOT / file).read_text().splitlines():
        match = re.fullmatch(rf"{re.escape(name)}(\[[^]]*\])?==(\S+)", line.strip())
        if match:
            return match.group(2)
    raise AssertionError(f"{file} pins no {name}")


def requirement_of(package: str, name: str, extra: str = "") -> Requirement:
    for text in metadata.requires(package) or ():
        requirement = Requirement(text)
        wanted = {"extra": extra} if extra else {"extra": ""}
        if requirement.name == name and (requirement.marker is None or requirement.marker.evaluate(wanted)):
            return requirement
    raise AssertionError(f"{package} does not require {name}" + (f" with [{extra}]" if extra else ""))


def test_the_pinned_gymnasium_is_installed():
    assert metadata.version("gymnasium") == pinned("requirements.txt", "gymnasium")


@pytest.mark.deep
def test_stable_baselines3_accepts_the_pinned_gymnasium():
    assert metadata.version("stable_baselines3") == pinned("requirements-deep.txt", "stable-baselines3")
    assert requirement_of("stable_baselines3", "gymnasium").specifier.contains(pinned("requirements.txt", "gymnasium"))


@pytest.mark.ray
def test_rllib_pins_the_same_gymnasium():
    assert metadata.version("ray") == pinned("requirements-distributed.txt", "ray")
    assert str(requirement_of("ray", "gymnasium", extra="rllib").specifier) == "==" + pinned("requirements.txt",
                                                                                           "gymnasium")
