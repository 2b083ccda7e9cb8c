"""Co-simulation core: SSP and parameter sets, FMU builds (Python and native), the multi-rate
master, the direct composition and a run. Imports nothing from the other layers of ``mast``."""
