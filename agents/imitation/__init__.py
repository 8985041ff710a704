"""Learning a policy from a planner: DAgger with the model-based controller as the expert
(:mod:`.dagger`)."""
