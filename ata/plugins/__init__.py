"""Built-in plugins: the MODEL.md team model, uncertainty injectors and allocation policies."""
