"""Stable-Baselines3 training entry points, hyperparameter files, wrappers and callbacks."""
