"""Track A of issue 39: the hopping controller teaches MonopedEndToEnd-v0's student (BC, then DAgger rounds).

params.py (the agent's params), teacher.py (the controller shadow-run on the student's states), student.py (the
network, its weights-only files and the policy evaluate.py plays), trainer.py (data collection, BC, DAgger, the
run's files). The agent registry's entry `bc_dagger` names trainer.make_trainer and student.greedy_policy.
"""
