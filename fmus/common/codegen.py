"""What the models' code generators share: compiling generated source with its constants checked.

The generators (the mechanism engine, the actuator kernels) write constants folded from the
parameters into the source as ``repr(float)``. A parameter so large (or small) that a
folded constant leaves the floating-point range would print as ``inf`` or ``nan``, which is
no Python literal: refused here with the parameters to blame, instead of a NameError.
"""
from __future__ import annotations

import ast
import inspect
import textwrap
import types
from typing import Callable, Mapping, Sequence

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
        raise OverflowError(f"{label}: a constant of the generated code is {bad[0]} (parameter values "
                            f"outside what floating-point arithmetic can hold){hint}")
    exec(code, namespace)  # noqa: S102 (the project's own generated code)
    fn = namespace[name]
    fn.source = source
    return fn


def largest_parameters(params: Mapping[str, object]) -> str:
    """A hint naming the parameters an overflow comes from: the largest in magnitude."""
    numbers = sorted(((abs(v), k, v) for k, v in params.items()
                      if isinstance(v, (int, float)) and not isinstance(v, bool)), reverse=True)
    huge = [f"{k} = {v!r}" for a, k, v in numbers if a >= 1e100] or [f"{k} = {v!r}" for a, k, v in numbers[:2]]
    return f"; check the largest parameter value(s): {', '.join(huge)}" if huge else ""


def inlined(fn: Callable, arguments: Mapping[str, str], results: Sequence[str], prefix: str) -> list[str]:
    """The lines of ``fn``'s body for a generated loop that would call it: ``results = fn(**arguments)``
    written out (no call per use; the same operations on the same values: the same floats).

    ``fn``: straight-line assignments and ``if``s whose branches end in ``return`` (a chain of them, then a
    last ``return``); ``arguments``: each parameter's expression (a parameter left out takes its default,
    written as its ``repr``; an expression other than a name is computed once, into ``prefix + name``); its
    own locals become ``prefix + name``; each ``return a, b`` becomes ``results = a, b``. The source is
    ``fn.source`` when set (read at import: a generator may run after an FMU's files are gone), else read now."""
    tree = ast.parse(textwrap.dedent(getattr(fn, "source", None) or inspect.getsource(fn))).body[0]
    params = [a.arg for a in tree.args.args]
    defaults = dict(zip(params[len(params) - len(tree.args.defaults):], tree.args.defaults))
    lines, names = [], {}
    for name in params:
        if name in arguments:
            text = arguments[name]
            if text.isidentifier():
                names[name] = text
            else:
                names[name] = prefix + name
                lines.append(f"{prefix + name} = {text}")
        else:
            names[name] = repr(ast.literal_eval(defaults[name]))

    class Rename(ast.NodeTransformer):
        def visit_Name(self, node: ast.Name) -> ast.AST:
            return ast.copy_location(ast.parse(names.get(node.id, prefix + node.id), mode="eval").body, node)

    def block(stmts: list, indent: str) -> list[str]:
        out = []
        for k, stmt in enumerate(stmts):
            if isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant):
                continue                                     # the docstring
            if isinstance(stmt, ast.Return):
                return out + [f"{indent}{', '.join(results)} = {ast.unparse(Rename().visit(stmt.value))}"]
            if isinstance(stmt, ast.If) and not stmt.orelse and isinstance(stmt.body[-1], ast.Return):
                return out + [f"{indent}if {ast.unparse(Rename().visit(stmt.test))}:", *block(stmt.body, indent + "    "),
                              f"{indent}else:", *block(stmts[k + 1:], indent + "    ")]
            if not isinstance(stmt, ast.Assign):
                raise ValueError(f"inlined: {fn.__name__}: {type(stmt).__name__} is not supported")
            out.append(f"{indent}{ast.unparse(Rename().visit(stmt))}")
        raise ValueError(f"inlined: {fn.__name__}: a path without return")

    return lines + block(tree.body, "")
