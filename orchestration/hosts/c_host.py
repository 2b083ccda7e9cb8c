"""A host in C for the native FMUs (``mast_host.c``), for Linux and, cross-compiled by zig, for Windows under Wine.

It checks that the FMUs' binaries behave on a platform as on this one: ``mast_host`` runs life cycles of every
FMU of a native SSP and then the system on the project's master's own exchange loop (``mast.core.exchange``'s
C, compiled into the host), with the parameters, the schedule and the initial inputs of a run of our master.
That run gives the reference trajectories; ``run_c_host`` returns the host's (tests/test_portability.py,
docs/native.md).

The plan file the host reads is written here (``write_plan``; its format: mast_host.c's header comment).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import struct
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from ..core.components import FMUComponent
from ..core.exchange import SOURCE as EXCHANGE_SOURCE
from ..core.master import Master
from ..core.motion import NoStimulus
from ..core.native.build import cache_dir
from ..core.native.compiler import PLATFORMS, NativeBuildError, c_compiler, compile_shared, fmi_headers
from ..core.ssp import SSPArchive, applicable_parameters, safe_extract

__all__ = ["HOST_SOURCE", "MasterRun", "master_run", "build_host", "wine", "launcher", "run_c_host", "HostRun"]

HOST_SOURCE = Path(__file__).with_name("mast_host.c")
#: the executable's suffix per platform (PLATFORMS' keys)
EXE = {"linux64": "", "aarch64-linux": "", "win64": ".exe"}
#: where Debian's libc6-arm64-cross puts the aarch64 C library qemu-user runs the aarch64 host with
ARM64_SYSROOT = Path("/usr/aarch64-linux-gnu")


@dataclass
class MasterRun:
    """A run of our master on a native SSP: what the C host needs to follow it, and its trajectories."""

    names: list[str]  # the components in exchange order
    folders: dict[str, Path]  # component -> its FMU unpacked (binaries/, sources/, resources/)
    identifiers: dict[str, str]  # component -> model identifier
    guids: dict[str, str]
    parameters: dict[str, list[tuple[str, int, object]]]  # component -> (type, value reference, value)
    units: list[tuple]  # exchange.CompiledLoop.units
    inputs: list[list[float]]  # per unit, the inputs the master set last in initialization mode
    t0: float
    h: float
    n_ticks: int
    record_every: int
    flat_names: list[str]  # the signal at each position of the flat vector's outputs
    outputs: dict[str, np.ndarray]  # our master's recorded trajectories, every published output


def master_run(ssp: Path, stop_time: float, folder: Path, record_step: float = 1e-3) -> MasterRun:
    """Run ``ssp`` (a native SSP without system inputs) on our master with its compiled exchange loop and keep
    what the C host needs, its FMUs unpacked into ``folder`` (the caller's). ValueError for an SSP with system
    inputs or when the master did not run the compiled loop."""
    with SSPArchive(ssp) as archive:
        system = archive.system
        if system.system_inputs:
            raise ValueError(
                f"{ssp}: the C host runs systems without inputs (this one has "
                f"{', '.join(system.system_inputs)}); e.g. MAST_standalone.ssp"
            )
        components, folders = {}, {}
        try:
            for name in system.components:
                fmu = system.fmu_path(name)
                folders[name] = safe_extract(fmu, folder / name, system.fmu_label(name))
                components[name] = _Initialized(name, fmu, folders[name])
            master = Master(system, components)
        except Exception:
            for comp in components.values():
                comp.close()
            raise
        order = list(system.components)
        bound = applicable_parameters(
            system, {n: components[n].parameter_names for n in order}, {n: components[n].parameter_units for n in order}
        )  # as Master binds them
        parameters = {
            n: [
                (components[n].variables[k].type, components[n].variables[k].valueReference, v)
                for k, v in bound[n].items()
            ]
            for n in order
        }
        identifiers = {n: components[n].md.coSimulation.modelIdentifier for n in order}
        guids = {n: components[n].md.guid for n in order}
        h = master.base_step
        record_every = round(record_step / h)
        n_ticks = round((stop_time - system.start_time) / h) // record_every * record_every
        published = list(
            dict.fromkeys(f"{c.start_element}.{c.start_connector}" for c in system.connections if c.start_element)
        )
        result = master.run(system.start_time + n_ticks * h, NoStimulus(), record=published, record_step=record_step)
        loop = master.exchange
        if loop is None:
            raise ValueError(
                "our master ran its Python exchange loop (no C compiler, or MAST_PYTHON_EXCHANGE=1): "
                "the C host follows the compiled one"
            )
        names = output_names(master.exchange_order, loop.units, components)
        outputs = {name: result[name] for name in published}
    inputs = [components[name].initial_inputs for name in master.exchange_order]
    return MasterRun(
        list(master.exchange_order),
        folders,
        identifiers,
        guids,
        parameters,
        loop.units,
        inputs,
        system.start_time,
        h,
        n_ticks,
        record_every,
        names,
        outputs,
    )


class _Initialized(FMUComponent):
    """An FMU component that keeps the inputs the master set last in initialization mode (``initial_inputs``)."""

    initial_inputs: list[float] = []
    _initializing = True

    def setter(self, names: Sequence[str]):
        set_values = super().setter(names)

        def kept(values: Sequence[float]) -> None:
            if self._initializing:
                self.initial_inputs = [float(v) for v in values]
            set_values(values)

        return kept

    def exit_initialization(self) -> None:
        self._initializing = False
        super().exit_initialization()


def output_names(order: Sequence[str], units: Sequence[tuple], components) -> list[str]:
    """The signal ("component.output") at each position of the flat vector's outputs."""
    names = []
    for name, unit in zip(order, units):
        variables = {v.valueReference: v.name for v in components[name].md.modelVariables if v.causality == "output"}
        names += [f"{name}.{variables[vr]}" for vr in unit[5]]
    return names


def build_host(platform: str, out_dir: Path) -> Path:
    """``mast_host`` for ``platform`` ("linux64", "win64") into ``out_dir``, compiled with the native FMUs' compiler
    (``c_compiler``: zig for win64) together with the master's exchange loop (NativeBuildError with its output)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"mast_host{EXE[platform]}"
    with tempfile.TemporaryDirectory(prefix="mast_c_host_") as tmp:
        (Path(tmp) / "mast_exchange.c").write_text(EXCHANGE_SOURCE)
        cmd = [
            *c_compiler(platform),
            "-O2",
            "-ffp-contract=off",
            "-std=c99",
            "-D_POSIX_C_SOURCE=200809L",
            f"-I{fmi_headers()}",
            f"-I{tmp}",
            "-o",
            str(target),
            str(HOST_SOURCE),
            *(["-ldl"] if platform != "win64" else []),
        ]
        done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise NativeBuildError(
            f"{HOST_SOURCE.name}: the C compiler failed ({' '.join(cmd[:4])} ...):\n{done.stderr.strip()[-4000:]}"
        )
    return target


def wine() -> Optional[str]:
    """The Wine launcher on PATH (Debian: ``wine``, ``wine-stable`` or ``wine64`` from the wine64 package), or
    None."""
    for name in ("wine", "wine-stable", "wine64", "/usr/lib/wine/wine64"):
        found = shutil.which(name)
        if found:
            return found
    return None


def launcher(platform: str) -> Optional[list[str]]:
    """The command that runs a ``platform`` program here: [] for linux64, Wine for win64 (``wine()``), qemu-user
    with Debian's aarch64 C library for aarch64-linux (packages qemu-user, libc6-arm64-cross); None when it is
    missing."""
    if platform == "linux64":
        return []
    if platform == "win64":
        found = wine()
        return None if found is None else [found]
    qemu = shutil.which("qemu-aarch64") or shutil.which("qemu-aarch64-static")
    if qemu is None or not (ARM64_SYSROOT / "lib").is_dir():
        return None
    return [qemu, "-L", str(ARM64_SYSROOT)]


def _library(folder: Path, identifier: str, platform: str, recompile: bool) -> Path:
    """The unpacked FMU's binary for ``platform``: its own unless ``recompile``, else compiled from its
    ``sources/`` by ``compile_shared`` (``c_compiler(platform)``), kept in the native FMUs' cache folder by the
    sources and the compiler command."""
    own = folder / "binaries" / platform / f"{identifier}{PLATFORMS[platform][1]}"
    if own.exists() and not recompile:
        return own
    sources = {p.name: p.read_bytes() for p in sorted((folder / "sources").glob("*"))}
    if not sources:
        raise NativeBuildError(f"{folder}: neither a {platform} binary nor sources to compile one")
    key = hashlib.sha256(" ".join(c_compiler(platform)[-3:]).encode())
    for name, data in sources.items():
        key.update(name.encode() + b"\0" + data)
    target = cache_dir() / "binaries" / key.hexdigest()[:16] / own.name
    if not target.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix="mast_c_host_", dir=target.parent) as tmp:
            compile_shared(sources, Path(tmp) / own.name, platform)
            os.replace(Path(tmp) / own.name, target)  # whole or absent for a concurrent process
    return target


def _host_path(path: Path, platform: str) -> str:
    """``path`` as the host program sees it: under Wine, drive Z: is the Unix root."""
    return "Z:" + str(path).replace("/", "\\") if platform == "win64" else str(path)


def _bits(value: float) -> str:
    return f"{struct.unpack('<Q', struct.pack('<d', float(value)))[0]:016x}"


def write_plan(run: MasterRun, platform: str, folder: Path, cycles: int, recompile: bool = False) -> Path:
    """The plan ``mast_host`` reads (format: mast_host.c) into ``folder``; the FMUs' ``platform`` binaries
    compiled from their sources where they have none, or with ``recompile`` (``_library``)."""
    lines = [
        "mast-host-plan 1",
        f"cycles {cycles}",
        f"run {_bits(run.t0)} {_bits(run.h)} {run.n_ticks} {run.record_every}",
        f"flat {len(run.flat_names)}",
        f"units {len(run.names)}",
    ]
    for name, unit, inputs in zip(run.names, run.units, run.inputs):
        multiple, step, feedthrough, vr_in, src, vr_out, offset = unit
        unpacked = run.folders[name]
        library = _library(unpacked, run.identifiers[name], platform, recompile)
        resources = (
            (unpacked / "resources").as_uri()
            if platform != "win64"
            else "file:///Z:" + (unpacked / "resources").as_posix()
        )
        typed = {
            kind: [(vr, v) for t, vr, v in run.parameters[name] if t == kind]
            for kind in ("Real", "Integer", "String", "Boolean")
        }
        if typed["Boolean"]:
            raise ValueError(f"{name}: Boolean parameters are not in the plan's format (mast_host.c)")
        lines += [
            f"unit {name}",
            f"library {_host_path(library, platform)}",
            f"guid {run.guids[name]}",
            f"resources {resources}",
            f"schedule {multiple} {_bits(step)} {int(feedthrough)}",
            f"reals {len(typed['Real'])} " + " ".join(f"{vr} {_bits(v)}" for vr, v in typed["Real"]),
            f"integers {len(typed['Integer'])} " + " ".join(f"{vr} {int(v)}" for vr, v in typed["Integer"]),
            f"strings {len(typed['String'])}",
            *(f"string {vr} {v}" for vr, v in typed["String"]),
            f"inputs {len(vr_in)} " + " ".join(map(str, [*vr_in, *src])),
            "initial " + " ".join(_bits(v) for v in inputs),
            f"outputs {len(vr_out)} " + " ".join(map(str, vr_out)) + f" {offset}",
        ]
        if any("\n" in str(v) for _, v in typed["String"]):
            raise ValueError(f"{name}: a String parameter with a line break is not in the plan's format")
    plan = folder / "plan.txt"
    plan.write_text("\n".join(lines) + "\n")
    return plan


@dataclass
class HostRun:
    """What ``mast_host`` reported: per component (cycles done, calls with an unexpected status), the run's
    status (0: every call succeeded), its trajectories by signal, and its console output."""

    cycles: dict[str, tuple[int, int]]
    status: int
    outputs: dict[str, np.ndarray]
    log: str


def run_c_host(
    run: MasterRun, host: Path, platform: str, cycles: int = 200, recompile: bool = False, timeout: float = 600.0
) -> HostRun:
    """Run ``host`` (``build_host``) on ``run``'s system and FMUs for ``platform`` (``launcher``; win64: Wine's
    prefix $WINEPREFIX, else ~/.cache/mast/wine); ``recompile``: the FMUs' binaries compiled from their sources
    here (``write_plan``). RuntimeError with the host's output when it fails or cannot run here."""
    with tempfile.TemporaryDirectory(prefix="mast_c_host_") as tmp:
        folder = Path(tmp)
        plan = write_plan(run, platform, folder, cycles, recompile)
        result = folder / "result.bin"
        cmd, env = [str(host), _host_path(plan, platform), _host_path(result, platform)], dict(os.environ)
        prefix = launcher(platform)
        if prefix is None:
            raise RuntimeError(
                f"{platform} programs do not run here (Debian: apt-get install "
                f"{'wine64' if platform == 'win64' else 'qemu-user libc6-arm64-cross'})"
            )
        cmd = prefix + cmd
        if platform == "win64":
            env.setdefault("WINEPREFIX", str(Path.home() / ".cache" / "mast" / "wine"))
            env.setdefault("WINEDEBUG", "-all")
        done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
        log = done.stdout + done.stderr
        report = [line.split() for line in done.stdout.splitlines()]
        counts = {w[1]: (int(w[2]), int(w[3])) for w in report if w and w[0] == "cycles"}
        status = [int(w[2]) for w in report if w and w[0] == "run"]
        if not status or not result.exists():
            raise RuntimeError(f"{' '.join(cmd)} failed (exit status {done.returncode}):\n{log[-4000:]}")
        rows = np.fromfile(result, dtype="<f8").reshape(-1, len(run.flat_names))
    return HostRun(counts, status[0], {name: rows[:, k] for k, name in enumerate(run.flat_names)}, log)
