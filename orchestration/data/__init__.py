"""Measured data: the measured-data format (``measured``) and lab file formats read into it."""
