"""Analyses built on the co-simulation core: the paper's reproduction, identification,
frequency responses, design comparison, synthesized measurements, workspace and replay."""
