"""Our own clients that call the sim's Gazebo and ros_control services the way the tutorials' helpers do,
for the rostest nodes test/rostest/gazebo_services_*_node.py (here so that catkin's relays of those nodes
can import it).

GazeboConnection and ControllersConnection of the tutorials (moving_cube_training, my_hopper_training,
openai_ros) make these calls in this order; these classes make the same calls with the same request
values, written from the interface descriptions in shared/reference/original_interfaces.md (section C).
One difference, on purpose: every wait here is bounded (the tutorials wait forever) and a failed call
raises instead of being printed.
"""
import rospy
from geometry_msgs.msg import Vector3
from std_srvs.srv import Empty

from controller_manager_msgs.srv import SwitchController, SwitchControllerRequest
from gazebo_msgs.msg import ODEPhysics
from gazebo_msgs.srv import SetPhysicsProperties, SetPhysicsPropertiesRequest

TIMEOUT = 10.0
# The physics the tutorials' GazeboConnection.init_values sends (time step 1 ms, 1000 updates per second).
TUTORIAL_ODE = dict(auto_disable_bodies=False, sor_pgs_precon_iters=0, sor_pgs_iters=50, sor_pgs_w=1.3,
                    sor_pgs_rms_error_tol=0.0, contact_surface_layer=0.001, contact_max_correcting_vel=0.0,
                    cfm=0.0, erp=0.2, max_contacts=20)


def _proxy(name, srv_type):
    try:
        rospy.wait_for_service(name, TIMEOUT)
    except rospy.ROSException:
        raise AssertionError(f"service {name} is not available after {TIMEOUT} s; is the sim running?") from None
    return rospy.ServiceProxy(name, srv_type)


class GazeboConnection:
    """pause / unpause / reset / gravity as the tutorials' GazeboConnection does them."""

    def __init__(self, gravity=(0.0, 0.0, -9.81)):
        self.pause = _proxy("/gazebo/pause_physics", Empty)
        self.unpause = _proxy("/gazebo/unpause_physics", Empty)
        self.reset_simulation = _proxy("/gazebo/reset_simulation", Empty)
        self.reset_world = _proxy("/gazebo/reset_world", Empty)
        self.set_physics = _proxy("/gazebo/set_physics_properties", SetPhysicsProperties)
        self.request = SetPhysicsPropertiesRequest(time_step=0.001, max_update_rate=1000.0,
                                                   gravity=Vector3(*gravity), ode_config=ODEPhysics(**TUTORIAL_ODE))
        self.init_values()

    def init_values(self):
        """Construction: reset the simulation, send the physics, then unpause and pause (openai_ros)."""
        self.reset_simulation()
        self.update_gravity_call()
        self.pause()

    def update_gravity_call(self):
        """pause -> set_physics_properties -> unpause, as the tutorials do around every physics change."""
        self.pause()
        response = self.set_physics(self.request)
        assert response.success, f"set_physics_properties failed: {response.status_message}"
        self.unpause()

    def change_gravity(self, x, y, z):
        self.request.gravity = Vector3(x, y, z)
        self.update_gravity_call()


class ControllersConnection:
    """reset_controllers: switch every controller off, then on again, BEST_EFFORT (strictness 1)."""

    def __init__(self, namespace, controllers):
        self.controllers = list(controllers)
        self.switch = _proxy(f"/{namespace}/controller_manager/switch_controller", SwitchController)

    def switch_controllers(self, start, stop, strictness=SwitchControllerRequest.BEST_EFFORT):
        return self.switch(SwitchControllerRequest(start_controllers=start, stop_controllers=stop,
                                                   strictness=strictness)).ok

    def reset_controllers(self):
        assert self.switch_controllers([], self.controllers), "switching the controllers off failed"
        assert self.switch_controllers(self.controllers, []), "switching the controllers on failed"

    def reset_controllers_as_the_tutorials_wrote_it(self):
        """Their switch_controllers assigns start_controllers twice, the second time the "off" list, and never
        sets stop_controllers (defect 13): the off call starts every controller, the on call starts none."""
        return self.switch_controllers(self.controllers, []) and self.switch_controllers([], [])
