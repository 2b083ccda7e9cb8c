"""Native FMUs: C generated from the models' own descriptions, compiled without Python at run time."""
