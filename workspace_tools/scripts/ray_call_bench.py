#!/usr/bin/env python3
"""The round trip of a trivial Ray actor method (workspace_tools.bench.ray_calls)."""
import sys

from workspace_tools.bench.ray_calls import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
