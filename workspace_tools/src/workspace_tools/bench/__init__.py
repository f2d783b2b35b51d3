"""./ws bench: the speed benchmark on the real nodes (workspace_tools.bench.main says what it measures)."""
