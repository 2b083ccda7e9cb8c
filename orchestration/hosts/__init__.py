"""Third-party hosts: the FMUs and SSPs in libcosim and ecos (``cosim``) and the black-box
interface checks a mechanism FMU must pass (``conformance``). Built on ``mast.core`` only."""
