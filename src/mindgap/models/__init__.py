"""Internal: the learners' models (beliefs, reward ensembles, dynamics, actors, PrefBias's networks)."""
