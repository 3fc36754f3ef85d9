"""Uncertainty injectors: fatigue noise, task attribute change, robot failure, latency."""
