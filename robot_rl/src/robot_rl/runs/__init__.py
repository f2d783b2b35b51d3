"""A run on disk: its folder and files, the ledger trainers write it through, its plots and video."""
