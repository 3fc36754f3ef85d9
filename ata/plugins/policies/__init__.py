"""Allocation policies: random, greedy, the MILP and keep (learned ones come as optional plugins)."""
