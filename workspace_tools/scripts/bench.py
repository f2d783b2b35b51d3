#!/usr/bin/env python3
"""./ws bench: the speed benchmark on the real nodes (workspace_tools.bench.main)."""
import sys

from workspace_tools.bench.main import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
