"""The C backend of the models' code generators: their generated Python, written as C.

The models already generate their hot code from their own descriptions: the mechanism
engine traces a description to straight-line functions (``engine.compile_function``), the
actuator writes its exact-discretisation step with the implicit friction solve
(``actuator.model.kernel_source``). That generated code uses a small, fixed subset of
Python: float arithmetic (``%`` on the non-negative tick counters), comparisons,
``if``/``elif``/``else``, ``for _ in range(N)`` with ``break``, (tuple) assignments, indexing of
the argument lists, calls of a few scalar functions and of other generated functions. Some model
code is written in the subset by hand and run by Python as it is (the controllers' tick,
fmus/controller/tick.py; the actuator's substep rule and its torque measurement's delay line; the
direct kinematics' restart, ``mechanism.model.restarted_dk``), so that C and Python share one source.
This module writes that subset as C, operation for operation and in the same
order (every binary operation parenthesised, no reassociation; compile without
``-ffast-math`` and with ``-ffp-contract=off``), so the C computes the same floats as the
Python the tests compare against. Anything outside the subset is refused with the line it
found, never guessed.

A generated Python function becomes ``static int NAME(...)``:

- ``%`` (the non-negative tick counters' only) is ``mast_mod`` (mast_native.h: fmod, exact);
- arguments named in ``arrays`` are ``double *`` (read by index, written by index ``S[k] = x``, the
  index a constant or a computed whole number, ``(int)`` in C, or by slice assignment ``x[:] = (...)``,
  ``values[k:] = (...)`` or ``S[k:k + 2] = (a, b)``: the same stores in Python); the other arguments are
  doubles;
- ``return (a, b, ...)`` (the engine's functions) writes ``out[0..]`` and returns 0; a function
  returning one computed number is a ``static double`` value function, callable in the
  expressions of others (``values``); ``float(x)``, ``math.pi``, ``math.exp(x)``, ``x ** y`` (libm's
  ``pow``, as Python's float power) are understood; ``return
  k`` (the actuator's status codes) returns k, as does ``return status`` (a status another
  generated function returned: ``status = f(..., ARRAY)``, its results in ARRAY); ``a, b = f(...)``
  calls another generated function that returns a tuple (its ``out`` a scratch array of the caller);
- ``packed`` groups of scalar arguments are taken as one array each (``pack``: ``ikjac(q0, q1, q2, H, r, ...)``
  becomes ``ikjac(double *q, double *P, ...)``): the fixed interface the runtime calls for any number of them;
- a call of a check the tracing recorded (``_checkN(...)``) becomes ``if (!(cond)) return
  -N;`` with ``cond`` the check's ``c_condition`` (a C expression of ``a0, a1, ...``); the
  caller reports which check failed, with the message the check's ``c_message`` gives.
"""

from __future__ import annotations

import ast
import math
import textwrap
from typing import Callable, Mapping, Optional, Sequence

__all__ = ["TranslationError", "to_c", "c_double", "split_invariants", "pack"]

#: Python names of the scalar functions the generators call -> C (libm or support/mast_native.h)
FUNCTIONS = {
    "tanh": "tanh",
    "exp": "exp",
    "sin": "sin",
    "cos": "cos",
    "sqrt": "sqrt",
    "_sin": "sin",
    "_cos": "cos",
    "_sqrt": "sqrt",
    "_atan2": "atan2",
    "_hypot": "mast_hypot",
    "_sign": "mast_sign",
    "_sgn0": "mast_sgn0",
    "_abs": "fabs",
    "abs": "fabs",
    "float": "(double)",
    "floor": "floor",
    "ceil": "ceil",
    "int": "trunc",  # int(x) of a float: its integer part, kept as a double
}
#: module constants a model's own source may use (``math.pi``)
CONSTANTS = {("math", "pi"): math.pi, ("math", "e"): math.e}

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_CMPOPS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}


class TranslationError(ValueError):
    """Generated Python outside the subset this backend writes as C."""


def c_double(value: float) -> str:
    """A C literal of exactly this double (repr round-trips; C reads it the same way)."""
    value = float(value)
    if math.isnan(value):
        return "NAN"
    if math.isinf(value):
        return "INFINITY" if value > 0 else "(-INFINITY)"
    text = repr(value)
    if "." not in text and "e" not in text and "inf" not in text:
        text += ".0"
    return f"({text})" if value < 0 or text.startswith("-") else text


class _Writer:
    def __init__(
        self,
        name: str,
        arrays: Sequence[str],
        checks: Mapping[str, object],
        calls: Sequence[str] = (),
        values: Sequence[str] = (),
        constants: Mapping[str, float] = (),
    ) -> None:
        self.name = name
        self.constants = dict(constants)
        self.calls = dict(calls) if isinstance(calls, Mapping) else {c: c for c in calls}  # Python -> C name
        self.values = set(values)
        self.arrays = set(arrays)
        self.checks = checks
        self.locals: dict[str, None] = {}
        self.scratch: dict[str, int] = {}  # the arrays that receive a called function's tuple, and their sizes
        self.lines: list[str] = []
        self.loops = 0
        self.returns_tuple = False
        self.returns_value = False

    def fail(self, node: ast.AST, what: str) -> None:
        raise TranslationError(
            f"{self.name}: line {getattr(node, 'lineno', '?')}: {what}: "
            f"{ast.unparse(node) if isinstance(node, ast.AST) else node}"
        )

    # -------------------------------------------------------------------------- expressions
    def expr(self, node: ast.AST) -> str:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.fail(node, "constant of an unsupported type")
            return c_double(node.value) if isinstance(node.value, float) else str(node.value)
        if isinstance(node, ast.Name):
            if node.id in self.arrays:
                self.fail(node, "an array used as a number")
            return c_double(self.constants[node.id]) if node.id in self.constants else node.id
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and (node.value.id, node.attr) in CONSTANTS
        ):
            return c_double(CONSTANTS[node.value.id, node.attr])
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mod):  # tick counters (>= 0): as Python
            return f"mast_mod({self.expr(node.left)}, {self.expr(node.right)})"
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return f"({self.expr(node.left)} {_BINOPS[type(node.op)]} {self.expr(node.right)})"
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return f"(-{self.expr(node.operand)})"
            if isinstance(node.op, ast.UAdd):
                return self.expr(node.operand)
            if isinstance(node.op, ast.Not):
                return f"(!{self.expr(node.operand)})"
        if isinstance(node, ast.Compare):
            parts, left = [], node.left
            for op, right in zip(node.ops, node.comparators):  # a < b < c: (a < b) && (b < c), as Python
                if type(op) not in _CMPOPS:
                    self.fail(node, "comparison operator")
                parts.append(f"({self.expr(left)} {_CMPOPS[type(op)]} {self.expr(right)})")
                left = right
            return parts[0] if len(parts) == 1 else "(" + " && ".join(parts) + ")"
        if isinstance(node, ast.BoolOp):
            op = " && " if isinstance(node.op, ast.And) else " || "
            return "(" + op.join(self.expr(v) for v in node.values) + ")"
        if isinstance(node, ast.IfExp):
            return f"({self.expr(node.test)} ? {self.expr(node.body)} : {self.expr(node.orelse)})"
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):  # Python's float ** is libm's pow
            return f"pow({self.expr(node.left)}, {self.expr(node.right)})"
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "math"
            and node.func.attr in FUNCTIONS
            and not node.keywords
        ):
            return f"{FUNCTIONS[node.func.attr]}({', '.join(self.expr(a) for a in node.args)})"
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and not node.keywords
            and (node.func.id in FUNCTIONS or node.func.id in self.values)
        ):
            return f"{FUNCTIONS.get(node.func.id, node.func.id)}({', '.join(self.expr(a) for a in node.args)})"
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in self.calls
            and not node.keywords
        ):  # another generated function: status code, results in its array argument
            args = [a.id if isinstance(a, ast.Name) and a.id in self.arrays else self.expr(a) for a in node.args]
            return f"{self.calls[node.func.id]}({', '.join(args)})"
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id in self.arrays:
            return f"{node.value.id}[{self.index(node.slice)}]"
        self.fail(node, "expression")
        return ""  # unreachable

    def index(self, node: ast.AST) -> str:
        """An array index: a constant, or a computed number (a whole one: Python indexes by its int)."""
        if isinstance(node, ast.Constant) and isinstance(node.value, int) and not isinstance(node.value, bool):
            return str(node.value)
        if isinstance(node, ast.Slice):
            self.fail(node, "slice read")
        return f"(int)({self.expr(node)})"

    # -------------------------------------------------------------------------- statements
    def assign_local(self, name: str, value: str, indent: str) -> None:
        if name in self.arrays:
            raise TranslationError(f"{self.name}: assignment to the array argument {name}")
        self.locals.setdefault(name)
        self.lines.append(f"{indent}{name} = {value};")

    def store_slice(self, target: ast.Subscript, value: ast.AST, indent: str, node: ast.AST) -> None:
        sl = target.slice
        if not (
            isinstance(target.value, ast.Name)
            and target.value.id in self.arrays
            and isinstance(sl, ast.Slice)
            and sl.step is None
            and isinstance(value, ast.Tuple)
        ):
            self.fail(node, "slice assignment (only ARRAY[k:] = (a, b, ...) or ARRAY[k:k + n] = (n numbers))")
        start = 0 if sl.lower is None else sl.lower.value
        if sl.upper is not None and not (
            isinstance(sl.upper, ast.Constant) and sl.upper.value == start + len(value.elts)
        ):
            self.fail(node, "slice assignment whose length is not the tuple's")
        # values first, then stores: the right-hand side may read the array (then through temporaries)
        temps = [self.expr(e) for e in value.elts]
        if any(f"{target.value.id}[" in text for text in temps):
            for k, text in enumerate(temps):
                self.assign_local(f"st{k}", text, indent)
            temps = [f"st{k}" for k in range(len(temps))]
        for k, text in enumerate(temps):
            self.lines.append(f"{indent}{target.value.id}[{start + k}] = {text};")

    def stmt(self, node: ast.stmt, indent: str) -> None:
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target, value = node.targets[0], node.value
            if isinstance(target, ast.Name):
                self.assign_local(target.id, self.expr(value), indent)
            elif (
                isinstance(target, ast.Tuple)
                and isinstance(value, ast.Call)
                and isinstance(value.func, ast.Name)
                and value.func.id in self.calls
                and all(isinstance(e, ast.Name) for e in target.elts)
            ):
                # a, b = f(...): another generated function returning a tuple, its results through a scratch array
                scratch = f"ret{len(self.scratch)}"
                self.scratch[scratch] = len(target.elts)
                self.arrays.add(scratch)
                call = self.expr(value)
                self.lines.append(f"{indent}{call[:-1]}{', ' if value.args else ''}{scratch});")
                for k, elt in enumerate(target.elts):
                    self.assign_local(elt.id, f"{scratch}[{k}]", indent)
            elif (
                isinstance(target, ast.Subscript)
                and isinstance(target.value, ast.Name)
                and target.value.id in self.arrays
                and not isinstance(target.slice, ast.Slice)
            ):  # ARRAY[k] = x
                self.lines.append(f"{indent}{target.value.id}[{self.index(target.slice)}] = {self.expr(value)};")
            elif isinstance(target, ast.Tuple) and isinstance(value, ast.Name) and value.id in self.arrays:
                for k, elt in enumerate(target.elts):  # x0, x1, ..., = x
                    self.assign_local(elt.id, f"{value.id}[{k}]", indent)
            elif isinstance(target, ast.Tuple) and isinstance(value, ast.Tuple) and len(target.elts) == len(value.elts):
                # a, b = c, d: every right-hand side before any store (through temporaries when they read targets)
                names = [e.id for e in target.elts]
                texts = [self.expr(e) for e in value.elts]
                if (
                    all(t not in names for t in texts)
                    and all(isinstance(e, ast.Name) for e in value.elts)
                    and not set(names) & {e.id for e in value.elts}
                ):
                    for n, t in zip(names, texts):
                        self.assign_local(n, t, indent)
                else:
                    for k, t in enumerate(texts):
                        self.assign_local(f"tup{k}", t, indent)
                    for k, n in enumerate(names):
                        self.assign_local(n, f"tup{k}", indent)
            elif isinstance(target, ast.Subscript):
                self.store_slice(target, value, indent, node)
            else:
                self.fail(node, "assignment")
        elif isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Name) and type(node.op) in _BINOPS:
            name = node.target.id
            self.assign_local(name, f"({name} {_BINOPS[type(node.op)]} {self.expr(node.value)})", indent)
        elif isinstance(node, ast.If):
            self.lines.append(f"{indent}if ({self.expr(node.test)}) {{")
            for s in node.body:
                self.stmt(s, indent + "    ")
            orelse = node.orelse
            while len(orelse) == 1 and isinstance(orelse[0], ast.If):  # elif chains
                self.lines.append(f"{indent}}} else if ({self.expr(orelse[0].test)}) {{")
                for s in orelse[0].body:
                    self.stmt(s, indent + "    ")
                orelse = orelse[0].orelse
            if orelse:
                self.lines.append(f"{indent}}} else {{")
                for s in orelse:
                    self.stmt(s, indent + "    ")
            self.lines.append(f"{indent}}}")
        elif isinstance(node, ast.For):
            it = node.iter
            if not (
                isinstance(node.target, ast.Name)
                and node.target.id == "_"
                and isinstance(it, ast.Call)
                and isinstance(it.func, ast.Name)
                and it.func.id == "range"
                and len(it.args) == 1
                and isinstance(it.args[0], (ast.Constant, ast.Name))
                and not node.orelse
            ):
                self.fail(node, "loop (only 'for _ in range(N)')")
            var = f"k{self.loops}"
            self.loops += 1
            self.lines.append(f"{indent}for (int {var} = 0; {var} < {self.expr(it.args[0])}; {var}++) {{")
            for s in node.body:
                self.stmt(s, indent + "    ")
            self.lines.append(f"{indent}}}")
        elif isinstance(node, ast.Break):
            self.lines.append(f"{indent}break;")
        elif isinstance(node, ast.Return):
            value = node.value
            if isinstance(value, ast.Tuple):
                self.returns_tuple = True
                for k, e in enumerate(value.elts):
                    self.lines.append(f"{indent}out[{k}] = {self.expr(e)};")
                self.lines.append(f"{indent}return 0;")
            elif isinstance(value, ast.Constant) and isinstance(value.value, int):
                self.lines.append(f"{indent}return {value.value};")
            elif isinstance(value, ast.Name) and value.id in self.locals:  # a status another function returned
                self.lines.append(f"{indent}return (int){value.id};")
            elif isinstance(value, (ast.BinOp, ast.Call, ast.Attribute, ast.IfExp)):  # a value function
                self.returns_value = True
                self.lines.append(f"{indent}return {self.expr(value)};")
            else:
                self.fail(node, "return (only a tuple, an integer status or one computed number)")
        elif (
            isinstance(node, ast.Expr)
            and isinstance(node.value, ast.Call)
            and isinstance(node.value.func, ast.Name)
            and node.value.func.id in self.checks
        ):
            self.check(node.value, indent)
        else:
            self.fail(node, "statement")

    def check(self, call: ast.Call, indent: str) -> None:
        key = call.func.id
        condition: Optional[str] = getattr(self.checks[key], "c_condition", None)
        if condition is None:
            raise TranslationError(f"{self.name}: check {key} ({self.checks[key]!r}) has no c_condition")
        number = int(key.replace("_check", ""))
        args = {f"a{k}": self.expr(a) for k, a in enumerate(call.args)}
        text = condition
        for k in sorted(args, key=lambda s: -int(s[1:])):  # a10 before a1
            text = text.replace(k, args[k])
        self.lines.append(f"{indent}if (!({text})) return -{number};")


def to_c(
    source: str,
    name: str,
    arrays: Sequence[str] = (),
    checks: Mapping[str, Callable] = (),
    static: bool = True,
    calls: Sequence[str] | Mapping[str, str] = (),
    values: Sequence[str] = (),
    constants: Mapping[str, float] = (),
    packed: Mapping[str, Sequence[str]] = (),
) -> str:
    """C of the one generated Python function in ``source`` (module docstring), named ``name``;
    ``calls``: other generated functions it may call (``status = f(..., ARRAY)``; a mapping: their C names);
    ``values``: value functions (one computed number) it may call in an expression; ``constants``: the
    module's named numbers it reads (written as their values); ``packed``: {array: the scalar arguments it
    carries, in order}: the function takes the array instead (``pack``), a fixed C interface for any size."""
    tree = ast.parse(textwrap.dedent(source))
    functions = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
    if len(functions) != 1 or len(tree.body) != 1:
        raise TranslationError(f"{name}: expected one generated function, found {len(tree.body)} statements")
    fn = functions[0]
    if packed:
        pack(fn, packed, name, list(calls))
        arrays = (*arrays, *packed)
    w = _Writer(name, arrays, dict(checks or {}), calls, values, constants)
    body = fn.body
    if (
        body
        and isinstance(body[0], ast.Expr)
        and isinstance(body[0].value, ast.Constant)
        and isinstance(body[0].value.value, str)
    ):
        body = body[1:]  # the docstring of a model function translated from its own source
    for s in body:
        w.stmt(s, "    ")
    args = [f"double *{a.arg}" if a.arg in w.arrays else f"double {a.arg}" for a in fn.args.args]
    if w.returns_tuple:
        args.append("double *out")
    if w.returns_value and (w.returns_tuple or any(line.strip().startswith("return 0;") for line in w.lines)):
        raise TranslationError(f"{name}: returns a number on one path and a status or tuple on another")
    head = f"{'static ' if static else ''}{'double' if w.returns_value else 'int'} {name}({', '.join(args)})"
    decl = [f"    double {a}[{n}];" for a, n in w.scratch.items()]
    names = [n for n in w.locals if n not in {a.arg for a in fn.args.args}]  # scalar arguments are assignable
    for k in range(0, len(names), 8):
        decl.append("    double " + ", ".join(names[k : k + 8]) + ";")
    return "\n".join([head, "{"] + decl + w.lines + ["}", ""])


def pack(fn: ast.FunctionDef, packed: Mapping[str, Sequence[str]], name: str, calls: Sequence[str] = ()) -> None:
    """``fn`` rewritten in place to take each array of ``packed`` ({array: its scalar arguments, in order}) instead
    of its scalars: the array at the first scalar's place (an array with no scalars right after the previous array,
    or first), each read of a scalar an index into its array, and each run of a whole group in the arguments of a
    call of ``calls`` (other generated functions) the array. A scalar out of its group's order, or assigned, is
    refused (TranslationError)."""
    where = {arg: (array, k) for array, names in packed.items() for k, arg in enumerate(names)}
    args = [a.arg for a in fn.args.args]
    out: list[str] = []
    i = 0
    while i < len(args):
        group = next((a for a, names in packed.items() if names and args[i : i + len(names)] == list(names)), None)
        if group is None and args[i] in where:
            raise TranslationError(f"{name}: argument {args[i]} is not in the order of its group {where[args[i]][0]}")
        out.append(group or args[i])
        i += len(packed[group]) if group else 1
    previous = -1
    for array in packed:
        if array not in out:
            out.insert(previous + 1, array)
        previous = out.index(array)

    class Pack(ast.NodeTransformer):
        def visit_Call(self, node: ast.Call) -> ast.AST:
            names = [a.id if isinstance(a, ast.Name) else None for a in node.args]
            called = isinstance(node.func, ast.Name) and node.func.id in calls
            for array, group in packed.items() if called else ():
                n = len(group)
                for k in range(len(names) - n + 1) if n else ():
                    if names[k : k + n] == list(group):
                        node.args[k : k + n] = [ast.Name(array, ast.Load())]
                        names[k : k + n] = [array]
            return self.generic_visit(node)

        def visit_Name(self, node: ast.Name) -> ast.AST:
            if node.id not in where:
                return node
            if not isinstance(node.ctx, ast.Load):
                raise TranslationError(f"{name}: the packed argument {node.id} is assigned")
            array, k = where[node.id]
            return ast.copy_location(ast.Subscript(ast.Name(array, ast.Load()), ast.Constant(k), ast.Load()), node)

    Pack().visit(fn)
    fn.args.args = [ast.arg(a) for a in out]
    ast.fix_missing_locations(fn)


def split_invariants(source: str, invariant: Sequence[str]) -> tuple[str, str, int]:
    """A generated straight-line function split in two, for a caller that calls it many times with the same
    ``invariant`` arguments (the mechanism's parameters): ``(invariants, main, n)``. ``invariants`` is the Python
    source of ``NAME_invariants(<the invariant arguments>)``, the function's top-level assignments whose values
    depend on those arguments and constants alone (through the scalar functions of FUNCTIONS), in their order,
    returning the ``n`` the rest reads; ``main`` is the function with those assignments replaced by reads of an
    added last argument ``K`` (``tN = K[k]``: an array for ``to_c``). The same operations on the same values:
    the floats do not change, they are computed once."""
    fn = ast.parse(textwrap.dedent(source)).body[0]
    if not isinstance(fn, ast.FunctionDef):
        raise TranslationError(f"split_invariants: expected one generated function, found {ast.dump(fn)[:60]}")
    assigned: dict[str, int] = {}
    for node in ast.walk(fn):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            assigned[node.id] = assigned.get(node.id, 0) + 1
    known = {a for a in invariant if a not in assigned}  # an argument the function reassigns varies
    hoisted: list[ast.Assign] = []
    for stmt in fn.body:
        if not (
            isinstance(stmt, ast.Assign)
            and len(stmt.targets) == 1
            and isinstance(stmt.targets[0], ast.Name)
            and assigned[stmt.targets[0].id] == 1
        ):
            continue
        calls = [n for n in ast.walk(stmt.value) if isinstance(n, ast.Call)]
        pure = all(isinstance(c.func, ast.Name) and c.func.id in FUNCTIONS and not c.keywords for c in calls)
        names = {n.id for n in ast.walk(stmt.value) if isinstance(n, ast.Name)} - {c.func.id for c in calls}
        if (
            pure
            and names <= known
            and not any(isinstance(n, (ast.Subscript, ast.Attribute)) for n in ast.walk(stmt.value))
        ):
            hoisted.append(stmt)
            known.add(stmt.targets[0].id)
    moved = {id(s) for s in hoisted}
    rest = [s for s in fn.body if id(s) not in moved]
    read = {n.id for s in rest for n in ast.walk(s) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Load)}
    kept = [s.targets[0].id for s in hoisted if s.targets[0].id in read]
    args = [a.arg for a in fn.args.args]
    invariants = "\n".join(
        [
            f"def {fn.name}_invariants({', '.join(a for a in args if a in invariant)}):",
            *(f"    {ast.unparse(s)}" for s in hoisted),
            f"    return ({''.join(f'{k}, ' for k in kept)})",
        ]
    )
    body = [f"    {k} = K[{j}]" for j, k in enumerate(kept)] + [textwrap.indent(ast.unparse(s), "    ") for s in rest]
    main = "\n".join([f"def {fn.name}({', '.join(args + ['K'])}):", *body])
    return invariants, main, len(kept)
