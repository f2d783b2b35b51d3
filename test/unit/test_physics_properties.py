"""pybullet_sim.physics_properties: Gazebo's set_physics_properties checked and mapped (no ROS)."""
import math

import pytest

from pybullet_sim.physics_properties import (
    OdeConfig,
    PhysicsProperties,
    check,
    not_honoured,
    real_time_factor,
    solver_settings,
)
from pybullet_sim.world import SolverSettings

# The tutorials' GazeboConnection.init_values
TUTORIAL_ODE = OdeConfig(auto_disable_bodies=False, sor_pgs_precon_iters=0, sor_pgs_iters=50, sor_pgs_w=1.3,
                         sor_pgs_rms_error_tol=0.0, contact_surface_layer=0.001, contact_max_correcting_vel=0.0,
                         cfm=0.0, erp=0.2, max_contacts=20)
TUTORIAL = PhysicsProperties(0.001, 1000.0, (0.0, 0.0, -9.81), TUTORIAL_ODE)


def test_the_tutorials_request_is_accepted_and_maps_onto_pybullets_solver():
    assert check(TUTORIAL) == ""
    assert solver_settings(TUTORIAL_ODE) == SolverSettings(iterations=50, residual_threshold=0.0, erp=0.2, cfm=0.0)
    assert real_time_factor(1000.0, 0.001) == 1.0
    assert real_time_factor(0.0, 0.001) == 0.0  # Gazebo: as fast as possible


def test_what_pybullet_cannot_honour_is_named():
    assert set(not_honoured(TUTORIAL_ODE)) == {"sor_pgs_w", "contact_surface_layer", "contact_max_correcting_vel",
                                               "max_contacts"}
    assert "over-relaxation" in not_honoured(TUTORIAL_ODE)["sor_pgs_w"]
    asked_more = OdeConfig(auto_disable_bodies=True, sor_pgs_precon_iters=5)
    assert {"auto_disable_bodies", "sor_pgs_precon_iters"} <= set(not_honoured(asked_more))
    assert "sor_pgs_w" not in not_honoured(OdeConfig())  # w = 1 is what PyBullet does


@pytest.mark.parametrize("changes, field", [
    (dict(time_step=math.nan), "time_step"),
    (dict(time_step=0.0), "time_step"),
    (dict(time_step=math.inf), "time_step"),
    (dict(max_update_rate=-1.0), "max_update_rate"),
    (dict(max_update_rate=math.nan), "max_update_rate"),
    (dict(gravity=(0.0, math.inf, 0.0)), "gravity"),
    (dict(ode=OdeConfig(sor_pgs_iters=0)), "sor_pgs_iters"),
    (dict(ode=OdeConfig(sor_pgs_iters=10_000)), "sor_pgs_iters"),
    (dict(ode=OdeConfig(erp=1.5)), "erp"),
    (dict(ode=OdeConfig(cfm=-1.0)), "cfm"),
    (dict(ode=OdeConfig(sor_pgs_w=math.nan)), "sor_pgs_w"),
    (dict(ode=OdeConfig(contact_surface_layer=math.inf)), "contact_surface_layer"),
])
def test_a_bad_number_refuses_the_request_naming_it(changes, field):
    request = PhysicsProperties(**{**TUTORIAL.__dict__, **changes})
    assert field in check(request)
