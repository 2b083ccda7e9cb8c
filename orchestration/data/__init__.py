"""Measured data from outside the project: lab file formats read into the measured-data format."""
