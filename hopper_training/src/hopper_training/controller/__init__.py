"""The monoped's hand-written hopping controller: its core (phase machine, laws, leg model), the adaptor that makes
it an env policy, and its trials on an in-process World. The ROS node is hopper_training.hop_controller_node."""
