"""Agent rllib_ppo: RLlib's PPO on its current API stack (EnvRunners, RLModule, Learner), the envs on Ray."""
