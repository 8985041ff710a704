"""Evaluating policies on fixed, seeded targets, and aggregates over training seeds (IQM with
bootstrap intervals)."""
