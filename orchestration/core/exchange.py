"""The master's exchange loop in C: the same schedule as ``Master.run``'s Python loop, call for call.

Between two recorded ticks the Python loop only moves numbers between FMUs: gather each due
component's inputs, fmi2SetReal, (a feedthrough component: fmi2GetReal of its outputs), fmi2DoStep,
fmi2GetReal, publish. Here that runs in C over the FMUs' own function pointers, one ctypes call per
recording interval instead of three per component and tick: the same calls in the same order with
the same arguments, so the results are bit-identical (tests/test_native.py). The master uses it when
every component is an FMU (``FMUComponent``) and a C compiler is there (``mast.core.native.compiler.compiler``);
otherwise, and with ``MAST_PYTHON_EXCHANGE=1``, the Python loop. The library is compiled once per
machine into ``cache_dir()`` (a fraction of a second).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import subprocess
import tempfile
from pathlib import Path
from typing import Optional, Sequence

SOURCE = r"""
#include <stddef.h>
#include <string.h>

typedef int (*set_fn)(void *, const unsigned int *, size_t, const double *);
typedef int (*get_fn)(void *, const unsigned int *, size_t, double *);
typedef int (*step_fn)(void *, double, double, int);

typedef struct {
    void *comp;
    set_fn set;
    get_fn get;
    step_fn step;
    long multiple;               /* steps every multiple-th base tick */
    double h;                    /* its step size */
    int feedthrough;             /* outputs follow the inputs: read them right after setting */
    int n_in;
    const unsigned int *vr_in;
    const int *src;              /* where each input comes from in flat */
    double *in_buf;
    int n_out;
    const unsigned int *vr_out;
    int offset;                  /* its outputs in flat */
    double *pending;             /* its outputs after its last step, published at its next communication point */
    long phase;                  /* n % multiple at the current tick: counted, not divided, at every tick */
} mast_unit;

/* Ticks n0 .. n1-1 of the master's loop (set in order, step, read), each followed by the publication of
   tick n+1 (pending outputs of the units due then, the system inputs' row stim[n+1-n0]).
   0: done; else the failed call: *at its tick, *which the unit, *call 0 setReal, 1 getReal, 2 doStep. */
int mast_ticks(mast_unit *units, int n_units, double *flat, int n_out, const double *stim, int n_stim,
               long n0, long n1, double t0, double h, long *at, int *which, int *call)
{
    for (int k = 0; k < n_units; k++) units[k].phase = n0 % units[k].multiple;
    for (long n = n0; n < n1; n++) {
        double t = t0 + (double)n * h;
        for (int k = 0; k < n_units; k++) {
            mast_unit *u = units + k;
            if (u->phase) continue;
            for (int i = 0; i < u->n_in; i++) u->in_buf[i] = flat[u->src[i]];
            if (u->set(u->comp, u->vr_in, (size_t)u->n_in, u->in_buf) > 1) { *at = n; *which = k; *call = 0; return 1; }
            if (u->feedthrough && u->get(u->comp, u->vr_out, (size_t)u->n_out, flat + u->offset) > 1) {
                *at = n; *which = k; *call = 1; return 1;
            }
        }
        for (int k = 0; k < n_units; k++) {
            mast_unit *u = units + k;
            if (u->phase) continue;
            if (u->step(u->comp, t, u->h, 1) > 1) { *at = n; *which = k; *call = 2; return 1; }
            if (u->get(u->comp, u->vr_out, (size_t)u->n_out, u->pending) > 1) {
                *at = n; *which = k; *call = 1; return 1;
            }
        }
        long m = n + 1;
        for (int k = 0; k < n_units; k++) {          /* phase of tick m; due then: publish its last step */
            mast_unit *u = units + k;
            if (++u->phase == u->multiple) u->phase = 0;
            if (u->phase == 0) memcpy(flat + u->offset, u->pending, sizeof(double) * (size_t)u->n_out);
        }
        memcpy(flat + n_out, stim + (size_t)(m - n0) * (size_t)n_stim, sizeof(double) * (size_t)n_stim);
    }
    return 0;
}
"""

CALLS = ("setReal", "getReal", "doStep")


class _Unit(ctypes.Structure):
    _fields_ = [
        ("comp", ctypes.c_void_p),
        ("set", ctypes.c_void_p),
        ("get", ctypes.c_void_p),
        ("step", ctypes.c_void_p),
        ("multiple", ctypes.c_long),
        ("h", ctypes.c_double),
        ("feedthrough", ctypes.c_int),
        ("n_in", ctypes.c_int),
        ("vr_in", ctypes.c_void_p),
        ("src", ctypes.c_void_p),
        ("in_buf", ctypes.c_void_p),
        ("n_out", ctypes.c_int),
        ("vr_out", ctypes.c_void_p),
        ("offset", ctypes.c_int),
        ("pending", ctypes.c_void_p),
        ("phase", ctypes.c_long),
    ]


def cache_dir() -> Path:
    """$MAST_EXCHANGE_CACHE, else ~/.cache/mast/exchange (XDG_CACHE_HOME honoured)."""
    if os.environ.get("MAST_EXCHANGE_CACHE"):
        return Path(os.environ["MAST_EXCHANGE_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "mast" / "exchange"


_LIBRARY: list = []


def library() -> Optional[ctypes.CDLL]:
    """The compiled loop (compiled at the first call of this process if the cache lacks it); None without a
    C compiler, when it does not compile, or with MAST_PYTHON_EXCHANGE=1."""
    if os.environ.get("MAST_PYTHON_EXCHANGE") == "1":
        return None
    if _LIBRARY:
        return _LIBRARY[0]
    from .native.compiler import NativeBuildError, compiler

    target = cache_dir() / f"exchange_{hashlib.sha256(SOURCE.encode()).hexdigest()[:16]}.so"
    lib = None
    try:
        if not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(prefix="mast_exchange_") as tmp:
                source, built = Path(tmp) / "exchange.c", Path(tmp) / "exchange.so"
                source.write_text(SOURCE)
                done = subprocess.run(
                    [compiler(), "-O2", "-shared", "-fPIC", "-o", str(built), str(source)],
                    capture_output=True,
                    text=True,
                )
                if done.returncode == 0:
                    os.replace(built, target)  # atomic: a concurrent process sees the whole library or none
        if target.exists():
            lib = ctypes.CDLL(str(target))
            lib.mast_ticks.restype = ctypes.c_int
            lib.mast_ticks.argtypes = [
                ctypes.c_void_p,
                ctypes.c_int,
                ctypes.c_void_p,
                ctypes.c_int,
                ctypes.c_void_p,
                ctypes.c_int,
                ctypes.c_long,
                ctypes.c_long,
                ctypes.c_double,
                ctypes.c_double,
                ctypes.POINTER(ctypes.c_long),
                ctypes.POINTER(ctypes.c_int),
                ctypes.POINTER(ctypes.c_int),
            ]
    except (OSError, NativeBuildError):
        lib = None
    _LIBRARY.append(lib)
    return lib


class CompiledLoop:
    """The due components' exchange between two recorded ticks, in C (module docstring).

    ``units``: per component, in exchange order, (functions, multiple, step, feedthrough, input value
    references, input positions in the flat vector, output value references, output offset); ``flat``:
    the master's flat vector (outputs, then the system inputs), which this object now holds in C memory.
    ``hold_gil``: the loop keeps the GIL (a pythonfmu FMU among the units: each of its calls takes the GIL
    to run Python, an uncontended re-entry instead of a take and release per call); else it releases it."""

    def __init__(
        self, lib: ctypes.CDLL, units: Sequence[tuple], flat: Sequence[float], n_out: int, hold_gil: bool = False
    ) -> None:
        self._ticks = lib.mast_ticks
        if hold_gil:
            fn = lib.mast_ticks
            self._ticks = ctypes.PYFUNCTYPE(fn.restype, *fn.argtypes)(ctypes.cast(fn, ctypes.c_void_p).value)
        self.n_out, self.n_stim = n_out, len(flat) - n_out
        #: what a host that follows this schedule needs (hosts/c_host.py): per unit (multiple, step, feedthrough,
        #: input value references, input positions in the flat vector, output value references, output offset)
        self.units = [tuple(u[1:]) for u in units]
        self.flat = (ctypes.c_double * len(flat))(*flat)
        self._keep = []  # the arrays the C structures point into

        def array(kind, values):
            arr = (kind * max(1, len(values)))(*values)
            self._keep.append(arr)
            return ctypes.addressof(arr)

        self._units = (_Unit * len(units))()
        self.pending = []
        for u, (functions, multiple, step, feedthrough, vr_in, src, vr_out, offset) in zip(self._units, units):
            comp, set_real, get_real, do_step = functions
            pending = (ctypes.c_double * max(1, len(vr_out)))(*flat[offset : offset + len(vr_out)])
            self.pending.append(pending)
            u.comp, u.set, u.get, u.step = comp, set_real, get_real, do_step
            u.multiple, u.h, u.feedthrough = multiple, step, int(feedthrough)
            u.n_in, u.vr_in, u.src = len(vr_in), array(ctypes.c_uint, vr_in), array(ctypes.c_int, src)
            u.in_buf = array(ctypes.c_double, [0.0] * len(vr_in))
            u.n_out, u.vr_out, u.offset = len(vr_out), array(ctypes.c_uint, vr_out), offset
            u.pending = ctypes.addressof(pending)
        self._stim = (ctypes.c_double * 0)()
        self._at, self._which, self._call = ctypes.c_long(), ctypes.c_int(), ctypes.c_int()

    def run(self, n0: int, n1: int, t0: float, h: float, stimulus) -> Optional[tuple[int, int, str]]:
        """Ticks n0 .. n1-1, then the publication of tick n1; the system inputs of ticks n0+1 .. n1 from
        ``stimulus(t)``. None, or the failed call: (tick, unit index, FMI call name)."""
        rows = n1 - n0 + 1
        size = rows * self.n_stim
        if len(self._stim) < size:
            self._stim = (ctypes.c_double * size)()
        if self.n_stim:
            stim = []
            for n in range(n0, n1 + 1):
                stim.extend(stimulus(t0 + n * h) if n > n0 else self.flat[self.n_out :])
            self._stim[:size] = stim
        code = self._ticks(
            self._units,
            len(self._units),
            self.flat,
            self.n_out,
            self._stim,
            self.n_stim,
            n0,
            n1,
            t0,
            h,
            ctypes.byref(self._at),
            ctypes.byref(self._which),
            ctypes.byref(self._call),
        )
        return None if code == 0 else (self._at.value, self._which.value, CALLS[self._call.value])
