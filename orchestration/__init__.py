"""mast: build, validate and run the MAST co-simulation (the ``orchestration/`` folder)."""
