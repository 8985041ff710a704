"""Experiments that compare methods: reach, closed vs open loop, perturbations, the demo's policy part."""
