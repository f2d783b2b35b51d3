#!/usr/bin/env python3
"""Write docs/reference/tasks.md, the tasks' reference, from the registered task specs (workspace_tools.tasks_doc)."""
import sys

from workspace_tools.tasks_doc import main

if __name__ == "__main__":
    sys.exit(main())
