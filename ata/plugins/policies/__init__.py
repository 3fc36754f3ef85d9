"""Allocation policies: random, greedy, the ITA-MILP baseline and keep (the learned ones come
as optional plugins)."""
