"""Runs every rostest file of test/rostest/ (each starts its own master on a free port)."""
import pytest

from workspace_tools.paths import REPO, ROSTESTS
from workspace_tools.processes import Processes

TEST_FILES = sorted(ROSTESTS.glob("*.test"))


@pytest.mark.parametrize("test_file", TEST_FILES, ids=[f.stem for f in TEST_FILES])
def test_rostest(test_file, tmp_path):
    runner = Processes(tmp_path, cwd=REPO)
    try:
        result = runner.run(["rostest", str(test_file.relative_to(REPO))], timeout=600)
    finally:
        runner.close()
    results = "\n".join(p.read_text() for p in sorted(tmp_path.glob("test_results/**/*.xml")))
    assert result.returncode == 0, f"{result.stdout[-4000:]}\n{result.stderr[-2000:]}\n{results[-4000:]}"
