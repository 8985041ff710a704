"""Learning a policy from a planner: DAgger with a model-based expert (:mod:`.dagger`)."""
