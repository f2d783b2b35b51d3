#!/usr/bin/env python3
"""roslaunch a file and exit with the first non-zero exit code of any of its nodes.

  roslaunch_checked.py [PACKAGE] LAUNCH_FILE [arg:=value ...]

Plain roslaunch exits 0 even when a required node (here: a training node) failed; ./ws run uses
this so that a failed training is a failed command. Starts a master if none is running, as
roslaunch does.
"""
import sys

import roslaunch
import roslaunch.parent
import roslaunch.pmon
import roslaunch.rlutil


class FailedNodes(roslaunch.pmon.ProcessListener):
    def __init__(self):
        self.exit_codes = []

    def process_died(self, process_name, exit_code):
        if exit_code:
            self.exit_codes.append(exit_code)


def main(argv) -> int:
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    launch_file = roslaunch.rlutil.resolve_launch_arguments(argv)[0]
    launch_args = [arg for arg in argv if ":=" in arg]
    uuid = roslaunch.rlutil.get_or_generate_uuid(None, False)
    roslaunch.configure_logging(uuid)
    failed = FailedNodes()
    parent = roslaunch.parent.ROSLaunchParent(uuid, [(launch_file, launch_args)], process_listeners=[failed])
    parent.start()
    try:
        parent.spin()
    finally:
        parent.shutdown()
    return failed.exit_codes[0] if failed.exit_codes else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
