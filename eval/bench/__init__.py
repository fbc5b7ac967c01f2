"""Speed benchmarks (``fawtgym bench <name>``): ratios measured in one run, never timed tests."""
