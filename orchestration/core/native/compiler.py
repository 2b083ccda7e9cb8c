"""The C toolchain of the native FMUs: which compiler builds for which platform, and the compile step itself.

Apart from ``build`` so that ``mast.core.build`` (the Python FMUs' C front) compiles with it without importing
what builds native FMUs from the models."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Mapping

CFLAGS = (
    "-O2",
    "-ffp-contract=off",
    "-fPIC",
    "-shared",
    "-std=c99",
    "-D_POSIX_C_SOURCE=200809L",
    "-Wall",
    "-Wno-unused-variable",
    "-Wno-unused-function",
    "-Wno-maybe-uninitialized",
    "-Wno-format-truncation",
)


class NativeBuildError(RuntimeError):
    """A native FMU cannot be built here (no C compiler, a compiler error, a model without a native form)."""


def compiler() -> str:
    """The C compiler: ``$CC``, else ``cc`` or ``gcc`` on PATH (NativeBuildError naming what was looked for)."""
    for name in ([os.environ["CC"]] if os.environ.get("CC") else []) + ["cc", "gcc"]:
        found = shutil.which(name.split()[0])
        if found:
            return found
    raise NativeBuildError(
        "mast build --native needs a C compiler: none of $CC, cc, gcc is on PATH (install gcc or clang, or set CC)"
    )


def fmi_headers() -> Path:
    """The FMI 2.0 headers (fmi2Functions.h ...): fmpy, a dependency of this project, ships them."""
    import fmpy

    folder = Path(fmpy.__file__).parent / "c-code"
    if not (folder / "fmi2Functions.h").exists():
        raise NativeBuildError(f"{folder}: the FMI 2.0 headers are missing from this fmpy installation")
    return folder


#: the oldest glibc the Linux binaries load on (zig links against that version's symbols: CentOS 7, RHEL 8 ...)
GLIBC_FLOOR = (2, 17)
#: binaries/ folder -> (zig target, library suffix); "aarch64-linux" is FMI 3.0's name, which fmpy also reads
#: for FMI 2.0 (FMI 2.0 names no ARM platform)
PLATFORMS = {
    "linux64": ("x86_64-linux-gnu.2.17", ".so"),
    "aarch64-linux": ("aarch64-linux-gnu.2.17", ".so"),
    "win64": ("x86_64-windows-gnu", ".dll"),
    "darwin64": ("x86_64-macos", ".dylib"),
}


def has_zig() -> bool:
    """Whether zig's C compiler is installed (PyPI package ziglang: ``pip install ziglang``)."""
    import importlib.util

    return importlib.util.find_spec("ziglang") is not None


def c_compiler(platform: str = "linux64") -> list[str]:
    """The compiler command for ``platform`` (a key of PLATFORMS): for linux64 ``$CC`` when set (the user's
    choice), else zig's C compiler for the platform's target (Linux binaries against glibc ``GLIBC_FLOOR``);
    without zig, for linux64 only, ``cc`` or ``gcc`` (``compiler()``). A binary of ``$CC``, ``cc`` or ``gcc``
    needs this machine's glibc or newer."""
    if platform == "linux64" and os.environ.get("CC"):
        return [compiler()]
    if has_zig():
        return [sys.executable, "-m", "ziglang", "cc", "-target", PLATFORMS[platform][0]]
    if platform == "linux64":
        return [compiler()]
    raise NativeBuildError(f"binaries for {platform} need a cross compiler: pip install ziglang")


def compile_shared(sources: Mapping[str, bytes], target: Path, platform: str = "linux64") -> None:
    """Compile the sources into the shared library ``target`` for ``platform`` (a key of PLATFORMS;
    NativeBuildError with the compiler's output)."""
    cc = c_compiler(platform)
    with tempfile.TemporaryDirectory(prefix="mast_native_") as tmp:
        tmp = Path(tmp)
        for name, data in sources.items():
            (tmp / name).write_bytes(data)
        c_files = sorted(str(tmp / n) for n in sources if n.endswith(".c"))
        cmd = [
            *cc,
            *CFLAGS,
            f"-I{fmi_headers()}",
            f"-I{tmp}",
            "-o",
            str(target),
            *c_files,
            *(["-lm"] if platform != "win64" else []),
            *(["-ldl"] if "linux" in platform else []),  # dladdr, dlopen (fmus/common/native/mast_guard.h)
        ]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode != 0:
            raise NativeBuildError(
                f"{target.name}: the C compiler failed ({' '.join(cmd[:2])} ...):\n{done.stderr.strip()[-4000:]}"
            )
