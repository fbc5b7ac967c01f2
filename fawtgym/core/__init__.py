"""Shared helpers that import nothing else of the package (envs, observers and agents depend on them)."""
