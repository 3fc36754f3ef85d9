"""The learned parts of ATA-HRL (torch): features, networks, checkpoints, training."""
