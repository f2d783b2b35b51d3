#!/usr/bin/env python3
"""The course's comparison: every agent on one task, at the same number of env steps (workspace_tools.compare)."""
import sys

from workspace_tools.compare import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
