"""Metrics, experiment runner, leaderboard, plots, paper reproductions, benchmarks, SITL hook."""
