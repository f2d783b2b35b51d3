"""Stable-Baselines3's deep agents (DQN, PPO, SAC): their params, VecEnv, trainer and greedy policy."""
