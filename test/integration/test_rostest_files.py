"""Runs every rostest file in this folder (each starts its own master on a free port)."""
from pathlib import Path

import pytest

from conftest import REPO, Processes

TEST_FILES = sorted(Path(__file__).parent.glob("*.test"))


@pytest.mark.parametrize("test_file", TEST_FILES, ids=[f.stem for f in TEST_FILES])
def test_rostest(test_file, tmp_path):
    runner = Processes(tmp_path, cwd=REPO)
    try:
        result = runner.run(["rostest", str(test_file.relative_to(REPO))], timeout=600)
    finally:
        runner.close()
    results = "\n".join(p.read_text() for p in sorted(tmp_path.glob("test_results/**/*.xml")))
    assert result.returncode == 0, f"{result.stdout[-4000:]}\n{result.stderr[-2000:]}\n{results[-4000:]}"
