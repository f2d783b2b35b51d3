"""Tabular Q-learning, the tutorials' agent: the Q-table, its trainers (one env or N) and its greedy policy."""
