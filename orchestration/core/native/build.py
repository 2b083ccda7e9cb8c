"""`mast build --native`: FMI 2.0 Co-Simulation FMUs with a compiled C binary, no Python at run time.

A native FMU is made from the Python FMU of the same model (``mast.core.build``):

- its modelDescription.xml is the Python FMU's (the same variables, value references, units,
  causality, variability, start values, descriptions and DefaultExperiment: they are generated in one place,
  ``fmus/common/slave.py``), with the generation tool, the GUID and the source file list changed;
- its C is the runtime of fmus/common/native, the same for every model: the wrapper ``fmi2_wrapper.c`` (the FMI
  glue) against the model interface ``mast_model.h``, the scalar helpers ``mast_native.h``, the parameters' range
  checks ``mast_ranges.c``, the matrix helpers
  ``mast_linalg.c`` and the direct kinematics ``mast_dk.c`` (``SUPPORT_FILES``), and its kind's
  (``models.runtime_files``:
  ``mast_actuator.c`` and a drive's ``mast_drive.c``, ``mast_mechanism.c``, ``mast_trajectory.c``); and what is
  generated for the model (``models.emit_model``): one model file of traced
  straight-line kernels and tables, and an actuator's or a mechanism's ``config.h`` (its sizes);
- the sources travel in ``sources/`` so a host on another platform can compile them (with the
  FMI 2.0 headers, which every importer has); the binary is ``binaries/linux64/<id>.so``, compiled
  here with zig's C compiler against glibc 2.17 (``c_compiler``; ``$CC`` when set, and without zig ``cc`` or
  ``gcc``), ``-O2 -ffp-contract=off``: the same floating-point operations as the Python model, no fused
  multiply-add.

Every parameter is read at run time, the actuator's ``n_dof`` (the size of its state) too: a native actuator
carries the chains n_dof = 1..``models.N_MAX`` and runs the one the host sets; one built for a parameter set
with a larger n_dof carries that chain too (``models.actuator_structures``), which is how the project's master
runs a larger one (``for_parameters``). Each native SSP carries FMUs built for its own bindings (their start
values).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import uuid
import zipfile
from pathlib import Path
from typing import Mapping, Optional, Sequence

from lxml import etree

from .compiler import PLATFORMS, NativeBuildError, compile_shared
from .models import Variable, emit_model, runtime_files, to_generate

__all__ = ["build_native_fmu", "build_native_all", "native_sources", "read_variables", "SUPPORT"]

REPO = Path(__file__).resolve().parents[3]
SUPPORT = REPO / "fmus" / "common" / "native"
#: the runtime every native FMU carries (the FMI glue, the model interface, the scalar and matrix helpers, the
#: direct kinematics); a kind of model adds its own (``models.RUNTIME``)
SUPPORT_FILES = (
    "fmi2_wrapper.c",
    "mast_guard.h",
    "mast_model.h",
    "mast_native.h",
    "mast_ranges.c",
    "mast_ranges.h",
    "mast_linalg.c",
    "mast_linalg.h",
    "mast_dk.c",
    "mast_dk.h",
)
#: what a native FMU was generated for (its parameter set), inside the archive
GENERATED_FOR = "resources/mast_native.json"


def read_variables(model_description: bytes) -> list[Variable]:
    """The ScalarVariables of a modelDescription.xml, in document order."""
    root = etree.fromstring(model_description)
    out = []
    for sv in root.iter("ScalarVariable"):
        typed = next(iter(sv))
        start = typed.get("start")
        kind = typed.tag
        value = {"Real": lambda s: float(s or 0.0), "Integer": lambda s: int(s or 0), "String": lambda s: s or ""}[
            kind
        ](start)
        out.append(Variable(sv.get("name"), int(sv.get("valueReference")), kind, sv.get("causality"), value))
    return out


def native_sources(
    identifier: str, block_class: type, parameters: Mapping[str, object], model_description: bytes
) -> tuple[dict[str, bytes], bytes]:
    """({file name: C source}, native modelDescription.xml) for the Python FMU's ``model_description``, whose
    variables are those of ``block_class`` built with ``parameters`` (``Block.for_parameters``: a trajectory of six
    coordinates, a mechanism of another description)."""
    block_class = block_class.for_parameters(parameters)
    variables = read_variables(model_description)
    model_file = f"{identifier}_model.c"
    generated = emit_model(identifier, "GUID", block_class, parameters, variables)
    runtime = SUPPORT_FILES + runtime_files(block_class)
    digest = hashlib.sha256("".join(generated[k] for k in sorted(generated)).encode() + model_description)
    for name in runtime:
        digest.update((SUPPORT / name).read_bytes())
    guid = "{" + str(uuid.UUID(bytes=digest.digest()[:16], version=4)) + "}"
    sources = {name: (SUPPORT / name).read_bytes() for name in runtime}
    sources.update({name: text.encode() for name, text in generated.items()})
    sources[model_file] = generated[model_file].replace('"GUID"', f'"{guid}"', 1).encode()
    root = etree.fromstring(model_description)
    root.set("guid", guid)
    root.set("generationTool", "MAST mast build --native (C generated from the model's code)")
    cs = root.find("CoSimulation")
    for old in cs.findall("SourceFiles"):
        cs.remove(old)
    files = etree.SubElement(cs, "SourceFiles")
    for name in sorted(sources):
        if name.endswith(".c"):
            etree.SubElement(files, "File", name=name)
    xml = etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
    return sources, xml


def build_native_fmu(
    identifier: str,
    python_fmu: Path,
    out_dir: Path,
    parameters: Mapping[str, object],
    platforms: Sequence[str] = ("linux64",),
) -> Path:
    """The native form of the Python FMU ``python_fmu`` (model ``identifier``) with ``parameters``, into
    ``out_dir``. ``python_fmu``
    may also be a native FMU of the same model (its modelDescription is the Python one's). ``platforms``:
    the binaries to build (PLATFORMS; which of them are run by the tests: docs/native.md)."""
    from ..build import block_class

    with zipfile.ZipFile(python_fmu) as z:
        md = z.read("modelDescription.xml")
    sources, xml = native_sources(identifier, block_class(identifier), parameters, md)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{identifier}.fmu"
    with tempfile.TemporaryDirectory(prefix="mast_native_") as tmp:
        libraries = {}
        for platform in platforms:
            library = Path(tmp) / platform / f"{identifier}{PLATFORMS[platform][1]}"
            library.parent.mkdir()
            compile_shared(sources, library, platform)
            libraries[f"binaries/{platform}/{library.name}"] = library
        partial = Path(tmp) / target.name
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zout:
            zout.writestr("modelDescription.xml", xml)
            for name, library in libraries.items():
                zout.write(library, name)
            zout.writestr(
                GENERATED_FOR,
                json.dumps({"identifier": identifier, "parameters": dict(parameters)}, indent=1, sort_keys=True),
            )
            for name, data in sorted(sources.items()):
                zout.writestr(f"sources/{name}", data)
        shutil.move(str(partial), target)
    return target


# ----------------------------------------------------------------------------------- every FMU and SSP
def has_native_form(identifier: str) -> bool:
    """Whether ``mast build --native`` can make this FMU (the models of ``models.emit_model``)."""
    from ..build import block_class
    from .models import native_kind

    return native_kind(block_class(identifier)) is not None


def _component_sets(ssd: Path) -> dict[str, tuple[str, dict]]:
    """Per component of ``ssd``: (FMU identifier, its complete parameter set)."""
    from ..build import block_class, default_parameters
    from ..ssp import applicable_parameters, read_ssd

    system = read_ssd(ssd)
    names = {  # a component's parameters: those its bound set gives its model (Block.for_parameters: a 3-RPS's)
        c: {p.name for p in block_class(Path(s.source).stem).for_parameters(s.parameters).PARAMETERS}
        for c, s in system.components.items()
    }
    bound = applicable_parameters(system, names)
    out = {}
    for comp, spec in system.components.items():
        ident = Path(spec.source).stem
        out[comp] = (ident, {**default_parameters(ident), **bound[comp]})
    return out


def build_native_all(
    out: Path,
    ssds: Sequence[Path],
    log=print,
    fmus: Optional[Sequence[str]] = None,
    platforms: Sequence[str] = ("linux64",),
) -> list[Path]:
    """Native FMUs into ``out/fmus/native`` (each for its default parameter set; ``fmus``: only these
    identifiers, default every FMU with a native form) and, for every SSD, ``out/ssp/native/<name>.ssp`` binding
    native FMUs built for its own parameter sets (a system with a model no generator knows is skipped, named in the
    log). Needs the Python FMUs
    of those FMUs and SSDs in ``out/fmus`` (``mast build``); ``platforms``: the binaries each FMU carries
    (``build_native_fmu``)."""
    from ..build import FMUS, build_ssp, default_parameters
    from ..ssp import read_ssd

    python_dir = out / "fmus"
    written = []
    cache: dict[str, Path] = {}

    def native(ident: str, params: dict, folder: Path) -> Path:
        key = json.dumps([ident, params], sort_keys=True, default=str)
        if key not in cache or not cache[key].exists():  # one built into a system's folder went with it
            cache[key] = build_native_fmu(ident, python_dir / f"{ident}.fmu", folder, params, platforms)
        elif cache[key].parent != folder:
            folder.mkdir(parents=True, exist_ok=True)
            shutil.copy2(cache[key], folder / cache[key].name)
        return folder / f"{ident}.fmu"

    for spec in FMUS:
        if has_native_form(spec.model_identifier) and (fmus is None or spec.model_identifier in fmus):
            written.append(
                native(spec.model_identifier, default_parameters(spec.model_identifier), out / "fmus" / "native")
            )
            log(f"built {written[-1]}")
    for ssd in map(Path, ssds):
        used = {Path(spec.source).stem for spec in read_ssd(ssd).components.values()}
        missing = sorted(ident for ident in used if not has_native_form(ident))
        if missing:  # models no generator knows (the EMPS bench's)
            log(f"skipped {ssd.name}: no native form for {', '.join(missing)}")
            continue
        comps = _component_sets(ssd)
        by_source: dict[str, dict] = {}
        for _comp, (ident, params) in comps.items():
            if by_source.setdefault(ident, params) != params:
                raise NativeBuildError(
                    f"{ssd}: the components using {ident}.fmu have different parameter sets; a "
                    "native FMU is built for one set (models.py), so this system has no native form"
                )
        with tempfile.TemporaryDirectory(prefix="mast_native_ssp_") as tmp:
            for ident, params in by_source.items():
                native(ident, params, Path(tmp))
            written.append(build_ssp(ssd, Path(tmp), out / "ssp" / "native"))
        log(f"built {written[-1]}")
    return written


# ----------------------------------------------------------------------------------- for another parameter set
def generated_for(fmu: Path) -> Optional[dict]:
    """What a native FMU was generated for ({identifier, parameters}); None for other FMUs."""
    with zipfile.ZipFile(fmu) as z:
        if GENERATED_FOR not in z.namelist():
            return None
        return json.loads(z.read(GENERATED_FOR))


def cache_dir() -> Path:
    """Where native FMUs made for other parameter sets are kept: $MAST_NATIVE_CACHE, else ~/.cache/mast/native."""
    if os.environ.get("MAST_NATIVE_CACHE"):
        return Path(os.environ["MAST_NATIVE_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "mast" / "native"


def for_parameters(fmu: Path, parameters: Mapping[str, object]) -> Path:
    """``fmu`` itself, or, for a native FMU whose generated code cannot run ``parameters`` (the component's bindings
    and overrides over the FMU's own set) as they are (``models.to_generate``: an actuator's n_dof above the chains
    it carries, ``models.N_MAX``), the same model generated for them too (kept in ``cache_dir()``): how the
    project's master runs native FMUs with any parameter set."""
    from fmus.common.parameters import ParameterError, validate

    from ..build import block_class

    made = generated_for(fmu)
    if made is None:
        return fmu
    ident = made["identifier"]
    specs = block_class(ident).PARAMETERS
    try:
        wanted = validate(specs, {**made["parameters"], **parameters}, ident)
    except ParameterError:  # the FMU names the bad value at initialisation, as every FMU does
        return fmu
    own = validate(specs, made["parameters"], ident)
    structure = to_generate(block_class(ident), own, wanted)  # the others are set at run time
    if not structure:
        return fmu
    key = hashlib.sha256(json.dumps([ident, own, structure], sort_keys=True, default=str).encode())
    for file in sorted(
        [*(REPO / "fmus").rglob("*.py"), *(REPO / "fmus").rglob("*.[ch]"), *Path(__file__).parent.glob("*.py")]
    ):  # the model and generator code
        key.update(file.read_bytes())
    folder = cache_dir() / key.hexdigest()[:16]
    target = folder / f"{ident}.fmu"
    if not target.exists():
        build_native_fmu(ident, fmu, folder, {**own, **structure})  # start values: the FMU's own
    return target
