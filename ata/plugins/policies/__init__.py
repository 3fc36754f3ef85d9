"""Allocation policies: random and greedy (learned ones come as optional plugins)."""
