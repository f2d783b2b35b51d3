"""Many envs at once: worker processes (pipes) or Ray actors, the faces over them, private sims, the Ray cluster."""
