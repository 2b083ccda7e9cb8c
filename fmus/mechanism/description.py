"""A mechanism described in one TOML file (docs/mechanism.md, "Mechanism description files").

The file gives the mechanism's name, its pose coordinates (a subset of x, y, z, psi, theta, phi;
units follow the pose component), the home pose, its legs built from templates (``legs.py``:
PRS, RPS, UPS, PUS) placed at base and platform attachment points with the driven joint and its
stroke, the bodies (mass, centre of mass, inertia) on the platform and on the legs, gravity, and
the parameters every number comes from, each with value, unit and source. Geometry and inertial
numbers are expressions of the parameters in a small subset (``Expression``): with floats they
evaluate, traced they make the parameters named inputs of the generated code (``traced``), so
that one generated code serves every parameter set (the native FMUs compute with what a host sets).

``load(path)`` reads and checks a file (``DescriptionError`` naming the file, the leg or body and
what was expected); ``DescriptionFile.describe(params)`` gives the engine's ``Description`` for a
parameter set (the file's values, overridden by ``params``). A file may ``extend`` another one of the
same folder: the other's mechanism with some parameters of its own (a design of the same structure).
"""

from __future__ import annotations

import ast
import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

from ..common.parameters import ParameterError
from ..common.tracer import cos, sin, sqrt, traced_input
from .engine import Body, Description, Engine, Evaluation, KinematicsError, TracedBody
from .legs import FAMILIES, OPTIONAL_FIELDS, TEMPLATES, Leg, prs_guess, rps_guess
from .topology import POSE_UNITS, Coordinate, Drive, Topology

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = [
    "DESCRIPTIONS",
    "DescriptionError",
    "DescriptionFile",
    "Described",
    "Expression",
    "Parameter",
    "kinematics",
    "load",
    "named_parameters",
]

#: the folder of the shipped description files (package data)
DESCRIPTIONS = Path(__file__).resolve().parent / "descriptions"


class DescriptionError(ValueError):
    """A description file that cannot be: the message names the file, the leg, body or parameter, and what was
    expected."""


# ===================================================================================== units
#: base dimensions of the units a description may use: (m, kg, s, rad, deg)
_BASE = {
    "m": (1, 0, 0, 0, 0),
    "kg": (0, 1, 0, 0, 0),
    "s": (0, 0, 1, 0, 0),
    "rad": (0, 0, 0, 1, 0),
    "deg": (0, 0, 0, 0, 1),
    "N": (1, 1, -2, 0, 0),
    "1": (0, 0, 0, 0, 0),
}
_NUMBER = None  # a literal number: takes the dimension its use needs (docs/mechanism.md)
_ONE = (0, 0, 0, 0, 0)


def dimension(unit: str) -> tuple[int, ...]:
    """The dimension of a unit written as the SSP files write them ("m", "kg.m2", "m/s2", "rad", "1")."""
    dims = [0] * 5
    parts = unit.split("/")
    if not unit or len(parts) > 2:
        raise ValueError(unit)
    for sign_, part in zip((1, -1), parts):
        for factor in part.split("."):
            base = factor.rstrip("0123456789-")
            power = factor[len(base) :] or "1"
            if base not in _BASE:
                raise ValueError(unit)
            for k, v in enumerate(_BASE[base]):
                dims[k] += sign_ * int(power) * v
    return tuple(dims)


def _unit_text(dims) -> str:
    if dims is _NUMBER:
        return "a number"
    names = ("m", "kg", "s", "rad", "deg")
    up = ".".join(f"{n}{p if p != 1 else ''}" for n, p in zip(names, dims) if p > 0)
    down = ".".join(f"{n}{-p if p != -1 else ''}" for n, p in zip(names, dims) if p < 0)
    return (up or "1") + (f"/{down}" if down else "")


# ===================================================================================== expressions
#: the functions an expression may call (evaluated with the engine's, so that they trace)
FUNCTIONS = {"sin": sin, "cos": cos, "sqrt": sqrt, "radians": lambda x: x * (math.pi / 180.0)}
SUBSET = "+ - * / ** (integer exponent), unary -, numbers, parameter names, pi, sin, cos, sqrt, radians"


class Expression:
    """A number of the file: a TOML number, or a string in the subset ``SUBSET`` of Python's expressions,
    checked when read (names, functions, dimensions) and evaluated with the engine's functions."""

    def __init__(self, source: Union[str, float, int], where: str, units: Mapping[str, str]) -> None:
        self.source, self.where = source, where
        if isinstance(source, bool) or not isinstance(source, (str, int, float)):
            raise DescriptionError(f"{where}: {source!r}: expected a number or an expression ({SUBSET})")
        if isinstance(source, (int, float)):
            self.tree, self.names = ast.Constant(float(source)), frozenset()
            return
        try:
            self.tree = ast.parse(source.strip(), mode="eval").body
        except SyntaxError as err:
            raise DescriptionError(f"{where}: expression {source!r} is not valid: {err.msg}") from None
        names: set[str] = set()
        for node in ast.walk(self.tree):
            self._allowed(node, units, names)
        self.names = frozenset(names)

    def _allowed(self, node: ast.AST, units: Mapping[str, str], names: set) -> None:
        bad = None
        if isinstance(node, ast.BinOp):
            if not isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)):
                bad = f"the operator {type(node.op).__name__}"
            elif isinstance(node.op, ast.Pow) and not (
                isinstance(node.right, ast.Constant) and type(node.right.value) is int and 0 < node.right.value < 9
            ):
                bad = "a power other than an integer literal 1..8"
        elif isinstance(node, ast.UnaryOp):
            if not isinstance(node.op, (ast.USub, ast.UAdd)):
                bad = f"the operator {type(node.op).__name__}"
        elif isinstance(node, ast.Call):
            if (
                not (isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS)
                or node.keywords
                or len(node.args) != 1
            ):
                what = node.func.id if isinstance(node.func, ast.Name) else ast.unparse(node.func)
                bad = f"the call {what}(...)" if what not in FUNCTIONS else f"{what} with other than one argument"
        elif isinstance(node, ast.Name):
            if isinstance(node.ctx, ast.Load) and node.id not in FUNCTIONS and node.id != "pi":
                if node.id not in units:
                    raise DescriptionError(
                        f"{self.where}: expression {self.source!r}: unknown parameter "
                        f"{node.id!r} (parameters: {', '.join(units) or 'none'})"
                    )
                names.add(node.id)
        elif isinstance(node, ast.Constant):
            if type(node.value) not in (int, float):
                bad = f"the constant {node.value!r}"
        elif not isinstance(node, (ast.operator, ast.unaryop, ast.expr_context)):
            bad = f"{type(node).__name__} ({ast.unparse(node) if isinstance(node, ast.expr) else ''})"
        if bad:
            raise DescriptionError(f"{self.where}: expression {self.source!r}: {bad} is outside the subset ({SUBSET})")

    def dims(self, units: Mapping[str, str]):
        """The expression's dimension (``_NUMBER`` when it is made of numbers alone); DescriptionError when it
        adds different dimensions or calls a function on an argument of the wrong one."""
        return self._dims(self.tree, units)

    def _dims(self, node, units):
        if isinstance(node, ast.Constant):
            return _NUMBER
        if isinstance(node, ast.Name):
            return _ONE if node.id == "pi" else dimension(units[node.id])
        if isinstance(node, ast.UnaryOp):
            return self._dims(node.operand, units)
        if isinstance(node, ast.Call):
            arg = self._dims(node.args[0], units)
            name = node.func.id
            if name == "sqrt":
                if arg is _NUMBER:
                    return arg
                if any(v % 2 for v in arg):
                    self._mismatch(f"sqrt of {_unit_text(arg)}")
                return tuple(v // 2 for v in arg)
            expected = dimension("deg") if name == "radians" else dimension("rad")
            if arg is not _NUMBER and arg not in (expected, _ONE):
                self._mismatch(f"{name} of {_unit_text(arg)} (expected {_unit_text(expected)})")
            return dimension("rad") if name == "radians" else _NUMBER
        a = self._dims(node.left, units)
        if isinstance(node.op, ast.Pow):
            return a if a is _NUMBER else tuple(v * node.right.value for v in a)
        b = self._dims(node.right, units)
        if isinstance(node.op, (ast.Add, ast.Sub)):
            if a is not _NUMBER and b is not _NUMBER and a != b:
                self._mismatch(f"{_unit_text(a)} {'+' if isinstance(node.op, ast.Add) else '-'} {_unit_text(b)}")
            return b if a is _NUMBER else a
        if a is _NUMBER or a == _ONE:
            return b if not isinstance(node.op, ast.Div) or b is _NUMBER else tuple(-v for v in b)
        if b is _NUMBER or b == _ONE:
            return a
        return tuple(x + y if isinstance(node.op, ast.Mult) else x - y for x, y in zip(a, b))

    def _mismatch(self, what: str) -> None:
        raise DescriptionError(f"{self.where}: expression {self.source!r}: {what}: units of different dimensions")

    def check(self, units: Mapping[str, str], expected: str) -> None:
        """DescriptionError unless the expression has the dimension of ``expected`` (or is a plain number)."""
        dims = self.dims(units)
        if dims is not _NUMBER and dims != dimension(expected) and not (expected == "1" and dims == dimension("rad")):
            raise DescriptionError(
                f"{self.where}: expression {self.source!r} is in {_unit_text(dims)}: expected "
                f"{expected} (its parameters' units: "
                f"{', '.join(f'{n} [{units[n]}]' for n in sorted(self.names))})"
            )

    def __call__(self, env: Mapping[str, object]):
        """The value with the parameters ``env`` (floats, or traced numbers)."""
        return self._eval(self.tree, env)

    def _eval(self, node, env):
        if isinstance(node, ast.Constant):
            return float(node.value)
        if isinstance(node, ast.Name):
            return math.pi if node.id == "pi" else env[node.id]
        if isinstance(node, ast.UnaryOp):
            v = self._eval(node.operand, env)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.Call):
            return FUNCTIONS[node.func.id](self._eval(node.args[0], env))
        a = self._eval(node.left, env)
        if isinstance(node.op, ast.Pow):  # repeated products: the same floats traced or not
            out = a
            for _ in range(node.right.value - 1):
                out = out * a
            return out
        b = self._eval(node.right, env)
        if isinstance(node.op, ast.Add):
            return a + b
        if isinstance(node.op, ast.Sub):
            return a - b
        if isinstance(node.op, ast.Mult):
            return a * b
        return a / b


# ===================================================================================== the file
@dataclass(frozen=True)
class Parameter:
    """A parameter of a description: ``value`` in ``unit``, and its ``source`` (paper table or equation,
    datasheet, measured data, or "assumed: reason"); ``range``: the values a parameter set may give it
    (inclusive bounds, the file's optional ``range = [lower, upper]``; none: any finite number)."""

    name: str
    value: float
    unit: str
    source: str
    range: tuple[float, float] = (-math.inf, math.inf)


def _table(data, where: str, required: Sequence[str], optional: Sequence[str] = ()) -> dict:
    if not isinstance(data, dict):
        raise DescriptionError(f"{where}: expected a table with {', '.join(required)}")
    missing = [k for k in required if k not in data]
    if missing:
        raise DescriptionError(
            f"{where}: missing {', '.join(repr(k) for k in missing)} (expected "
            f"{', '.join(list(required) + list(optional))})"
        )
    unknown = [k for k in data if k not in required and k not in optional]
    if unknown:
        raise DescriptionError(
            f"{where}: unknown {', '.join(repr(k) for k in unknown)} (expected "
            f"{', '.join(list(required) + list(optional))})"
        )
    return data


@dataclass
class _BodySpec:
    name: str
    on: str  # "platform", or the leg's part it rides on ("leg_1:link")
    mass: Expression
    com: tuple
    inertia: tuple
    optional: bool

    def expressions(self):
        return [self.mass, *self.com, *(e for row in self.inertia for e in row)]


@dataclass
class _LegSpec:
    name: str
    template: object
    fields: dict  # field -> Expression or tuple of 3
    kind: str
    stroke: tuple
    bodies: list  # _BodySpec per part


class DescriptionFile:
    """A checked description file (``load``): ``name`` (the mechanism, the ``kinematics`` parameter's value),
    ``title``, ``path``, ``parameters`` (name -> ``Parameter``, in the file's order), ``coordinates``, the
    legs, bodies and home pose as expressions; ``describe`` makes the engine's description."""

    def __init__(self, path: Path, text: str) -> None:
        self.path = Path(path)
        where = self.path.name
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise DescriptionError(f"{where}: not valid TOML: {err}") from None
        if "extends" in data:
            _table(data, where, ("extends", "parameters"), ("title",))
            base = load(self.path.with_name(data["extends"]))
            mech = dict(base.data["mechanism"])
            if "title" in data:
                mech["title"] = data["title"]
            params = dict(base.data["parameters"])
            for name in data["parameters"]:
                if name not in params:
                    raise DescriptionError(
                        f"{where}: parameter {name!r} is not one of {data['extends']}'s "
                        f"({', '.join(params)}): a design that extends another sets its values"
                    )
            params.update(data["parameters"])
            data = {**base.data, "mechanism": mech, "parameters": params}
            self.extends: Optional[str] = base.path.name
        else:
            self.extends = None
        self.data = data
        _table(data, where, ("mechanism", "parameters", "legs"), ("leg", "bodies"))
        mech = _table(
            data["mechanism"], f"{where}: [mechanism]", ("name", "coordinates", "home", "gravity"), ("title",)
        )
        self.name, self.title = str(mech["name"]), str(mech.get("title", mech["name"]))
        self.parameters = self._parameters(data["parameters"], where)
        units = {n: p.unit for n, p in self.parameters.items()}
        self.units = units
        # the legs and their family
        legs = data["legs"]
        if not isinstance(legs, list) or not legs:
            raise DescriptionError(f"{where}: [[legs]]: expected one table per leg")
        shared = data.get("leg", {})
        self.legs = [self._leg({**shared, **leg}, k, where, units) for k, leg in enumerate(legs)]
        families = {leg.template.family for leg in self.legs}
        if len(families) != 1:
            raise DescriptionError(
                f"{where}: legs of templates {', '.join(sorted({l.template.name for l in self.legs}))}"
                f": every leg of a mechanism must be of one family (docs/mechanism.md)"
            )
        self.family = FAMILIES[families.pop()]
        coords = mech["coordinates"]
        if not isinstance(coords, list) or not all(c in POSE_UNITS for c in coords) or len(set(coords)) != len(coords):
            raise DescriptionError(
                f"{where}: [mechanism] coordinates {coords!r}: expected distinct pose components "
                f"from {', '.join(POSE_UNITS)}"
            )
        self.coordinates = tuple(coords)
        if len(self.legs) != len(self.coordinates):
            raise DescriptionError(
                f"{where}: {len(self.legs)} drives (one per leg) for {len(self.coordinates)} "
                f"coordinates ({', '.join(self.coordinates)}): expected one driven joint per "
                f"coordinate"
            )
        if self.coordinates != self.family.coordinates:
            raise DescriptionError(
                f"{where}: [mechanism] coordinates {', '.join(self.coordinates)}: legs of the "
                f"{self.family.name} family ({', '.join(sorted({l.template.name for l in self.legs}))})"
                f" need the coordinates {', '.join(self.family.coordinates)}"
            )
        home = _table(mech["home"], f"{where}: [mechanism.home]", self.coordinates)
        self.home = tuple(
            self._expr(home[c], f"{where}: [mechanism.home] {c}", POSE_UNITS[c]) for c in self.coordinates
        )
        self.gravity = self._expr(mech["gravity"], f"{where}: [mechanism] gravity", "m/s2")
        self.bodies = [
            self._body(b, f"{where}: body {b.get('name', k + 1)!r}" if isinstance(b, dict) else where, units, None)
            for k, b in enumerate(data.get("bodies", []))
        ]
        names = [b.name for leg in self.legs for b in leg.bodies] + [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise DescriptionError(f"{where}: bodies {names}: each name at most once")
        # which parameters are the geometry's (kinematic) and which the generated code takes (traced)
        geometry = set()
        for leg in self.legs:
            for e in leg.fields.values():
                for x in e if isinstance(e, tuple) else (e,):
                    geometry |= x.names
        used = set(geometry) | self.gravity.names
        for b in [b for leg in self.legs for b in leg.bodies] + self.bodies:
            for e in b.expressions():
                used |= e.names
        self.kinematic = tuple(n for n in self.parameters if n in geometry)
        self.traced = tuple(n for n in self.parameters if n in used)
        self._check_home()

    # ---------------------------------------------------------------------------------- reading
    def _parameters(self, table, where: str) -> dict:
        if not isinstance(table, dict):
            raise DescriptionError(f"{where}: [parameters]: expected a table of name = {{ value, unit, source }}")
        out = {}
        for name, entry in table.items():
            w = f"{where}: parameter {name!r}"
            if not name.isidentifier() or name in FUNCTIONS or name == "pi":
                raise DescriptionError(f"{w}: expected a name (letters, digits, _), not a function's")
            _table(entry, w, ("value", "unit", "source"), ("range",))
            value = entry["value"]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise DescriptionError(f"{w}: value {value!r}: expected a finite number")
            bounds = entry.get("range", [-math.inf, math.inf])
            if not (
                isinstance(bounds, list)
                and len(bounds) == 2
                and all(isinstance(b, (int, float)) and not isinstance(b, bool) and not math.isnan(b) for b in bounds)
                and bounds[0] < bounds[1]
            ):
                raise DescriptionError(
                    f"{w}: range {bounds!r}: expected [lower, upper] with lower < upper (inf for no bound)"
                )
            if not bounds[0] <= value <= bounds[1]:
                raise DescriptionError(f"{w}: value {value!r} outside its range [{bounds[0]:g}, {bounds[1]:g}]")
            try:
                dimension(str(entry["unit"]))
            except ValueError:
                raise DescriptionError(
                    f"{w}: unit {entry['unit']!r}: expected a unit made of "
                    f"{', '.join(_BASE)} (for example m, rad, kg, kg.m2, m/s2, 1)"
                ) from None
            if not str(entry["source"]).strip():
                raise DescriptionError(
                    f"{w}: expected its source (paper table or equation, datasheet, measured data,"
                    f" or 'assumed: reason')"
                )
            out[name] = Parameter(
                name, float(value), str(entry["unit"]), str(entry["source"]), (float(bounds[0]), float(bounds[1]))
            )
        return out

    def _expr(self, source, where: str, unit: str) -> Expression:
        e = Expression(source, where, self.units)
        e.check(self.units, unit)
        return e

    def _vector(self, source, where: str, unit: str) -> tuple:
        if not isinstance(source, list) or len(source) != 3:
            raise DescriptionError(f"{where}: {source!r}: expected three numbers or expressions (x, y, z)")
        return tuple(self._expr(v, f"{where}[{k}]", unit) for k, v in enumerate(source))

    def _leg(self, leg, k: int, where: str, units) -> _LegSpec:
        w = f"{where}: leg {k + 1}"
        if not isinstance(leg, dict) or "template" not in leg:
            raise DescriptionError(f"{w}: expected a table with template = {' | '.join(TEMPLATES)}")
        template = TEMPLATES.get(leg["template"])
        if template is None:
            raise DescriptionError(f"{w}: template {leg['template']!r}: expected one of {', '.join(TEMPLATES)}")
        name = str(leg.get("name", f"leg_{k + 1}"))
        w = f"{where}: leg {name!r} ({template.name})"
        optional = [f for f in template.fields if f in OPTIONAL_FIELDS]
        required = [f for f in template.fields if f not in OPTIONAL_FIELDS]
        _table(leg, w, ["template", *required], ["name", "drive", "drives", "bodies", *optional])
        fields = {}
        for f, unit in template.fields.items():
            src = leg.get(f, OPTIONAL_FIELDS.get(f))
            if f in ("base", "platform", "guide", "axis"):
                fields[f] = self._vector(src, f"{w}: {f}", unit)
            else:
                fields[f] = self._expr(src, f"{w}: {f}", unit)
        drives = leg.get("drives", [leg["drive"]] if "drive" in leg else [])
        drivable = " or ".join(template.drivable)
        if not isinstance(drives, list) or len(drives) != 1:
            got = "no driven joint" if not drives else f"{len(drives)} driven joints"
            raise DescriptionError(
                f'{w}: {got}: expected exactly one, drive = {{ joint = "{drivable}", kind, stroke = [lower, upper] }}'
            )
        drive = _table(drives[0], f"{w}: drive", ("joint", "kind", "stroke"))
        if drive["joint"] not in template.drivable:
            raise DescriptionError(
                f"{w}: drive joint {drive['joint']!r}: expected {drivable} (the {template.name} "
                f"template's drivable joint)"
            )
        kind = template.drivable[drive["joint"]]
        if drive["kind"] != kind:
            raise DescriptionError(f"{w}: drive kind {drive['kind']!r}: joint {drive['joint']} is {kind}")
        stroke = drive["stroke"]
        if not (
            isinstance(stroke, list)
            and len(stroke) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in stroke)
            and stroke[0] < stroke[1]
        ):
            raise DescriptionError(
                f"{w}: drive stroke {stroke!r}: expected [lower, upper] "
                f"[{'m' if kind == 'linear' else 'rad'}] with lower < upper"
            )
        bodies = leg.get("bodies", {})
        if not isinstance(bodies, dict) or any(p not in template.parts for p in bodies):
            raise DescriptionError(
                f"{w}: bodies {list(bodies) if isinstance(bodies, dict) else bodies!r}: expected "
                f"a table by part ({', '.join(template.parts)})"
            )
        specs = []
        for part in template.parts:
            body = bodies.get(part, {"mass": 0.0})
            body_name = name if len(template.parts) == 1 else f"{name}_{part}"
            specs.append(
                self._body(
                    {"name": body_name, **body}, f"{w}: body {body_name!r} (part {part})", units, f"{name}:{part}"
                )
            )
        return _LegSpec(name, template, fields, kind, (float(stroke[0]), float(stroke[1])), specs)

    def _body(self, body, where: str, units, on: Optional[str]) -> _BodySpec:
        _table(body, where, ("name", "mass"), ("com", "inertia", "optional"))
        zero = [0.0, 0.0, 0.0]
        inertia = body.get("inertia", [zero, zero, zero])
        if not isinstance(inertia, list) or len(inertia) != 3:
            raise DescriptionError(
                f"{where}: inertia {inertia!r}: expected a 3x3 tensor [[xx, xy, xz], ...] "
                f"[kg.m2] about the centre of mass"
            )
        return _BodySpec(
            str(body["name"]),
            on or "platform",
            self._expr(body["mass"], f"{where}: mass", "kg"),
            self._vector(body.get("com", zero), f"{where}: com", "m"),
            tuple(self._vector(row, f"{where}: inertia row {k + 1}", "kg.m2") for k, row in enumerate(inertia)),
            bool(body.get("optional", False)),
        )

    # ---------------------------------------------------------------------------------- checks
    def _check_home(self) -> None:
        """With the file's values: every leg closes at home, within its stroke; home is not singular."""
        where = self.path.name
        desc = self.describe(owner=where)
        try:
            home = desc.topology.home
        except (ValueError, ZeroDivisionError, OverflowError) as exc:
            raise DescriptionError(
                f"{where}: [mechanism.home] cannot be evaluated with the file's values: {type(exc).__name__}: {exc}"
            ) from None
        try:
            pose, R, S = self.family.pose(list(home), desc.legs)
        except KinematicsError as exc:
            raise DescriptionError(f"{where}: the home pose {self._pose_text(home)} is not admissible: {exc}") from None
        for leg, spec, Si in zip(desc.legs, self.legs, S):
            try:
                rho, _ = leg.close(Si, list(home))
            except KinematicsError as exc:
                raise DescriptionError(
                    f"{where}: leg {spec.name!r} ({spec.template.name}) does not close at the home "
                    f"pose {self._pose_text(home)}: {exc}"
                ) from None
            lo, hi = spec.stroke
            if not lo <= rho <= hi:
                raise DescriptionError(
                    f"{where}: leg {spec.name!r}: its drive's stroke [{lo:g}, {hi:g}] excludes home "
                    f"({rho:.6g} at the home pose {self._pose_text(home)})"
                )
        engine = Engine(desc, g=0.0)
        try:
            engine.jacobian(home)
            margins = engine.margins(home)
        except KinematicsError as exc:
            raise DescriptionError(f"{where}: the home pose {self._pose_text(home)} is singular: {exc}") from None
        if not margins.smallest > 0.0:
            raise DescriptionError(
                f"{where}: the home pose {self._pose_text(home)} is singular: margins parallel "
                f"{margins.parallel:.3g}, inverse {margins.inverse:.3g} m/m"
            )

    def _pose_text(self, home) -> str:
        return "(" + ", ".join(f"{c} = {v:.6g} {POSE_UNITS[c]}" for c, v in zip(self.coordinates, home)) + ")"

    # ---------------------------------------------------------------------------------- descriptions
    def values(
        self, params: Optional[Mapping[str, object]] = None, masses: bool = True, owner: str = ""
    ) -> dict[str, float]:
        """The parameters' values: the file's (``params`` None), or those of ``params``, which must hold every
        parameter the description uses, as numbers (ParameterError naming the first missing or not a number);
        ``masses=False``: those that are not the geometry's (``kinematic``) are 0 (a kinematic model: massless
        bodies, no gravity), and need not be in ``params``."""
        out = {}
        for name, p in self.parameters.items():
            if not masses and name not in self.kinematic:
                out[name] = 0.0
            elif params is None:
                out[name] = p.value
            elif name in params:
                try:
                    out[name] = float(params[name])
                except (TypeError, ValueError):
                    raise ParameterError(
                        f"{owner or self.path.name}: parameter {name!r} = {params[name]!r}: expected a number "
                        f"[{p.unit}] ({self.name} description, {self.path.name})"
                    ) from None
            elif name in self.traced:
                raise ParameterError(
                    f"{owner or self.path.name}: missing parameter {name!r} [{p.unit}] of the "
                    f"{self.name} description ({self.path.name})"
                )
            else:
                out[name] = p.value
        return out

    def describe(
        self, params: Optional[Mapping[str, object]] = None, masses: bool = True, traced: bool = False, owner: str = ""
    ) -> "Described":
        """The engine's description with ``values(params, masses)``; ``traced``: the parameters ``traced`` as
        named inputs of the generated functions (the same floats as the constants, up to the sign of a zero)."""
        return Described(self, self.values(params, masses, owner), masses, traced, owner or self.path.name)


class Described(Description):
    """The engine's description of a description file at parameter values (``DescriptionFile.describe``):
    ``values`` (name -> float), ``legs`` (``legs.Leg`` with float geometry), ``bodies`` (``Body``)."""

    def __init__(
        self, file: DescriptionFile, values: Mapping[str, float], masses: bool, traced: bool, owner: str
    ) -> None:
        self.file, self.params, self.masses, self.traced = file, dict(values), masses, traced
        self.name = file.name
        self.coordinates = file.coordinates
        self.joints = tuple(f"rho_{k + 1}" for k in range(len(file.legs)))
        self.legs = self.legs_at(self.params, False)
        self.bodies = tuple(self._bodies(self.params, owner))
        radius = max(math.hypot(*leg.platform_point()) for leg in self.legs)
        #: per coordinate, whether its length is the platform's radius: a tilt moves the spherical joints by their
        #: largest distance from P times the angle (else 1 m)
        self.radius_scaled = tuple(POSE_UNITS[c] != "m" for c in self.coordinates)
        self.lengths = tuple(radius if scaled else 1.0 for scaled in self.radius_scaled)
        #: the parameter values when traced as inputs (``Evaluation.parameters``), in the file's ``traced`` order
        self.values = {n: self.params[n] for n in file.traced} if traced else None

    def legs_at(self, env: Mapping[str, object], traced: bool) -> list[Leg]:
        """The legs with the parameters ``env`` (floats, or traced numbers: ``traced``)."""
        out = []
        for k, spec in enumerate(self.file.legs):
            geometry = {f: tuple(x(env) for x in e) if isinstance(e, tuple) else e(env) for f, e in spec.fields.items()}
            out.append(Leg(spec.template, k, geometry, traced))
        return out

    def body_specs(self) -> list:
        """The bodies as the file gives them (name, mass, com, inertia as expressions; ``optional``), legs' first."""
        return [b for leg in self.file.legs for b in leg.bodies] + list(self.file.bodies)

    def _bodies(self, env: Mapping[str, float], owner: str) -> list[Body]:
        out = []
        for spec in self.body_specs():
            mass = spec.mass(env)
            com = tuple(e(env) for e in spec.com)
            inertia = tuple(tuple(e(env) for e in row) for row in spec.inertia)
            if spec.optional and mass == 0.0 and not any(any(row) for row in inertia):
                continue
            try:
                out.append(Body(spec.name, mass, com, inertia))
            except ValueError as exc:
                blamed = [e for row in spec.inertia for e in row] if "inertia" in str(exc) else [spec.mass]
                names = sorted({n for e in blamed for n in e.names})
                raise ParameterError(f"{owner}: parameters {named_parameters(names)}: {exc}") from None
        return out

    def key(self) -> tuple:
        return ("Described", str(self.file.path), tuple(self.params.items()), self.masses, self.traced)

    def evaluate(self, q: Sequence) -> Evaluation:
        if self.values is None:
            legs, bodies = self.legs, None
        else:
            env = {n: traced_input(q[0], n) for n in self.file.traced}
            env.update({n: v for n, v in self.params.items() if n not in env})
            legs = self.legs_at(env, True)
            bodies = [
                TracedBody(
                    s.name,
                    s.mass(env),
                    tuple(e(env) for e in s.com),
                    tuple(tuple(e(env) for e in row) for row in s.inertia),
                )
                for s in self.body_specs()
            ]
        pose, R, S = self.file.family.pose(q, legs)
        rho, frames = [], []
        for leg, Si in zip(legs, S):
            r, parts = leg.close(Si, q)
            rho.append(r)
            frames += parts
        frames += [((pose[0], pose[1], pose[2]), R)] * len(self.file.bodies)
        present = {b.name for b in (bodies if bodies is not None else self.bodies)}
        frames = [f for spec, f in zip(self.body_specs(), frames) if spec.name in present]
        if self.values is None:
            return Evaluation(rho, pose, frames)
        return Evaluation(rho, pose, frames, bodies, self.values, self.file.gravity(env))

    def guess(self, rho: Sequence[float]) -> tuple[float, ...]:
        """Level pose for the mean joint coordinate (3PRS: ``level_height``), else the home pose (``guess_rule``)."""
        rule, numbers = self.guess_rule(self.legs, self.params)
        return rule(*rho, *numbers) if rule else tuple(float(v) for v in numbers)

    def guess_rule(self, legs: Sequence[Leg], env: Mapping[str, object]) -> tuple[Optional[Callable], tuple]:
        """The direct kinematics' cold start as (rule, numbers): ``rule(rho_1, .., rho_n, *numbers)`` (a function of
        the generated-code subset, legs.py) with the ``numbers`` the geometry gives it, or (None, the guess
        itself), for ``legs`` and the parameters ``env`` (floats, or traced numbers: the native mechanism computes
        the numbers from the parameters a host sets and translates the rule). 3PRS: the level pose for the mean
        slider position (``legs.prs_guess``); 3-RPS: the level pose for the mean leg length (``legs.rps_guess``);
        otherwise the home pose."""
        g = legs[0]
        if self.file.family.name == "plane" and all(leg.template.name == "PRS" for leg in legs):
            return prs_guess, (g.g["base_radius"], g.g["platform_radius"], g.g["length"], g.cb, g.sb)
        if self.file.family.name == "plane":  # RPS: the leg length is the distance in the leg's plane
            return rps_guess, (g.g["base_radius"] - g.g["platform_radius"],)
        return None, tuple(e(env) for e in self.file.home)

    @property
    def topology(self) -> Topology:
        """The file's coordinates, one drive per leg (rho_k, its kind and stroke), the home pose at these values."""
        home = tuple(float(e(self.params)) for e in self.file.home)
        return Topology(
            self.name,
            tuple(Coordinate(c) for c in self.coordinates),
            tuple(Drive(j, spec.kind, spec.stroke) for j, spec in zip(self.joints, self.file.legs)),
            home,
        )

    def sketch(self):
        """The base (a disc through the legs' base points), each leg's parts (``legs.Leg.sketch``), the platform (a
        disc through the spherical joints) and its spherical joints."""
        from .engine import Part

        rim = [2.0 * math.pi * k / _RIM_POINTS for k in range(_RIM_POINTS)]
        R0 = max(math.hypot(*leg.base_point()[:2]) for leg in self.legs)
        r = max(math.hypot(*leg.platform_point()) for leg in self.legs)
        parts = [Part("plate", None, [(R0 * math.cos(a), R0 * math.sin(a), 0.0) for a in rim])]
        names = [b.name for b in self.bodies]
        for leg, spec in zip(self.legs, self.file.legs):
            parts += leg.sketch([b.name for b in spec.bodies if b.name in names], spec.stroke[0])
        parts += [
            Part("plate", "platform", [(r * math.cos(a), r * math.sin(a), 0.0) for a in rim]),
            Part("joint", "platform", [leg.platform_point() for leg in self.legs]),
        ]
        return tuple(parts)


#: points on the outline of the base and of the platform in the drawing
_RIM_POINTS = 48


def named_parameters(names: Sequence[str]) -> str:
    """Parameters as an error names them: 'I_payload_*' for several of one prefix, else each."""
    if len(names) > 1:
        prefix = names[0]
        for n in names[1:]:
            while not n.startswith(prefix):
                prefix = prefix[:-1]
        if prefix.endswith("_"):
            return f"'{prefix}*'"
    return ", ".join(f"'{n}'" for n in names)


#: the shipped files' text, read when this module is imported: a model bundled in an FMU reads them from the
#: folder it was imported from, which its host may remove while the model lives on
_SHIPPED = {p.name: p.read_text(encoding="utf-8") for p in sorted(DESCRIPTIONS.glob("*.toml"))}


@functools.lru_cache(maxsize=32)
def _load(path: Path, text: str) -> DescriptionFile:
    return DescriptionFile(path, text)


def load(path: Union[str, Path]) -> DescriptionFile:
    """The checked description file at ``path``, or the shipped one of that name (``DESCRIPTIONS``: "3PRS_T" or
    "3PRS_T.toml")."""
    p = Path(path)
    if not p.suffix:
        p = p.with_suffix(".toml")
    if p.parent == Path(".") or p.parent == DESCRIPTIONS:
        if p.name in _SHIPPED:
            return _load(DESCRIPTIONS / p.name, _SHIPPED[p.name])
        if p.parent == Path("."):
            p = DESCRIPTIONS / p.name
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as err:
        raise DescriptionError(f"{p.name}: cannot be read: {err}") from None
    return _load(p.resolve(), text)


def kinematics() -> dict[str, Path]:
    """The shipped mechanisms by name (the ``kinematics`` parameter's values): their description files that
    extend no other."""
    out = {}
    for name, text in _SHIPPED.items():
        data = tomllib.loads(text)
        if "extends" not in data:
            out[str(data.get("mechanism", {}).get("name", name))] = DESCRIPTIONS / name
    return out
