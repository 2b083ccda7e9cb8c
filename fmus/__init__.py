"""Model code of the MAST FMUs.

Each sub-package holds one FMU: the model equations (plain Python, importable
in tests and in the direct composition) and, apart from them, the thin FMI
wrapper in ``fmu.py``. Imports inside this package are relative so that the
build can bundle it into each FMU under a unique module name.
"""
