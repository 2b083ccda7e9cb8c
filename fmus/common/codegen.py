"""What the models' code generators share: compiling generated source with its constants checked.

The generators (the mechanism engine, the actuator kernels) write constants folded from the
parameters into the source as ``repr(float)``. A parameter so large (or small) that a
folded constant leaves the floating-point range would print as ``inf`` or ``nan``, which is
no Python literal: refused here with the parameters to blame, instead of a NameError.
"""

from __future__ import annotations

import types
from typing import Callable, Mapping

_NON_FINITE = {"inf", "nan"}


def compile_generated(source: str, name: str, label: str, namespace: dict, hint: str = "") -> Callable:
    """``exec`` ``source`` into ``namespace`` and return the function ``name`` (``label``: its file name)."""
    code = compile(source, f"<{label}>", "exec")
    names, stack = set(), [code]
    while stack:  # the global names the code and its functions use: 'inf' or 'nan' only from a printed constant
        c = stack.pop()
        names.update(c.co_names)
        stack.extend(k for k in c.co_consts if isinstance(k, types.CodeType))
    bad = sorted((names & _NON_FINITE) - namespace.keys())
    if bad:
        raise OverflowError(
            f"{label}: a constant of the generated code is {bad[0]} (parameter values "
            f"outside what floating-point arithmetic can hold){hint}"
        )
    exec(code, namespace)  # noqa: S102 (the project's own generated code)
    fn = namespace[name]
    fn.source = source
    return fn


def largest_parameters(params: Mapping[str, object]) -> str:
    """A hint naming the parameters an overflow comes from: the largest in magnitude."""
    numbers = sorted(
        ((abs(v), k, v) for k, v in params.items() if isinstance(v, (int, float)) and not isinstance(v, bool)),
        reverse=True,
    )
    huge = [f"{k} = {v!r}" for a, k, v in numbers if a >= 1e100] or [f"{k} = {v!r}" for a, k, v in numbers[:2]]
    return f"; check the largest parameter value(s): {', '.join(huge)}" if huge else ""
