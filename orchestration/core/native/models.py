"""The generated part of a native FMU, from the model the Python FMU runs (``mast build --native``).

A native FMU runs on the runtime of fmus/common/native, C written by hand and the same for every model of a kind
(the FMI glue, the matrix helpers, the direct kinematics for n coordinates, and per kind: mast_actuator.c and
mast_drive.c, mast_mechanism.c, mast_controller.c, mast_trajectory.c; ``runtime_files``), against one fixed
interface per kind. What is generated here for one model is its traced straight-line kernels, its tables
(variables, parameter ranges, chains and kernels, which parameter feeds which traced input) and the sizes in its
``config.h``.

Each emitter builds the Python block with the FMU's parameter set and takes its generated
code, which ``translate.to_c`` writes as C:

- actuator: the exact-discretisation step with the implicit friction solve, bound by name
  (``ActuatorBlock._bind``'s source, with the parameters' numbers as names too), one kernel per
  structure the parameters select, for each chain n_dof = 1..``N_MAX`` (one binary, the chain chosen
  by n_dof at initialisation); the parameters' numbers traced through the model's relations
  (``kernel_constants``, ``state_matrices``, ``backlash_systems``, ``friction_constants``); the
  discretisation of each step size computed by the runtime (``mast_expm``) with the model's substep rule
  (``substep_rule``, ``substeps_enough``); the torque measurement's filter and delay line
  (sensor.py: ``filter_coefficients``, ``delay_split``, ``measurement_step``, ``relayout``); a drive's
  ``pi_step`` and ``current_gains``;
- mechanism (every description, ``mechanism_model``): the engine's traced functions (inverse kinematics with its
  Jacobian, inverse dynamics, pose), driven by the engine's Newton direct kinematics
  (mast_dk.c), and what the parameters alone give as traced kernels with their tables (the cold start,
  ``Described.guess_rule``; the platform points of the lengths; the bodies; ``designs.CHECKS``), the checks and
  the messages in mast_mechanism.c; the engine traces the description with every parameter (geometry,
  bodies, payload, g) as a named input (``designs.traced_engine``), so one C file serves every
  parameter set;
- controllers (``native_controllers``: the joint cascade, feed-forward, computed torque,
  workspace; on mast_controller.c): the same traced engine of their own geometry (inverse kinematics; the feed-forward
  and computed-torque controllers' inverse model: direct kinematics and dynamics; the workspace
  controller's direct kinematics and Jacobian), and the tick the Python controllers run
  (``fmus.controller.tick.tick_sources``: ``DriveController``'s schedule, the IK cache, the
  reference's rates, each controller's own law lines, ``position_lines`` and ``velocity_lines``, the
  ticks inside a step),
  translated; what it calls is translated from the models' own source (``pi_step``,
  ``drive_gains``, ``cascade_gains``, ``transmission_ratio``, the controllers' ``LAWS``,
  ``reference.rates``, ``inverse_model.motor_torque``, ``guide_friction``); their kinematic model's parameters,
  cold start, coordinate lengths and checks of a parameter set are the native mechanism's (``mechanism_model``'s
  tables and kernels for the controller's engine, run by mast_mechanism.c: ``mast_mechanism_setup``,
  ``mast_mechanism_guess``, ``mast_mechanism_check``), for every description;
- trajectory: the tables of the sine about the home pose (mast_trajectory.c; its parameters read at run time).

The direct kinematics' restart policy (warm start, else cold; a cold restart after a failed warm
start, never after a singularity) is ``mechanism.model.restarted_dk``, which ``MechanismBlock`` and
``InverseModel`` run and the mechanism and the feed-forward and computed-torque controllers translate.

What the models' generators do not cover is restated in C, held to the Python model by
tests/test_native.py: in the runtime, the outputs of the actuator at rest, its doubling of its substeps around
``mast_expm`` and the allocation of its delay line, the mechanism's restart and messages
(``MechanismBlock._compute``) and its checks of a parameter set (``designs.describe``'s, over tables:
``mast_mechanism_check``), the controllers' life cycle for n axes (mast_controller.c: ``initialize``,
``evaluate`` once per communication point, ``do_step`` over the ticks of a step, the inverse model's and the
workspace controller's direct kinematics, ``InverseModel.currents``, ``WorkspaceController._wsdk``, and the
messages of their failures) on the state layout of ``tick.layout`` (config.h: CTRL_N, CTRL_<FIELD>, its parameter
slot sized by the controller's traced parameters).

Parameters: all read at run time, with what depends on them computed at initialisation: the
trajectory's, the actuator's (n_dof too: the chains 1..``N_MAX`` are all in the binary; a parameter set with
a larger n_dof adds its own, ``actuator_structures``), the mechanism's and the controllers' (gains, cycle
times, transmission, geometry, the inverse model's bodies and its actuator constants, by
``inverse_model.model_constants`` traced); the checks the Python model makes of a parameter set (ranges,
``DriveController._ratio``, ``designs.describe``) run at exitInitializationMode with its messages. An n_dof
above the chains an actuator carries is refused there with a message naming it and ``N_MAX``; the project's
master generates the model with that chain when it needs one (``to_generate``, ``build.for_parameters``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

from fmus.common.parameters import Param
from fmus.common.slave import MAX_STEP_SIZE, MAX_STEP_TICKS
from fmus.controller.tick import DK_FAILED, MODEL_FAILED, layout, tick_sources
from fmus.mechanism.coupling import EXTRAPOLATION
from fmus.mechanism.model import CONDENSE_ABOVE

from .translate import c_double, split_invariants, to_c

__all__ = [
    "Variable",
    "emit_model",
    "emit_mechanism",
    "mechanism_model",
    "mechanism_variables",
    "c_string",
    "to_generate",
    "actuator_structures",
    "N_MAX",
    "RUNTIME",
    "runtime_files",
]


@dataclass(frozen=True)
class Variable:
    """A variable of the modelDescription (value references are 0..n-1 in order)."""

    name: str
    vr: int
    type: str  # "Real", "Integer", "String"
    causality: str  # "input", "output", "parameter"
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
def _why_function(name: str, checks: Mapping[str, object], static: bool = True) -> str:
    """``const char *name(int check)``: the message of the traced check ``_check<N>`` (its c_message)."""
    cases = [
        f"    case {int(k.replace('_check', ''))}: return {_literal(v.c_message)};" for k, v in sorted(checks.items())
    ]
    return "\n".join(
        [
            f"{'static ' if static else ''}const char *{name}(int check)",
            "{",
            "    switch (check) {",
            *cases,
            '    default: return "a check of the description failed";',
            "    }",
            "}",
            "",
        ]
    )


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


def _check_function(
    params: Sequence[Param], vrs: Mapping[str, int], extra: Sequence[str] = (), model_check: bool = False
) -> str:
    """``check``: the Python model's range checks (``Param.check``, the same messages) by the runtime's
    ``mast_check_ranges`` over a table of the parameters' ranges, then the C lines ``extra`` (the model's own
    checks across parameters); ``model_check``: then the model's own checks of the set (``model_check``, in the
    model's part of the file)."""
    bound = lambda x: c_double(x) if math.isfinite(x) else ("INFINITY" if x > 0 else "-INFINITY")  # noqa: E731
    rows = [
        f"    {{{_literal(spec.name)}, {vrs[spec.name]}, {int(spec.kind is int)}, {bound(spec.minimum)}, "
        f"{bound(spec.maximum)}, {int(bool(spec.exclusive))}, {_literal(spec.expected())}}},"
        for spec in params
        if spec.kind is not str
    ]
    lines = [
        "static const mast_range RANGES[] = {",
        *(rows or ['    {"", 0, 0, 0.0, 0.0, 0, ""},']),
        "};",
        "",
        "static int check(const mast_parameters *p, char *msg, size_t size)",
        "{",
        f"    if (mast_check_ranges(RANGES, {len(rows)}, p, msg, size)) return MAST_PARAMETER_ERROR;",
        *extra,
        "    return model_check(p, msg, size);" if model_check else "    return MAST_OK;",
        "}",
        "",
    ]
    prototype = ["static int model_check(const mast_parameters *p, char *msg, size_t size);", ""] if model_check else []
    return "\n".join(prototype + lines)


def _model_struct(
    identifier: str,
    guid: str,
    variables: Sequence[Variable],
    n_inputs: int,
    n_io: int,
    feedthrough: bool,
    state: str = "State",
    functions: str = "",
    cycle_time: int = -1,
) -> str:
    """MAST_MODEL: the model's table row; ``state``: its state's type, ``functions``: the prefix of its initialize
    and do_step (a runtime's, e.g. ``mast_mechanism_``); ``cycle_time``: the value reference of its cycle-time
    parameter (-1: none), whose MAX_STEP_TICKS bound the step the wrapper accepts (else MAX_STEP_SIZE: slave.py)."""
    return (
        f"const mast_model MAST_MODEL = {{{_literal(identifier)}, {_literal(guid)}, {len(variables)}, VARIABLES, "
        f"{n_inputs}, {n_io}, sizeof({state}), check, {functions}initialize, {functions}do_step, "
        f"{functions + 'evaluate' if feedthrough else 'NULL'}, {cycle_time}, {c_double(MAX_STEP_TICKS)}, "
        f"{c_double(MAX_STEP_SIZE)}}};\n"
    )


_HEAD = """/* Generated by mast build --native from the {what} (mast.core.native.models): do not edit. */
#include "mast_native.h"
#include "mast_model.h"
#include "mast_ranges.h"
{more}
"""
#: the runtime files (fmus/common/native) a kind of model runs on besides those every model has (build.SUPPORT_FILES)
RUNTIME = {
    "mechanism": ("mast_mechanism.c", "mast_mechanism.h"),
    "trajectory": ("mast_trajectory.c", "mast_trajectory.h"),
    "actuator": ("mast_actuator.c", "mast_actuator.h"),
    "controller": ("mast_controller.c", "mast_controller.h", "mast_mechanism.c", "mast_mechanism.h"),
}
#: a mechanism's checks of a parameter set after its ranges (the runtime's: designs.describe's, from the tables)
MECHANISM_CHECK = "    if (mast_mechanism_check(p, msg, size)) return MAST_PARAMETER_ERROR;"
#: and a drive's (an actuator with its current loop: DriveActuatorBlock)
DRIVE = ("mast_drive.c", "mast_drive.h")


def runtime_files(block_class: type) -> tuple[str, ...]:
    """The runtime files of ``block_class``'s native form besides those every model has (build.SUPPORT_FILES)."""
    from fmus.actuator.drive import DriveActuatorBlock

    return RUNTIME.get(native_kind(block_class), ()) + (DRIVE if issubclass(block_class, DriveActuatorBlock) else ())


# ----------------------------------------------------------------------------------- actuator
#: the chains every native actuator carries, n_dof = 1..N_MAX, one chosen by n_dof at initialisation (a parameter
#: set with a larger n_dof adds its own: ``actuator_structures``; docs/native.md: why 8)
N_MAX = 8
#: the actuator's parameters that make the chain: its size (n_dof: the state's) and its lists (n_dof >= 3)
ACTUATOR_STRUCTURE = ("n_dof", "J_chain", "K_chain", "C_chain")
#: the chain's lists (n_dof >= 3) and whether their numbers must be > 0 (else >= 0), as ``chain`` parses them
CHAIN_LISTS = {"J_chain": True, "K_chain": True, "C_chain": False}
#: longest torque-measurement delay line of a native actuator, in communication steps (delay_meas / h + 2)
SENSOR_SAMPLES = 4096
#: step sizes whose exact discretisation a native actuator instance keeps (a varying-step host brings more:
#: the oldest is recomputed when it comes back, about 3.4 us with the default parameters: docs/native.md)
DISCRETISATIONS_KEPT = 8
#: the kernel_constants the native actuator's runtime reads (the same slot in every chain's Q: config.h's ACT_Q_*)
_SHARED_CONSTANTS = (
    "tau_c", "omega_c", "tau_s", "omega_s", "ripple", "rk", "iR", "mg", "kT", "rho0", "rmin", "rmax", "md"
)  # fmt: skip


def actuator_structures(parameters: Mapping[str, object]) -> tuple[int, ...]:
    """The n_dof values a native actuator generated for ``parameters`` runs (its chains): 1..N_MAX, and the set's
    own n_dof when it is larger."""
    n = int(parameters["n_dof"])
    return (*range(1, N_MAX + 1), *((n,) if n > N_MAX else ()))


def _indexed(source: str, slots: Mapping[str, tuple[str, int]], extra: Sequence[str]) -> str:
    """``source`` with each name of ``slots`` read from its array (``NAME`` -> ``ARRAY[k]``) and the
    function's arguments extended by ``extra``: a kernel bound by name (ActuatorBlock._bind) becomes one
    that reads its numbers from the instance."""
    import ast

    class Rewrite(ast.NodeTransformer):
        def visit_Name(self, node: ast.Name) -> ast.AST:
            if node.id in slots:
                array, k = slots[node.id]
                return ast.copy_location(ast.Subscript(ast.Name(array, ast.Load()), ast.Constant(k), ast.Load()), node)
            return node

    tree = Rewrite().visit(ast.parse(source))
    tree.body[0].args.args += [ast.arg(a) for a in extra]
    return ast.unparse(ast.fix_missing_locations(tree)) + "\n"


def _chain_count(name: str, N: int) -> int:
    """How many numbers the chain's list ``name`` holds for n_dof = N."""
    return N if name == "J_chain" else N - 1


def _structure_block(block, N: int):
    """The ActuatorBlock of the chain n_dof = ``N`` with ``block``'s other parameters: what the generator takes
    from it is the structure (the sizes, the names of the kernel's numbers), every number being read at run time,
    so the lists of a chain are placeholders."""
    from fmus.actuator.model import ActuatorBlock

    lists = {name: " ".join(["1.0"] * _chain_count(name, N)) for name in CHAIN_LISTS} if N >= 3 else {}
    return ActuatorBlock({**block.params, **lists, "n_dof": N, "backlash": 0.0}, name=block.name)


def _actuator_variants(block) -> list[tuple[str, dict, bool]]:
    """The structures a kernel can have for this n_dof, with a parameter set that selects each:
    friction (none, Coulomb, Stribeck) x position ripple (off, on) x backlash (off, on; n_dof = 2 only)."""
    out = []
    for friction, (tau_c, tau_s) in (("none", (0.0, 0.0)), ("coulomb", (1.0, 0.0)), ("stribeck", (1.0, 1.0))):
        for ripple in (0.0, 1.0):
            for backlash in (0.0, 1e-3) if block.N == 2 else (0.0,):
                name = f"{friction}{'_ripple' if ripple else ''}{'_backlash' if backlash else ''}"
                out.append(
                    (name, {"tau_c": tau_c, "tau_s": tau_s, "tau_ripple": ripple, "backlash": backlash}, backlash > 0.0)
                )
    return out


def _actuator(block, vrs: Mapping[str, int]) -> tuple[str, str]:
    """ActuatorBlock's generated part (mast_actuator.h; the runtime mast_actuator.c runs it), every parameter read at
    run time, n_dof too: one chain per n_dof of ``actuator_structures`` (``_actuator_chain``, chosen at
    initialisation); what no chain changes, translated from the model's own code: the friction solve's numbers
    (``friction_constants`` traced), the torque measurement (sensor.py: ``filter_coefficients``, ``delay_split``,
    ``relayout``, ``measurement_step``), the substep rule (``substep_rule``, ``substeps_enough``); the tables of the
    chains and their kernels. (model part, config.h)"""
    import inspect

    from fmus.actuator import model as am
    from fmus.actuator import sensor
    from fmus.common.tracer import Graph, compile_function, lift

    # --- the friction solve's numbers for a substep of d omega_N / d tau_L = b (traced friction_constants)
    code, friction_keys = [], {}
    for kind, stribeck in (("coulomb", False), ("stribeck", True)):
        g = Graph()
        names = ["b", "tau_c", "omega_c", "tau_s", "omega_s"]
        ins = {n: g.input(n) for n in names}
        fc = am.friction_constants(ins, ins["b"], stribeck)
        friction_keys[kind] = list(fc)
        fn = compile_function(
            f"friction_{kind}", names, [lift(g, v) for v in fc.values()], g, label=f"actuator {kind} friction"
        )
        code.append(to_c(fn.source, f"act_friction_{kind}", static=False))
    # --- the torque measurement and the substep rule (ActuatorBlock._substeps): the model's own functions
    limits = {"MAX_PHASE_PER_SUBSTEP": am.MAX_PHASE_PER_SUBSTEP, "BACKLASH_SUBSTEP": am.BACKLASH_SUBSTEP}
    for fn, name, arrays, constants in (
        (sensor.filter_coefficients, "filter_coefficients", (), {}),
        (sensor.delay_split, "delay_split", (), {}),
        (sensor.relayout, "relayout", ("old", "line"), {}),
        (sensor.measurement_step, "measurement_step", ("line",), {}),
        (am.substep_rule, "substep_rule", (), limits),
        (am.substeps_enough, "substeps_enough", (), {}),
    ):
        code.append(to_c(inspect.getsource(fn), f"act_{name}", arrays=arrays, constants=constants, static=False))
    reals = [spec.name for spec in block.PARAMETERS if spec.kind is float]
    kernels, chains, sizes, shared = [], [], [], None
    for N in actuator_structures(block.params):
        chain = _structure_block(block, N)
        keys = list(chain.constants)
        slots = {k: keys.index(k) for k in _SHARED_CONSTANTS}
        assert shared in (None, slots), "kernel_constants: the chains' shared numbers must keep their slots"
        shared = slots
        chain_code, rows, chain_row, nq, nh = _actuator_chain(chain, reals, friction_keys, len(kernels))
        code += chain_code
        kernels += rows
        chains.append(chain_row)
        sizes.append((2 * N + 1, nq, nh, 3 * N - 2))
    nx, nq, nh, lists = [max(s) for s in zip(*sizes)]
    row = lambda items: ", ".join(str(v) for v in items)  # noqa: E731
    tables = [
        "/* each kernel of every chain: its structure (friction 0 none, 1 Coulomb, 2 Stribeck; ripple; backlash),",
        "   where its friction numbers start in H (mast_actuator.h) */",
        "const mast_actuator_kernel ACTUATOR_KERNELS[] = {",
        *(f"    {{{row(r)}}}," for r in kernels),
        "};",
        "/* each chain: n_dof, its numbers, its kernels (first, count), the slots in Q of A, B, J, K, Ag, B3, bw,",
        "   hb */",
        "const mast_actuator_chain ACTUATOR_CHAINS[] = {",
        *(f"    {{{row(r)}}}," for r in chains),
        "};",
        f"const int ACTUATOR_N_CHAINS = {len(chains)};",
        f"const int ACTUATOR_REAL_VR[ACT_N_REALS] = {{{row(vrs[n] for n in reals)}}};   /* {', '.join(reals)} */",
        "",
    ]
    drive = ("k_pc", "k_ic", "T_cur", "u_max") if "k_pc" in vrs else ()
    config = "\n".join(
        [
            f"/* Generated by mast build --native for {block.name} (mast.core.native.models): the sizes of this "
            "actuator "
            "and the value references its runtime reads (mast_actuator.h) */",
            "#ifndef CONFIG_H",
            "#define CONFIG_H",
            f"#define ACT_NX {nx}",
            f"#define ACT_NQ {nq}",
            f"#define ACT_NH {nh}",
            f"#define ACT_N_REALS {len(reals)}",
            f"#define ACT_N_LISTS {max(1, lists)}",
            f"#define ACT_KEPT {DISCRETISATIONS_KEPT}",
            f"#define ACT_SENSOR_SAMPLES {SENSOR_SAMPLES}",
            f"#define ACT_N_MAX {N_MAX}",
            f"#define ACT_COUPLING_PHASE {c_double(am.COUPLING_PHASE)}",
            *(f"#define ACT_Q_{k.upper()} {i}" for k, i in shared.items()),
            *(
                f"#define ACT_VR_{n.upper()} {vrs[n]}"
                for n in (
                    "n_dof",
                    "J_chain",
                    "K_chain",
                    "C_chain",
                    "rho_min",
                    "rho_max",
                    "rho_0",
                    "backlash",
                    "T_meas",
                    "delay_meas",
                    "tau_offset",
                    *drive,
                )
            ),
            "#endif",
            "",
        ]
    )
    if drive:
        from fmus.actuator.drive import current_gains, pi_step

        code += [
            to_c(inspect.getsource(pi_step), "act_pi_step", static=False),
            to_c(inspect.getsource(current_gains), "act_current_gains", static=False),
        ]
    return "\n".join(code + tables), config


def _actuator_chain(
    block, reals: Sequence[str], friction_keys: Mapping[str, list], first: int
) -> tuple[list[str], list[tuple], tuple, int, int]:
    """The generated part of the chain n_dof = ``block.N``, each from the model's own code:

    - ``constants_n<N>(reals, lists, Q)``: the parameters' numbers (``kernel_constants``, the state matrices A, B
      of ``state_matrices`` with ``two_inertia`` and ``transmission_ratio``, the backlash's two systems of
      ``backlash_systems``, J and K; for n_dof >= 3 from the numbers of J_chain, K_chain, C_chain), traced with the
      parameters as named inputs by the mechanism engine's tracer (``engine.compile_function``) and translated;
    - ``kernel_n<N>_<structure>``: the step kernel of each structure (friction, ripple, backlash: the kernels
      numbered from ``first`` in the whole file), the model's own bound-by-name kernel (ActuatorBlock._bind's
      source, ``symbolic``), its names read from the instance's arrays.

    Returns (the code, each kernel's row of ACTUATOR_KERNELS, the chain's row of ACTUATOR_CHAINS, the sizes of Q
    and H)."""
    from fmus.actuator import model as am
    from fmus.common.tracer import Graph, compile_function, lift

    N = block.N
    nx = 2 * N + 1
    # --- the parameters' numbers, traced through the model's relations
    g = Graph()
    traced = {**block.params, **{name: g.input(name) for name in reals}}
    lists = (
        {name: [g.input(f"{name}_{k}") for k in range(_chain_count(name, N))] for name in CHAIN_LISTS}
        if N >= 3
        else None
    )
    items = [e.value for values in (lists or {}).values() for e in values]
    J, K, C = am.chain(traced, lists)
    A, B, _ = am.state_matrices(traced, (J, K, C))
    i_R = am.transmission_ratio(traced["p"], traced["i_r"])
    constants = am.kernel_constants(traced, i_R, A, B, J, K, C)
    assert list(constants) == list(block.constants)
    outputs, offsets = list(constants.values()), {"Ag": -1, "B3": -1}
    parts = [("A", list(A.ravel())), ("B", list(B.ravel())), ("J", list(J)), ("K", list(K))]
    if N == 2:
        Ac, Ag, B3 = am.backlash_systems(A, B, J, K, C)
        parts += [("Ag", list(Ag.ravel())), ("B3", list(B3.ravel()))]
    for key, values in parts:
        offsets[key] = len(outputs)
        outputs += values
    fn = compile_function("constants", reals + items, [lift(g, v) for v in outputs], g, label="actuator constants")
    code = [to_c(fn.source, f"constants_n{N}", packed={"reals": reals, "lists": items})]
    # --- the kernels, one per structure, their numbers read from Q (parameters) and H (step size)
    q_slots = {f"Q_{k}": ("Q", i) for i, k in enumerate(constants)}
    rows, sizes = [], []
    fr_code = {None: 0, "coulomb": 1, "stribeck": 2}
    for name, chosen, backlash in _actuator_variants(block):
        vb = am.ActuatorBlock({**block.params, **chosen}, name=block.name)
        slots, h_names = dict(q_slots), []
        friction = "stribeck" if chosen["tau_s"] > 0.0 else "coulomb" if chosen["tau_c"] > 0.0 else None
        if backlash:
            source = am.backlash_kernel_source(vb, 0.0, 1, named=True, symbolic=True)
            blocks = [("PC", (5, 5)), ("GC", (5, 3)), ("PG", (5, 5)), ("GG", (5, 3))]
            prefixes = ("FC_", "FG_")
        else:
            source = am.kernel_source(
                vb, am.name_grid("P", (nx, nx)), am.name_grid("G", (nx, 2)), 1, named=True, symbolic=True
            )
            blocks = [("P", (nx, nx)), ("G", (nx, 2))]
            prefixes = ("F_",)
        for prefix, shape in blocks:
            h_names += am.name_grid(prefix, shape).ravel().tolist()
        friction_at = []
        for prefix in prefixes:
            friction_at.append(len(h_names))
            h_names += [prefix + k for k in (friction_keys[friction] if friction else [])]
        h_names.append("H_SUB")  # the substep, for the carried mass (ActuatorBlock._bind's numbers)
        slots.update({n: ("H", k) for k, n in enumerate(h_names)})
        code.append(
            to_c(_indexed(source, slots, ("H", "Q", "M_SUB")), f"kernel_n{N}_{name}", arrays=("values", "x", "H", "Q"))
        )
        ripple = int(chosen["tau_ripple"] > 0.0)
        rows.append(
            (
                f"kernel_n{N}_{name}",
                fr_code[friction],
                ripple,
                int(backlash),
                friction_at[0],
                friction_at[-1],
                len(h_names) - 1,
            )
        )
        sizes.append(len(h_names))
    keys = list(constants)
    chain = (
        N,
        f"constants_n{N}",
        first,
        len(rows),
        offsets["A"],
        offsets["B"],
        offsets["J"],
        offsets["K"],
        offsets["Ag"],
        offsets["B3"],
        keys.index("bw"),
        keys.index("hb") if N == 2 else -1,
    )
    return code, rows, chain, len(outputs), max(sizes)


# ----------------------------------------------------------------------------------- mechanism
def _ikjac_c(eng, name: str, checks: Mapping[str, object]) -> str:
    """The engine's traced inverse kinematics with its Jacobian as C ``name``, ``name_p`` (the engine's traced
    parameters, ``eng.parameters``, from the array P; none for an engine traced with them as constants) and
    ``name_m``, the same as mast_dk's ``mast_ikjac`` (its model: P)."""
    args = "".join(f", P[{k}]" for k in range(len(eng.parameters)))
    q = ", ".join(f"q{k}" for k in range(eng.n))
    return "\n".join(
        [
            to_c(eng._fn("ikjac").source, name, checks=checks),
            f"static int {name}_p(const double *P, {', '.join(f'double q{k}' for k in range(eng.n))}, double *out)",
            "{",
            "    (void)P;",
            f"    return {name}({q}{args}, out);",
            "}",
            f"static int {name}_m(const void *P, const double *q, double *out) {{ return {name}_p(P, "
            f"{', '.join(f'q[{k}]' for k in range(eng.n))}, out); }}",
            "",
        ]
    )


def _dk_call(eng, model: str, names: str, lengths: str, q: str, J: str, text: str) -> str:
    """C: mast_dk of the engine ``eng`` (``ikjac_m``, ``why``) for rho, from and into ``q``, J into ``J``."""
    return (
        f"mast_dk(&(mast_dk_problem){{{eng.n}, ikjac_m, {model}, why, {names}, {lengths}, {c_double(eng.margin)}, "
        f"{c_double(eng.cond_limit)}, 1e-12, 50}}, rho, {q}, {J}, {text})"
    )


def _mechanism(block, vrs: Mapping[str, int]) -> tuple[str, str]:
    """MechanismBlock of any description for every parameter set: the engine traced with the description's
    parameters (geometry, bodies, payload, g) as named inputs (``designs.traced_engine``), their values read at
    initialisation (``mechanism_model``), the checks of ``designs.describe`` (the same messages) by the runtime
    (``mast_mechanism_check``) at exitInitializationMode. (model file, config.h)"""
    from fmus.mechanism.designs import traced_engine

    eng = traced_engine(block.params, block.name)
    return mechanism_model(eng, vrs, block.INPUTS)


def mechanism_variables(n: int) -> list[Variable]:
    """The variables of a mechanism of ``n`` drives without parameters (the connector convention,
    ``fmus.mechanism.model.Variables``): its inputs per drive, outputs F_k, the pose x, y, z, psi, theta, phi, Fc_k
    and Mc_k."""
    from fmus.mechanism.model import INPUT_NAMES
    from fmus.mechanism.topology import POSE

    ks = range(1, n + 1)
    inputs = [f"{kind}_{k}" for kind in INPUT_NAMES for k in ks]
    outputs = [f"F_{k}" for k in ks] + list(POSE) + [f"Fc_{k}" for k in ks] + [f"Mc_{k}" for k in ks]
    return [
        Variable(name, vr, "Real", "input" if vr < len(inputs) else "output", 0.0)
        for vr, name in enumerate(inputs + outputs)
    ]


def _parameter_kernel(name: str, inputs: Sequence[str], graph, outputs: Sequence[object]) -> str:
    """``int name(double *P, double *out)``: ``outputs`` (numbers, or expressions traced in ``graph`` from its inputs
    ``inputs``, the traced parameters P) as straight-line C (at least one output: 0.0 when there is none)."""
    from fmus.common.tracer import compile_function, lift

    fn = compile_function(name, inputs, [lift(graph, v) for v in (list(outputs) or [0.0])], graph, label=name)
    return to_c(fn.source, name, packed={"P": list(inputs)}, static=False)


def _guess(eng, env: Mapping[str, object]) -> tuple[Optional[object], tuple]:
    """The description's cold start as (rule, its numbers with the parameters ``env``): ``Described.guess_rule``,
    or, for a description written in Python (tests' scratch mechanisms), its guess when it does not depend on rho
    (the same pose for rho = 0 and rho = 1 m; ValueError naming the description otherwise)."""
    n, d = eng.n, eng.description
    if hasattr(d, "guess_rule"):
        return d.guess_rule(d.legs_at(env, True), env)
    poses = []
    for rho in ([0.0] * n, [1.0] * n):
        try:
            poses.append(tuple(float(v) for v in d.guess(rho)))
        except Exception as err:  # noqa: BLE001 (the description's own code: any failure means no constant guess)
            raise ValueError(f"{d.name}: its guess fails at rho = {rho}: {err}") from None
    if poses[0] != poses[1] or len(poses[0]) != n:
        raise ValueError(
            f"{d.name}: its guess {poses[0]} at rho = 0 and {poses[1]} at rho = 1 m is not one pose of "
            f"{n} coordinates: the native mechanism takes a constant cold start or a rule (Described.guess_rule)"
        )
    return None, poses[0]


def _check_rows(name: str, units: Mapping[str, str], env: Mapping[str, object]) -> tuple[list[str], list[object]]:
    """The rows of ``designs.CHECKS[name]`` (mast_mechanism_check) and the values they compare and show
    (expressions of the parameters ``env``)."""
    from fmus.mechanism.description import Expression
    from fmus.mechanism.designs import CHECKS

    values: list[object] = []
    index: dict[str, int] = {}

    def at(source: str) -> int:
        if source not in index:
            index[source] = len(values)
            values.append(Expression(source, f"designs.CHECKS[{name!r}]", units)(env))
        return index[source]

    rows = []
    for check in CHECKS.get(name, ()):
        shown = [at(x) for x in check.shown]
        a, b = (at(x) for x in check.operands) if check.kind == "less" else (0, 0)
        when = at(check.when[0]) if check.when[0] else -1
        fmt = c_string(check.message).replace("{}", "%s")
        rows.append(
            f"    {{{int(check.kind == 'assembles')}, {int(check.regular)}, {when}, {int(check.when[1] == 'zero')}, "
            f"{a}, {b}, {len(shown)}, {{{', '.join(str(k) for k in shown) or '0'}}}, {fmt}}},"
        )
    return rows, values


def mechanism_model(eng, vrs: Mapping[str, int], inputs: Sequence[str], bodies: bool = True) -> tuple[str, str]:
    """The generated part of a native mechanism (mast_mechanism.h) for the engine ``eng`` of any description
    (traced with its parameters as named inputs, ``designs.traced_engine``, or with its numbers as constants: a
    description written in Python): its traced kernels (inverse kinematics with its Jacobian, dynamics, pose),
    each split into what the parameters alone fix (``split_invariants``: computed at initialisation) and the rest,
    with a fixed interface (``packed``: q, J, rho_dot, rho_ddot, the parameters P as arrays); what the parameters
    alone give, traced (the cold start's numbers, ``Described.guess_rule``; the platform points the coordinates'
    lengths come from; the bodies; the values of the description's checks, ``designs.CHECKS``); the restart policy
    (``mechanism.model.restarted_dk``) and the cold start's rule translated from their own source; the tables
    (value references, names, bodies, checks). ``vrs``: the FMU's value references by name (the parameters, with
    'kinematics', 'attached' and the update period 'T_mech'; {} for a mechanism without parameters); ``inputs``:
    the FMU's input names; ``bodies``: whether the checks include the bodies' (not for a kinematic model: its bodies
    are none). (model part, config.h)"""
    import inspect

    from fmus.common.tracer import Graph
    from fmus.mechanism.description import named_parameters
    from fmus.mechanism.designs import KINEMATICS
    from fmus.mechanism.legs import level_height
    from fmus.mechanism.model import SINGULAR, restarted_dk

    n, names = eng.n, list(eng.parameters)
    d = eng.description
    fns = {name: eng._fn(key) for name, key in (("ikjac", "ikjac"), ("dynamics", "forces"), ("pose", "pose"))}
    checks = {k: v for fn in fns.values() for k, v in fn.namespace.items() if k.startswith("_check")}
    q = [f"q{j}" for j in range(n)]
    groups = {
        "q": q,
        "J": [f"J{j}{k}" for j in range(n) for k in range(n)],
        "rho_dot": [f"rd{k}" for k in range(n)],
        "rho_ddot": [f"rdd{k}" for k in range(n)],
        "P": names,
    }
    code, sizes = [], {}
    for name, fn in fns.items():
        invariants, main, sizes[name] = split_invariants(fn.source, names)
        code += [
            to_c(invariants, f"mech_{name}_invariants", packed={"P": names}, static=False),
            to_c(
                main,
                f"mech_{name}",
                arrays=("K",),
                checks=checks,
                static=False,
                packed={k: v for k, v in groups.items() if k in ("q", "P") or name == "dynamics"},
            ),
        ]
    args = list(inspect.signature(restarted_dk).parameters)
    joints = args[: args.index("warm")]
    packing = {"rho": joints} if joints != ["rho"] else {}
    code += [
        to_c(
            inspect.getsource(restarted_dk),
            "mech_restarted_dk",
            arrays=("S", "out", *(() if packing else ("rho",))),
            calls={"dk": "mast_mechanism_dk"},
            constants={"SINGULAR": SINGULAR},
            packed=packing,
            static=False,
        ),
        _why_function("mech_why", checks, static=False),
    ]
    # what the parameters alone give, traced from the description with the parameters as inputs
    graph = Graph()
    inputs_p = names or ["P0"]  # a mechanism without parameters: one slot no kernel reads (MECH_NP >= 1)
    file = getattr(d, "file", None)
    env: dict[str, object] = dict(getattr(d, "params", {}))
    env.update({p: graph.input(p) for p in names})
    rule, numbers = _guess(eng, env)
    if rule is not None:  # translated from its own source, with the value function it may call
        rule_args, source = list(inspect.signature(rule).parameters), inspect.getsource(rule)
        calls = [f for f in (level_height,) if f"{f.__name__}(" in source]
        code += [
            *(to_c(inspect.getsource(f), f.__name__) for f in calls),
            to_c(
                source,
                "mech_guess_rule",
                packed={"rho": rule_args[:n], "G": rule_args[n:]},
                static=False,
                values=tuple(f.__name__ for f in calls),
            ),
        ]
    legs = d.legs_at(env, True) if file is not None else []
    points = [x for leg in legs for x in leg.platform_point()]
    specs = d.body_specs() if file is not None and bodies else []
    bodies = [v for b in specs for v in (b.mass(env), *(e(env) for row in b.inertia for e in row))]
    units = {p: file.parameters[p].unit for p in file.parameters} if file is not None else {}
    rows, values = _check_rows(d.name, units, env) if file is not None else ([], [])
    code += [
        _parameter_kernel("mech_guess_numbers", inputs_p, graph, numbers),
        _parameter_kernel("mech_platform", inputs_p, graph, points),
        _parameter_kernel("mech_bodies", inputs_p, graph, bodies),
        _parameter_kernel("mech_check_values", inputs_p, graph, values),
    ]
    radius = d.radius_scaled if file is not None else (False,) * n  # a description in Python: constant lengths
    lengths = [c_double(1.0 if scaled else v) for v, scaled in zip(eng.lengths, radius)]
    row = lambda items: ", ".join(str(v) for v in items)  # noqa: E731
    body_rows = [
        f"    {{{_literal(b.name)}, {int(b.optional)}, {_literal(named_parameters(sorted(b.mass.names)))}, "
        f"{_literal(named_parameters(sorted({x for r in b.inertia for e in r for x in e.names})))}}},"
        for b in specs
    ]
    kinematics = [k for k in KINEMATICS if isinstance(k, str)]
    tables = [
        "/* the tables of this mechanism (mast_mechanism.h) */",
        f"const int MECH_TRACED_VR[MECH_NP] = {{{row([vrs.get(p, -1) for p in names] or [-1])}}};   "
        f"/* {', '.join(names) or 'none'} */",
        f"const int MECH_LENGTH_RADIUS[MECH_N] = {{{row(int(r) for r in radius)}}};",
        f"const double MECH_LENGTH_VALUE[MECH_N] = {{{row(lengths)}}};",
        f"const char *const MECH_COORDINATES[MECH_N] = {{{row(_literal(c) for c in d.coordinates)}}};",
        f"const char *const MECH_INPUT_NAMES[MECH_KINDS * MECH_N] = {{{row(_literal(i) for i in inputs)}}};",
        f"const char *const MECH_NAME = {_literal(d.name)};",
        f"const char *const MECH_KINEMATICS[] = {{{row(_literal(k) for k in kinematics)}}};",
        f"const int MECH_NKINEMATICS = {len(kinematics)};",
        "const mast_mechanism_body MECH_BODY[] = {",
        *(body_rows or ['    {"", 0, "", ""},']),
        "};",
        "const mast_parameter_check MECH_CHECK[] = {",
        *(rows or ['    {0, 0, -1, 0, 0, 0, 0, {0}, ""},']),
        "};",
        "",
    ]
    config = "\n".join(
        [
            f"/* Generated by mast build --native from the description {d.name} "
            "(mast.core.native.models): the sizes of this mechanism (mast_mechanism.h) */",
            "#ifndef CONFIG_H",
            "#define CONFIG_H",
            f"#define MECH_N {n}",
            f"#define MECH_NP {len(inputs_p)}",
            *[f"#define MECH_NK_{name.upper()} {max(1, k)}" for name, k in sizes.items()],
            f"#define MECH_NG {max(1, len(numbers))}",
            f"#define MECH_GUESS_RULE {int(rule is not None)}",
            f"#define MECH_NL {len(legs)}",
            f"#define MECH_NB {len(specs)}",
            f"#define MECH_NV {max(1, len(values))}",
            f"#define MECH_NCHECK {len(rows)}",
            f"#define MECH_ATTACHED_VR {vrs.get('attached', -1)}",
            f"#define MECH_KINEMATICS_VR {vrs.get('kinematics', -1)}",
            f"#define MECH_UPDATE_VR {vrs.get('T_mech', -1)}",
            f"#define MECH_MARGIN {c_double(eng.margin)}",
            f"#define MECH_COND_LIMIT {c_double(eng.cond_limit)}",
            f"#define MECH_EXTRAPOLATION {c_double(EXTRAPOLATION)}",
            f"#define MECH_CONDENSE_ABOVE {c_double(CONDENSE_ABOVE)}",
            "#endif",
            "",
        ]
    )
    return "\n".join(code + tables), config


# ----------------------------------------------------------------------------------- controller
def _controller_config(block, eng, L: Mapping[str, int], model: bool, workspace: bool, mechanism: str) -> str:
    """config.h of a native controller (mast_controller.h): its axes, its state's layout ``L`` (``tick.layout``:
    each field as CTRL_<FIELD>, the tick counter ``n`` as CTRL_TICK), what it has (an inverse model, the workspace
    direct kinematics), the tick's failure codes and the traced forces' output count; and the sizes of its
    kinematic model (``mechanism``: the config.h ``mechanism_model`` writes)."""
    import ast

    from fmus.controller.inverse_model import CONSTANTS

    fields = [("TICK" if k == "n" else k.upper(), v) for k, v in L.items()]
    sizes = [line for line in mechanism.splitlines() if line.startswith("#define MECH_")]
    forces = len(ast.parse(eng._fn("forces").source).body[0].body[-1].value.elts) if model else block.n
    return "\n".join(
        [
            f"/* Generated by mast build --native for {type(block).__name__} of {', '.join(block.COORDINATES)} "
            "(mast.core.native.models): do not edit. */",
            "#ifndef CONFIG_H",
            "#define CONFIG_H",
            f"#define CTRL_N {block.n}",
            *(f"#define CTRL_{name} {value}" for name, value in fields),
            f"#define CTRL_K_T {CONSTANTS.index('k_T')}   /* k_T's place in inverse_model.CONSTANTS */",
            f"#define CTRL_INVERSE_MODEL {int(model)}",
            f"#define CTRL_WORKSPACE {int(workspace)}",
            f"#define CTRL_FORCES_OUT {forces}",
            f"#define CTRL_MODEL_FAILED {MODEL_FAILED}",
            f"#define CTRL_DK_FAILED {DK_FAILED}",
            "/* its kinematic model's (mast_mechanism.h) */",
            *sizes,
            "#endif",
            "",
        ]
    )


def _packing(name: str, scalars: Sequence[str], first: str, target: str) -> list[str]:
    """C: ``static int name(double <scalars>..., double *S, double *out)`` (``first``: "S": S comes first) calling
    ``target(array of the scalars, S, out)``: the tick calls with n numbers, the runtime takes an array."""
    numbers = ", ".join(f"double {a}" for a in scalars)
    params = f"double *S, {numbers}, double *out" if first == "S" else f"{numbers}, double *S, double *out"
    return [
        f"static int {name}({params})",
        "{",
        f"    double a[{len(scalars)}] = {{{', '.join(scalars)}}};",
        f"    return {target}(a, S, out);",
        "}",
        "",
    ]


def _joint_controller(block, vrs: Mapping[str, int]) -> tuple[str, str]:
    """A controller of ``native_controllers`` on the runtime mast_controller.c: (model file, config.h). Generated:
    the traced kernels of its kinematic model (and its inverse model's dynamics), the tick translated
    (``tick_sources``), the functions it calls translated from their own source, what the parameters fix
    (``ctrl_constants``) and the checks of a parameter set; the tables of its inputs and coordinates."""
    import inspect

    from fmus.actuator.model import transmission_ratio
    from fmus.controller.model import cascade_gains, pi_step
    from fmus.mechanism.topology import POSE_UNITS

    kind = native_controller(type(block))
    if kind is None:
        raise ValueError(f"{type(block).__name__} has no native form yet")
    model = hasattr(block, "model")  # the feed-forward and computed-torque controllers' inverse model
    cascade = kind is not native_controllers()[2]
    workspace = kind is native_controllers()[3]
    # the kinematic model (and the inverse model's dynamics): the engine traced with the controller's
    # geometry (and bodies) as inputs, read at initialisation (designs.traced_engine); its parameters, cold start,
    # lengths and checks of a parameter set are the native mechanism's (mechanism_model, mast_mechanism.c)
    from fmus.mechanism.designs import traced_engine

    eng = traced_engine(block.params, block.name, masses=model)
    mech_code, mech_config = mechanism_model(
        eng, vrs, [v.name for v in mechanism_variables(eng.n) if v.causality == "input"], bodies=model
    )
    L = layout(block.n, len(eng.parameters))  # the state's parameter slot: this engine's traced parameters
    if any(L[k] != v for k, v in type(block).LAYOUT.items() if v < L["P"]):
        raise ValueError(f"{block.name}: the tick's state layout differs from tick.layout before its parameters")

    def P(name: str) -> str:
        return f"p->real[{vrs[name]}]"

    laws = type(block).LAWS  # the laws' arithmetic the tick calls, translated from their own source
    # the controller's own gains, by its own function (FeedForwardController, ComputedTorque, Workspace)
    own, own_call = None, ""
    if kind is native_controllers()[1]:
        from fmus.controller.feedforward import feedforward_gains as own

        own_call = (
            f"    feedforward_gains({P('k_ff_v')}, {P('k_ff_tau')}, transmission_ratio({P('p')}, {P('i_r')}), "
            f"S + {L['own']});"
        )
    elif not cascade:
        from fmus.controller.computed_torque import error_gains as own

        own_call = f"    error_gains({P('omega_n')}, {P('zeta')}, S + {L['own']});"
    elif workspace:
        from fmus.controller.workspace import pose_gain as own

        own_call = "\n".join(
            f"    S[{L['own'] + k}] = pose_gain({P('k_v')}, {P(f'k_v_scale_{c}')});"
            for k, c in enumerate(block.COORDINATES)
        )
    n, PO = eng.n, L["P"]
    ik, fns = eng._fn("ik"), [eng._fn("ik"), eng._fn("ikjac")] + ([eng._fn("forces")] if model else [])
    checks = {k: v for fn in fns for k, v in fn.namespace.items() if k.startswith("_check")}
    args = ", ".join(f"S[{PO + k}]" for k in range(len(eng.parameters)))
    q = [f"q{k}" for k in range(n)]
    start, laws_source, steps = tick_sources(type(block))  # pose mode only: the modes are no FMU variables
    ratios = "".join(
        f"    if (mast_controller_ratio_check({_literal(name)}, {P(name)}, {P('T_cur')}, msg, size)) "
        "return MAST_PARAMETER_ERROR;\n"
        for name in ("T_pos", "T_vel")
    )
    table = lambda items: ", ".join(_literal(v) for v in items)  # noqa: E731
    coordinates = table(eng.description.coordinates)
    dk = _dk_call(eng, f"S + {PO}", "CTRL_COORDINATES", f"S + {L['lengths']}", "q", "J", "msg, size")
    inverse_model = []
    if model:
        from fmus.actuator.model import guide_friction
        from fmus.controller.inverse_model import CONSTANTS, motor_torque
        from fmus.controller.reference import rates
        from fmus.mechanism.model import SINGULAR, restarted_dk

        params = ", ".join(f"S[{PO + k}]" for k in range(len(eng.parameters)))
        J = ", ".join(f"J[{k}]" for k in range(n * n))
        motion = ", ".join(f"a[{k}]" for k in range(n, 3 * n))
        inverse_model = [
            _model_constants_c(vrs),
            to_c(eng._fn("forces").source, "forces", checks=checks),
            "int ctrl_forces(const double *q, const double *J, const double *a, const double *S, double *F)",
            "{",
            f"    return forces({', '.join(f'q[{k}]' for k in range(n))}, {J}, {motion}, {params}, F);",
            "}",
            "",
            to_c(inspect.getsource(rates), "rates"),
            to_c(inspect.getsource(guide_friction), "guide_friction"),
            to_c(inspect.getsource(motor_torque), "motor_torque", values=("guide_friction",)),
            "double ctrl_motor_torque(double rho_dot, double rho_ddot, double F, const double *c)",
            "{",
            "    return motor_torque(rho_dot, rho_ddot, F, "
            f"{', '.join(f'c[{k}]' for k in range(CONSTANTS.index('k_T')))});",
            "}",
            "",
            to_c(
                inspect.getsource(restarted_dk),
                "ctrl_restarted_dk",
                arrays=("rho", "S", "out"),
                calls={"dk": "mast_controller_dk"},
                constants={"SINGULAR": SINGULAR},
                static=False,
            ),
            *_packing("currents", [f"a{k}" for k in range(3 * n)], "", "mast_controller_currents"),
        ]
    constants = [
        "/* DriveController._constants: the schedule, the transmission, the kinematic model and the gains from the",
        "   parameters (checked by model_check) */",
        "void ctrl_constants(const mast_parameters *p, double *S)",
        "{",
        f"    S[{L['T_cur']}] = {P('T_cur')};",
        f"    S[{L['T_pos']}] = {P('T_pos')};",
        f"    S[{L['N_pos']}] = nearbyint({P('T_pos')} / {P('T_cur')});",
        f"    S[{L['N_vel']}] = nearbyint({P('T_vel')} / {P('T_cur')});",
        f"    S[{L['i_R']}] = transmission_ratio({P('p')}, {P('i_r')});",
        *(
            [f"    S[{L['attached']}] = p->integer[{vrs['attached']}];", f"    model_constants(p, S + {L['model']});"]
            if model
            else []
        ),
        "    /* the gains, by the controller's own functions */",
        *(
            [
                f"    cascade_gains({P('k_v')}, {P('k_p')}, {P('k_i')}, {P('T_vel')}, "
                f"transmission_ratio({P('p')}, {P('i_r')}), S + {L['gains']});"
            ]
            if cascade
            else []
        ),
        f"    S[{L['gains'] + 3}] = {P('i_max')};",
        *([own_call] if own_call else []),
        "}",
        "",
    ]
    body = "\n".join(
        [
            mech_code,
            to_c(ik.source, "ik", checks=checks),
            f"static int ik_s(double *S, {', '.join(f'double {a}' for a in q)}, double *out)",
            "{",
            f"    return ik({', '.join(q)}, {args}, out);",
            "}",
            "",
            _ikjac_c(eng, "ikjac", checks),
            f"static int ikjac_s(double *S, {', '.join(f'double {a}' for a in q)}, double *out)",
            "{",
            f"    return ikjac_p(S + {PO}, {', '.join(q)}, out);",
            "}",
            "",
            _why_function("why", checks),
            "const char *ctrl_why(int check) { return why(check); }",
            "",
            "int ctrl_dk(const double *rho, double *S, double *q, double *J, char *msg, size_t size)",
            "{",
            f"    return {dk};",
            "}",
            "",
            f"const char *const CTRL_INPUT_NAMES[] = {{{table(block.INPUTS)}}};",
            f"const char *const CTRL_COORDINATES[] = {{{coordinates}}};",
            f"const char *const CTRL_UNITS[] = {{{table(POSE_UNITS[c] for c in block.COORDINATES)}}};",
            "",
            "/* the controller's checks of its parameter set after the ranges (DriveController, designs.describe) */",
            "static int model_check(const mast_parameters *p, char *msg, size_t size)",
            "{",
            ratios + MECHANISM_CHECK,
            "    return MAST_OK;",
            "}",
            "",
            to_c(inspect.getsource(pi_step), "pi_step"),
            to_c(inspect.getsource(transmission_ratio), "transmission_ratio"),
            to_c(inspect.getsource(cascade_gains), "cascade_gains"),
            *inverse_model,
            to_c(inspect.getsource(own), own.__name__) if own else "",
            *constants,
            *(_packing("wsdk", [f"r{k}" for k in range(n)], "", "mast_controller_wsdk") if workspace else []),
            to_c(start, "start", arrays=("values", "S", "R"), calls=("ik_s",)),
            *[to_c(inspect.getsource(law), law.__name__) for law in laws],
            to_c(
                laws_source,
                "laws",
                arrays=("values", "S", "R", "CUR", "QM", "JK"),
                calls=("ik_s", "pi_step", "rates", "currents", "wsdk", "ikjac_s"),
                values=[law.__name__ for law in laws],
            ),
            to_c(steps, "steps", arrays=("values", "S", "R", "CUR", "QM", "JK"), calls=("laws",)),
            "/* the tick for the runtime (static above: the compiler specialises laws for steps, inlines steps) */",
            "int ctrl_start(double *values, double *S, double *R) { return start(values, S, R); }",
            "int ctrl_laws(double *values, double *S, double *R, double *CUR, double *QM, double *JK, double n)",
            "{",
            "    return laws(values, S, R, CUR, QM, JK, n);",
            "}",
            "int ctrl_steps(double *values, double *S, double *R, double *CUR, double *QM, double *JK, double n, "
            "double m)",
            "{",
            "    return steps(values, S, R, CUR, QM, JK, n, m);",
            "}",
            "",
        ]
    )
    return body, _controller_config(block, eng, L, model, workspace, mech_config)


def _model_constants_c(vrs: Mapping[str, int]) -> str:
    """``model_constants(p, out)``: the inverse model's actuator constants (``inverse_model.CONSTANTS``) from
    the parameters, by ``inverse_model.model_constants`` traced (``two_inertia``, ``transmission_ratio``)."""
    from fmus.common.tracer import Graph, compile_function, lift
    from fmus.controller.inverse_model import CONSTANTS, model_constants

    g = Graph()
    names = (
        "J_motor",
        "J_gearbox",
        "J_coupling",
        "J_brake",
        "J1_scale",
        "J_guide",
        "M_load",
        "i_r",
        "p",
        "b_v",
        "g_guide",
        "tau_c",
        "omega_c",
        "tau_s",
        "omega_s",
        "k_T",
    )
    constants = model_constants({n: g.input(n) for n in names})
    assert tuple(constants) == CONSTANTS
    fn = compile_function(
        "traced_model_constants", names, [lift(g, v) for v in constants.values()], g, label="inverse model constants"
    )
    args = ", ".join(f"p->real[{vrs[n]}]" for n in names)
    return "\n".join(
        [
            to_c(fn.source, "traced_model_constants"),
            "/* InverseModel's actuator constants (inverse_model.CONSTANTS) at initialisation */",
            "static void model_constants(const mast_parameters *p, double *out)",
            "{",
            f"    traced_model_constants({args}, out);",
            "}",
            "",
        ]
    )


def native_kind(block_class: type) -> Optional[str]:
    """Which generator makes ``block_class``'s C ('actuator', 'mechanism', 'controller', 'trajectory'),
    None when it has no native form yet (e.g. the EMPS bench's load axis and controller)."""
    from fmus.actuator.drive import DriveActuatorBlock
    from fmus.actuator.model import ActuatorBlock
    from fmus.mechanism.model import MechanismBlock
    from fmus.trajectory.model import TrajectoryBlock

    for kind, classes in (
        ("actuator", (ActuatorBlock, DriveActuatorBlock)),
        ("mechanism", (MechanismBlock,)),
        ("trajectory", (TrajectoryBlock,)),
        ("controller", native_controllers()),
    ):
        if native_controller(block_class) if kind == "controller" else issubclass(block_class, classes):
            return kind
    return None


#: what a controller's class made for a mechanism's axes and parameters sets (``DriveController.for_parameters``:
#: ``_specialised``, ``_with_parameters``, ``_declare``); a subclass setting more has no native form
_SPECIALISED = frozenset(
    {"COORDINATES", "PARAMETERS", "MECHANISM", "INPUTS", "OUTPUTS", "UNITS", "DESCRIPTIONS", "FEEDTHROUGH", "LAYOUT"}
    | {"SIZE", "__module__", "__qualname__", "__doc__", "__dict__", "__weakref__"}
)


def native_controller(block_class: type) -> Optional[type]:
    """The controller of ``native_controllers`` that ``block_class`` is, or is made from for a mechanism's axes and
    parameters (its subclasses setting nothing else); None if none."""
    for cls in block_class.__mro__:
        if cls in native_controllers():
            return cls
        if not set(vars(cls)) <= _SPECIALISED:
            return None
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
    """TrajectoryBlock's tables (mast_trajectory.h): per output <c>_cmd, the value references of <c>_home and
    amplitude_<c>; the frequency's."""
    coordinates = [name.removesuffix("_cmd") for name in block.OUTPUTS]
    row = lambda items: ", ".join(str(v) for v in items)  # noqa: E731
    return "\n".join(
        [
            f"const int TRAJECTORY_N = {len(coordinates)};   /* {', '.join(block.OUTPUTS)} */",
            f"const int TRAJECTORY_HOME_VR[] = {{{row(vrs[f'{c}_home'] for c in coordinates)}}};",
            f"const int TRAJECTORY_AMPLITUDE_VR[] = {{{row(vrs[f'amplitude_{c}'] for c in coordinates)}}};",
            f"const int TRAJECTORY_FREQUENCY_VR = {vrs['frequency']};",
            "",
        ]
    )


# ----------------------------------------------------------------------------------- entry point
def to_generate(block_class: type, generated: Mapping[str, object], wanted: Mapping[str, object]) -> dict[str, object]:
    """What the C generated for the parameter set ``generated`` cannot take at run time from ``wanted``: {} when it
    runs ``wanted`` as it is (every parameter read at run time), else the parameters to generate it for: an
    actuator's chain (``ACTUATOR_STRUCTURE``) when its n_dof is not one of the chains of ``actuator_structures``."""
    if native_kind(block_class) == "actuator" and int(wanted["n_dof"]) not in actuator_structures(generated):
        return {k: wanted[k] for k in ACTUATOR_STRUCTURE}
    return {}


def emit_model(
    identifier: str, guid: str, block_class: type, parameters: Mapping[str, object], variables: Sequence[Variable]
) -> dict[str, str]:
    """The generated C files of the FMU ``identifier`` (its modelDescription ``variables``), from ``block_class``
    built with ``parameters``: ``<identifier>_model.c`` (the kernels and tables), and a mechanism's ``config.h``
    (its sizes); the runtime they run on: ``RUNTIME``."""
    vrs = {v.name: v.vr for v in variables}
    kind = native_kind(block_class)
    if kind == "mechanism":  # its variables and parameters: its description's (as the Python FMU's, slave.py)
        block_class = block_class.for_parameters(parameters)
    n_inputs, n_io = len(block_class.INPUTS), len(block_class.INPUTS) + len(block_class.OUTPUTS)
    expected = list(block_class.INPUTS + block_class.OUTPUTS) + [p.name for p in block_class.PARAMETERS]
    if [v.name for v in variables] != expected or [v.vr for v in variables] != list(range(len(variables))):
        raise ValueError(
            f"{identifier}: the modelDescription's variables are not the block's inputs, outputs and "
            "parameters in value-reference order"
        )
    block = block_class(dict(parameters), name=identifier)
    # parameter starts: the exact values (the XML prints 16 digits; the Python FMU starts from parameters.json)
    variables = [
        Variable(v.name, v.vr, v.type, v.causality, block.params[v.name]) if v.causality == "parameter" else v
        for v in variables
    ]
    extra: list[str] = []
    files, more, state, functions = {}, "", "State", ""
    if kind == "actuator":
        axis = getattr(block, "axis", block)  # DriveActuatorBlock: the axis behind its current loop
        body, files["config.h"] = _actuator(axis, vrs)
        extra = ["    if (mast_actuator_check(p, msg, size)) return MAST_PARAMETER_ERROR;"]
        runtime = "drive" if axis is not block else "actuator"
        more, state, functions = f'#include "mast_{runtime}.h"\n', f"mast_{runtime}_state", f"mast_{runtime}_"
    elif kind == "mechanism":
        body, files["config.h"] = _mechanism(block, vrs)
        extra = [MECHANISM_CHECK]
        more, state, functions = '#include "mast_mechanism.h"\n', "mast_mechanism_state", "mast_mechanism_"
    elif kind == "controller":
        body, files["config.h"] = _joint_controller(block, vrs)
        more, state, functions = '#include "mast_controller.h"\n', "mast_controller_state", "mast_controller_"
    elif kind == "trajectory":
        body = _trajectory(block, vrs)
        more, state, functions = '#include "mast_trajectory.h"\n', "mast_trajectory_state", "mast_trajectory_"
    else:
        raise ValueError(f"{identifier}: {block_class.__name__} has no native form yet")
    files[f"{identifier}_model.c"] = "".join(
        [
            _HEAD.format(what=f"{block_class.__module__}.{block_class.__name__}", more=more),
            _variable_table(variables),
            "\n",
            _check_function(block_class.PARAMETERS, vrs, extra, kind == "controller"),
            "\n",
            body,
            "\n",
            _model_struct(
                identifier,
                guid,
                variables,
                n_inputs,
                n_io,
                bool(block_class.FEEDTHROUGH),
                state,
                functions,
                vrs[block_class.CYCLE_TIME] if block_class.CYCLE_TIME else -1,
            ),
        ]
    )
    return files


def emit_mechanism(identifier: str, guid: str, eng) -> dict[str, str]:
    """The generated C files of a native mechanism FMU for the engine ``eng`` of a description traced with its
    numbers as constants (no parameters; ``mechanism_variables`` its variables): ``<identifier>_model.c`` and
    ``config.h`` (``mechanism_model``, as for a mechanism with parameters, ``emit_model``)."""
    if eng.parameters:
        raise ValueError(
            f"{identifier}: {eng.description.name} is traced with parameters {eng.parameters}: a "
            "mechanism with parameters is generated from its block (emit_model)"
        )
    variables = mechanism_variables(eng.n)
    inputs = [v.name for v in variables if v.causality == "input"]
    model, config = mechanism_model(eng, {}, inputs)
    return {
        "config.h": config,
        f"{identifier}_model.c": "".join(
            [
                _HEAD.format(what=f"description {eng.description.name}", more='#include "mast_mechanism.h"\n'),
                _variable_table(variables),
                "\n",
                _check_function((), {}, [MECHANISM_CHECK]),
                "\n",
                model,
                "\n",
                _model_struct(
                    identifier,
                    guid,
                    variables,
                    len(inputs),
                    len(variables),
                    False,
                    "mast_mechanism_state",
                    "mast_mechanism_",
                ),
            ]
        ),
    }
