"""The moving cube's task envs, one module per task (the module's name is the task's)."""
