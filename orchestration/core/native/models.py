"""The generated part of a native FMU, from the model the Python FMU runs (``mast build --native``).

A native FMU runs on the runtime of fmus/common/native, C written by hand and the same for every model of a kind
(the FMI glue, the matrix helpers, the direct kinematics for n coordinates, and per kind: mast_actuator.c and
mast_drive.c, mast_mechanism.c, mast_trajectory.c; ``runtime_files``), against one fixed interface per kind. What
is generated here for one model is its traced straight-line kernels, its tables (variables, parameter ranges,
chains and kernels, which parameter feeds which traced input) and the sizes in its ``config.h``.

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
- mechanism (every design): the engine's traced functions (inverse kinematics with its
  Jacobian, inverse dynamics, pose), driven by the engine's Newton direct kinematics
  (mast_dk.c); the engine traces the description with every parameter (geometry,
  bodies, payload, g) as a named input (``designs.traced_engine``), so one C file serves every
  parameter set;
- controllers (``native_controllers``: the joint cascade, feed-forward, computed torque,
  workspace): the same traced engine of their own geometry (inverse kinematics; the feed-forward
  and computed-torque controllers' inverse model: direct kinematics and dynamics; the workspace
  controller's direct kinematics and Jacobian), and the tick the Python controllers run
  (``fmus.controller.tick.tick_sources``: ``DriveController``'s schedule, the IK cache, the
  reference's rates, each controller's own law lines, ``position_lines`` and ``velocity_lines``, the
  ticks inside a step),
  translated; what it calls is translated from the models' own source (``pi_step``,
  ``drive_gains``, ``cascade_gains``, ``transmission_ratio``, the controllers' ``LAWS``,
  ``reference.rates``, ``inverse_model.motor_torque``, ``guide_friction``,
  ``designs.level_height``);
- trajectory: the tables of the sine about the home pose (mast_trajectory.c; its parameters read at run time).

The direct kinematics' restart policy (warm start, else cold; a cold restart after a failed warm
start, never after a singularity) is ``mechanism.model.restarted_dk``, which ``MechanismBlock`` and
``InverseModel`` run and the mechanism and the feed-forward and computed-torque controllers translate.

What the models' generators do not cover is restated in C, held to the Python model by
tests/test_native.py: in the runtime, the outputs of the actuator at rest, its doubling of its substeps around
``mast_expm`` and the allocation of its delay line, the mechanism's restart and messages
(``MechanismBlock._compute``); still in this module's strings (the next step of issue 25): the one attempt of
the direct kinematics each controller's C file makes (``dk``: ``mast_dk`` from its guess) and the messages
around it (``InverseModel.torques``, ``WorkspaceController._wsdk``), the controllers' ``evaluate`` and
``do_step`` around the tick (once per communication point, the step's checks and messages), and the 3PRS
design's checks of a parameter set (``designs.describe``'s).

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
from fmus.controller.tick import DK_FAILED, LAYOUT, MODEL_FAILED, SIZE, tick_sources

from .translate import c_double, split_invariants, to_c

__all__ = [
    "Variable",
    "emit_model",
    "emit_mechanism",
    "mechanism_model",
    "mechanism_variables",
    "mechanism_guess",
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
) -> str:
    """MAST_MODEL: the model's table row; ``state``: its state's type, ``functions``: the prefix of its initialize
    and do_step (a runtime's, e.g. ``mast_mechanism_``)."""
    return (
        f"const mast_model MAST_MODEL = {{{_literal(identifier)}, {_literal(guid)}, {len(variables)}, VARIABLES, "
        f"{n_inputs}, {n_io}, sizeof({state}), check, {functions}initialize, {functions}do_step, "
        f"{'evaluate' if feedthrough else 'NULL'}}};\n"
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
}
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
_SHARED_CONSTANTS = ("tau_c", "omega_c", "tau_s", "omega_s", "ripple", "rk", "iR", "mg", "kT", "rho0", "rmin", "rmax")


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
        slots.update({n: ("H", k) for k, n in enumerate(h_names)})
        code.append(
            to_c(_indexed(source, slots, ("H", "Q", "M_SUB")), f"kernel_n{N}_{name}", arrays=("values", "x", "H", "Q"))
        )
        ripple = int(chosen["tau_ripple"] > 0.0)
        rows.append((f"kernel_n{N}_{name}", fr_code[friction], ripple, int(backlash), friction_at[0], friction_at[-1]))
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


def _traced_parameters_c(vrs: Mapping[str, int]) -> str:
    """``traced_parameters(p, P)``: the values of ``designs.TRACED_PARAMETERS`` as the host set them (0 for those
    the FMU does not have: a kinematic model's masses and g, ``PRS3.traced(masses=False)``)."""
    from fmus.mechanism.designs import TRACED_PARAMETERS

    return "\n".join(
        [
            "static void traced_parameters(const mast_parameters *p, double *P)",
            "{",
            *[
                f"    P[{k}] = {f'p->real[{vrs[n]}]' if n in vrs else '0.0'};   /* {n} */"
                for k, n in enumerate(TRACED_PARAMETERS)
            ],
            "}",
            "",
        ]
    )


def _describe_checks_c(vrs: Mapping[str, int], payload: bool, why: str = "why", mechanism: bool = False) -> list[str]:
    """C lines (in a function with ``p``, ``msg``, ``size``) of ``designs.describe``'s checks of a parameter set
    after its ranges, with its messages: the kinematics, kinematics.Geometry.checked (beta = 0), the payload's
    inertia tensor (``payload``: engine.Body), designs._check_inclined (beta != 0). Needs ``ikjac`` (traced), or, in a
    ``mechanism``, its hoisted kernels (mast_mechanism.h); ``why``: the message function of its checks."""
    from fmus.mechanism.designs import KINEMATICS, TRACED_PARAMETERS

    P = {name: f"P[{k}]" for k, name in enumerate(TRACED_PARAMETERS)}
    params = ", ".join(f"P[{k}]" for k in range(len(TRACED_PARAMETERS)))
    kind = f'p->string[{vrs["kinematics"]}] ? p->string[{vrs["kinematics"]}] : ""'
    R = {n: f"mast_repr({P[n]}, {n.lower()}, sizeof {n.lower()})" for n in ("H", "r", "L", "beta")}
    lines = [
        f"    double P[{len(TRACED_PARAMETERS)}], out[12], inv[9], det;",
        "    char h[40], r[40], l[40], beta[40], a1[40], a2[40], a3[40];",
        "    traced_parameters(p, P);",
        *(
            f"    if (strcmp({kind}, \"{name}\") == 0) {{ snprintf(msg, size, \"parameter 'kinematics' = '%s': this "
            "native "
            f'FMU computes the 3PRS it was generated from", {kind}); return MAST_PARAMETER_ERROR; }}'
            for name in KINEMATICS
            if name != "3PRS"
        ),
        f'    if (strcmp({kind}, "3PRS") != 0) {{',
        f"        snprintf(msg, size, \"parameter 'kinematics' = '%s': expected one of {', '.join(KINEMATICS)}\", "
        f"{kind});",
        "        return MAST_PARAMETER_ERROR;",
        "    }",
        f"    double cb = cos({P['beta']}), sb = sin({P['beta']});",
        f"    double z = level_height(0.0, 0.0, 0.0, {P['H']}, {P['r']}, {P['L']}, cb, sb);",
        *(
            [
                "    double K[MECH_NK_IKJAC], level[3] = {z, 0.0, 0.0};",
                "    mech_ikjac_invariants(P, K);",
                "    int code = mech_ikjac(level, P, K, out);",
            ]
            if mechanism
            else ["    int code = ikjac(z, 0.0, 0.0, " + params + ", out);"]
        ),
        f"    if ({P['beta']} == 0.0) {{   /* kinematics.Geometry.checked */",
        f"        if (!({P['r']} < {P['H']})) {{",
        "            snprintf(msg, size, \"parameter 'r' = %s: must be < H = %s m (working assembly: the spherical "
        "joints "
        f'lie inside the guide radius)", {R["r"]}, {R["H"]});',
        "            return MAST_PARAMETER_ERROR;",
        "        }",
        f"        if (!({P['H']} - {P['r']} < {P['L']})) {{",
        f"            snprintf(msg, size, \"parameter 'L' = %s: must exceed H - r = %s m, or the legs cannot reach the "
        f'platform", {R["L"]}, mast_repr({P["H"]} - {P["r"]}, h, sizeof h));',
        "            return MAST_PARAMETER_ERROR;",
        "        }",
        "        if (code || !mast_inv(3, out + 3, inv, &det)) {",
        "            snprintf(msg, size, \"parameters 'alpha_1', 'alpha_2', 'alpha_3' = (%s, %s, %s) rad: the "
        "mechanism "
        'cannot be assembled at the level pose: %s", '
        f"mast_repr({P['alpha_1']}, a1, sizeof a1), mast_repr({P['alpha_2']}, a2, sizeof a2), "
        f'mast_repr({P["alpha_3"]}, a3, sizeof a3), code ? {why}(-code) : "singular configuration");',
        "            return MAST_PARAMETER_ERROR;",
        "        }",
        "    }",
    ]
    if payload:
        names = ("I_payload_xx", "I_payload_xy", "I_payload_xz", "I_payload_yy", "I_payload_yz", "I_payload_zz")
        I = [P[n] for n in names]
        tensor = ", ".join(I[k] for k in (0, 1, 2, 1, 3, 4, 2, 4, 5))
        lines += [
            "    /* the payload's inertia tensor (engine.Body), when there is a payload */",
            f"    double tensor[9] = {{{tensor}}}, big = 1.0;",
            "    for (int k = 0; k < 9; k++) if (fabs(tensor[k]) > big) big = fabs(tensor[k]);",
            f"    int any = {P['m_payload']} != 0.0;",
            "    for (int k = 0; k < 9; k++) any = any || tensor[k] != 0.0;",
            "    if (any && mast_sym3_min_eig(tensor) < -1e-12 * big) {",
            "        snprintf(msg, size, \"parameters 'I_payload_*': body payload: inertia tensor is not positive "
            'semi-definite");',
            "        return MAST_PARAMETER_ERROR;",
            "    }",
        ]
    lines += [
        f"    if ({P['beta']} != 0.0 && code) {{   /* designs._check_inclined */",
        "        snprintf(msg, size, \"parameters 'H', 'r', 'L', 'beta' = %s m, %s m, %s m, %s rad: the mechanism "
        "cannot be "
        'assembled at the level pose with the sliders at the foot of their guides: %s", '
        f"{R['H']}, {R['r']}, {R['L']}, {R['beta']}, {why}(-code));",
        "        return MAST_PARAMETER_ERROR;",
        "    }",
    ]
    return lines


def _level_height_c() -> str:
    """``designs.level_height`` (the direct kinematics' cold start), translated from its own source."""
    import inspect

    from fmus.mechanism.designs import level_height

    return to_c(inspect.getsource(level_height), "level_height")


def _mechanism(block, vrs: Mapping[str, int]) -> tuple[str, str]:
    """MechanismBlock for every parameter set of the 3PRS: the engine traced with the geometry, the bodies, the
    payload and g as named inputs (``designs.traced_engine``), their values read at initialisation
    (``mechanism_model``); the geometry checks of ``designs.describe`` (the same messages) at
    exitInitializationMode. (model file, config.h)"""
    from fmus.mechanism.designs import TRACED_PARAMETERS, traced_engine

    eng = traced_engine(block.params, block.name)
    if (
        tuple(eng.parameters) != TRACED_PARAMETERS
        or len(eng.lengths) != 3
        or eng.lengths != (1.0, block.params["r"], block.params["r"])
    ):
        raise ValueError(
            f"{block.name}: the native mechanism expects the 3PRS traced with {TRACED_PARAMETERS} and "
            "the coordinate lengths (1, r, r)"
        )
    r = TRACED_PARAMETERS.index("r")
    joints = ", ".join(f"r{k}" for k in range(eng.n))
    # PRS3.guess: the level pose for the mean slider position, its cosines from beta as PRS3 computes them
    guess = (
        f"def guess({joints}, {', '.join(TRACED_PARAMETERS)}):\n"
        f"    return (level_height({joints}, H, r, L, cos(beta), sin(beta)), 0.0, 0.0)\n"
    )
    model, config = mechanism_model(
        eng,
        [vrs.get(name, -1) for name in TRACED_PARAMETERS],
        (-1, r, r),
        vrs["attached"],
        guess,
        block.INPUTS,
        [_level_height_c()],
        vrs.get("T_mech", -1),
    )
    return "\n".join(
        [
            model,
            _traced_parameters_c(vrs),
            "/* designs.describe's checks of a parameter set (after the ranges), with its messages */",
            "static int model_check(const mast_parameters *p, char *msg, size_t size)",
            "{",
            *_describe_checks_c(vrs, payload=True, why="mech_why", mechanism=True),
            "    return MAST_OK;",
            "}",
            "",
        ]
    ), config


def mechanism_guess(eng) -> str:
    """The Python source of ``guess(r0, ..., <the traced parameters>)``: the description's cold start of the
    direct kinematics when it does not depend on rho (the same pose for rho = 0 and rho = 1 m); ValueError
    naming the description otherwise (a guess that moves with rho has a native form when written as one, as
    the 3PRS's level pose: ``_mechanism``)."""
    n, d = eng.n, eng.description
    poses = []
    for rho in ([0.0] * n, [1.0] * n):
        try:
            poses.append(tuple(float(v) for v in d.guess(rho)))
        except Exception as err:  # noqa: BLE001 (the description's own code: any failure means no constant guess)
            raise ValueError(f"{d.name}: its guess fails at rho = {rho}: {err}") from None
    if poses[0] != poses[1] or len(poses[0]) != n:
        raise ValueError(
            f"{d.name}: its guess {poses[0]} at rho = 0 and {poses[1]} at rho = 1 m is not one pose of "
            f"{n} coordinates: the native mechanism takes a constant cold start (or one written as a "
            "generated function)"
        )
    args = ", ".join([f"r{k}" for k in range(n)] + list(eng.parameters))
    return f"def guess({args}):\n    return ({', '.join(c_double(v) for v in poses[0])},)\n"


def mechanism_variables(n: int) -> list[Variable]:
    """The variables of a mechanism of ``n`` drives without parameters (the connector convention): inputs rho_k,
    rho_dot_k, rho_ddot_k, outputs F_k and the pose x, y, z, psi, theta, phi."""
    from fmus.mechanism.topology import POSE

    inputs = [f"{kind}_{k}" for kind in ("rho", "rho_dot", "rho_ddot") for k in range(1, n + 1)]
    outputs = [f"F_{k}" for k in range(1, n + 1)] + list(POSE)
    return [
        Variable(name, vr, "Real", "input" if vr < len(inputs) else "output", 0.0)
        for vr, name in enumerate(inputs + outputs)
    ]


def mechanism_model(
    eng,
    traced_vrs: Sequence[int],
    length_parameters: Sequence[int],
    attached_vr: int,
    guess: str,
    inputs: Sequence[str],
    support: Sequence[str] = (),
    update_vr: int = -1,
) -> tuple[str, str]:
    """The generated part of a native mechanism (mast_mechanism.h) for the engine ``eng`` of any description: its
    traced kernels (inverse kinematics with its Jacobian, dynamics, pose), each split into what the parameters
    alone fix (``split_invariants``: computed at initialisation, not at every step) and the rest, with a fixed
    interface (``packed``: q, J, rho_dot, rho_ddot, the parameters P as arrays); the restart policy
    (``mechanism.model.restarted_dk``) and the cold start ``guess`` (Python source of the generated subset)
    translated; the tables. ``traced_vrs``: per traced parameter (``eng.parameters``), its value reference or
    -1; ``length_parameters``: per coordinate, the traced parameter that is its length (``Engine.lengths``) or
    -1 (then the engine's number); ``attached_vr``: the value reference of 'attached', or -1; ``inputs``: the
    FMU's input names; ``support``: C the guess calls (value functions); ``update_vr``: the value reference of
    the update period 'T_mech' (mechanism.model.UPDATE_PERIOD), or -1: every step. (model part, config.h)"""
    import inspect

    from fmus.mechanism.model import SINGULAR, restarted_dk

    n, names = eng.n, list(eng.parameters)
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
        *support,
        to_c(
            guess,
            "mech_guess",
            packed={"rho": [f"r{k}" for k in range(n)], "P": names},
            static=False,
            values=("level_height",),
        ),
        _why_function("mech_why", checks, static=False),
    ]
    lengths = [c_double(v if k < 0 else 0.0) for v, k in zip(eng.lengths, length_parameters)]
    row = lambda items: ", ".join(str(v) for v in items)  # noqa: E731
    tables = [
        "/* the tables of this mechanism (mast_mechanism.h) */",
        f"const int MECH_TRACED_VR[MECH_NP] = {{{row(traced_vrs or [-1])}}};   /* {', '.join(names) or 'none'} */",
        f"const int MECH_LENGTH_PARAMETER[MECH_N] = {{{row(length_parameters)}}};",
        f"const double MECH_LENGTH_VALUE[MECH_N] = {{{row(lengths)}}};",
        f"const char *const MECH_COORDINATES[MECH_N] = {{{row(_literal(c) for c in eng.description.coordinates)}}};",
        f"const char *const MECH_INPUT_NAMES[3 * MECH_N] = {{{row(_literal(i) for i in inputs)}}};",
        "",
    ]
    config = "\n".join(
        [
            f"/* Generated by mast build --native from the description {eng.description.name} "
            "(mast.core.native.models): the sizes of this mechanism (mast_mechanism.h) */",
            "#ifndef CONFIG_H",
            "#define CONFIG_H",
            f"#define MECH_N {n}",
            f"#define MECH_NP {max(1, len(names))}",
            *[f"#define MECH_NK_{name.upper()} {max(1, k)}" for name, k in sizes.items()],
            f"#define MECH_ATTACHED_VR {attached_vr}",
            f"#define MECH_UPDATE_VR {update_vr}",
            f"#define MECH_MARGIN {c_double(eng.margin)}",
            f"#define MECH_COND_LIMIT {c_double(eng.cond_limit)}",
            "#endif",
            "",
        ]
    )
    return "\n".join(code + tables), config


# ----------------------------------------------------------------------------------- controller
def _workspace_dk(block) -> str:
    """The workspace controller's direct kinematics of the measured joints in C (Engine.dk from the last
    solution, else from the description's guess, as WorkspaceController._wsdk); ``dk_error`` makes the
    message of a failure by running it again (the guess is only updated on success)."""
    eng = block.kinematics
    coordinates = ", ".join(_literal(n) for n in eng.description.coordinates)
    W, G, A = LAYOUT["warm"], LAYOUT["guess"], LAYOUT["model_args"]
    dk_call = _dk_call(eng, "S + " + str(LAYOUT["P"]), "K_COORDINATES", "LENGTHS(S)", "q", "J", "msg, size")
    return "\n".join(
        [
            f"static const char *const K_COORDINATES[] = {{{coordinates}}};",
            "",
            "static int wsdk_eval(const double *rho, double *S, double *q, char *msg, size_t size)",
            "{",
            "    double J[9];",
            f"    if (S[{W}] == 1.0) {{ for (int k = 0; k < 3; k++) q[k] = S[{G} + k]; }} else guess(S, rho, q);",
            f"    int code = {dk_call};",
            "    if (code) return code;",
            f"    for (int k = 0; k < 3; k++) S[{G} + k] = q[k];",
            f"    S[{W}] = 1.0;",
            "    return 0;",
            "}",
            "",
            "static int wsdk(double r0, double r1, double r2, double *S, double *out)",
            "{",
            "    double rho[3] = {r0, r1, r2};",
            "    char text[1024];",
            "    return wsdk_eval(rho, S, out, text, sizeof text);",
            "}",
            "",
            "static int dk_error(double *S, double t, char *msg, size_t size)",
            "{",
            "    double q[3];",
            "    char text[1024], r0[40], r1[40], r2[40], ts[40];",
            f"    wsdk_eval(S + {A}, S, q, text, sizeof text);",
            '    snprintf(msg, size, "direct kinematics of the measured joints rho = (%s, %s, %s) m failed at t = %s '
            's: %s", '
            f"mast_repr(S[{A}], r0, sizeof r0), mast_repr(S[{A} + 1], r1, sizeof r1), mast_repr(S[{A} + 2], r2, "
            "sizeof r2), "
            "mast_repr(t, ts, sizeof ts), text);",
            "    return MAST_KINEMATICS_ERROR;",
            "}",
            "",
        ]
    )


def _joint_controller(block, vrs: Mapping[str, int]) -> str:
    import inspect

    from fmus.actuator.model import transmission_ratio
    from fmus.controller.model import cascade_gains, pi_step

    if type(block) not in native_controllers():
        raise ValueError(f"{type(block).__name__} has no native form yet")
    model = hasattr(block, "model")  # the feed-forward and computed-torque controllers' inverse model
    cascade = type(block) is not native_controllers()[2]
    workspace = type(block) is native_controllers()[3]

    def P(name: str) -> str:
        return f"p->real[{vrs[name]}]"

    laws = type(block).LAWS  # the laws' arithmetic the tick calls, translated from their own source
    # the controller's own gains, by its own function (FeedForwardController, ComputedTorque, Workspace)
    own, own_call = None, ""
    if type(block) is native_controllers()[1]:
        from fmus.controller.feedforward import feedforward_gains as own

        own_call = (
            f"    feedforward_gains({P('k_ff_v')}, {P('k_ff_tau')}, transmission_ratio({P('p')}, {P('i_r')}), "
            f"s->S + {LAYOUT['own']});"
        )
    elif not cascade:
        from fmus.controller.computed_torque import error_gains as own

        own_call = f"    error_gains({P('omega_n')}, {P('zeta')}, s->S + {LAYOUT['own']});"
    elif workspace:
        from fmus.controller.workspace import pose_gain as own

        own_call = "\n".join(
            f"    s->S[{LAYOUT['own'] + k}] = pose_gain({P('k_v')}, {P(f'k_v_scale_{c}')});"
            for k, c in enumerate(block.COORDINATES)
        )
    # the kinematic model (and the inverse model's dynamics): the engine traced with the controller's
    # geometry (and bodies) as inputs, read at initialisation (designs.traced_engine)
    from fmus.mechanism.designs import TRACED_PARAMETERS, traced_engine

    eng = traced_engine(block.params, block.name, masses=model)
    if tuple(eng.parameters) != TRACED_PARAMETERS:
        raise ValueError(f"{block.name}: the native controller expects the 3PRS traced with {TRACED_PARAMETERS}")
    ik, fns = eng._fn("ik"), [eng._fn("ik"), eng._fn("ikjac")] + ([eng._fn("forces")] if model else [])
    checks = {k: v for fn in fns for k, v in fn.namespace.items() if k.startswith("_check")}
    PO = LAYOUT["P"]
    args = ", ".join(f"S[{PO + k}]" for k in range(len(TRACED_PARAMETERS)))
    start, laws_source, steps = tick_sources(type(block))  # pose mode only: the modes are no FMU variables
    inputs = ", ".join(_literal(n) for n in block.INPUTS)
    ratios = "".join(
        f"    if (ratio_check({_literal(name)}, {P(name)}, {P('T_cur')}, msg, size)) return MAST_PARAMETER_ERROR;\n"
        for name in ("T_pos", "T_vel")
    )
    return "\n".join(
        [
            f"typedef struct {{ double S[{SIZE}]; double before[{SIZE}]; double evaluated; char text[1024]; }} State;",
            "/* before: S before the laws of the tick evaluated; text: the message of a failed direct kinematics */",
            "",
            f"#define LENGTHS(S) ((S) + {SIZE - 3})   /* Engine.lengths (1, r, r) [m]: the margins compare motions */",
            "",
            _traced_parameters_c(vrs),
            to_c(ik.source, "ik", checks=checks),
            "static int ik_s(double *S, double q0, double q1, double q2, double *out)",
            "{",
            f"    return ik(q0, q1, q2, {args}, out);",
            "}",
            "",
            _ikjac_c(eng, "ikjac", checks),
            "static int ikjac_s(double *S, double q0, double q1, double q2, double *out)",
            "{",
            f"    return ikjac_p(S + {PO}, q0, q1, q2, out);",
            "}",
            "",
            _level_height_c(),
            "/* PRS3.guess: the level pose for the mean carriage position (the direct kinematics' cold start) */",
            "static void guess(const double *S, const double *rho, double *out)",
            "{",
            f"    out[0] = level_height(rho[0], rho[1], rho[2], S[{PO}], S[{PO + 1}], S[{PO + 2}], S[{LAYOUT['cb']}], "
            f"S[{LAYOUT['sb']}]);",
            "    out[1] = 0.0;",
            "    out[2] = 0.0;",
            "}",
            "",
            _why_function("why", checks),
            "/* DriveController._ratio: a loop's cycle time an integer multiple of T_cur */",
            "static int ratio_check(const char *name, double T, double T_cur, char *msg, size_t size)",
            "{",
            "    char a[40], b[40];",
            "    double ratio = T / T_cur, n = nearbyint(ratio);",
            "    if (n < 1.0 || fabs(ratio - n) > 1e-6 * n) {",
            "        snprintf(msg, size, \"parameter '%s' = %s s must be an integer multiple of T_cur = %s s (ratio "
            '%.9g)", '
            "name, mast_repr(T, a, sizeof a), mast_repr(T_cur, b, sizeof b), ratio);",
            "        return 1;",
            "    }",
            "    return 0;",
            "}",
            "",
            "/* the controller's checks of its parameter set after the ranges (DriveController, designs.describe) */",
            "static int model_check(const mast_parameters *p, char *msg, size_t size)",
            "{",
            ratios + "\n".join(_describe_checks_c(vrs, payload=model)),
            "    return MAST_OK;",
            "}",
            "",
            to_c(inspect.getsource(pi_step), "pi_step"),
            to_c(inspect.getsource(transmission_ratio), "transmission_ratio"),
            to_c(inspect.getsource(cascade_gains), "cascade_gains"),
            _inverse_model(eng, vrs) if model else "",
            to_c(inspect.getsource(own), own.__name__) if own else "",
            to_c(start, "start", arrays=("values", "S", "R"), calls=("ik_s",)),
            _workspace_dk(block) if workspace else "",
            *[to_c(inspect.getsource(law), law.__name__) for law in laws],
            to_c(
                laws_source,
                "laws",
                arrays=("values", "S", "R", "CUR", "QM", "JK"),
                calls=("ik_s", "pi_step", "rates", "currents", "wsdk", "ikjac_s"),
                values=[law.__name__ for law in laws],
            ),
            to_c(steps, "steps", arrays=("values", "S", "R", "CUR", "QM", "JK"), calls=("laws",)),
            f"static const char *const INPUT_NAMES[] = {{{inputs}}};",
            "",
            "static int input_error(const double *values, double t, char *msg, size_t size)",
            "{",
            "    char v[40], w[40];",
            "    for (int k = 0; k < 9; k++) {",
            "        if (!isfinite(values[k])) {",
            "            snprintf(msg, size, \"input '%s' = %s is not finite at t = %s s\", INPUT_NAMES[k], "
            "mast_repr(values[k], v, sizeof v), mast_repr(t, w, sizeof w));",
            "            return MAST_MODEL_ERROR;",
            "        }",
            "    }",
            "    return MAST_OK;",
            "}",
            "",
            "static int ik_error(const double *values, double t, int check, char *msg, size_t size)",
            "{",
            "    char a[40], b[40], c[40], d[40];",
            '    snprintf(msg, size, "inverse kinematics of the pose command z = %s m, psi = %s rad, theta = %s rad '
            "failed "
            'at t = %s s: %s", mast_repr(values[0], a, sizeof a), mast_repr(values[1], b, sizeof b), '
            "mast_repr(values[2], c, sizeof c), mast_repr(t, d, sizeof d), why(check));",
            "    return MAST_KINEMATICS_ERROR;",
            "}",
            "",
            "static int initialize(void *state, double *values, const mast_parameters *p, double t0, char *msg, "
            "size_t size)",
            "{",
            "    State *s = state;",
            "    double R[3];",
            f"    for (int k = 0; k < {SIZE}; k++) s->S[k] = 0.0;",
            "    s->evaluated = -1.0;",
            f"    s->S[{LAYOUT['t0']}] = t0;",
            "    /* the schedule, the transmission and the kinematic model from the parameters (checked by "
            "model_check) */",
            f"    s->S[{LAYOUT['T_cur']}] = {P('T_cur')};",
            f"    s->S[{LAYOUT['T_pos']}] = {P('T_pos')};",
            f"    s->S[{LAYOUT['N_pos']}] = nearbyint({P('T_pos')} / {P('T_cur')});",
            f"    s->S[{LAYOUT['N_vel']}] = nearbyint({P('T_vel')} / {P('T_cur')});",
            f"    s->S[{LAYOUT['i_R']}] = transmission_ratio({P('p')}, {P('i_r')});",
            f"    traced_parameters(p, s->S + {PO});",
            f"    s->S[{LAYOUT['cb']}] = cos(s->S[{PO + TRACED_PARAMETERS.index('beta')}]);",
            f"    s->S[{LAYOUT['sb']}] = sin(s->S[{PO + TRACED_PARAMETERS.index('beta')}]);",
            *(
                [
                    f"    s->S[{LAYOUT['attached']}] = p->integer[{vrs['attached']}];",
                    f"    model_constants(p, s->S + {LAYOUT['model']});",
                ]
                if model
                else []
            ),
            f"    LENGTHS(s->S)[0] = 1.0; LENGTHS(s->S)[1] = s->S[{PO + 1}]; LENGTHS(s->S)[2] = s->S[{PO + 1}];",
            "    /* the gains from the parameters, by the controller's own functions */",
            *(
                [
                    f"    cascade_gains({P('k_v')}, {P('k_p')}, {P('k_i')}, {P('T_vel')}, "
                    f"transmission_ratio({P('p')}, {P('i_r')}), s->S + {LAYOUT['gains']});"
                ]
                if cascade
                else []
            ),
            f"    s->S[{LAYOUT['gains'] + 3}] = {P('i_max')};",
            *([own_call] if own_call else []),
            "    if (input_error(values, t0, msg, size)) return MAST_MODEL_ERROR;",
            "    int code = start(values, s->S, R);",
            "    return code ? ik_error(values, t0, -code, msg, size) : MAST_OK;",
            "}",
            "",
            "/* the message of the tick's failure code (DriveController._failed) */",
            "static int tick_error(State *s, double *values, int code, char *msg, size_t size)",
            "{",
            f"    double T = s->S[{LAYOUT['T_cur']}], t0 = s->S[{LAYOUT['t0']}];",
            *([f"    if (code == {MODEL_FAILED}) return model_error(s->S, msg, size);"] if model else []),
            *(
                [f"    if (code == {DK_FAILED}) return dk_error(s->S, t0 + s->S[{LAYOUT['failed']}] * T, msg, size);"]
                if workspace
                else []
            ),
            f"    return ik_error(values, t0 + s->S[{LAYOUT['failed']}] * T, -code, msg, size);",
            "}",
            "",
            "/* DriveController._laws of tick n (the outputs too); 0, or an error code with msg */",
            "static int run_laws(State *s, double *values, double n, char *msg, size_t size)",
            "{",
            "    double R[3], CUR[3], QM[3], JK[12];",
            "    int code = laws(values, s->S, R, CUR, QM, JK, n);",
            "    return code ? tick_error(s, values, code, msg, size) : MAST_OK;",
            "}",
            "",
            "/* DriveController.evaluate: the laws of the communication point's tick, once per tick */",
            "static int evaluate(void *state, double *values, const mast_parameters *p, char *msg, size_t size)",
            "{",
            "    State *s = state;",
            "    (void)p;",
            f"    double n = s->S[{LAYOUT['n']}];",
            "    if (s->evaluated == n) memcpy(s->S, s->before, sizeof s->S);",
            "    else { memcpy(s->before, s->S, sizeof s->S); s->evaluated = n; }",
            f"    double t = s->S[{LAYOUT['t0']}] + n * s->S[{LAYOUT['T_cur']}];",
            "    double sum = 0.0;",
            "    for (int k = 0; k < 9; k++) sum += values[k];",
            "    if (sum - sum != 0.0 && input_error(values, t, msg, size)) return MAST_MODEL_ERROR;",
            "    return run_laws(s, values, n, msg, size);",
            "}",
            "",
            "static int do_step(void *state, double *values, const mast_parameters *p, double t, double h, char *msg, "
            "size_t size)",
            "{",
            "    State *s = state;",
            "    char a[40], b[40], c[40];",
            f"    double T = s->S[{LAYOUT['T_cur']}];",
            "    double m = nearbyint(h / T);",
            "    if (m < 1.0 || fabs(h - m * T) > 1e-6 * T) {",
            '        snprintf(msg, size, "step size h = %s s is not a positive integer multiple of T_cur = %s s", '
            "mast_repr(h, a, sizeof a), mast_repr(T, b, sizeof b));",
            "        return MAST_MODEL_ERROR;",
            "    }",
            f"    double n = s->S[{LAYOUT['n']}], t0 = s->S[{LAYOUT['t0']}];",
            "    if (fabs(t - (t0 + n * T)) > 0.5 * T) {",
            '        snprintf(msg, size, "do_step at t = %s s, but tick %.0f belongs to t = %s s (steps must be '
            "contiguous "
            'from initialize)", mast_repr(t, a, sizeof a), n, mast_repr(t0 + n * T, c, sizeof c));',
            "        return MAST_MODEL_ERROR;",
            "    }",
            "    int code;",
            "    if (s->evaluated != n && (code = evaluate(s, values, p, msg, size))) return code;",
            "    double R[3], CUR[3], QM[3], JK[12];",
            "    if ((code = steps(values, s->S, R, CUR, QM, JK, n, m)))",
            "        return tick_error(s, values, code, msg, size);",
            f"    s->S[{LAYOUT['n']}] = n + m;",
            "    return MAST_OK;",
            "}",
            "",
        ]
    )


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


def _inverse_model(eng, vrs: Mapping[str, int]) -> str:
    """FeedForwardController's inverse model (InverseModel.currents) in C: the engine's direct
    kinematics (``mechanism.model.restarted_dk``, translated, as InverseModel.torques runs it) and traced
    dynamics (``eng``, the traced engine of the controller's parameters: ``ikjac_p`` and ``forces`` with them read at
    initialisation; no forces when ``attached`` = 0), then ``motor_torque`` and ``guide_friction`` translated from their
    own source, with the actuator's constants computed at initialisation (``model_constants``, into
    S[model]). ``currents`` is what the tick calls; ``model_error`` makes the message of a failed
    evaluation by running it again (the guess is only updated on success, so it fails the same way)."""
    import inspect

    from fmus.actuator.model import guide_friction
    from fmus.controller.inverse_model import CONSTANTS, motor_torque
    from fmus.controller.reference import rates
    from fmus.mechanism.model import SINGULAR, restarted_dk

    MC = LAYOUT["model"]
    torque = ", ".join(f"S[{MC + k}]" for k in range(CONSTANTS.index("k_T")))
    W, G, A, PO = LAYOUT["warm"], LAYOUT["guess"], LAYOUT["model_args"], LAYOUT["P"]
    params = ", ".join(f"S[{PO + k}]" for k in range(len(eng.parameters)))
    dk = _dk_call(eng, f"S + {PO}", "M_COORDINATES", "LENGTHS(S)", "out", "out + 3", "s->text, sizeof s->text")
    coordinates = ", ".join(_literal(n) for n in eng.description.coordinates)
    checks = {k: v for k, v in eng._fn("forces").namespace.items() if k.startswith("_check")}
    return "\n".join(
        [
            _model_constants_c(vrs),
            to_c(eng._fn("forces").source, "forces", checks=checks),
            to_c(inspect.getsource(rates), "rates"),
            to_c(inspect.getsource(guide_friction), "guide_friction"),
            to_c(inspect.getsource(motor_torque), "motor_torque", values=("guide_friction",)),
            f"static const char *const M_COORDINATES[] = {{{coordinates}}};",
            "",
            "/* mechanism.model.dk for the inverse model: one attempt from its last solution (warm), else from the",
            "   description's guess; S: the instance's state (State's first member), out: q, then J = dq/drho */",
            "static int dk(double *rho, double warm, double *S, double *out)",
            "{",
            "    State *s = (State *)S;",
            f"    if (warm == 1.0) {{ for (int k = 0; k < 3; k++) out[k] = S[{G} + k]; }} else guess(S, rho, out);",
            f"    return {dk};",
            "}",
            "",
            to_c(
                inspect.getsource(restarted_dk),
                "restarted_dk",
                arrays=("rho", "S", "out"),
                calls=("dk",),
                constants={"SINGULAR": SINGULAR},
            ),
            "/* InverseModel.currents at a = (rho, rho_dot, rho_ddot); 0, or an error code with msg */",
            "static int model_eval(const double *a, double *S, double *out, char *msg, size_t size)",
            "{",
            "    double qJ[12], *q = qJ, *J = qJ + 3, F[12] = {0.0, 0.0, 0.0};",
            f"    if (S[{LAYOUT['attached']}] != 0.0) {{",
            f"        int code = restarted_dk((double *)a, S[{W}], S, qJ);   /* rho: a[0..2] */",
            "        if (code) {",
            '            snprintf(msg, size, "%s", ((State *)S)->text);',
            "            return code;",
            "        }",
            "        code = forces(q[0], q[1], q[2], J[0], J[1], J[2], J[3], J[4], J[5], J[6], J[7], J[8], "
            f"a[3], a[4], a[5], a[6], a[7], a[8], {params}, F);",
            "        if (code) {",
            '            snprintf(msg, size, "%s", why(-code));',
            "            return MAST_KINEMATICS_ERROR;",
            "        }",
            f"        for (int k = 0; k < 3; k++) S[{G} + k] = q[k];",
            f"        S[{W}] = 1.0;",
            "    }",
            f"    for (int j = 0; j < 3; j++) out[j] = motor_torque(a[3 + j], a[6 + j], F[j], {torque}) / "
            f"S[{MC + CONSTANTS.index('k_T')}];",
            "    return 0;",
            "}",
            "",
            "static int currents(double r0, double r1, double r2, double v0, double v1, double v2, double a0, double "
            "a1, "
            "double a2, double *S, double *out)",
            "{",
            "    double a[9] = {r0, r1, r2, v0, v1, v2, a0, a1, a2};",
            "    char text[1024];",
            "    return model_eval(a, S, out, text, sizeof text);",
            "}",
            "",
            "static int model_error(double *S, char *msg, size_t size)",
            "{",
            "    double out[3], a[9];",
            "    char text[1024], r0[40], r1[40], r2[40];",
            f"    for (int k = 0; k < 9; k++) a[k] = S[{A} + k];",
            "    model_eval(a, S, out, text, sizeof text);",
            '    snprintf(msg, size, "inverse dynamic model at rho = (%s, %s, %s) m: %s", mast_repr(a[0], r0, sizeof '
            "r0), "
            "mast_repr(a[1], r1, sizeof r1), mast_repr(a[2], r2, sizeof r2), text);",
            "    return MAST_KINEMATICS_ERROR;",
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
    kind = native_kind(block_class)
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
        more, state, functions = '#include "mast_mechanism.h"\n', "mast_mechanism_state", "mast_mechanism_"
    elif kind == "controller":
        body = _joint_controller(block, vrs)
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
            _check_function(block_class.PARAMETERS, vrs, extra, kind in ("mechanism", "controller")),
            "\n",
            body,
            "\n",
            _model_struct(identifier, guid, variables, n_inputs, n_io, bool(block_class.FEEDTHROUGH), state, functions),
        ]
    )
    return files


def emit_mechanism(identifier: str, guid: str, eng) -> dict[str, str]:
    """The generated C files of a native mechanism FMU for the engine ``eng`` of a description traced with its
    numbers as constants (no parameters; ``mechanism_variables`` its variables): ``<identifier>_model.c`` and
    ``config.h`` (``mechanism_model``, with the description's constant cold start, ``mechanism_guess``)."""
    if eng.parameters:
        raise ValueError(
            f"{identifier}: {eng.description.name} is traced with parameters {eng.parameters}: a "
            "mechanism with parameters is generated from its block (emit_model)"
        )
    variables = mechanism_variables(eng.n)
    inputs = [v.name for v in variables if v.causality == "input"]
    model, config = mechanism_model(eng, [], [-1] * eng.n, -1, mechanism_guess(eng), inputs)
    return {
        "config.h": config,
        f"{identifier}_model.c": "".join(
            [
                _HEAD.format(what=f"description {eng.description.name}", more='#include "mast_mechanism.h"\n'),
                _variable_table(variables),
                "\n",
                _check_function((), {}),
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
