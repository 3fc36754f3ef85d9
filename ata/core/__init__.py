"""The small core: kernel, state, mission files, registry, random numbers."""
