"""Expression tracing: record arithmetic as a graph, differentiate it, write it as straight-line code.

A function written with ordinary arithmetic and this module's functions (``sin``, ``cos``, ``sqrt``,
``atan2``, ``hypot``, ``sign``, ``require``) evaluates floats as usual. Called on traced numbers
(``Expr``, the inputs of a ``Graph``: ``Graph.input(name)``) it records every operation instead, as
nodes of an expression DAG (hash-consed: one node per distinct operation; constants folded with
rules exact for finite values, so a traced value is the same float as a plain evaluation, up to the
sign of a zero). A traced number refuses to be branched on (``TraceError``): decisions go through
``sign``, ``require`` or parameters.

On a graph:

- ``Forward(graph, seeds)``: the forward-mode derivative of any node along the direction ``seeds``
  ({input name: its derivative}), itself a node of the same graph (so derivatives can be derived);
- ``Second(graph, first, seeds)``: the second derivative along a path whose first derivative is
  ``first`` (a ``Forward``) and whose inputs have second derivative ``seeds``;
- ``compile_function(name, inputs, outputs, graph)``: straight-line Python computing the outputs from
  the named inputs, on floats or (``vector=True``) on numpy arrays; ``fn.source`` is its text, which
  the native generator (mast.core.native.translate) turns into C;
- ``needed(outputs, checks)``: the nodes the outputs depend on (with the checks on them).

``require(check, x, ...)`` records an admissibility check: the generated code calls ``check`` where
the values are computed (it raises on an inadmissible point; over arrays it clears the point from a
mask instead).

Users: the mechanism engine (fmus.mechanism.engine: Jacobians and inverse dynamics of a description),
the native generator's traced constants (mast.core.native.models).
"""

from __future__ import annotations

import math
from typing import Callable, Optional, Sequence

import numpy as np

from .block import ModelError
from .codegen import compile_generated

__all__ = [
    "Graph",
    "Expr",
    "TraceError",
    "lift",
    "graph_of",
    "add",
    "sub",
    "mul",
    "div",
    "neg",
    "unary",
    "sin",
    "cos",
    "sqrt",
    "sign",
    "atan2",
    "hypot",
    "require",
    "traced",
    "traced_input",
    "Derivative",
    "Forward",
    "Second",
    "needed",
    "compile_function",
]


class Graph:
    """An expression DAG: nodes in creation order (a valid evaluation order), hash-consed."""

    def __init__(self) -> None:
        self.nodes: list[Expr] = []
        self.memo: dict = {}
        self.checks: list[Expr] = []

    def node(self, op: str, args: tuple, value=None, key=None) -> "Expr":
        """The node ``op(args)`` (``value``: a constant's float, an input's name), the existing one if recorded."""
        k = key if key is not None else (op, *(a.id for a in args))
        found = self.memo.get(k)
        if found is not None:
            return found
        n = Expr(self, len(self.nodes), op, args, value)
        self.nodes.append(n)
        self.memo[k] = n
        return n

    def const(self, value: float) -> "Expr":
        """The constant ``value`` (one node per float, told apart bit for bit)."""
        value = float(value)
        return self.node("const", (), value, key=("const", value.hex()))

    def input(self, name: str) -> "Expr":
        """The input ``name``: an argument of the functions ``compile_function`` writes."""
        return self.node("input", (), name, key=("input", name))


class TraceError(TypeError):
    """A description branched on a traced value (use sign, require, or a parameter instead)."""


class Expr:
    """A traced number: a node of the expression graph. Arithmetic builds new nodes."""

    __slots__ = ("g", "id", "op", "args", "value")

    def __init__(self, g: Graph, id_: int, op: str, args: tuple, value) -> None:
        self.g, self.id, self.op, self.args, self.value = g, id_, op, args, value

    # never copied: graphs are immutable once built
    def __deepcopy__(self, memo):
        return self

    def __repr__(self) -> str:
        return f"Expr#{self.id}({self.op})"

    def __bool__(self):
        raise TraceError(
            "a mechanism description may not branch on a traced value; use sign(), require() "
            "or decide on parameters only"
        )

    __lt__ = __le__ = __gt__ = __ge__ = lambda self, other: self.__bool__()  # noqa: E731

    def __add__(self, o):
        return add(self, o)

    def __radd__(self, o):
        return add(o, self)

    def __sub__(self, o):
        return sub(self, o)

    def __rsub__(self, o):
        return sub(o, self)

    def __mul__(self, o):
        return mul(self, o)

    def __rmul__(self, o):
        return mul(o, self)

    def __truediv__(self, o):
        return div(self, o)

    def __rtruediv__(self, o):
        return div(o, self)

    def __neg__(self):
        return neg(self)

    def __pos__(self):
        return self

    def __abs__(self):
        return unary("abs", self, abs)


def lift(g: Graph, x) -> Expr:
    """``x`` as a node of ``g``: itself if traced, else a constant."""
    return x if isinstance(x, Expr) else g.const(x)


def graph_of(*xs) -> Optional[Graph]:
    """The graph of the first traced value among ``xs``; None if every one is a plain number."""
    for x in xs:
        if isinstance(x, Expr):
            return x.g
    return None


def _is(x: Expr, value: float) -> bool:
    return x.op == "const" and x.value == value


# Folding rules are exact for finite values (x*1, x+0, x*0 -> 0, 0/x -> 0): the traced values are
# the same floats as a plain evaluation of the description, up to the sign of a zero.
def add(a, b):
    """a + b, folded where exact (``a + b`` on a traced number calls this)."""
    g = graph_of(a, b)
    if g is None:
        return a + b
    a, b = lift(g, a), lift(g, b)
    if a.op == "const" and b.op == "const":
        return g.const(a.value + b.value)
    if _is(a, 0.0):
        return b
    if _is(b, 0.0):
        return a
    return g.node("add", (a, b))


def sub(a, b):
    """a - b, folded where exact."""
    g = graph_of(a, b)
    if g is None:
        return a - b
    a, b = lift(g, a), lift(g, b)
    if a.op == "const" and b.op == "const":
        return g.const(a.value - b.value)
    if _is(b, 0.0):
        return a
    if _is(a, 0.0):
        return neg(b)
    return g.node("sub", (a, b))


def mul(a, b):
    """a * b, folded where exact (x * 0 -> 0, x * 1 -> x, x * -1 -> -x)."""
    g = graph_of(a, b)
    if g is None:
        return a * b
    a, b = lift(g, a), lift(g, b)
    if a.op == "const" and b.op == "const":
        return g.const(a.value * b.value)
    if _is(a, 0.0) or _is(b, 0.0):
        return g.const(0.0)
    if _is(a, 1.0):
        return b
    if _is(b, 1.0):
        return a
    if _is(a, -1.0):
        return neg(b)
    if _is(b, -1.0):
        return neg(a)
    return g.node("mul", (a, b))


def div(a, b):
    """a / b, folded where exact (0 / x -> 0, x / 1 -> x)."""
    g = graph_of(a, b)
    if g is None:
        return a / b
    a, b = lift(g, a), lift(g, b)
    if a.op == "const" and b.op == "const":
        return g.const(a.value / b.value)
    if _is(a, 0.0):
        return g.const(0.0)
    if _is(b, 1.0):
        return a
    return g.node("div", (a, b))


def neg(a):
    """-a (--x -> x)."""
    if not isinstance(a, Expr):
        return -a
    if a.op == "const":
        return a.g.const(-a.value)
    if a.op == "neg":
        return a.args[0]
    return a.g.node("neg", (a,))


def unary(op: str, a, fn: Callable[[float], float]):
    """``fn(a)`` for a plain number or a traced constant; else the node ``op(a)`` (``op`` needs its derivative
    rules in ``Forward`` and ``Second`` and its function in ``compile_function``)."""
    if not isinstance(a, Expr):
        return fn(a)
    if a.op == "const":
        return a.g.const(fn(a.value))
    return a.g.node(op, (a,))


def _sign(x: float) -> float:
    return 1.0 if x > 0.0 else -1.0


def _sgn0(x: float) -> float:
    return 1.0 if x >= 0.0 else -1.0


def sin(x):
    """sin for floats and traced numbers."""
    return unary("sin", x, math.sin)


def cos(x):
    """cos for floats and traced numbers."""
    return unary("cos", x, math.cos)


def sqrt(x):
    """sqrt for floats and traced numbers (guard the argument with ``require`` first)."""
    return unary("sqrt", x, math.sqrt)


def sign(x):
    """1.0 if x > 0 else -1.0 (so sign(0) = -1); its derivative is zero."""
    return unary("sign", x, _sign)


def atan2(y, x):
    """atan2 for floats and traced numbers."""
    g = graph_of(y, x)
    if g is None:
        return math.atan2(y, x)
    y, x = lift(g, y), lift(g, x)
    if y.op == "const" and x.op == "const":
        return g.const(math.atan2(y.value, x.value))
    return g.node("atan2", (y, x))


def hypot(a, b):
    """math.hypot for floats and traced numbers."""
    g = graph_of(a, b)
    if g is None:
        return math.hypot(a, b)
    a, b = lift(g, a), lift(g, b)
    if a.op == "const" and b.op == "const":
        return g.const(math.hypot(a.value, b.value))
    return g.node("hypot", (a, b))


def require(check: Callable[..., None], *args) -> None:
    """Admissibility check: ``check(*values)`` must raise (the caller's error, e.g. KinematicsError) if the values
    are not admissible.

    With floats it runs at once; traced, it runs at that point of every generated function
    that computes its first argument.
    """
    g = graph_of(*args)
    if g is None:
        check(*args)
        return
    lifted = tuple(lift(g, a) for a in args)  # constants first: the check's id follows them
    node = Expr(g, len(g.nodes), "check", lifted, check)
    g.nodes.append(node)
    g.checks.append(node)


def traced(x) -> bool:
    """True for a traced number (for descriptions that need to know; rarely useful)."""
    return isinstance(x, Expr)


def traced_input(like, name: str) -> Expr:
    """The named input ``name`` of the expression graph the traced number ``like`` belongs to: a parameter
    traced as an argument of the generated functions (a description's ``Evaluation.parameters``)."""
    if not isinstance(like, Expr):
        raise TypeError(f"traced_input({name!r}): {like!r} is not a traced number")
    return like.g.input(name)


# ===================================================================================== derivatives
class Derivative:
    """A derivative of every node (memoized), built in post-order by the subclass's ``_rule``."""

    def __init__(self, g: Graph, seeds: dict[str, object]) -> None:
        self.g = g
        self.seeds = seeds  # input name -> derivative of the input (Expr or float)
        self.d: dict[int, Expr] = {}
        self.zero = g.const(0.0)

    def __call__(self, n: Expr) -> Expr:
        d = self.d.get(n.id)
        if d is not None:
            return d
        # iterative post-order (graphs are deep: avoid Python recursion)
        stack = [n]
        while stack:
            top = stack[-1]
            if top.id in self.d:
                stack.pop()
                continue
            pending = [a for a in top.args if a.id not in self.d]
            if pending and top.op != "check":
                stack.extend(pending)
                continue
            stack.pop()
            self.d[top.id] = self._rule(top)
        return self.d[n.id]

    def _rule(self, n: Expr) -> Expr:
        raise NotImplementedError


class Forward(Derivative):
    """Forward-mode derivative of every node along one seed."""

    def _rule(self, n: Expr) -> Expr:
        op, g, d = n.op, self.g, self.d
        if op == "const":
            return self.zero
        if op == "input":
            return lift(g, self.seeds.get(n.value, 0.0))
        if op == "check":
            return self.zero
        a = n.args[0]
        da = d[a.id]
        if op == "add":
            return add(da, d[n.args[1].id])
        if op == "sub":
            return sub(da, d[n.args[1].id])
        if op == "neg":
            return neg(da)
        if op == "mul":
            b = n.args[1]
            return add(mul(a, d[b.id]), mul(da, b))
        if op == "div":
            b = n.args[1]
            return div(sub(da, mul(n, d[b.id])), b)
        if op == "sin":
            return mul(cos(a), da)
        if op == "cos":
            return neg(mul(sin(a), da))
        if op == "sqrt":
            return mul(div(0.5, n), da)
        if op == "atan2":
            y, x = a, n.args[1]
            dy, dx = da, d[x.id]
            return div(sub(mul(x, dy), mul(y, dx)), add(mul(x, x), mul(y, y)))
        if op == "hypot":
            b = n.args[1]
            return div(add(mul(a, da), mul(b, d[b.id])), n)
        if op == "abs":
            return mul(unary("sgn0", a, _sgn0), da)
        if op in ("sign", "sgn0"):
            return self.zero
        raise AssertionError(f"no derivative rule for {op}")


class Second(Derivative):
    """Second derivative along a path whose first derivative is ``first`` and whose inputs have
    second derivative ``seeds`` (empty: zero, as the mechanism engine takes it for rho_ddot = 0, adding the
    q acceleration that follows afterwards)."""

    def __init__(self, g: Graph, first: Forward, seeds: dict[str, object]) -> None:
        super().__init__(g, seeds)
        self.p1 = first

    def _rule(self, n: Expr) -> Expr:
        op, g, d, p1 = n.op, self.g, self.d, self.p1
        if op == "const" or op == "check":
            return self.zero
        if op == "input":
            return lift(g, self.seeds.get(n.value, 0.0))
        a = n.args[0]
        aa = d[a.id]
        if op == "add":
            return add(aa, d[n.args[1].id])
        if op == "sub":
            return sub(aa, d[n.args[1].id])
        if op == "neg":
            return neg(aa)
        if op == "mul":
            b = n.args[1]
            return add(add(mul(a, d[b.id]), mul(2.0, mul(p1(a), p1(b)))), mul(aa, b))
        if op == "div":  # a = n b  ->  a'' = n'' b + 2 n' b' + n b''
            b = n.args[1]
            return div(sub(sub(aa, mul(2.0, mul(p1(n), p1(b)))), mul(n, d[b.id])), b)
        if op == "sin":
            va = p1(a)
            return sub(mul(cos(a), aa), mul(sin(a), mul(va, va)))
        if op == "cos":
            va = p1(a)
            return neg(add(mul(sin(a), aa), mul(cos(a), mul(va, va))))
        if op == "sqrt":  # n^2 = a  ->  2 n n'' + 2 n'^2 = a''
            vn = p1(n)
            return mul(div(0.5, n), sub(aa, mul(2.0, mul(vn, vn))))
        if op == "atan2":  # n' = N / r2, N = x y' - y x', N' = x y'' - y x'', r2' = 2 (x x' + y y')
            y, x = a, n.args[1]
            r2 = add(mul(x, x), mul(y, y))
            dN = sub(mul(x, aa), mul(y, d[x.id]))
            dr2 = mul(2.0, add(mul(x, p1(x)), mul(y, p1(y))))
            return div(sub(dN, mul(p1(n), dr2)), r2)
        if op == "hypot":  # n^2 = a^2 + b^2 -> n n'' + n'^2 = a a'' + a'^2 + b b'' + b'^2
            b = n.args[1]
            va, vb, vn = p1(a), p1(b), p1(n)
            num = add(add(mul(a, aa), mul(va, va)), add(mul(b, d[b.id]), mul(vb, vb)))
            return div(sub(num, mul(vn, vn)), n)
        if op == "abs":
            return mul(unary("sgn0", a, _sgn0), aa)
        if op in ("sign", "sgn0"):
            return self.zero
        raise AssertionError(f"no second-derivative rule for {op}")


# ===================================================================================== code generation
_FUNCS = {
    "sin": "_sin",
    "cos": "_cos",
    "sqrt": "_sqrt",
    "atan2": "_atan2",
    "hypot": "_hypot",
    "sign": "_sign",
    "sgn0": "_sgn0",
    "abs": "_abs",
}
_BINOP = {"add": "+", "sub": "-", "mul": "*", "div": "/"}


def needed(outputs: Sequence[Expr], checks: Sequence[Expr]) -> set[int]:
    """Nodes the outputs depend on, plus the checks on any of them (and what those checks read)."""
    seen: set[int] = set()

    def close(roots):
        stack = [r for r in roots if r.op != "const" and r.id not in seen]
        while stack:
            n = stack.pop()
            if n.id in seen:
                continue
            seen.add(n.id)
            stack.extend(a for a in n.args if a.op != "const" and a.id not in seen)

    close(outputs)
    changed = True
    while changed:
        changed = False
        for c in checks:
            tested = c.args[0] if c.args else None
            if c.id not in seen and tested is not None and (tested.id in seen or tested.op == "input"):
                close([c])
                changed = True
    return seen


_VECTOR_FUNCS = {
    "_sin": np.sin,
    "_cos": np.cos,
    "_sqrt": np.sqrt,
    "_atan2": np.arctan2,
    "_hypot": np.hypot,
    "_sign": lambda x: np.where(x > 0.0, 1.0, -1.0),
    "_sgn0": lambda x: np.where(x >= 0.0, 1.0, -1.0),
    "_abs": np.abs,
}


def _admissible(check: Callable, rejected: type[Exception]) -> Callable:
    """The check as a mask over arrays: its ``admissible`` method, else the check called point by point
    (a point where it raises ``rejected`` is not admissible)."""
    vector = getattr(check, "admissible", None)
    if vector is not None:
        return vector

    def pointwise(*args):
        arrays = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in args))
        ok = np.empty(arrays[0].shape, dtype=bool)
        for idx in np.ndindex(ok.shape):
            try:
                check(*(float(a[idx]) for a in arrays))
                ok[idx] = True
            except rejected:
                ok[idx] = False
        return ok

    return pointwise


def compile_function(
    name: str,
    inputs: Sequence[str],
    outputs: Sequence[Expr],
    graph: Graph,
    label: str = "",
    vector: bool = False,
    prior: Optional[tuple[Sequence[Expr], set[int]]] = None,
    rejected: type[Exception] = ModelError,
) -> Callable:
    """Straight-line Python computing ``outputs`` (a flat tuple) from the named inputs.

    Nodes in creation order (checks where the description called ``require``); a node used
    once is written into its user's expression (same operations, same order: same floats),
    up to a nesting depth that keeps the generated source easy on the parser.

    ``vector``: the same code on numpy arrays (inputs broadcast together); a check does not
    raise but clears its points from a mask, returned as one more output (True: admissible;
    the other outputs are meaningless where it is False).
    ``rejected``: the exception by which a check without an ``admissible`` method (its
    array form) refuses a point, when it is called point by point there.

    ``prior = (values, done)``: the nodes ``done`` (and their checks) were computed, at the same inputs, by
    another generated function whose output tuple, its nodes ``values`` in order, this one takes as its first
    argument ``_prior``: they are not computed again, those this one reads are unpacked from it (``values``
    must hold every such node: ``Engine._kept``).
    """
    ids = needed(outputs, graph.checks)
    unpack = []
    if prior is not None:
        values, done = prior
        ids -= done
        read = {a.id for i in ids for a in graph.nodes[i].args} | {o.id for o in outputs}
        first = {}
        for k, v in enumerate(values):
            first.setdefault(v.id, k)
        unpack = [
            f"t{v.id}" if v.id in done and v.id in read and v.op not in ("input", "const") and first[v.id] == k else "_"
            for k, v in enumerate(values)
        ]
        missing = {i for i in read & done if graph.nodes[i].op not in ("input", "const")} - set(first)
        assert not missing, f"internal error: {name} reads nodes the prior function does not give: {sorted(missing)}"
        inputs = ["_prior", *inputs]
    ns: dict = {
        "_sin": math.sin,
        "_cos": math.cos,
        "_sqrt": math.sqrt,
        "_atan2": math.atan2,
        "_hypot": math.hypot,
        "_sign": _sign,
        "_sgn0": _sgn0,
        "_abs": abs,
    }
    if vector:
        ns.update(_VECTOR_FUNCS)
    uses: dict[int, int] = {}
    for i in ids:
        for a in graph.nodes[i].args:
            uses[a.id] = uses.get(a.id, 0) + 1
    for o in outputs:
        uses[o.id] = uses.get(o.id, 0) + 2
    inline: dict[int, tuple[str, int]] = {}  # node id -> (expression, nesting depth)

    def ref(n: Expr) -> tuple[str, int]:
        if n.op == "const":
            return (repr(n.value) if n.value >= 0 or math.isnan(n.value) else f"({n.value!r})"), 0
        if n.op == "input":
            return n.value, 0
        if n.id in inline:
            text, depth = inline.pop(n.id)
            return f"({text})", depth
        return f"t{n.id}", 0

    def expr(n: Expr) -> tuple[str, int]:
        parts = [ref(a) for a in n.args]
        depth = 1 + max((d for _, d in parts), default=0)
        if n.op in _BINOP:
            return f"{parts[0][0]} {_BINOP[n.op]} {parts[1][0]}", depth
        if n.op == "neg":
            return f"-{parts[0][0]}", depth
        return f"{_FUNCS[n.op]}({', '.join(p for p, _ in parts)})", depth

    lines = [f"def {name}({', '.join(inputs)}):"]
    if unpack:
        lines.append(f"    {', '.join(unpack)}, = _prior")
    if vector:
        lines.append("    _ok = True")
    for i in sorted(ids):
        n = graph.nodes[i]
        if n.op in ("input", "const"):
            continue
        if n.op == "check":
            key = f"_check{i}"
            ns[key] = _admissible(n.value, rejected) if vector else n.value
            call = f"{key}({', '.join(ref(a)[0] for a in n.args)})"
            lines.append(f"    _ok = _ok & {call}" if vector else f"    {call}")
            continue
        text, depth = expr(n)
        if uses.get(n.id, 0) == 1 and depth < 24:
            inline[n.id] = (text, depth)  # written where it is used
        else:
            lines.append(f"    t{i} = {text}")
    lines.append(f"    return ({''.join(ref(o)[0] + ', ' for o in outputs)}{'_ok, ' if vector else ''})")
    assert not inline, "internal error: an inlined expression was never used"
    fn = compile_generated("\n".join(lines), name, f"mast engine: {label or name}", ns)
    fn.namespace = ns  # what the source calls (the checks): for the C backend (mast.core.native)
    if not vector:
        return fn

    def on_arrays(*args):
        with np.errstate(all="ignore"):  # outside the mask: NaN, never an exception
            return fn(*args)

    on_arrays.source = fn.source
    return on_arrays
