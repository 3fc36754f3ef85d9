"""Built-in plugins: the team model (docs/model.md), uncertainty injectors, allocation policies."""
