"""The monoped's task envs, one module per task (the module's name is the task's), on the base in base.py."""
