"""What the models' code generators share: compiling generated source with its constants checked.

The generators (the mechanism engine, the actuator kernels) write constants folded from the
parameters into the source as ``repr(float)``. A parameter so large (or small) that a
folded constant leaves the floating-point range would print as ``inf`` or ``nan``, which is
no Python literal: refused here with the parameters to blame, instead of a NameError.
"""
from __future__ import annotations

import io
import tokenize
from typing import Callable, Mapping

_NON_FINITE = {"inf", "nan"}


def compile_generated(source: str, name: str, label: str, namespace: dict, hint: str = "") -> Callable:
    """``exec`` ``source`` into ``namespace`` and return the function ``name`` (``label``: its file name)."""
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.NAME and tok.string in _NON_FINITE and tok.string not in namespace:
            raise OverflowError(f"{label}: a constant of the generated code is {tok.string} (parameter values "
                                f"outside what floating-point arithmetic can hold){hint}")
    exec(compile(source, f"<{label}>", "exec"), namespace)  # noqa: S102 (the project's own generated code)
    fn = namespace[name]
    fn.source = source
    return fn


def largest_parameters(params: Mapping[str, object]) -> str:
    """A hint naming the parameters an overflow comes from: the largest in magnitude."""
    numbers = sorted(((abs(v), k, v) for k, v in params.items()
                      if isinstance(v, (int, float)) and not isinstance(v, bool)), reverse=True)
    huge = [f"{k} = {v!r}" for a, k, v in numbers if a >= 1e100] or [f"{k} = {v!r}" for a, k, v in numbers[:2]]
    return f"; check the largest parameter value(s): {', '.join(huge)}" if huge else ""
