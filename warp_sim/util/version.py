"""The package version (also in pyproject.toml), which a checkpoint records: another version may simulate
differently, so its checkpoints are not resumed."""
__version__ = "0.1.0"
