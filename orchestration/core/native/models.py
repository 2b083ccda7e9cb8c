"""One C model file per FMU, from the model the Python FMU runs (``mast build --native``).

Each emitter builds the Python block with the FMU's parameter set and takes its generated
code, which ``translate.to_c`` writes as C:

- actuator: the exact-discretisation step with the implicit friction solve
  (``ActuatorBlock._compile``), one kernel per step size the systems use;
- mechanism (every design): the engine's traced functions (inverse kinematics with its
  Jacobian, inverse dynamics, pose), driven by the engine's Newton direct kinematics
  (``mast_native.h``);
- controllers (``native_controllers``: the joint cascade, feed-forward, computed torque,
  workspace): the engine's traced inverse kinematics, and the cascade's tick with each one's laws;
  the feed-forward and computed-torque controllers' inverse model (the model engine's direct
  kinematics and traced dynamics), the workspace controller's direct kinematics and Jacobian;
- trajectory: the sine about the home pose (its parameters read at run time).

What the models' generators do not cover is written here, in the same Python subset, and
translated too: the outputs of the actuator at rest (``initialize``), the description's cold
start of the direct kinematics (``guess``) and the controllers' tick (``DriveController``'s
schedule with each controller's position and velocity laws; the functions they call are
translated from the models' own source: ``pi_step``, ``drive_gains``, ``cascade_gains``,
``transmission_ratio``, ``reference.rates``, ``inverse_model.motor_torque``, ``guide_friction``).
The schedule and the laws are a second statement of the controllers', held bit-identical to the
Python models by tests/test_native.py until the Python controllers run this generated tick
themselves (docs/native.md); so is the C glue of the direct kinematics (``MechanismBlock._compute``,
``InverseModel.torques``, ``WorkspaceController._dk``: warm start, cold restart, messages).

Parameters: the trajectory's, the joint controller's gains, limits and transmission
(``CONTROLLER_TUNABLE``: its gains computed at initialisation by the controller's own
``drive_gains``/``cascade_gains``, translated) and the mechanism's masses, inertias and g
(``MECHANISM_TUNABLE``: inputs of the engine's ``forces_of``) are read at run time. The others
have their values inlined, as in the Python model (where the actuator's kernel is compiled at
the first step and the engine traces with the geometry as constants): ``generated_parameters`` names
them, the C model checks at initialisation that each still has the value it was generated for,
and refuses another value with a message naming it (the Python model's range checks come first,
with the same messages). The project's master generates the model for another set of those when
it needs one (``build.for_parameters``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

from fmus.common.parameters import Param
from fmus.mechanism.designs import GRAVITY_PARAMETER, INERTIAL_PARAMETERS

from .translate import c_double, to_c

__all__ = ["Variable", "emit_model", "c_string", "generated_parameters"]

#: relative difference below which a Real parameter counts as the value a model was generated for
#: (a host that applies a modelDescription start value, printed with 16 digits, gets the same model)
SAME_VALUE = 1e-13


@dataclass(frozen=True)
class Variable:
    """A variable of the modelDescription (value references are 0..n-1 in order)."""

    name: str
    vr: int
    type: str          # "Real", "Integer", "String"
    causality: str     # "input", "output", "parameter"
    start: object


def c_string(text: str) -> str:
    """A C string literal of ``text``."""
    out = ['"']
    for ch in text:
        if ch in '\\"':
            out.append("\\" + ch)
        elif ch == "\n":
            out.append("\\n")
        elif ch == "%":
            out.append("%%")
        elif 32 <= ord(ch) < 127:
            out.append(ch)
        else:
            out.extend(f"\\{b:03o}" for b in ch.encode())
    out.append('"')
    return "".join(out)


def _literal(text: str) -> str:
    """A C string literal used as data, not as a format."""
    return c_string(text).replace("%%", "%")


# ----------------------------------------------------------------------------------- shared parts
def _why_function(name: str, checks: Mapping[str, object]) -> str:
    """``static const char *name(int check)``: the message of the traced check ``_check<N>`` (its c_message)."""
    cases = [f"    case {int(k.replace('_check', ''))}: return {_literal(v.c_message)};" for k, v in sorted(checks.items())]
    return "\n".join([f"static const char *{name}(int check)", "{", "    switch (check) {", *cases,
                      "    default: return \"a check of the description failed\";", "    }", "}", ""])


def _variable_table(variables: Sequence[Variable]) -> str:
    rows = []
    for v in variables:
        kind = {"Real": "MAST_REAL", "Integer": "MAST_INTEGER", "String": "MAST_STRING"}[v.type]
        causality = {"input": "MAST_INPUT", "output": "MAST_OUTPUT", "parameter": "MAST_PARAMETER"}[v.causality]
        real = c_double(float(v.start)) if v.type == "Real" else "0.0"
        integer = str(int(v.start)) if v.type == "Integer" else "0"
        string = _literal(str(v.start)) if v.type == "String" else '""'
        rows.append(f"    {{{_literal(v.name)}, {kind}, {causality}, {real}, {integer}, {string}}},")
    return "static const mast_variable VARIABLES[] = {\n" + "\n".join(rows) + "\n};\n"


def _check_function(params: Sequence[Param], vrs: Mapping[str, int], fixed: Mapping[str, object]) -> str:
    """``check``: the Python model's range checks (``Param.check``, the same messages), then, for the
    parameters in ``fixed``, that the value is the one the code was generated for."""
    lines = ["static int check(const mast_parameters *p, char *msg, size_t size)", "{",
             "    char v[40], c[40];", "    (void)v; (void)c;"]
    for spec in params:
        vr = vrs[spec.name]
        name = spec.name
        if spec.kind is str:
            if name in fixed:
                lines += [
                    f"    if (strcmp(p->string[{vr}] ? p->string[{vr}] : \"\", {_literal(str(fixed[name]))}) != 0) {{",
                    f"        snprintf(msg, size, \"parameter '{name}' = '%s': this native FMU was generated for "
                    f"{name} = '%s'; rebuild it (mast build --native) for another value\", p->string[{vr}] ? "
                    f"p->string[{vr}] : \"\", {_literal(str(fixed[name]))});",
                    "        return MAST_PARAMETER_ERROR;", "    }"]
            continue
        expected = c_string(spec.expected())
        if spec.kind is int:
            value, show = f"(double)p->integer[{vr}]", f"snprintf(v, sizeof v, \"%d\", p->integer[{vr}])"
        else:
            value, show = f"p->real[{vr}]", f"mast_repr(p->real[{vr}], v, sizeof v)"
            lines += [f"    if (!isfinite({value})) {{", f"        {show};",
                      f"        snprintf(msg, size, \"parameter '{name}' = %s: expected a finite number\", v);",
                      "        return MAST_PARAMETER_ERROR;", "    }"]
        lo, hi = ("<=", ">=") if spec.exclusive else ("<", ">")
        bad = []
        if spec.minimum != -math.inf:
            bad.append(f"{value} {lo} {c_double(spec.minimum)}")
        if spec.maximum != math.inf:
            bad.append(f"{value} {hi} {c_double(spec.maximum)}")
        if bad:
            lines += [f"    if ({' || '.join(bad)}) {{", f"        {show};",
                      f"        snprintf(msg, size, \"parameter '{name}' = %s: expected \" {expected}, v);",
                      "        return MAST_PARAMETER_ERROR;", "    }"]
        if name in fixed:
            if spec.kind is int:
                same = f"p->integer[{vr}] == {int(fixed[name])}"
                shown = f"snprintf(c, sizeof c, \"%d\", {int(fixed[name])})"
            else:
                ref = c_double(float(fixed[name]))
                same = f"fabs(p->real[{vr}] - {ref}) <= {c_double(SAME_VALUE)} * fabs({ref})"
                shown = f"mast_repr({ref}, c, sizeof c)"
            lines += [f"    if (!({same})) {{", f"        {show};", f"        {shown};",
                      f"        snprintf(msg, size, \"parameter '{name}' = %s: this native FMU was generated for "
                      f"{name} = %s; rebuild it (mast build --native) for another value\", v, c);",
                      "        return MAST_PARAMETER_ERROR;", "    }"]
    lines += ["    return MAST_OK;", "}", ""]
    return "\n".join(lines)


def _model_struct(identifier: str, guid: str, variables: Sequence[Variable], n_inputs: int, n_io: int) -> str:
    return (f"const mast_model MAST_MODEL = {{{_literal(identifier)}, {_literal(guid)}, {len(variables)}, VARIABLES, "
            f"{n_inputs}, {n_io}, sizeof(State), check, initialize, do_step}};\n")


_HEAD = """/* Generated by mast build --native from the {what} (mast.core.native.models): do not edit. */
#include "mast_native.h"
#include "mast_model.h"

"""


# ----------------------------------------------------------------------------------- actuator
def _actuator(block, step_sizes: Sequence[float]) -> str:
    from fmus.actuator.model import _ERRORS

    kernels, keys = [], []
    for k, h in enumerate(step_sizes):
        key = float(f"{h:.12g}")      # ActuatorBlock._select's key
        kernel, _substeps = block._compile(key)
        kernels.append(to_c(kernel.source, f"kernel_{k}", arrays=("values", "x")))
        keys.append(key)
    p, N = block.params, block.N
    n_in = len(block.INPUTS)
    nx = 2 * N + 1
    tau_c, omega_c, tau_s, omega_s = (float(p[k]) for k in ("tau_c", "omega_c", "tau_s", "omega_s"))
    # ActuatorBlock.initialize + _write_outputs at rest (x = 0), in the generated-code subset
    rest = ["def rest(values):", "    u = values[0]", "    F = values[1]",
            "    if u - u != 0.0: return 1", "    if F - F != 0.0: return 2",
            "    w = 0.0", f"    tf = {tau_c!r}*tanh(w/{omega_c!r})"]
    if tau_s > 0.0:
        rest.append(f"    tf = tf + {tau_s!r}*exp(-((w/{omega_s!r})*(w/{omega_s!r})))*tanh(w/{omega_c!r})")
    weight = float(p["M_load"]) * float(p["g_guide"])
    rest.append(f"    tl = -{block.i_R!r}*(F + {weight!r}) - tf")
    if float(p["tau_ripple"]) > 0.0:
        rest.append("    tl = tl - 0.0")    # sin(0) at rest: tau_ripple * 0.0
    rest += [f"    al = 0.0 + {float(block.B[2 * N, 1])!r}*tl",
             f"    values[{n_in}:] = ({float(p['rho_0'])!r} + {block.i_R!r}*0.0, {block.i_R!r}*w, {block.i_R!r}*al, "
             f"0.0, 0.0, 0.0, {float(p['k_T'])!r}*0.0, {float(p['k_T'])!r}*0.0)",
             "    return 0"]
    rest_c = to_c("\n".join(rest) + "\n", "rest", arrays=("values",))
    names = ", ".join(_literal(_ERRORS[k]) for k in sorted(_ERRORS))
    key_list = ", ".join(c_double(k) for k in keys)
    cases = "\n".join(f"    case {k}: code = kernel_{k}(values, s->x); break;" for k in range(len(keys)))
    shown = ", ".join(f"{k:g}" for k in keys)
    rho0, iR = c_double(float(p["rho_0"])), c_double(block.i_R)
    return "\n".join([
        f"typedef struct {{ double x[{nx}]; }} State;", "",
        *kernels, rest_c,
        f"static const char *const INPUT_NAMES[] = {{{names}}};",
        f"static const double KEYS[] = {{{key_list}}};", "",
        "static int input_error(const double *values, int code, double t, char *msg, size_t size)", "{",
        "    char v[40];",
        "    double x = values[code - 1];",
        "    mast_repr(x, v, sizeof v);",
        "    snprintf(msg, size, \"input '%s' = %s at t=%.9g s is not finite\", INPUT_NAMES[code - 1], v, t);",
        "    return MAST_MODEL_ERROR;", "}", "",
        "static int initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size)",
        "{", "    State *s = state;", "    (void)p;",
        f"    for (int k = 0; k < {nx}; k++) s->x[k] = 0.0;",
        "    int code = rest(values);",
        "    return code ? input_error(values, code, t0, msg, size) : MAST_OK;", "}", "",
        "static int do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg, size_t size)",
        "{", "    State *s = state;", "    char v[40], key_text[40];", "    int code = -1;", "    (void)p;",
        "    if (!(h > 0.0 && isfinite(h))) {",
        "        snprintf(msg, size, \"step size h = %s s: expected a finite positive number\", mast_repr(h, v, sizeof v));",
        "        return MAST_MODEL_ERROR;", "    }",
        "    snprintf(key_text, sizeof key_text, \"%.12g\", h);",
        "    double key = strtod(key_text, NULL);",
        "    int which = -1;",
        # a host that adds steps (libcosim: t = 2.0001 s, h = 9.99999999997669e-05 s) is a rounding off a key
        f"    for (int k = 0; k < {len(keys)}; k++) if (KEYS[k] == key || fabs(KEYS[k] - h) <= 1e-9 * KEYS[k]) which = k;",
        "    switch (which) {", cases, "    default:",
        f"        snprintf(msg, size, \"step size h = %s s: this native FMU has the exact discretisation for h in "
        f"{{{shown}}} s (the step sizes of the systems it was built for); rebuild it (mast build --native) for another\", "
        f"mast_repr(h, v, sizeof v));",
        "        return MAST_MODEL_ERROR;", "    }",
        "    if (code == 1 || code == 2) return input_error(values, code, t, msg, size);",
        "    if (code == 3) {",
        "        snprintf(msg, size, \"diverged at t=%.9g s (non-finite state)\", t + h);",
        "        return MAST_MODEL_ERROR;", "    }",
        "    if (code == 4) {",
        f"        snprintf(msg, size, \"carriage left the stroke [%g, %g] m: rho = %.6g m at t=%.9g s\", "
        f"{c_double(float(p['rho_min']))}, {c_double(float(p['rho_max']))}, {rho0} + {iR} * s->x[{N}], t + h);",
        "        return MAST_MODEL_ERROR;", "    }",
        "    return MAST_OK;", "}", ""])


# ----------------------------------------------------------------------------------- mechanism
def _guess_source(desc) -> str:
    """PRS3.guess (the direct kinematics' cold start) in the generated-code subset."""
    lines = ["def guess(rho):", "    mean = (rho[0] + rho[1] + rho[2]) / 3.0"]
    if not desc.inclined:
        lines.append(f"    return (mean + {desc.geometry.home_reach!r}, 0.0, 0.0)")
    else:
        lines += [f"    gap = {desc.r!r} - {desc.H!r} + mean * {desc._sb!r}",
                  f"    w2 = {desc.L!r} * {desc.L!r} - gap * gap",
                  "    if 0.0 > w2: w2 = 0.0",
                  f"    return (mean * {desc._cb!r} + sqrt(w2), 0.0, 0.0)"]
    return "\n".join(lines) + "\n"


def _mechanism(block, vrs: Mapping[str, int]) -> str:
    eng = block.engine
    ikjac = eng._fn("ikjac")
    if block.attached:    # the masses, inertias and g read at run time (MECHANISM_TUNABLE)
        main, tunable = eng.forces_of(INERTIAL_PARAMETERS, GRAVITY_PARAMETER)
    else:
        main, tunable = eng._fn("pose"), []
    checks = {**ikjac.namespace, **main.namespace}
    checks = {k: v for k, v in checks.items() if k.startswith("_check")}
    ik_c = to_c(ikjac.source, "ikjac", checks=checks)
    main_c = to_c(main.source, "dynamics" if block.attached else "pose", checks=checks)
    guess_c = to_c(_guess_source(eng.description), "guess", arrays=("rho",))
    inputs = ", ".join(_literal(n) for n in block.INPUTS)
    coordinates = ", ".join(_literal(n) for n in eng.description.coordinates)
    lengths = ", ".join(c_double(v) for v in eng.lengths)
    if len(eng.lengths) != 3:
        raise ValueError(f"{block.name}: the native direct kinematics takes three coordinates, not {len(eng.lengths)}")
    dk = (f"mast_dk3(ikjac, why, COORDINATES, LENGTHS, {c_double(eng.margin)}, values, q, J, 1e-12, 50, "
          f"{c_double(eng.cond_limit)}, why_text, sizeof why_text)")
    if block.attached:
        call = "dynamics(q[0], q[1], q[2], J[0], J[1], J[2], J[3], J[4], J[5], J[6], J[7], J[8], " \
               "values[3], values[4], values[5], values[6], values[7], values[8], " \
               + "".join(f"p->real[{vrs[name]}], " for name in tunable) + "values + 9)"
        write = [f"    code = {call};"]
    else:
        write = ["    values[9] = 0.0; values[10] = 0.0; values[11] = 0.0;",
                 "    code = pose(q[0], q[1], q[2], values + 12);"]
    return "\n".join([
        "typedef struct { double q[3]; int warm; } State;", "",
        ik_c, main_c, guess_c,
        _why_function("why", checks),
        f"static const char *const INPUT_NAMES[] = {{{inputs}}};",
        f"static const char *const COORDINATES[] = {{{coordinates}}};",
        f"static const double LENGTHS[] = {{{lengths}}};   /* Engine.lengths [m]: the margins compare motions */", "",
        "static int kinematics_error(const double *values, double t, const char *what, char *msg, size_t size)", "{",
        "    char a[40], b[40], c[40], d[40];",
        "    snprintf(msg, size, \"at t = %s s, rho = (%s, %s, %s) m: %s\", mast_repr(t, d, sizeof d), "
        "mast_repr(values[0], a, sizeof a), mast_repr(values[1], b, sizeof b), mast_repr(values[2], c, sizeof c), what);",
        "    return MAST_KINEMATICS_ERROR;", "}", "",
        "/* MechanismBlock._compute: direct kinematics (warm start, else cold), then the forces and the pose */",
        "static int compute(State *s, double *values, const mast_parameters *p, double t, char *msg, size_t size)", "{",
        "    (void)p;",
        "    char v[40], w[40], why_text[1024];",
        "    double q[3], J[9], cold[3];",
        "    int code;",
        "    for (int k = 0; k < 9; k++) {",
        "        if (!isfinite(values[k])) {",
        "            snprintf(msg, size, \"input '%s' = %s is not finite at t = %s s\", INPUT_NAMES[k], "
        "mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));",
        "            return MAST_MODEL_ERROR;", "        }", "    }",
        "    guess(values, cold);",
        "    for (int k = 0; k < 3; k++) q[k] = s->warm ? s->q[k] : cold[k];",
        f"    code = {dk};",
        "    if (code && code != MAST_SINGULARITY_ERROR && s->warm) {   /* never restarted after a SingularityError */",
        "        for (int k = 0; k < 3; k++) q[k] = cold[k];",
        f"        code = {dk};",
        "    }",
        "    if (code) {",
        "        kinematics_error(values, t, why_text, msg, size);",
        "        return code;          /* MAST_KINEMATICS_ERROR, or MAST_SINGULARITY_ERROR: it stays one */",
        "    }",
        *write,
        "    if (code) return kinematics_error(values, t, why(-code), msg, size);",
        "    for (int k = 0; k < 3; k++) s->q[k] = q[k];",
        "    s->warm = 1;",
        "    return MAST_OK;", "}", "",
        "static int initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size)",
        "{", "    State *s = state;", "    s->warm = 0;", "    return compute(s, values, p, t0, msg, size);",
        "}", "",
        "static int do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg, size_t size)",
        "{", "    return compute(state, values, p, t + h, msg, size);", "}", ""])


# ----------------------------------------------------------------------------------- controller
#: layout of the joint cascade's state (doubles): tick count, t0, IK cache (valid, pose), PI states, commands
#: ("failed": the tick whose inverse kinematics failed, for the message), then the gains computed at
#: initialisation from the parameters (``gains``: cascade_gains, then drive_gains)
_S = {"n": 0, "t0": 1, "ik": 2, "pose": 3, "x_v": 6, "x_c": 9, "u": 12, "rho_cmd": 15, "omega_cmd": 18, "i_cmd": 21,
      "failed": 24, "gains": 25,
      # the feed-forward controller: JointReference's samples (newest first) and their count, i_ff, the
      # inverse model's direct-kinematics guess (valid flag, pose) and the arguments of a failed evaluation
      "hist": 32, "k": 44, "i_ff": 45, "warm": 48, "guess": 49, "model_args": 52,
      # the computed-torque controller: the reference's rates (rho_dot_ref, rho_ddot_ref), kept between ticks
      "rates": 61,
      # the controller's own gains computed at initialisation (feedforward_gains, error_gains, pose_gains)
      "own": 67}
_NS = 70
#: the joint controller's parameters read at run time (the gains); the others (cycle times, kinematic
#: model) are in the generated code
#: the mechanism's parameters read at run time: the masses and inertias of the legs and the platform, and g
#: (mechanism.designs.INERTIAL_PARAMETERS); the geometry and the payload are in the generated code
MECHANISM_TUNABLE = frozenset({GRAVITY_PARAMETER} | {name for mass, tensor in INERTIAL_PARAMETERS.values()
                                                     for name in (mass, *(v for row in tensor for v in row)) if name})
CONTROLLER_TUNABLE = ("k_v", "k_p", "k_i", "k_pc", "k_ic", "i_max", "u_max", "p", "i_r")
#: the feed-forward controller's: the transmission (p, i_r) is also in its inlined inverse model
FEEDFORWARD_TUNABLE = ("k_v", "k_p", "k_i", "k_pc", "k_ic", "i_max", "u_max", "k_ff_v", "k_ff_tau")
#: the computed-torque controller's: the drive's gains and limits (no cascade gains; p, i_r in its model)
COMPUTED_TORQUE_TUNABLE = ("k_pc", "k_ic", "i_max", "u_max", "omega_n", "zeta")
#: the workspace controller's: the velocity and current loops' (its pose gains k_v * k_v_scale_* and i_R inlined)
WORKSPACE_TUNABLE = ("k_v", "k_p", "k_i", "k_pc", "k_ic", "i_max", "u_max", "k_v_scale_z", "k_v_scale_psi",
                     "k_v_scale_theta")
#: a failure of the workspace controller's direct kinematics of the measured joints
_DK_FAILED = 2000
#: a failure of the feed-forward controller's inverse model (its direct kinematics or dynamics)
_MODEL_FAILED = 1000


def _pi_lines(out: str, x: str, e: str, k_p: str, k_iT: str, limit: str, indent: str,
              offset: str = "0.0") -> list[str]:
    """A call of ``controller.model.pi_step`` (translated from its own source); its results land in
    the scratch array PI."""
    i = indent
    return [f"{i}c = pi_step({e}, {x}, {k_p}, {k_iT}, {limit}, {offset}, PI)", f"{i}{out} = PI[0]",
            f"{i}{x} = PI[1]"]


def _reference_lines(block, indent: str) -> list[str]:
    """JointReference.update at a position tick (after the IK): the new sample rho_cmd, then the rates
    rd_j, rdd_j (reference.rates, translated), kept in S[rates]."""
    i, H, K, Q = indent, _S["hist"], _S["k"], _S["rates"]
    old = ", ".join(f"S[{H + k}]" for k in range(9))
    lines = [f"{i}S[{H + 3}:] = ({old})", f"{i}S[{H}:] = (rc0, rc1, rc2)",
             f"{i}k = S[{K}] + 1.0", f"{i}if k > 4.0: k = 4.0", f"{i}S[{K}:] = (k,)"]
    for j in range(3):
        lines += [f"{i}c = rates(k, rc{j}, S[{H + 3 + j}], S[{H + 6 + j}], S[{H + 9 + j}], {block.reference.T!r}, RT)",
                  f"{i}S[{Q + j}:] = (RT[0],)", f"{i}S[{Q + 3 + j}:] = (RT[1],)"]
    return lines


def _currents_lines(args: str, indent: str) -> list[str]:
    """InverseModel.currents(args) into CUR; a failure ends the ticks (its message: ``model_error``)."""
    i = indent
    return [f"{i}c = currents({args}, S, CUR)", f"{i}if c != 0:", f"{i}    S[{_S['failed']}:] = (n,)",
            f"{i}    S[{_S['model_args']}:] = ({args})", f"{i}    return {_MODEL_FAILED}"]


def _workspace_lines(block, indent: str) -> list[str]:
    """WorkspaceController._position_law (pose mode): the direct kinematics of the measured joints
    (``wsdk``, warm-started from the last), the pose-space P law, through drho/dq at that pose."""
    i, i_R = indent, block.i_R
    lines = [f"{i}c = wsdk(values[3], values[4], values[5], S, QM)", f"{i}if c != 0:",
             f"{i}    S[{_S['failed']}:] = (n,)", f"{i}    S[{_S['model_args']}:] = (values[3], values[4], values[5])",
             f"{i}    return {_DK_FAILED}"]
    lines += [f"{i}qd{k} = S[{_S['own'] + k}]*(values[{k}] - QM[{k}])" for k in range(3)]
    lines.append(f"{i}c = k_ikjac(QM[0], QM[1], QM[2], JK)")
    lines += [f"{i}oc{j} = (JK[{3 + 3 * j}]*qd0 + JK[{4 + 3 * j}]*qd1 + JK[{5 + 3 * j}]*qd2)/{i_R!r}" for j in range(3)]
    return lines


def _workspace_dk(block) -> str:
    """The workspace controller's direct kinematics of the measured joints in C (Engine.dk from the last
    solution, else from the description's guess, as WorkspaceController._dk); ``dk_error`` makes the
    message of a failure by running it again (the guess is only updated on success)."""
    eng = block.kinematics
    ikjac = eng._fn("ikjac")
    checks = {k: v for k, v in ikjac.namespace.items() if k.startswith("_check")}
    coordinates = ", ".join(_literal(n) for n in eng.description.coordinates)
    lengths = ", ".join(c_double(v) for v in eng.lengths)
    W, G, A = _S["warm"], _S["guess"], _S["model_args"]
    return "\n".join([
        to_c(ikjac.source, "k_ikjac", checks=checks), to_c(_guess_source(eng.description), "guess", arrays=("rho",)),
        _why_function("why_k", checks),
        f"static const char *const K_COORDINATES[] = {{{coordinates}}};",
        f"static const double K_LENGTHS[] = {{{lengths}}};", "",
        "static int wsdk_eval(const double *rho, double *S, double *q, char *msg, size_t size)", "{",
        "    double J[9];",
        f"    if (S[{W}] == 1.0) {{ for (int k = 0; k < 3; k++) q[k] = S[{G} + k]; }} else guess((double *)rho, q);",
        f"    int code = mast_dk3(k_ikjac, why_k, K_COORDINATES, K_LENGTHS, {c_double(eng.margin)}, rho, q, J, 1e-12, "
        f"50, {c_double(eng.cond_limit)}, msg, size);",
        "    if (code) return code;",
        f"    for (int k = 0; k < 3; k++) S[{G} + k] = q[k];", f"    S[{W}] = 1.0;", "    return 0;", "}", "",
        "static int wsdk(double r0, double r1, double r2, double *S, double *out)", "{",
        "    double rho[3] = {r0, r1, r2};", "    char text[1024];",
        "    return wsdk_eval(rho, S, out, text, sizeof text);", "}", "",
        "static int dk_error(double *S, double t, char *msg, size_t size)", "{",
        "    double q[3];", "    char text[1024], r0[40], r1[40], r2[40], ts[40];",
        f"    wsdk_eval(S + {A}, S, q, text, sizeof text);",
        "    snprintf(msg, size, \"direct kinematics of the measured joints rho = (%s, %s, %s) m failed at t = %s s: %s\", "
        f"mast_repr(S[{A}], r0, sizeof r0), mast_repr(S[{A} + 1], r1, sizeof r1), mast_repr(S[{A} + 2], r2, sizeof r2), "
        "mast_repr(t, ts, sizeof ts), text);",
        "    return MAST_KINEMATICS_ERROR;", "}", ""])


def _feedforward_lines(block, indent: str) -> list[str]:
    """FeedForwardController's position law after the P law: velocity feed-forward, the inverse model's
    currents on the reference (i_ff)."""
    i, Q = indent, _S["rates"]
    kff_v_iR, kff_tau = f"S[{_S['own']}]", f"S[{_S['own'] + 1}]"
    lines = [f"{i}oc{j} = oc{j} + {kff_v_iR}*S[{Q + j}]" for j in range(3)]
    lines.append(f"{i}if {kff_tau} != 0.0:")
    lines += _currents_lines(", ".join([f"rc{j}" for j in range(3)] + [f"S[{Q + k}]" for k in range(6)]), i + "    ")
    lines += [f"{i}    if{j} = {kff_tau}*CUR[{j}]" for j in range(3)]
    return lines


def _computed_torque_lines(block, indent: str) -> list[str]:
    """ComputedTorqueController._velocity_law: the model's currents at the measured state for the
    acceleration a = rho_ddot_ref + K_D e_dot + K_P e, limited to i_max."""
    i, Q, i_R, i_max = indent, _S["rates"], block.i_R, f"S[{_S['gains'] + 5}]"
    lines = [f"{i}rdm{j} = {i_R!r}*values[{6 + j}]" for j in range(3)]
    K_P, K_D = f"S[{_S['own']}]", f"S[{_S['own'] + 1}]"
    lines += [f"{i}acc{j} = S[{Q + 3 + j}] + {K_D}*(S[{Q + j}] - rdm{j}) + {K_P}*(rc{j} - values[{3 + j}])"
              for j in range(3)]
    lines += _currents_lines("values[3], values[4], values[5], rdm0, rdm1, rdm2, acc0, acc1, acc2", i)
    lines += [f"{i}ic{j} = {i_max} if CUR[{j}] > {i_max} else (-{i_max} if CUR[{j}] < -{i_max} else CUR[{j}])"
              for j in range(3)]
    return lines


def _ik_lines(indent: str) -> list[str]:
    """DriveController._update_ik: the engine's inverse kinematics of the pose inputs, cached by pose."""
    i, P = indent, _S["pose"]
    return [f"{i}if not (S[{_S['ik']}] == 1.0 and values[0] == S[{P}] and values[1] == S[{P + 1}] "
            f"and values[2] == S[{P + 2}]):",
            f"{i}    c = ik(values[0], values[1], values[2], R)",
            f"{i}    if c != 0:",
            f"{i}        S[{_S['failed']}:] = (n,)",
            f"{i}        return c",
            f"{i}    rc0 = R[0]", f"{i}    rc1 = R[1]", f"{i}    rc2 = R[2]",
            f"{i}    S[{_S['ik']}:] = (1.0, values[0], values[1], values[2])"]


def _joint_sources(block) -> tuple[str, str]:
    """A controller's start (``initialize`` after the reset) and ``m`` ticks (``do_step``), in the
    generated-code subset: DriveController's schedule (controller/model.py) with the laws of the
    joint cascade (ControllerBlock), the feed-forward (its reference and inverse model), the
    computed-torque or the workspace controller."""
    ff = hasattr(block, "_kff_tau")     # FeedForwardController
    ct = hasattr(block, "K_P")          # ComputedTorqueController
    ws = hasattr(block, "_q_meas")      # WorkspaceController
    names = {k: [f"{p}{j}" for j in range(3)] for k, p in
             (("x_v", "xv"), ("x_c", "xc"), ("u", "u"), ("rho_cmd", "rc"), ("omega_cmd", "oc"), ("i_cmd", "ic"))}
    unpack = [f"    {v} = S[{_S[k] + j}]" for k, vs in names.items() for j, v in enumerate(vs)]
    unpack += [f"    if{j} = S[{_S['i_ff'] + j}]" for j in range(3)] if ff else []
    state = ", ".join(v for vs in names.values() for v in vs)
    store = [f"    S[{_S['x_v']}:] = ({state})", *([f"    S[{_S['i_ff']}:] = (if0, if1, if2)"] if ff else []),
             f"    values[12:] = ({', '.join(names['u'] + names['rho_cmd'] + names['omega_cmd'] + names['i_cmd'])})",
             "    return 0"]
    start = ["def start(values, S, R):", "    n = 0.0", *unpack, *_ik_lines("    "), *store]
    kv_iR, kp, kiT, kpc, kicT, i_max, u_max = (f"S[{_S['gains'] + k}]" for k in range(7))
    body = [f"        if n % {float(block._N_pos)!r} == 0.0:", *_ik_lines("            ")]
    body += _reference_lines(block, "            ") if ff or ct else []
    if ct:              # omega_cmd reports the reference speed
        body += [f"            oc{j} = S[{_S['rates'] + j}]/{block.i_R!r}" for j in range(3)]
    elif ws:
        body += _workspace_lines(block, "            ")
    else:
        body += [f"            oc{j} = {kv_iR}*(rc{j} - values[{3 + j}])" for j in range(3)]
    body += _feedforward_lines(block, "            ") if ff else []
    body.append(f"        if n % {float(block._N_vel)!r} == 0.0:")
    if ct:
        body += _computed_torque_lines(block, "            ")
    for j in range(0 if ct else 3):    # velocity PI with the feed-forward current i_ff (0.0: the cascade has none)
        body += _pi_lines(f"ic{j}", f"xv{j}", f"oc{j} - values[{6 + j}]", kp, kiT, i_max, "            ",
                          f"if{j}" if ff else "0.0")
    for j in range(3):
        body += _pi_lines(f"u{j}", f"xc{j}", f"ic{j} - values[{9 + j}]", kpc, kicT, u_max, "        ")
    body.append("        n = n + 1.0")
    ticks = ["def ticks(values, S, R, PI, RT, CUR, QM, JK, m):", f"    n = S[{_S['n']}]", *unpack, "    for _ in range(m):", *body,
             "    S[0:] = (n,)", *store]
    return "\n".join(start) + "\n", "\n".join(ticks) + "\n"


def _joint_controller(block, vrs: Mapping[str, int]) -> str:
    import inspect

    from fmus.actuator.model import transmission_ratio
    from fmus.controller.model import ControllerBlock, cascade_gains, drive_gains, pi_step

    if type(block) not in native_controllers():
        raise ValueError(f"{type(block).__name__} has no native form yet")
    model = hasattr(block, "model")     # the feed-forward and computed-torque controllers' inverse model
    cascade = type(block) is not native_controllers()[2]
    workspace = type(block) is native_controllers()[3]

    def P(name: str) -> str:
        return f"p->real[{vrs[name]}]"

    # the controller's own gains, by its own function (FeedForwardController, ComputedTorque, Workspace)
    own, own_call = None, ""
    if type(block) is native_controllers()[1]:
        from fmus.controller.feedforward import feedforward_gains as own
        own_call = (f"    feedforward_gains({P('k_ff_v')}, {P('k_ff_tau')}, transmission_ratio({P('p')}, {P('i_r')}), "
                    f"s->S + {_S['own']});")
    elif not cascade:
        from fmus.controller.computed_torque import error_gains as own
        own_call = f"    error_gains({P('omega_n')}, {P('zeta')}, s->S + {_S['own']});"
    elif workspace:
        from fmus.controller.workspace import pose_gains as own
        own_call = (f"    pose_gains({P('k_v')}, {P('k_v_scale_z')}, {P('k_v_scale_psi')}, {P('k_v_scale_theta')}, "
                    f"s->S + {_S['own']});")
    ik = block.kinematics._fn("ik")
    checks = {k: v for k, v in ik.namespace.items() if k.startswith("_check")}
    start, ticks = _joint_sources(block)
    T = c_double(block.T_cur)
    inputs = ", ".join(_literal(n) for n in block.INPUTS)
    return "\n".join([
        f"typedef struct {{ double S[{_NS}]; }} State;", "",
        to_c(ik.source, "ik", checks=checks),
        to_c(inspect.getsource(pi_step), "pi_step"),
        to_c(inspect.getsource(transmission_ratio), "transmission_ratio"),
        to_c(inspect.getsource(cascade_gains), "cascade_gains"),
        to_c(inspect.getsource(drive_gains), "drive_gains"),
        _inverse_model(block) if model else "",
        to_c(inspect.getsource(own), own.__name__) if own else "",
        to_c(start, "start", arrays=("values", "S", "R"), calls=("ik",)),
        _workspace_dk(block) if workspace else "",
        to_c(ticks, "ticks", arrays=("values", "S", "R", "PI", "RT", "CUR", "QM", "JK"),
             calls=("ik", "pi_step", "rates", "currents", "wsdk", "k_ikjac")),
        _why_function("why", checks),
        f"static const char *const INPUT_NAMES[] = {{{inputs}}};", "",
        "static int input_error(const double *values, double t, char *msg, size_t size)", "{",
        "    char v[40], w[40];",
        "    for (int k = 0; k < 12; k++) {",
        "        if (!isfinite(values[k])) {",
        "            snprintf(msg, size, \"input '%s' = %s is not finite at t = %s s\", INPUT_NAMES[k], "
        "mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));",
        "            return MAST_MODEL_ERROR;", "        }", "    }", "    return MAST_OK;", "}", "",
        "static int ik_error(const double *values, double t, int check, char *msg, size_t size)", "{",
        "    char a[40], b[40], c[40], d[40];",
        "    snprintf(msg, size, \"inverse kinematics of the pose command z = %s m, psi = %s rad, theta = %s rad failed "
        "at t = %s s: %s\", mast_repr(values[0], a, sizeof a), mast_repr(values[1], b, sizeof b), "
        "mast_repr(values[2], c, sizeof c), mast_repr(t, d, sizeof d), why(check));",
        "    return MAST_KINEMATICS_ERROR;", "}", "",
        "static int initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size)",
        "{", "    State *s = state;", "    double R[3];",
        f"    for (int k = 0; k < {_NS}; k++) s->S[k] = 0.0;",
        f"    s->S[{_S['t0']}] = t0;",
        "    /* the gains from the parameters, by the controller's own functions */",
        *([f"    cascade_gains({P('k_v')}, {P('k_p')}, {P('k_i')}, {P('T_vel')}, "
           f"transmission_ratio({P('p')}, {P('i_r')}), s->S + {_S['gains']});"] if cascade else []),
        f"    drive_gains({P('k_pc')}, {P('k_ic')}, {P('T_cur')}, {P('i_max')}, {P('u_max')}, s->S + {_S['gains'] + 3});",
        *([own_call] if own_call else []),
        "    if (input_error(values, t0, msg, size)) return MAST_MODEL_ERROR;",
        "    int code = start(values, s->S, R);",
        "    return code ? ik_error(values, t0, -code, msg, size) : MAST_OK;", "}", "",
        "static int do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg, size_t size)",
        "{", "    State *s = state;", "    double R[3], PI[2], RT[2], CUR[3], QM[3], JK[12];",
        "    char a[40], b[40], c[40];",
        "    (void)p;",
        f"    double m = nearbyint(h / {T});",
        f"    if (m < 1.0 || fabs(h - m * {T}) > 1e-6 * {T}) {{",
        "        snprintf(msg, size, \"step size h = %s s is not a positive integer multiple of T_cur = %s s\", "
        f"mast_repr(h, a, sizeof a), mast_repr({T}, b, sizeof b));",
        "        return MAST_MODEL_ERROR;", "    }",
        f"    double n = s->S[{_S['n']}], t0 = s->S[{_S['t0']}];",
        f"    if (fabs(t - (t0 + n * {T})) > 0.5 * {T}) {{",
        "        snprintf(msg, size, \"do_step at t = %s s, but tick %.0f belongs to t = %s s (steps must be contiguous "
        f"from initialize)\", mast_repr(t, a, sizeof a), n, mast_repr(t0 + n * {T}, c, sizeof c));",
        "        return MAST_MODEL_ERROR;", "    }",
        "    double sum = 0.0;",
        "    for (int k = 0; k < 12; k++) sum += values[k];",
        "    if (sum - sum != 0.0 && input_error(values, t, msg, size)) return MAST_MODEL_ERROR;",
        "    int code = ticks(values, s->S, R, PI, RT, CUR, QM, JK, m);",
        *([f"    if (code == {_MODEL_FAILED}) return model_error(s->S, msg, size);"] if model else []),
        *([f"    if (code == {_DK_FAILED}) return dk_error(s->S, t0 + s->S[{_S['failed']}] * {T}, msg, size);"]
          if workspace else []),
        f"    if (code) return ik_error(values, t0 + s->S[{_S['failed']}] * {T}, -code, msg, size);",
        "    return MAST_OK;", "}", ""])


def _inverse_model(block) -> str:
    """FeedForwardController's inverse model (InverseModel.currents) in C: the engine's direct
    kinematics (warm start, else cold, as InverseModel.torques) and traced dynamics, then
    ``motor_torque`` and ``guide_friction`` translated from their own source. ``currents`` is what the
    tick calls; ``model_error`` makes the message of a failed evaluation by running it again (the
    guess is only updated on success, so it fails the same way)."""
    import inspect

    from fmus.actuator.model import guide_friction
    from fmus.controller.inverse_model import motor_torque
    from fmus.controller.reference import rates

    model = block.model
    parts = [to_c(inspect.getsource(rates), "rates"),
             to_c(inspect.getsource(guide_friction), "guide_friction"),
             to_c(inspect.getsource(motor_torque), "motor_torque", values=("guide_friction",))]
    torque = ", ".join(f"{float(v)!r}" for v in (model.J, model.i_R, model.b_v, model.weight, *model._friction))
    W, G, A = _S["warm"], _S["guess"], _S["model_args"]
    if model.engine is None:    # attached = 0: no mechanism forces
        dynamics = ["    double F[3] = {0.0, 0.0, 0.0};", "    (void)S; (void)msg; (void)size;"]
    else:
        eng = model.engine
        ikjac, forces = eng._fn("ikjac"), eng._fn("forces")
        checks = {k: v for k, v in {**ikjac.namespace, **forces.namespace}.items() if k.startswith("_check")}
        coordinates = ", ".join(_literal(n) for n in eng.description.coordinates)
        lengths = ", ".join(c_double(v) for v in eng.lengths)
        dk = (f"mast_dk3(m_ikjac, why_model, M_COORDINATES, M_LENGTHS, {c_double(eng.margin)}, a, q, J, 1e-12, 50, "
              f"{c_double(eng.cond_limit)}, msg, size)")
        parts += [to_c(ikjac.source, "m_ikjac", checks=checks), to_c(forces.source, "m_dynamics", checks=checks),
                  to_c(_guess_source(eng.description), "guess", arrays=("rho",)),
                  _why_function("why_model", checks),
                  f"static const char *const M_COORDINATES[] = {{{coordinates}}};",
                  f"static const double M_LENGTHS[] = {{{lengths}}};", ""]
        dynamics = [
            "    double q[3], J[9], cold[3], F[12];",
            "    guess((double *)a, cold);",
            f"    for (int k = 0; k < 3; k++) q[k] = S[{W}] == 1.0 ? S[{G} + k] : cold[k];",
            f"    int code = {dk};",
            f"    if (code && code != MAST_SINGULARITY_ERROR && S[{W}] == 1.0) {{   /* never restarted after a SingularityError */",
            "        for (int k = 0; k < 3; k++) q[k] = cold[k];",
            f"        code = {dk};", "    }",
            "    if (code) return code;",
            "    code = m_dynamics(q[0], q[1], q[2], J[0], J[1], J[2], J[3], J[4], J[5], J[6], J[7], J[8], "
            "a[3], a[4], a[5], a[6], a[7], a[8], F);",
            "    if (code) {", "        snprintf(msg, size, \"%s\", why_model(-code));", "        return MAST_KINEMATICS_ERROR;", "    }",
            f"    for (int k = 0; k < 3; k++) S[{G} + k] = q[k];", f"    S[{W}] = 1.0;"]
    parts += [
        "/* InverseModel.currents at a = (rho, rho_dot, rho_ddot); 0, or an error code with msg */",
        "static int model_eval(const double *a, double *S, double *out, char *msg, size_t size)", "{",
        *dynamics,
        f"    for (int j = 0; j < 3; j++) out[j] = motor_torque(a[3 + j], a[6 + j], F[j], {torque}) / "
        f"{float(model.k_T)!r};",
        "    return 0;", "}", "",
        "static int currents(double r0, double r1, double r2, double v0, double v1, double v2, double a0, double a1, "
        "double a2, double *S, double *out)", "{",
        "    double a[9] = {r0, r1, r2, v0, v1, v2, a0, a1, a2};", "    char text[1024];",
        "    return model_eval(a, S, out, text, sizeof text);", "}", "",
        "static int model_error(double *S, char *msg, size_t size)", "{",
        "    double out[3], a[9];", "    char text[1024], r0[40], r1[40], r2[40];",
        f"    for (int k = 0; k < 9; k++) a[k] = S[{A} + k];",
        "    model_eval(a, S, out, text, sizeof text);",
        "    snprintf(msg, size, \"inverse dynamic model at rho = (%s, %s, %s) m: %s\", mast_repr(a[0], r0, sizeof r0), "
        "mast_repr(a[1], r1, sizeof r1), mast_repr(a[2], r2, sizeof r2), text);",
        "    return MAST_KINEMATICS_ERROR;", "}", ""]
    return "\n".join(parts)


def native_kind(block_class: type) -> Optional[str]:
    """Which generator makes ``block_class``'s C ('actuator', 'mechanism', 'controller', 'trajectory'),
    None when it has no native form yet (e.g. the EMPS bench's load axis and controller)."""
    from fmus.actuator.model import ActuatorBlock
    from fmus.mechanism.model import MechanismBlock
    from fmus.trajectory.model import TrajectoryBlock

    for kind, classes in (("actuator", (ActuatorBlock,)), ("mechanism", (MechanismBlock,)),
                          ("trajectory", (TrajectoryBlock,)), ("controller", native_controllers())):
        if block_class in classes or (kind != "controller" and issubclass(block_class, classes)):
            return kind
    return None


def native_controllers() -> tuple[type, ...]:
    """The controllers with a native form: the joint cascade, feed-forward, computed torque, workspace."""
    from fmus.controller.computed_torque import ComputedTorqueController
    from fmus.controller.feedforward import FeedForwardController
    from fmus.controller.model import ControllerBlock
    from fmus.controller.workspace import WorkspaceController

    return ControllerBlock, FeedForwardController, ComputedTorqueController, WorkspaceController


# ----------------------------------------------------------------------------------- trajectory
def _trajectory(block, vrs: Mapping[str, int]) -> str:
    """TrajectoryBlock._write, its parameters read at run time (tunable as in the Python FMU)."""
    P = {name: f"p->real[{vrs[name]}]" for name in ("z_home", "psi_home", "theta_home", "amplitude_z",
                                                    "amplitude_psi", "amplitude_theta", "frequency")}
    return "\n".join([
        "typedef struct { double t0; } State;", "",
        "static int write(const State *s, double *values, const mast_parameters *p, double t, char *msg, size_t size)",
        "{", "    char v[40];",
        "    if (!isfinite(t)) {",
        "        snprintf(msg, size, \"time t = %s s is not finite\", mast_repr(t, v, sizeof v));",
        "        return MAST_MODEL_ERROR;", "    }",
        f"    double omega = 2.0 * {c_double(math.pi)} * {P['frequency']};",
        "    double sn = sin(omega * (t - s->t0));",
        f"    values[0] = {P['z_home']} + {P['amplitude_z']} * sn;",
        f"    values[1] = {P['psi_home']} + {P['amplitude_psi']} * sn;",
        f"    values[2] = {P['theta_home']} + {P['amplitude_theta']} * sn;",
        "    return MAST_OK;", "}", "",
        "static int initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, size_t size)",
        "{", "    State *s = state;", "    s->t0 = t0;", "    return write(s, values, p, t0, msg, size);", "}", "",
        "static int do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg, size_t size)",
        "{", "    return write(state, values, p, t + h, msg, size);", "}", ""])


# ----------------------------------------------------------------------------------- entry point
def generated_parameters(block_class: type, parameters: Mapping[str, object]) -> dict[str, object]:
    """The parameters whose values the generated code of ``block_class`` holds (the others are read
    at run time): another value needs another build."""
    kind = block_class.__module__.split(".")[-2]
    if kind == "trajectory":
        return {}
    if kind == "controller":
        tunable = {"ControllerBlock": CONTROLLER_TUNABLE, "FeedForwardController": FEEDFORWARD_TUNABLE,
                   "ComputedTorqueController": COMPUTED_TORQUE_TUNABLE,
                   "WorkspaceController": WORKSPACE_TUNABLE}[block_class.__name__]
        return {k: v for k, v in parameters.items() if k not in tunable}
    if kind == "mechanism":
        return {k: v for k, v in parameters.items() if k not in MECHANISM_TUNABLE}
    return dict(parameters)


def emit_model(identifier: str, guid: str, block_class: type, parameters: Mapping[str, object],
               variables: Sequence[Variable], step_sizes: Optional[Sequence[float]] = None) -> str:
    """The C model file of the FMU ``identifier`` (its modelDescription ``variables``), generated from
    ``block_class`` built with ``parameters``; ``step_sizes`` [s]: the actuator's communication steps."""
    vrs = {v.name: v.vr for v in variables}
    n_inputs, n_io = len(block_class.INPUTS), len(block_class.INPUTS) + len(block_class.OUTPUTS)
    expected = list(block_class.INPUTS + block_class.OUTPUTS) + [p.name for p in block_class.PARAMETERS]
    if [v.name for v in variables] != expected or [v.vr for v in variables] != list(range(len(variables))):
        raise ValueError(f"{identifier}: the modelDescription's variables are not the block's inputs, outputs and "
                         "parameters in value-reference order")
    block = block_class(dict(parameters), name=identifier)
    # parameter starts: the exact values (the XML prints 16 digits; the Python FMU starts from parameters.json)
    variables = [Variable(v.name, v.vr, v.type, v.causality, block.params[v.name]) if v.causality == "parameter"
                 else v for v in variables]
    kind = native_kind(block_class)
    if kind == "actuator":
        if block._sensor is not None:
            raise ValueError(f"{identifier}: the torque measurement model (T_meas, delay_meas, tau_offset) has no "
                             "native form yet; build the Python FMU for it")
        if not step_sizes:
            raise ValueError(f"{identifier}: the actuator's native form needs the step sizes it will be stepped with")
        body = _actuator(block, step_sizes)
    elif kind == "mechanism":
        body = _mechanism(block, vrs)
    elif kind == "controller":
        body = _joint_controller(block, vrs)
    elif kind == "trajectory":
        body = _trajectory(block, vrs)
    else:
        raise ValueError(f"{identifier}: {block_class.__name__} has no native form yet")
    fixed = generated_parameters(block_class, block.params)
    return "".join([_HEAD.format(what=f"{block_class.__module__}.{block_class.__name__}"),
                    _variable_table(variables), "\n",
                    _check_function(block_class.PARAMETERS, vrs, fixed), "\n", body, "\n",
                    _model_struct(identifier, guid, variables, n_inputs, n_io)])
