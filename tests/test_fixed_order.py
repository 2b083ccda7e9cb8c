"""Small linear algebra in a fixed order (fmus/common/fixed_order.py): right against scipy/LAPACK (the
independent route), the same floats as the native FMUs' C, and no BLAS left in a co-simulation's arithmetic
(a run under another OpenBLAS kernel is bit-identical), issue 24."""

from __future__ import annotations

import ctypes
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import load_params
from scipy.linalg import expm as scipy_expm
from scipy.linalg import matrix_balance

from fmus.actuator.model import ActuatorBlock, chain_frequencies, fastest_mode
from fmus.common.fixed_order import eig_max, expm, matmul
from mast.core.native.compiler import compiler

ROOT = Path(__file__).resolve().parents[1]


def _generators(count: int = 24) -> list[np.ndarray]:
    """The actuator's augmented matrices [[A B], [0 0]] (with and without backlash, n_dof 1 to 3) for parameter
    sets spread over a decade either side of the identified ones, times steps from 10 us to 10 ms."""
    rng = np.random.default_rng(11)
    base = load_params("actuator_identified")
    out = []
    for k in range(count):
        params = {
            **base,
            **{
                name: base[name] * 10.0 ** rng.uniform(-1.0, 1.0)
                for name in ("R", "L", "k_T", "J_motor", "J_guide", "K_t", "C_t", "b_v")
            },
        }
        if k % 3 == 1:
            params["backlash"] = 1e-3
        if k % 3 == 2:
            params = {
                **params,
                "n_dof": 3,
                "J_chain": "1.2e-4 1e-4 1.1e-4",
                "K_chain": "3000 2500",
                "C_chain": "0.01 0.02",
            }
        block = ActuatorBlock(params)
        for M in block._generators():
            for h in (1e-5, 1e-4, 1e-3, 1e-2):
                out.append(M * min(h, 40.0 / max(block._omega_max, 1.0)))
    return out


def test_the_exponential_agrees_with_scipys_pade_route():
    """Normwise in LAPACK's balanced coordinates (the matrices mix A, rad and rad/s), to 1e-11: the same bound as
    the native mast_expm's against scipy (tests/test_native.py)."""
    worst = 0.0
    for X in _generators():
        E, reference = expm(X), scipy_expm(X)
        d = matrix_balance(X, permute=False, separate=True)[1][0]
        scaled = d[None, :] / d[:, None]
        worst = max(
            worst,
            float(np.abs((E - reference) * scaled).sum(axis=0).max() / np.abs(reference * scaled).sum(axis=0).max()),
        )
    assert worst < 1e-11, worst
    assert np.isnan(expm(np.array([[np.inf, 0.0], [0.0, 1.0]]))).all()


def test_the_product_and_the_largest_eigenvalue_agree_with_numpy_and_lapack():
    rng = np.random.default_rng(3)
    A, B = rng.normal(size=(5, 7)), rng.normal(size=(7, 4))
    assert matmul(A, B) == pytest.approx(A @ B, rel=1e-13, abs=1e-13)
    for n in (2, 3, 5, 8):
        G = rng.normal(size=(n, n))
        S = G + G.T
        assert eig_max(S.tolist()) == pytest.approx(np.linalg.eigvalsh(S).max(), rel=1e-12, abs=1e-12)
    for J, K in (([1.2e-4, 2.1e-4], [1500.0]), ([1.2e-4, 1e-4, 1.1e-4], [3000.0, 2500.0]), ([3e-4], [])):
        expected = 2.0 * np.pi * chain_frequencies(J, K).max(initial=0.0)
        assert fastest_mode(J, K) == pytest.approx(expected, rel=1e-12)


@pytest.fixture(scope="module")
def c_routines(tmp_path_factory) -> ctypes.CDLL:
    """mast_expm and mast_eig_max (mast_linalg.c) compiled as the native build compiles them."""
    from mast.core.native.compiler import CFLAGS

    tmp = tmp_path_factory.mktemp("fixed_order_c")
    source = tmp / "routines.c"
    source.write_text(
        '#include "mast_native.h"\n'
        "int expm_c(int n, const double *M, double *E) { return mast_expm(n, M, E); }\n"
        "double eig_max_c(int n, double *S) { return mast_eig_max(n, S); }\n"
    )
    library = tmp / "routines.so"
    flags = [f for f in CFLAGS if f.startswith(("-O", "-ffp", "-f", "-std", "-D"))]
    support = ROOT / "fmus" / "common" / "native"
    subprocess.run(
        [
            compiler(),
            *flags,
            "-shared",
            f"-I{support}",
            "-o",
            str(library),
            str(source),
            str(support / "mast_linalg.c"),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    lib = ctypes.CDLL(str(library))
    lib.eig_max_c.restype = ctypes.c_double
    return lib


def test_the_python_and_the_native_routines_compute_the_same_floats(c_routines):
    """Bit for bit: fixed_order.expm against mast_expm on the actuator's matrices, fastest_mode's eigenvalue
    against mast_eig_max: the Python and the native actuator discretise with the same digits."""
    pointer = ctypes.POINTER(ctypes.c_double)
    for X in _generators():
        X = np.ascontiguousarray(X)
        E = np.zeros_like(X)
        assert c_routines.expm_c(len(X), X.ctypes.data_as(pointer), E.ctypes.data_as(pointer)) == 0
        assert np.array_equal(expm(X), E)
    rng = np.random.default_rng(5)
    for n in (2, 3, 4, 8):
        G = rng.normal(size=(n, n))
        S = np.ascontiguousarray(G + G.T)
        expected = eig_max(S.tolist())
        assert c_routines.eig_max_c(n, S.ctypes.data_as(pointer)) == expected


_RUN = """
import json, sys
from mast.core.motion import SineMotion
from mast.core.run import simulate
result = simulate(sys.argv[1], SineMotion("z", amplitude=0.01, frequency=4.0), stop_time=0.3, direct=True,
                  parameters={"actuator_1": {"backlash": 0.004}, "actuator_2": {"backlash": 0.004},
                              "actuator_3": {"backlash": 0.004}})
print(json.dumps({k: [float(x).hex() for x in v] for k, v in result.signals.items()}))
"""


@pytest.mark.regime
@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="OpenBLAS kernels named for x86-64")
def test_a_run_with_backlash_is_bit_identical_under_another_blas_kernel(tmp_path):
    """The direct composition of the default system, hunting with backlash (the chaotic case: any difference in
    the last bits grows), in two processes whose OpenBLAS uses different kernels (this process's environment,
    and Prescott: SSE3 only, every x86-64 has it; or unset when this one is Prescott): the same floats."""
    from mast.core.build import FMUS, build_fmu, build_ssp
    from mast.core.ssp import read_ssd

    source = ROOT / "ssp" / "MAST.ssd"
    needed = {Path(c.source).stem for c in read_ssd(source).components.values()}
    for spec in FMUS:
        if spec.model_identifier in needed:
            build_fmu(spec, tmp_path / "fmus")
    ssp = build_ssp(source, tmp_path / "fmus", tmp_path / "ssp")
    other = "Prescott" if os.environ.get("OPENBLAS_CORETYPE", "") != "Prescott" else ""
    runs = []
    for kernel in (os.environ.get("OPENBLAS_CORETYPE"), other):
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
        if kernel:
            env["OPENBLAS_CORETYPE"] = kernel
        done = subprocess.run(
            [sys.executable, "-c", _RUN, str(ssp)], env=env, capture_output=True, text=True, check=True
        )
        runs.append(json.loads(done.stdout))
    assert runs[0].keys() == runs[1].keys()
    differing = [k for k in runs[0] if runs[0][k] != runs[1][k]]
    assert not differing, differing
