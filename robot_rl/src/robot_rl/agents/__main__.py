"""python -m robot_rl.agents needs-deep NAME: exit 0 if agent NAME needs requirements-deep.txt (./ws)."""
import sys

from .registry import main

sys.exit(main(sys.argv[1:]))
