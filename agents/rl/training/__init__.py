"""Training a policy: the algorithms and what each needs from the env, rl-zoo3 style recipes, the
training-only wrappers a recipe may name, resumable runs and supervised parallel runs."""
