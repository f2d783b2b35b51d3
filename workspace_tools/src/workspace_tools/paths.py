"""Where the tests find the files of the source checkout: the repository root, the rostest files with their
nodes, and the helper programs that the pytest tests run as processes of their own. Valid where this module
is loaded from the checkout (./ws, a catkin devel space), not from an install space."""
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]  # this file is REPO/workspace_tools/src/workspace_tools/paths.py
ROSTESTS = REPO / "test" / "rostest"
PROGRAMS = REPO / "test" / "programs"
