"""PyBullet stand-in for Gazebo: the World and its parts (no ROS) here, the sim node and its client in .ros."""
from pkgutil import extend_path

# The generated msg and srv modules live in the devel (or install) space's pybullet_sim. catkin's
# generated __init__ there joins this folder to it; this joins it the other way round, for a process
# whose sys.path lists this folder first (a multiprocessing "spawn" child inherits such a sys.path).
__path__ = extend_path(__path__, __name__)
