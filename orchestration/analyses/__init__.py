"""Analyses built on the co-simulation core: what a design can reach, how a model replays a record."""
