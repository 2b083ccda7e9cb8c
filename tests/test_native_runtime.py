"""The native runtime (fmus/common/native) for any number of drives: its matrix helpers against numpy, and a
native mechanism generated and compiled for a scratch six-drive description (a 6-UPS hexapod written here in the
engine's description format) against the Python engine of the same description."""

from __future__ import annotations

import ctypes
import math
import subprocess

import numpy as np
import pytest

from fmus.common import tracer as E
from fmus.mechanism.engine import Body, Description, Engine, Evaluation
from fmus.mechanism.kinematics import KinematicsError
from mast.core.native.build import SUPPORT, SUPPORT_FILES
from mast.core.native.compiler import CFLAGS, compile_shared, compiler
from mast.core.native.models import RUNTIME, emit_mechanism


# ---------------------------------------------------------------------------- matrix helpers
@pytest.fixture(scope="module")
def linalg(tmp_path_factory) -> ctypes.CDLL:
    """mast_linalg.c compiled as the native build compiles it."""
    library = tmp_path_factory.mktemp("linalg") / "linalg.so"
    flags = [f for f in CFLAGS if f.startswith(("-O", "-ffp", "-std", "-D"))]
    subprocess.run(
        [
            compiler(),
            *flags,
            "-shared",
            "-fPIC",
            f"-I{SUPPORT}",
            "-o",
            str(library),
            str(SUPPORT / "mast_linalg.c"),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    return ctypes.CDLL(str(library))


def _pointer(a: np.ndarray):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_the_inverse_and_the_singular_values_for_any_n_agree_with_numpy(linalg, n):
    """mast_inv (cofactors for n = 3, else Gauss-Jordan as engine._inv) and mast_sv_extremes (one-sided Jacobi)
    against LAPACK through numpy, the independent route, on random matrices with columns of other scales."""
    rng = np.random.default_rng(n)
    for _ in range(20):
        m = rng.normal(size=(n, n)) * 10.0 ** rng.uniform(-1, 1, size=n)  # columns of other scales
        inv, det = np.zeros((n, n)), ctypes.c_double()
        assert linalg.mast_inv(n, _pointer(np.ascontiguousarray(m)), _pointer(inv), ctypes.byref(det)) == 1
        np.testing.assert_allclose(inv @ m, np.eye(n), atol=1e-10 * np.linalg.cond(m))
        assert det.value == pytest.approx(np.linalg.det(m), rel=1e-9)
        lo, hi = ctypes.c_double(), ctypes.c_double()
        linalg.mast_sv_extremes(n, _pointer(np.ascontiguousarray(m)), ctypes.byref(lo), ctypes.byref(hi))
        sv = np.linalg.svd(m, compute_uv=False)
        assert (lo.value, hi.value) == pytest.approx((sv[-1], sv[0]), rel=1e-10)
    singular = np.ones((n, n))
    singular[:, 0] = 0.0
    assert linalg.mast_inv(n, _pointer(singular), _pointer(np.zeros((n, n))), ctypes.byref(ctypes.c_double())) == 0


# ---------------------------------------------------------------------------- a six-drive mechanism
def _rzyx(psi, theta, phi):
    cx, sx, cy, sy, cz, sz = (E.cos(psi), E.sin(psi), E.cos(theta), E.sin(theta), E.cos(phi), E.sin(phi))
    return (
        (cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx),
        (sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx),
        (-sy, cy * sx, cy * cx),
    )


def _ring(radius: float, angles_deg) -> list[tuple[float, float, float]]:
    return [(radius * math.cos(math.radians(a)), radius * math.sin(math.radians(a)), 0.0) for a in angles_deg]


#: a Gough-Stewart platform (assumed dimensions, a scratch description): base joints in pairs 20 deg apart on
#: a 0.5 m circle, platform joints in pairs on a 0.3 m circle turned by 60 deg, each leg from a base joint to the
#: nearer platform joint of the neighbouring pair; the driven joints are the six leg lengths [m]
BASE = _ring(0.5, [a + s for a in (0.0, 120.0, 240.0) for s in (-10.0, 10.0)])
PLATFORM = _ring(0.3, [a + s for a in (0.0, 120.0, 240.0) for s in (-50.0, 50.0)])
HOME = (0.0, 0.0, 0.8, 0.0, 0.0, 0.0)


class Hexapod(Description):
    name = "6-UPS scratch"
    coordinates = ("x", "y", "z", "psi", "theta", "phi")
    joints = tuple(f"rho_{k}" for k in range(1, 7))
    bodies = (
        Body("platform", 20.0, (0.01, -0.02, 0.03), ((0.3, 0.01, -0.02), (0.01, 0.35, 0.015), (-0.02, 0.015, 0.5))),
    )
    lengths = (1.0, 1.0, 1.0, 0.3, 0.3, 0.3)  # the platform's radius turns its angles into metres

    def evaluate(self, q):
        x, y, z, psi, theta, phi = q
        R = _rzyx(psi, theta, phi)
        rho = []
        for b, p in zip(BASE, PLATFORM):
            leg = [(x, y, z)[i] + R[i][0] * p[0] + R[i][1] * p[1] + R[i][2] * p[2] - b[i] for i in range(3)]
            rho.append(E.sqrt(leg[0] * leg[0] + leg[1] * leg[1] + leg[2] * leg[2]))
        return Evaluation(rho, list(q), [((x, y, z), R)])

    def guess(self, rho):
        return HOME


class MastParameters(ctypes.Structure):
    _fields_ = [
        ("real", ctypes.POINTER(ctypes.c_double)),
        ("integer", ctypes.POINTER(ctypes.c_int)),
        ("string", ctypes.POINTER(ctypes.c_char_p)),
    ]


_STEP = ctypes.CFUNCTYPE(
    ctypes.c_int,
    ctypes.c_void_p,
    ctypes.POINTER(ctypes.c_double),
    ctypes.POINTER(MastParameters),
    ctypes.c_double,
    ctypes.c_double,
    ctypes.c_char_p,
    ctypes.c_size_t,
)
_INIT = ctypes.CFUNCTYPE(
    ctypes.c_int,
    ctypes.c_void_p,
    ctypes.POINTER(ctypes.c_double),
    ctypes.POINTER(MastParameters),
    ctypes.c_double,
    ctypes.c_char_p,
    ctypes.c_size_t,
)


class MastModel(ctypes.Structure):
    """mast_model.h's mast_model"""

    _fields_ = [
        ("identifier", ctypes.c_char_p),
        ("guid", ctypes.c_char_p),
        ("n_variables", ctypes.c_int),
        ("variables", ctypes.c_void_p),
        ("n_inputs", ctypes.c_int),
        ("n_io", ctypes.c_int),
        ("state_size", ctypes.c_size_t),
        ("check", ctypes.c_void_p),
        ("initialize", _INIT),
        ("do_step", _STEP),
        ("evaluate", ctypes.c_void_p),
    ]


def test_a_six_drive_mechanism_is_generated_compiled_and_computes_the_python_engines_forces(tmp_path):
    """The native mechanism of a 6-UPS (n = 6 from the engine; nothing in the runtime is sized for three): the
    direct kinematics warm-started along a motion and the forces, against the Python engine of the same
    description (Engine.dk from the last solution, Engine.forces); a pose out of reach refused with the
    engine's message for six joints."""
    eng = Engine(Hexapod())
    assert eng.n == 6
    generated = emit_mechanism("Hexapod", "{hexapod}", eng)
    assert "#define MECH_N 6" in generated["config.h"]
    runtime = (*SUPPORT_FILES, *RUNTIME["mechanism"])
    sources = {name: (SUPPORT / name).read_bytes() for name in runtime}
    sources.update({name: text.encode() for name, text in generated.items()})
    library = tmp_path / "Hexapod.so"
    compile_shared(sources, library)
    model = MastModel.in_dll(ctypes.CDLL(str(library)), "MAST_MODEL")
    assert (model.n_inputs, model.n_io) == (7 * 6, 7 * 6 + 6 + 6 + 2 * 6)  # mechanism.model.Variables
    state = ctypes.create_string_buffer(model.state_size)
    values = (ctypes.c_double * model.n_io)()  # the drives' forces and masses 0: no condensation, F alone
    params = MastParameters()
    msg = ctypes.create_string_buffer(2048)
    rng = np.random.default_rng(6)
    amplitude = np.array([0.02, 0.02, 0.03, 0.05, 0.05, 0.08])
    q_path = [np.array(HOME) + amplitude * math.sin(0.3 * k) for k in range(40)]
    q_prev, worst = None, 0.0
    for k, q_pose in enumerate(q_path):
        rho = eng.ik(q_pose)
        rd, rdd = rng.uniform(-0.1, 0.1, 6), rng.uniform(-1.0, 1.0, 6)
        values[:18] = [*rho, *rd, *rdd]
        code = (
            model.initialize(state, values, ctypes.byref(params), 0.0, msg, len(msg))
            if k == 0
            else model.do_step(state, values, ctypes.byref(params), 1e-3 * (k - 1), 1e-3, msg, len(msg))
        )
        assert code == 0, msg.value.decode()
        q, J, _ = eng.dk(rho, q_prev)
        expected = np.array(eng.forces(q, J, rd, rdd))
        got = np.array(values[42:54])  # F and the pose, after the 42 inputs
        np.testing.assert_allclose(got[6:], q_pose, atol=1e-11)  # the pose: the motion's own
        worst = max(worst, float(np.abs(got - expected).max() / np.abs(expected[:6]).max()))
        q_prev = q
    assert worst <= 1e-12, worst
    # out of reach: every leg 0.3 m; the engine's refusal, with the six joints in the message
    values[:6] = [0.3] * 6
    code = model.do_step(state, values, ctypes.byref(params), 1.0, 1e-3, msg, len(msg))
    with pytest.raises(KinematicsError) as python:
        eng.dk([0.3] * 6, HOME)
    refusal = "direct kinematics did not converge for rho = (0.3, 0.3, 0.3, 0.3, 0.3, 0.3) m: 50 iterations"
    assert code == 3 and str(python.value).startswith(refusal)
    assert msg.value.decode().startswith("at t = 1.001 s, rho = (0.3, 0.3, 0.3, 0.3, 0.3, 0.3) m: " + refusal)
