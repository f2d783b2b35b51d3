"""The agents a run can train: the registry (AgentSpec), tabular Q-learning and Stable-Baselines3's deep agents."""
