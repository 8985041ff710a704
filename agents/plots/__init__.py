"""Charts of the agents' results (matplotlib, Agg backend)."""
