"""`mast build`: FMUs from fmus/, SSP archives from ssp/.

Each FMU bundles the ``fmus`` model package under a module name unique to
that FMU and its source (``mast_<fmu>_<hash>``), and its entry script too
(``mast_<fmu>_<hash>_entry.py``: pythonfmu imports the entry script by name and
takes the slave class from the module it finds in ``sys.modules``, so two
versions of one FMU with the same script name would both run the first one's
code). Several MAST FMUs, or two versions of one, share a Python interpreter
without their modules colliding. Parameter start values are taken from the parameter sets that the
default system (``ssp/MAST.ssd``, then the other ``ssp/*.ssd``) binds to the
first component using the FMU: the .ssv files stay the one place where values
live. Each FMU carries ``resources/requirements.txt`` (its Python packages, for
``pythonfmu deploy``) and declares canGetAndSetFMUstate.

On Linux each FMU's binary is a small C front (``fmus/common/pythonfmu_shim.c``, one
source compiled once per build and FMI version with the C compiler the native route finds)
in front of pythonfmu's (or pythonfmu3's) library, shipped beside it as ``<id>.pythonfmu.so``:
it returns fmi2Error (fmi3Error) for a call the FMI state machine does not allow, where
pythonfmu can only say Fatal. Without a C compiler the FMUs keep pythonfmu's binary (and
answer such a call with Fatal); the build says so once per FMI version.

Each built SSP gets its parameter bindings flattened: one .ssv per component
(``resources/parameters/<component>.ssv``) holding the values of the source
bindings merged in order, with their units and descriptions, all named
``FLAT_SET_NAME``. Third-party hosts need this: libcosim applies only the first
parameter set of a component, ecos applies one named set (``--parameterSet``).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import shutil
import sys
import tempfile
import zipfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable, Iterator, Mapping, Optional, Union

from lxml import etree

from fmus.common.slave import PYTHONFMU_LIBRARY_SUFFIX

from . import ssd, ssv
from .ssp import applicable_parameters, read_ssd
from .units import Unit

REPO = Path(__file__).resolve().parents[2]
FMUS_SRC = REPO / "fmus"
SSP_SRC = REPO / "ssp"


def default_build_dir() -> Path:
    """Where ``mast build`` writes, and the other commands look for what it built: ``$MAST_BUILD`` when set
    (tests/test_docs.py runs the documented commands on a build of its own), else build/ of the source
    checkout (an editable install), else build/ in the current directory (after a plain ``pip install .``
    this module lives in site-packages, which is no place for build outputs)."""
    if os.environ.get("MAST_BUILD"):
        return Path(os.environ["MAST_BUILD"])
    return REPO / "build" if (REPO / "pyproject.toml").is_file() else Path.cwd() / "build"


@dataclass(frozen=True)
class FmuSpec:
    model_identifier: str  # class name in fmus/<package>/fmu.py and the FMU file name
    package: str  # sub-package of fmus/


FMUS = (
    FmuSpec("MastActuator", "actuator"),
    FmuSpec("MastMechanism", "mechanism"),
    FmuSpec("MastController", "controller"),
    # controllers: the same interface, defaults from their own systems ssp/MAST_<controller>.ssd (mast.core.controllers)
    FmuSpec("MastWorkspaceController", "controller"),
    FmuSpec("MastFeedForwardController", "controller"),
    FmuSpec("MastComputedTorqueController", "controller"),
    FmuSpec("MastTrajectory", "trajectory"),
    # mechanism designs: the same model, defaults from their own systems ssp/MAST_<design>.ssd (mast.core.designs)
    FmuSpec("Mast3PRS120", "mechanism"),
    FmuSpec("Mast3PRSInclined", "mechanism"),
    FmuSpec("MastActuatorsOnly", "mechanism"),
    # other mechanisms: a system of their own each, ssp/MAST_<design>.ssd (mast.core.designs.MECHANISMS), with a
    # controller built for it (its parameters and kinematic model the description's)
    FmuSpec("Mast3RPS", "mechanism"),
    FmuSpec("Mast3RPSController", "controller"),
    FmuSpec("Mast6UPS", "mechanism"),
    FmuSpec("Mast6UPSController", "controller"),
    FmuSpec("Mast6UPSTrajectory", "trajectory"),  # the pose command of ssp/MAST_6UPS_standalone.ssd
    FmuSpec("Mast6PUS", "mechanism"),
    FmuSpec("Mast6PUSController", "controller"),
    # single-axis test benches (ssp/EMPS_bench.ssd)
    FmuSpec("MastLoadAxis", "actuator"),
    FmuSpec("MastEmpsController", "controller"),
)

#: Python packages the bundled model code imports (pythonfmu itself travels inside each FMU);
#: written to resources/requirements.txt for `pythonfmu deploy`. tests/test_fmi_behaviour.py
#: checks it against the imports of fmus/ and the project's own dependencies, markers included (pip, which
#: `pythonfmu deploy` runs on the file, honours them).
FMU_REQUIREMENTS = (
    "numpy>=1.24",
    "scipy>=1.10",
    "tomli>=1.1; python_version < '3.11'",
)  # tomli: the description files on Python 3.10

#: name of the one parameter set per component in a built SSP (ecos: --parameterSet default)
FLAT_SET_NAME = "default"


#: the C front of the Python FMUs' binary (module docstring): one source for FMI 2.0 and 3.0 (FMI_VERSION),
#: and where each version's Linux binary lives in the FMU (pythonfmu's library goes beside it)
FRONT_SOURCE = FMUS_SRC / "common" / "pythonfmu_shim.c"
#: the live-instance registry and time checks the front shares with the native FMUs' wrapper
FRONT_GUARD = FMUS_SRC / "common" / "native" / "mast_guard.h"
FRONT_BINARY = {2: "binaries/linux64/{}.so", 3: "binaries/x86_64-linux/{}.so"}


def status_front(fmi_version: int = 2) -> tuple[Optional[bytes], str]:
    """(the compiled C front of an FMI ``fmi_version`` FMU's Linux binary, "") or (None, why there is none here)."""
    if not sys.platform.startswith("linux"):
        return None, f"the C front is built for Linux x86_64 only (here: {sys.platform})"
    if not FRONT_SOURCE.is_file():
        return None, f"{FRONT_SOURCE} is missing from this installation"
    return _compiled_front(FRONT_SOURCE.read_bytes(), FRONT_GUARD.read_bytes(), fmi_version)


@functools.lru_cache(maxsize=4)
def _compiled_front(source: bytes, guard: bytes, fmi_version: int) -> tuple[Optional[bytes], str]:
    from .native.compiler import NativeBuildError, compile_shared

    with tempfile.TemporaryDirectory(prefix="mast_front_") as tmp:
        target = Path(tmp) / "front.so"
        try:  # the version first; #line keeps the compiler's line numbers those of the file
            compile_shared(
                {
                    FRONT_SOURCE.name: f"#define FMI_VERSION {fmi_version}\n#line 1\n".encode() + source,
                    FRONT_GUARD.name: guard,
                },
                target,
            )
        except NativeBuildError as err:
            return None, str(err)
        return target.read_bytes(), ""


def front_note(fmi_version: int = 2) -> Optional[str]:
    """What a build without the C front should tell its user (None: the front is built)."""
    front, why = status_front(fmi_version)
    return (
        None
        if front is not None
        else (
            f"note: the Python FMUs (FMI {fmi_version}.0) keep pythonfmu's binary, which answers a call FMI does not "
            f"allow with fmi{fmi_version}Fatal instead of fmi{fmi_version}Error ({why})"
        )
    )


def _put_front(items: dict[str, bytes], identifier: str, fmi_version: int = 2) -> bool:
    """Make the C front the FMU's Linux binary and move pythonfmu's beside it (False: no front here)."""
    front, _ = status_front(fmi_version)
    binary = FRONT_BINARY[fmi_version].format(identifier)
    if front is None or binary not in items:
        return False
    items[binary.removesuffix(".so") + PYTHONFMU_LIBRARY_SUFFIX + ".so"] = items.pop(binary)
    items[binary] = front
    return True


def _source_hash(extra: bytes) -> str:
    digest = hashlib.sha256(extra)
    for file in sorted([*FMUS_SRC.rglob("*.py"), *FMUS_SRC.rglob("*.toml")]):  # the code and the descriptions
        digest.update(file.relative_to(FMUS_SRC).as_posix().encode())
        digest.update(file.read_bytes())
    return digest.hexdigest()[:10]


def block_class(model_identifier: str):
    """The Block class the project's FMU ``model_identifier`` wraps (fmus/<package>/fmu.py)."""
    import importlib

    for spec in FMUS:
        if spec.model_identifier == model_identifier:
            return getattr(importlib.import_module(f"fmus.{spec.package}.fmu"), model_identifier).block_class
    raise ValueError(f"no model of this project is built as {model_identifier}.fmu")


def _first_use(model_identifier: str, ssd: Optional[Path] = None):
    """(system, component name) of the first component using the FMU, in ``ssd`` or else in ssp/MAST.ssd, then
    ssp/*.ssd."""
    main = SSP_SRC / "MAST.ssd"
    candidates = [ssd] if ssd is not None else [main] + [p for p in sorted(SSP_SRC.glob("*.ssd")) if p != main]
    for path in candidates:
        system = read_ssd(path)
        for name, comp in system.components.items():
            if Path(comp.source).stem == model_identifier:
                return system, name
    raise ValueError(
        f"{', '.join(map(str, candidates))}: no component uses {model_identifier}.fmu, "
        "so it gives no default parameters"
    )


def default_parameters(model_identifier: str, ssd: Optional[Path] = None) -> dict:
    """Bindings of the first component using the FMU (``_first_use``): merged in order and restricted to the FMU's
    own parameters (``ssp.applicable_parameters``)."""
    system, name = _first_use(model_identifier, ssd)
    units = {
        c: {p.name: p.unit for p in block_class(Path(s.source).stem).for_parameters(s.parameters).PARAMETERS}
        for c, s in system.components.items()
    }
    return applicable_parameters(system, units, units)[name]


def default_experiment(model_identifier: str) -> tuple[float, float, float]:
    """(start time, stop time, step size) [s] for the FMU's DefaultExperiment: those of the first system that uses
    it (``_first_use``: its DefaultExperiment) and the step size that system gives the component (its
    StepSizeHint, else the base step). A block with a cycle time proposes that instead (``Block.CYCLE_TIME``,
    fmus/common/slave.py). ValueError naming the system when it lacks a stop time or a step size."""
    system, name = _first_use(model_identifier)
    step = system.components[name].step_size or system.base_step
    if step is None or system.stop_time is None:
        raise ValueError(
            f"system '{system.name}': no {'step size' if step is None else 'stop time'} for '{name}' "
            f"(osp:StepSizeHint or baseStepSize; ssd:DefaultExperiment stopTime), which "
            f"{model_identifier}.fmu's DefaultExperiment takes"
        )
    return (system.start_time, system.stop_time, step)


@contextmanager
def _staged(spec: FmuSpec, parameters: Optional[dict], fmi_version: int = 2) -> Iterator[tuple[Path, str, list[Path]]]:
    """A temporary folder holding what every FMU of ``spec`` bundles: (folder, unique module name, files).

    The model package under the unique name, parameters.json (``parameters``, default: the
    SSD bindings) and requirements.txt; the module name hashes the sources, the defaults and the FMI version.
    Afterwards the bundled copy (and the entry script, named after it) leave ``sys.modules``:
    the build imported them, and they must not shadow anything.
    """
    parameters = default_parameters(spec.model_identifier) if parameters is None else parameters
    defaults = json.dumps(parameters, indent=1, sort_keys=True)
    # the FMI 3.0 variant's copy gets a name of its own: a process that loads both variants of a model must not
    # import one's modules from the other's folder (which its host may delete while the modules live on)
    module = f"mast_{spec.package}_{_source_hash(defaults.encode() + (b'' if fmi_version == 2 else b' fmi3'))}"
    with tempfile.TemporaryDirectory(prefix="mast_build_") as tmp:
        tmp = Path(tmp)
        shutil.copytree(FMUS_SRC, tmp / module, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        (tmp / "parameters.json").write_text(defaults)
        (tmp / "requirements.txt").write_text("".join(f"{r}\n" for r in FMU_REQUIREMENTS))
        try:
            yield tmp, module, [tmp / module, tmp / "parameters.json", tmp / "requirements.txt"]
        finally:
            for name in [m for m in sys.modules if m.startswith(module)]:
                del sys.modules[name]


def build_fmu(spec: FmuSpec, out_dir: Path, parameters: Optional[dict] = None) -> Path:
    """Build one FMU into ``out_dir`` and return its path."""
    from pythonfmu.builder import FmuBuilder

    out_dir.mkdir(parents=True, exist_ok=True)
    with _staged(spec, parameters) as (tmp, module, files):
        script = tmp / f"{module}_entry.py"  # unique: see the module docstring
        script.write_text(
            f'"""FMU entry point generated by mast build: the model lives in {module}/{spec.package}/."""\n'
            f"from {module}.common.fmi import keep_alive\n"
            f"from {module}.{spec.package}.fmu import {spec.model_identifier}  # noqa: F401\n\n"
            f"{spec.model_identifier}.experiment = {default_experiment(spec.model_identifier)!r}  # "
            "DefaultExperiment\n\n"
            "# pythonfmu 0.7.0 re-executes this file at every instantiation and then releases one reference\n"
            "# to this module's globals it never took (findClass: Py_DECREF on PyModule_GetDict); holding one\n"
            "# more reference per execution keeps the count balanced, so instances can come and go.\n"
            "keep_alive(globals())\n"
        )
        fmu = FmuBuilder.build_FMU(
            script,
            dest=out_dir / f"{spec.model_identifier}.fmu",
            project_files=files,
            needsExecutionTool=False,
            canGetAndSetFMUstate=True,
        )
    _complete(Path(fmu), spec, parameters)
    return Path(fmu)


def build_fmu3(spec: FmuSpec, out_dir: Path, parameters: Optional[dict] = None) -> Path:
    """The FMI 3.0 variant of one FMU (pythonfmu3, fmus/common/fmi3.py) into ``out_dir``.

    The same bundled model package, parameter defaults and requirements as the
    FMI 2.0 build; the entry script defines the slave class itself because
    pythonfmu3 finds it by a regular expression on the script's text
    (``class <Name>(... Fmi3Slave ...):``) and imports the script once, by its
    (unique) module name.
    """
    import importlib

    from pythonfmu3.builder import FmuBuilder as Fmu3Builder

    wrapper = getattr(importlib.import_module(f"fmus.{spec.package}.fmu"), spec.model_identifier)
    block = wrapper.block_class
    doc = (wrapper.__doc__ or block.__doc__ or "").strip().split("\n")[0].replace('"""', "'")
    out_dir.mkdir(parents=True, exist_ok=True)
    with _staged(spec, parameters, fmi_version=3) as (tmp, module, files):
        block_module = block.__module__.replace("fmus.", f"{module}.", 1)
        script = tmp / f"{module}_fmi3_entry.py"
        script.write_text(
            f'"""FMI 3.0 entry point generated by mast build: the model lives in {module}/{spec.package}/."""\n'
            "from pythonfmu3 import Fmi3Slave\n\n"
            f"from {module}.common.fmi3 import BlockSlave3\n"
            f"from {block_module} import {block.__name__}\n\n\n"
            f"class {spec.model_identifier}(BlockSlave3, Fmi3Slave):\n"
            f'    """{doc}"""\n\n'
            f"    block_class = {block.__name__}\n"
            f"    experiment = {default_experiment(spec.model_identifier)!r}\n"
            f"    author = {getattr(wrapper, 'author', None)!r}\n"
            f"    version = {getattr(wrapper, 'version', None)!r}\n"
        )
        fmu = Fmu3Builder.build_FMU(
            script,
            dest=tmp / "out",
            project_files=files,
            needsExecutionTool=False,
            canGetAndSetFMUState=True,
            canHandleVariableCommunicationStepSize=True,
        )
        target = out_dir / f"{spec.model_identifier}.fmu"
        shutil.move(str(fmu), target)
    _rewrite(target, lambda items: _put_front(items, spec.model_identifier, 3))
    return target


def _complete(fmu: Path, spec: FmuSpec, parameters: Optional[dict] = None) -> None:
    """The FMU pythonfmu wrote, with its model description completed and the C front as its linux64 binary."""

    def complete(items: dict[str, bytes]) -> None:
        items["modelDescription.xml"] = _complete_model_description(items["modelDescription.xml"], spec, parameters)
        _put_front(items, spec.model_identifier)

    _rewrite(fmu, complete)


def _rewrite(fmu: Path, change: Callable[[dict[str, bytes]], object]) -> None:
    """Rewrite the archive ``fmu`` with ``change`` applied to its entries ({name: bytes}, changed in place)."""
    with zipfile.ZipFile(fmu) as zin:
        items = {name: zin.read(name) for name in zin.namelist()}
    change(items)
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zout:
        for name, data in items.items():
            zout.writestr(name, data)


def _complete_model_description(xml: bytes, spec: FmuSpec, parameters: Optional[dict] = None) -> bytes:
    """What pythonfmu 0.7 leaves out of modelDescription.xml: the units (from the model's declarations: of the class
    whose variables the FMU's built-in ``parameters`` give, default the SSD bindings, ``Block.for_parameters``: a
    mechanism's follow its topology) and ModelStructure/InitialUnknowns, which FMI 2.0 requires for outputs with
    initial="calculated"."""
    params = default_parameters(spec.model_identifier) if parameters is None else parameters
    block = block_class(spec.model_identifier).for_parameters(params)
    units = dict(block.UNITS)
    units.update({p.name: p.unit for p in block.PARAMETERS if p.kind is float and p.unit})
    root = etree.fromstring(xml)
    used = []
    for var in root.iter("ScalarVariable"):
        unit = units.get(var.get("name"))
        real = var.find("Real")
        if unit and real is not None:
            real.set("unit", unit)
            used.append(unit)
    if used:
        defs = etree.Element("UnitDefinitions")
        for unit in sorted(set(used)):
            etree.SubElement(defs, "Unit", name=unit)
        root.find("CoSimulation").addnext(defs)
    outputs = root.find("ModelStructure/Outputs")
    if outputs is not None and root.find("ModelStructure/InitialUnknowns") is None:
        initial = etree.Element("InitialUnknowns")
        for unknown in outputs.iterfind("Unknown"):
            etree.SubElement(initial, "Unknown", index=unknown.get("index"))
        outputs.addnext(initial)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def build_ssp(ssd: Path, fmu_dir: Path, out_dir: Path) -> Path:
    """Pack ``ssd`` with the FMUs it references and its bindings flattened (one .ssv per component)."""
    from fmpy import read_model_description

    system = read_ssd(ssd)  # checks the structure and that every bound .ssv exists
    names = {}
    for comp, spec in system.components.items():
        fmu = fmu_dir / Path(spec.source).name
        if not fmu.exists():
            raise FileNotFoundError(f"{ssd}: component source {spec.source} needs {fmu}, which was not built")
        names[comp] = {
            v.name: v.unit or "" for v in read_model_description(str(fmu)).modelVariables if v.causality == "parameter"
        }
    structure, parameter_sets = flatten_bindings(ssd, names)
    ratings = sorted({c.ratings for c in system.components.values() if c.ratings} - set(parameter_sets))
    for source in ratings:  # the ratings (mast sizing) the system names, packed as they are
        if not (ssd.parent / source).is_file():
            raise FileNotFoundError(f"{ssd}: its drives name the ratings {source}, which does not exist")
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{ssd.stem}.ssp"
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        zout.writestr("SystemStructure.ssd", structure)
        for source in sorted({c.source for c in system.components.values()}):
            fmu = fmu_dir / Path(source).name
            if not fmu.exists():
                raise FileNotFoundError(f"{ssd}: component source {source} needs {fmu}, which was not built")
            zout.write(fmu, source)
        for source, data in parameter_sets.items():
            zout.writestr(source, data)
        for source in ratings:
            zout.write(ssd.parent / source, source)
    return target


def flatten_bindings(
    ssd_path: Path, parameter_names: Mapping[str, Union[Iterable[str], Mapping[str, str]]]
) -> tuple[bytes, dict[str, bytes]]:
    """``ssd_path`` with each component's bindings replaced by one: (SystemStructure.ssd, {archive path: .ssv}).

    Values merge in binding order (later bindings override), each keeping the
    unit and description of the binding that set it; the units the values use
    are declared in the .ssv. Only the component's own parameters (``parameter_names``
    per component) are kept, so hosts that refuse unknown names run the result; a name
    that no component of its set has is refused (``ssp.applicable_parameters``).
    A component without bindings keeps none. With ``parameter_names`` mapping each name to the
    unit the component declares, a value given in another unit of that dimension (``unit="g"``
    for a mass in kg) is written converted, in the declared unit: hosts that ignore units
    (libcosim, ecos) then read the right value.
    """
    declared = {c: dict(n) for c, n in parameter_names.items() if isinstance(n, Mapping)}
    bound = applicable_parameters(read_ssd(ssd_path), parameter_names, declared)  # the typo and unit checks
    document = ssd.read(ssd_path)
    sets: dict[str, bytes] = {}
    for comp in document.system.elements:
        if not comp.bindings:
            continue
        merged: dict[str, ssv.ParameterValue] = {}
        units: dict[str, Unit] = {}
        sources = []
        for binding in comp.bindings:
            if binding.source:
                values = ssv.read(ssd_path.parent / binding.source)
                sources.append(binding.source)
            else:
                values = binding.values
                sources.append("inline values")
                units.update(document.units)  # written into the flattened set if its values use them
            merged.update(values.parameters)
            units.update(values.units)
        own = set(parameter_names[comp.name])
        merged = {k: v for k, v in merged.items() if k in own}
        for k, p in merged.items():
            if p.si is not None and (p.si.factor != 1.0 or p.si.offset) and declared.get(comp.name, {}).get(k):
                merged[k] = dataclasses.replace(p, value=bound[comp.name][k], unit=declared[comp.name][k], written=None)
        used = dict.fromkeys(p.unit for p in merged.values() if p.unit)
        path = f"resources/parameters/{comp.name}.ssv"
        sets[path] = ssv.ParameterSet(
            FLAT_SET_NAME,
            merged,
            {u: units[u] for u in used if u in units},
            f"Parameters of '{comp.name}' in {ssd_path.name}: {', '.join(sources)} merged in this order by mast build",
        ).to_bytes()
        comp.bindings = [ssd.ParameterBinding(path)]
    document.comments.append(
        f"Built by mast build from {ssd_path.name}: each component's parameter bindings are "
        f"flattened into one set, resources/parameters/<component>.ssv, named '{FLAT_SET_NAME}'."
    )
    return document.to_bytes(), sets


def build_all(out: Optional[Path] = None, ssds: Iterable[Path] = (), log=print, fmi3: bool = False) -> list[Path]:
    """Build every FMU and every SSP of ssp/*.ssd into ``out`` (default: ``default_build_dir()``); return the
    written paths.

    ``fmi3=True`` also builds the FMI 3.0 variants into ``out/fmus3`` (needs pythonfmu3).
    """
    out = default_build_dir() if out is None else out
    written = []
    for version in (2, 3) if fmi3 else (2,):
        if front_note(version):
            log(front_note(version))
    for spec in FMUS:
        written.append(build_fmu(spec, out / "fmus"))
        log(f"built {written[-1]}")
        if fmi3:
            written.append(build_fmu3(spec, out / "fmus3"))
            log(f"built {written[-1]}")
    for ssd_file in list(ssds) or sorted(SSP_SRC.glob("*.ssd")):
        written.append(build_ssp(Path(ssd_file), out / "fmus", out / "ssp"))
        log(f"built {written[-1]}")
    return written
