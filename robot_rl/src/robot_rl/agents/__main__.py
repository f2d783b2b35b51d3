"""python -m robot_rl.agents needs-deep|needs-ray NAME: exit 0 if agent NAME needs requirements-deep.txt
(requirements-distributed.txt) (./ws)."""
import sys

from .registry import main

sys.exit(main(sys.argv[1:]))
