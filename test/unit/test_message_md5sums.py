"""Our gazebo_msgs and controller_manager_msgs have upstream's md5sums, so Gazebo clients talk to our sim.

ROS compares these sums in every topic and service handshake: a client built against the real packages
refuses a peer whose sum differs. The expected values below are upstream's, copied from code generated
from the real packages and committed to public repositories, never computed from our own .msg files:

- [PY3] jmscslgroup/py3rosmsgs @ d3c48d686ab05fa0b13a15b0d139354298759dd5, genpy output of ROS Noetic's
  packages (gazebo_msgs/msg/_ContactsState.py, controller_manager_msgs/srv/_SwitchController.py, ...):
  the source of every value here.
- [TIAGO] LounesBenHamoudi/Tiago_ws @ f58a191f760d8609944417e78f0b40f81f1d318a,
  devel/.private/gazebo_msgs/lib/python3/dist-packages/gazebo_msgs/{msg,srv}/_*.py and the same for
  controller_manager_msgs: the same value for every gazebo_msgs type and for ControllerState,
  HardwareInterfaceResources, List/Load/UnloadController. (Its SwitchController predates start_asap and
  timeout: request 434da54a..., service 5e857ded...; noetic-devel's is the one below.)
- [ROSSERIAL] stanfordroboticsclub/StanfordQuadruped, dingo_nano/libraries/ros_lib (rosserial's Noetic
  headers): gazebo_msgs/ContactsState.h acbcb160..., controller_manager_msgs/SwitchController.h request
  36d99a97... (with start_asap and timeout) and response 6f6da388....
"""
import pytest

from controller_manager_msgs.msg import ControllerState, HardwareInterfaceResources
from controller_manager_msgs.srv import ListControllers, LoadController, SwitchController, UnloadController
from gazebo_msgs.msg import ContactsState, ContactState, LinkState, ModelState, ODEPhysics
from gazebo_msgs.srv import (
    GetLinkState,
    GetModelState,
    GetPhysicsProperties,
    GetWorldProperties,
    SetModelState,
    SetPhysicsProperties,
)

EMPTY = "d41d8cd98f00b204e9800998ecf8427e"  # md5 of an empty definition: an empty request

MESSAGES = [  # type, upstream md5sum, sources
    (ContactState, "48c0ffb054b8c444f870cecea1ee50d9"),  # PY3, TIAGO
    (ContactsState, "acbcb1601a8e525bf72509f18e6f668d"),  # PY3, TIAGO, ROSSERIAL
    (ODEPhysics, "667d56ddbd547918c32d1934503dc335"),  # PY3, TIAGO
    (ModelState, "9330fd35f2fcd82d457e54bd54e10593"),  # PY3, TIAGO
    (LinkState, "0818ebbf28ce3a08d48ab1eaa7309ebe"),  # PY3, TIAGO
    (ControllerState, "aeb6b261d97793ab74099a3740245272"),  # PY3, TIAGO
    (HardwareInterfaceResources, "f25b55cbf1d1f76e82e5ec9e83f76258"),  # PY3, TIAGO
]

SERVICES = [  # type, service md5sum, request md5sum, response md5sum
    (SetPhysicsProperties, "97e2057080558ce4730434b5fae75c91", "abd9f82732b52b92e9d6bb36e6a82452",
     "2ec6f3eff0161f4257b808b12bc830c2"),  # PY3, TIAGO
    (GetPhysicsProperties, "575a5e74786981b7df2e3afc567693a6", EMPTY, "575a5e74786981b7df2e3afc567693a6"),  # PY3, TIAGO
    (GetModelState, "4c515e936d3319c9610c559c60bfc3d4", "19d412713cefe4a67437e17a951e759e",
     "ccd51739bb00f0141629e87b792e92b9"),  # PY3, TIAGO
    (SetModelState, "5b3ab0281d4f5445def017e3a2e4a07b", "cb042b0e91880f4661b29ea5b6234350",
     "2ec6f3eff0161f4257b808b12bc830c2"),  # PY3, TIAGO
    (GetLinkState, "09d6c98cce97b35f7ab9bd70300657ab", "7551675c30aaa71f7c288d4864552001",
     "8ba55ad34f9c072e75c0de57b089753b"),  # PY3, TIAGO
    (GetWorldProperties, "36bb0f2eccf4d8be971410c22818ba3f", EMPTY, "36bb0f2eccf4d8be971410c22818ba3f"),  # PY3, TIAGO
    (SwitchController, "b29a7abc673b2c54c14b54e50f8d06a5", "36d99a977432b71d4bf16ce5847949d7",
     "6f6da3883749771fac40d6deb24a8c02"),  # PY3; request and response also ROSSERIAL
    (ListControllers, "1341feb2e63fa791f855565d0da950d8", EMPTY, "1341feb2e63fa791f855565d0da950d8"),  # PY3, TIAGO
    (LoadController, "647e5c54b8d6468952d8d31f1efe96c0", "c1f3d28f1b044c871e6eff2e9fc3c667",
     "6f6da3883749771fac40d6deb24a8c02"),  # PY3, TIAGO
    (UnloadController, "647e5c54b8d6468952d8d31f1efe96c0", "c1f3d28f1b044c871e6eff2e9fc3c667",
     "6f6da3883749771fac40d6deb24a8c02"),  # PY3, TIAGO
]


@pytest.mark.parametrize("msg_type, md5sum", MESSAGES, ids=[m[0]._type for m in MESSAGES])
def test_message_md5sum_is_upstreams(msg_type, md5sum):
    assert msg_type._md5sum == md5sum, f"{msg_type._type}: the definition differs from upstream's"


@pytest.mark.parametrize("srv_type, md5sum, request_md5sum, response_md5sum", SERVICES,
                         ids=[s[0]._type for s in SERVICES])
def test_service_md5sums_are_upstreams(srv_type, md5sum, request_md5sum, response_md5sum):
    assert (srv_type._md5sum, srv_type._request_class._md5sum, srv_type._response_class._md5sum) == \
        (md5sum, request_md5sum, response_md5sum), f"{srv_type._type}: the definition differs from upstream's"


def test_switch_controller_is_noetics():
    """noetic-devel's SwitchController: start_asap and timeout after the strictness constants."""
    request = SwitchController._request_class
    assert request.__slots__ == ["start_controllers", "stop_controllers", "strictness", "start_asap", "timeout"]
    assert (request.BEST_EFFORT, request.STRICT) == (1, 2)
