"""Training: genomes, selection, fitness rollouts, backends, runs and the warm start."""
