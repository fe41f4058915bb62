"""The plan as one FMI 2.0 (or, ``fmi=3``, FMI 3.0) co-simulation FMU (a container): its FMUs unpacked under
resources/, the system as data (resources/system.txt: the wiring the master's loop takes, parameters, start values, the container's
variables), and a binary built from the master's own compiled loop (``stepping/container.c``, which includes
``stepping/native_loop.c``) with the same compiler flags, so that a host running the container gets what
``run`` of the plan gives, bit for bit.

Its binary is built for linux64, and for win64 (MinGW-w64, the same C: the inner FMUs' DLLs loaded with
LoadLibrary) where the cross compiler is on PATH and every inner FMU has a win64 binary.

What this export takes (everything else is refused before anything is written, one line naming it): FMI 2.0
co-simulation FMUs with a linux64 binary (C, or pythonfmu's behind our loader, which finds its Python as
when a host loads the FMU alone), Gauss-Seidel or Jacobi (instances at their own rates too, as the master's multi-rate passes), the
iterated coupling (``stepping/container_iter.c``, included by container.c: the coupling loops rolled back
through the inner FMUs' fmi2GetFMUstate / fmi2SetFMUstate), Real connections, recorded Real,
Integer and Boolean outputs, no events, input tables or requirements.  The container's variables: the
recorded outputs (named as their columns), the open inputs and the parameters of the inner FMUs of type
Real, Integer or Boolean (``instance.variable``, the scenario's value as start), in the plan's order.

The FMI 3.0 face (``stepping/container3.c`` around the same runtime, binaries/x86_64-linux): the same
variables as Float64, Int32 and Boolean with the same value references, the GUID as instantiation token; the
inner FMUs stay FMI 2.0.
"""
from __future__ import annotations

import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

from ..messages.errors import CosimError, ScenarioError
from ..model.archive import safe_extract
from ..model.description import CO_SIMULATION
from ..stepping import native
from ..stepping.settings import IterationSpec
from ..stepping.table import GAUSS_SEIDEL, ITERATED, JACOBI
from .records import InstancePlan, Plan
from .wiring import RowLayout, Wiring

SOURCE = native.SOURCE.with_name("container.c")
SOURCE3 = native.SOURCE.with_name("container3.c")   # the FMI 3.0 face: includes container.c
SOURCE_ITER = native.SOURCE.with_name("container_iter.c")   # the iterated coupling: container.c includes it
#: The FMI 3.0 standard's headers container3.c includes (FMPy's copy: :func:`native.fmi_headers`).
HEADERS3 = ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")
FORMAT = "wmr-container 4"   # the first line of system.txt (container.c's VERSION_TAG)


#: The FMI 2.0 types of the container's variables, and their letters in system.txt.
TYPES = {"Real": "R", "Integer": "I", "Boolean": "B"}
#: Their FMI 3.0 types (the FMI 3.0 face of the container).
TYPES3 = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
#: The FMI versions the container can be written for, and the binaries' folder of each platform in each.
PLATFORM_FOLDERS = {2: {"linux64": "linux64", "win64": "win64"}, 3: {"linux64": "x86_64-linux", "win64": "x86_64-windows"}}


@dataclass
class ContainerVar:
    """One variable of the container: ``kind`` "o" (a recorded output: ``ref`` its row slot for a Real, the
    inner FMU's value reference for an Integer or a Boolean, read from it when the host asks), "i" (an open
    input) or "p" (a parameter; ``ref`` the inner FMU's value reference), ``inst`` its instance's index,
    ``type`` its FMI 2.0 type (a key of :data:`TYPES`), ``start`` its value as a float (an Integer's or a
    Boolean's exactly: 0.0 or 1.0 for false or true)."""

    name: str
    kind: str
    inst: int
    ref: int
    start: float
    variability: str
    unit: str | None
    description: str
    type: str = "Real"


def _hex(text: str) -> str:
    return "x" + text.encode().hex()


def _num(x: float) -> str:
    return float(x).hex()


def refuse(plan: Plan, out: Path, name: str) -> None:
    """ScenarioError, one line, for what this container cannot hold (nothing is written before)."""
    sc = plan.scenario

    def no(field: str, reason: str) -> None:
        raise ScenarioError(sc.file, field, f"{reason}: it cannot be exported as an FMU container yet")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        raise ScenarioError(sc.file, "--name", f"{name!r}: a model identifier is a C name (letters, digits, _)")
    if sys.platform != "linux":
        raise CosimError("export-fmu builds the container's linux64 binary: run it on Linux")
    if sc.algorithm not in (GAUSS_SEIDEL, JACOBI, ITERATED):
        no("experiment.algorithm", f"{sc.algorithm!r} (only gauss-seidel, jacobi and iterated)")
    for n, ip in plan.instances.items():
        _refuse_instance(plan, n, ip, out, no)
    if plan.last_step is not None:   # a host steps the container by whole steps of the scenario's
        no("experiment.stop", f"stop = {sc.stop!r} s is not on the grid of step = {sc.step!r} s (the run's last step "
                              f"is {plan.last_step!r} s; the container takes whole steps)")
    if plan.events or plan.conditions:
        no("events", "events (timed or on conditions)")
    if plan.inputs:
        no("inputs", "input tables")
    if plan.requirements:
        no("requirements", "requirements")
    for c in plan.connections:
        if not c.is_float64:
            no("connections", f"{c.src}.{c.src_var.name} -> {c.dst}.{c.dst_var.name} is not Real to Real")
    for r in plan.record:
        if r.var.type not in TYPES:
            no("record", f"{r.column} is {r.var.fmi_type} (only Real, Integer and Boolean outputs)")


def _refuse_instance(plan: Plan, n: str, ip: InstancePlan, out: Path, no: Any) -> None:
    where = f"instances.{n}"
    if ip.model.fmi != 2:
        no(where, f"{ip.model.path.name} is an FMI {ip.model.fmi}.0 FMU (only FMI 2.0)")
    if ip.interface != CO_SIMULATION:
        no(where, f"{ip.model.path.name} runs as Model Exchange (only co-simulation)")
    # (an FMU without a binary for this platform, linux64, has no plan: the master's resolution refuses it)
    if out.resolve() == ip.model.path.resolve():
        raise ScenarioError(plan.scenario.file, "--out", f"{out} is the FMU of instance {n}: write the container "
                                                          "elsewhere")


def variables(plan: Plan, layout: RowLayout) -> list[ContainerVar]:
    """The container's variables: recorded outputs, then open inputs and parameters (Real, Integer, Boolean) by
    instance (``inst``: its index in the plan's order)."""
    cols = plan.columns()
    index = {n: i for i, n in enumerate(plan.order)}
    out = [ContainerVar(r.column, "o", -1 if r.var.type == "Real" else index[r.instance],
                        layout.slot(r) if r.var.type == "Real" else r.var.vr, 0.0,
                        "continuous" if r.var.variability == "continuous" else "discrete", cols[r.column]["unit"],
                        f"{r.instance}.{plan.instances[r.instance].our_name(r.var)} of {cols[r.column]['fmu']}",
                        r.var.type)
           for r in plan.record]
    driven = {(c.dst, c.dst_var.name) for c in plan.connections}
    for i, n in enumerate(plan.order):
        ip = plan.instances[n]
        given = {var.name: value for var, value in ip.parameters}
        for var in ip.model.variables.values():
            open_input = var.causality == "input" and (n, var.name) not in driven
            parameter = var.causality == "parameter" and var.variability in ("fixed", "tunable")
            value = given.get(var.name, var.start)
            if var.type not in TYPES or not (open_input or parameter) or value is None:
                continue
            unit = var.unit.name if var.type == "Real" and var.unit is not None else None
            variability = var.variability if parameter else "continuous" if var.type == "Real" else "discrete"
            out.append(ContainerVar(f"{n}.{ip.our_name(var)}", "i" if open_input else "p", i, var.vr,
                                    float(value) if var.type == "Real" else float(int(value)), variability, unit,
                                    var.description or f"{var.name} of {ip.model.path.name}", var.type))
    seen: dict[str, ContainerVar] = {}
    for v in out:
        if v.name in seen:
            raise ScenarioError(plan.scenario.file, "record", f"{v.name!r} would be the container's variable twice "
                                                              f"(a recorded output and {_A[v.kind]})")
        seen[v.name] = v
    return out


_KIND = {"o": "output", "i": "input", "p": "parameter"}
_A = {"o": "a recorded output", "i": "an open input", "p": "a parameter"}


def system_text(plan: Plan, layout: RowLayout, wiring: Wiring, cvars: list[ContainerVar],
                dirs: dict[str, str]) -> str:
    """resources/system.txt (read by container.c)."""
    index = {(v.inst, v.type, v.ref): j for j, v in enumerate(cvars) if v.kind != "o"}
    own_rates = any(plan.instances[n].decimation > 1 for n in plan.order)   # (the master's MultiRate)
    lines = [FORMAT, f"system {len(plan.order)} {layout.n_double} {int(plan.scenario.algorithm == JACOBI)} 1 "
                     f"{_num(plan.scenario.step or 0.0)} {len(cvars)} {int(own_rates)}"]
    for i, n in enumerate(plan.order):
        ip = plan.instances[n]
        copies = wiring.copies(n)
        lines.append(" ".join(["inst", _hex(n), _hex(dirs[n]), _hex(ip.model.identifier), _hex(ip.model.md.guid),
                               str(int(ip.tolerance is not None)), _num(ip.tolerance or 0.0),
                               str(len(wiring.vrs[n])), str(len(layout.reals[n])), str(layout.offset[n]),
                               str(len(copies)), str(len(ip.parameters)), str(ip.decimation)]))
        lines.append(" ".join(str(vr) for vr in wiring.vrs[n]) or "")
        lines.append(" ".join(str(vr) for vr, _ in layout.reals[n]) or "")
        for c in copies:
            src = next((m for m in plan.order if c.src is layout.out_arr[m]), None)
            if src is None:   # (tables and events are refused: every copy reads the row)
                raise CosimError(f"{n}: an input copy that does not read the row")
            lines.append(f"copy {c.pos} {layout.offset[src] + c.slot} {_num(c.factor)} {_num(c.offset)}")
        for var, value in ip.parameters:
            lines.append(f"param {_param(var, value)} {index.get((i, var.type, var.vr), -1)}")
    for v in cvars:
        lines.append(f"var {v.kind} {TYPES[v.type]} {v.inst} {v.ref} {_num(v.start)} "
                     f"{int(v.variability == 'tunable' or v.kind == 'i')}")
    lines += iteration_text(plan, layout, wiring)
    lines.append("end")
    return "\n".join(lines) + "\n"


def iteration_text(plan: Plan, layout: RowLayout, wiring: Wiring) -> list[str]:
    """The iterated coupling's lines of system.txt (read by container_iter.c): ``iteration 0`` where the
    algorithm is another; else the settings (method 0 fixed point, 1 Newton; tolerance; max_iterations;
    relaxation; inputs linear 0/1; Jacobian from directional derivatives 0/1) and the components of the
    plan's graph of copies in stepping order (FeedGraph.components, as the master's Iterated steps them):
    ``comp LOOP N members...`` and, for a loop, ``unknown`` lines, one per coupling input in the master's
    order (its members in order, each one's copies in order that read an output of the loop: instance,
    input position, input value reference, the row slot it reads, the instance and value reference of that
    output, factor, offset)."""
    sc = plan.scenario
    if sc.algorithm != ITERATED:
        return ["iteration 0"]
    spec = sc.iteration or IterationSpec()
    graph = plan.feeds
    lines = [f"iteration 1 {int(spec.method == 'newton')} {_num(spec.tolerance)} {spec.max_iterations} "
             f"{_num(spec.relaxation)} {int(spec.inputs == 'linear')} {int(spec.jacobian == 'directional')} "
             f"{len(graph.components)}"]
    for comp in graph.components:
        loop = graph.is_loop(comp)
        unknowns = []
        if loop:
            mine = {plan.order[i] for i in comp}
            for i in comp:
                n = plan.order[i]
                for c in wiring.copies(n):
                    src = next((m for m in plan.order if c.src is layout.out_arr[m]), None)
                    if src is None or src not in mine:
                        continue
                    unknowns.append(f"unknown {i} {c.pos} {wiring.vrs[n][c.pos]} {layout.offset[src] + c.slot} "
                                    f"{plan.order.index(src)} {layout.reals[src][c.slot][0]} {_num(c.factor)} "
                                    f"{_num(c.offset)}")
        lines.append(f"comp {int(loop)} {len(comp)} {' '.join(map(str, comp))} {len(unknowns)}")
        lines += unknowns
    return lines


def _param(var: Any, value: Any) -> str:
    if var.type == "Real":
        return f"R {var.vr} {_num(float(value))}"
    if var.type == "String":
        return f"S {var.vr} {_hex(str(value))}"
    if var.type == "Boolean":
        return f"B {var.vr} {int(bool(value))}"
    return f"I {var.vr} {int(value)}"


def _attributes(j: int, v: ContainerVar) -> str:
    """The attributes of the container's variable ``v`` (its value reference ``j + 1``) common to its FMI 2.0
    and 3.0 descriptions: name, value reference, causality, variability, initial."""
    initial = ' initial="exact"' if v.kind == "p" else ' initial="calculated"' if v.kind == "o" else ""
    return (f'name={quoteattr(v.name)} valueReference="{j + 1}" causality="{_KIND[v.kind]}" '
            f'variability="{v.variability}"{initial}')


def _typed(v: ContainerVar) -> str:
    """The attributes of a variable's type element: a Real's unit, the start value of an input or parameter."""
    unit = f' unit={quoteattr(v.unit)}' if v.unit and v.type == "Real" else ""
    if v.kind == "o":
        return unit
    start = repr(v.start) if v.type == "Real" else str(int(v.start)) if v.type == "Integer" else \
        ("true" if v.start else "false")
    return f'{unit} start="{start}"'


def model_description(plan: Plan, name: str, guid: str, cvars: list[ContainerVar]) -> str:
    """The container's modelDescription.xml (FMI 2.0 co-simulation)."""
    sc = plan.scenario
    units = sorted({v.unit for v in cvars if v.unit and v.type == "Real"})
    rows = []
    for j, v in enumerate(cvars):
        rows.append(f'    <ScalarVariable {_attributes(j, v)} description={quoteattr(v.description)}><{v.type}{_typed(v)}/>'
                    "</ScalarVariable>")
    outs = "".join(f'<Unknown index="{j + 1}"/>' for j, v in enumerate(cvars) if v.kind == "o")
    unit_defs = ("  <UnitDefinitions>" + "".join(f"<Unit name={quoteattr(u)}/>" for u in units) +
                 "</UnitDefinitions>\n") if units else ""
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" modelName={quoteattr(name)} '
            f'guid="{guid}" generationTool="wmr-cosim export-fmu" variableNamingConvention="flat" '
            f'numberOfEventIndicators="0"\n  description={quoteattr(f"the system of {Path(sc.file).name} as one FMU")}>\n'
            f'  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="false" '
            'canNotUseMemoryManagementFunctions="true"/>\n' + unit_defs +
            '  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>\n'
            f'  <DefaultExperiment startTime="{sc.start!r}" stopTime="{sc.stop!r}" stepSize="{sc.step!r}"/>\n'
            "  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure><Outputs>{outs}</Outputs><InitialUnknowns>{outs}</InitialUnknowns></ModelStructure>\n"
            "</fmiModelDescription>\n")


#: The platforms a container is built for: linux64 always, win64 where it can be (:func:`platforms`).
PLATFORMS = ("linux64", "win64")
_LIB = {"linux64": "so", "win64": "dll"}


def platforms(plan: Plan, asked: list[str] | None = None, fmi: int = 2) -> tuple[list[str], str | None]:
    """The platforms to build the container for, and a note saying why win64 is not among them (None where it
    is, or where ``asked`` leaves it out).  ``asked`` None: linux64, and win64 where MinGW-w64 is on PATH and
    every inner FMU has a win64 binary; else those named, refused (one line) where one cannot be built.  The
    FMI 3.0 face (``fmi`` 3) is built for Linux only, so far."""
    want = list(PLATFORMS) if asked is None else asked
    for p in want:
        if p not in PLATFORMS:
            raise ScenarioError(plan.scenario.file, "--platforms", f"{p!r}: the platforms are {', '.join(PLATFORMS)}")
    if "linux64" not in want:
        raise ScenarioError(plan.scenario.file, "--platforms", "linux64 is always built (the export runs on Linux)")
    if "win64" not in want:
        return ["linux64"], None
    why = "the FMI 3.0 face is built for x86_64-linux only, so far" if fmi == 3 else None
    for n in plan.order if why is None else ():
        ip = plan.instances[n]
        binary = f"binaries/win64/{ip.model.identifier}.dll"
        with zipfile.ZipFile(ip.model.path) as zf:
            if binary not in zf.namelist():
                why = f"instances.{n}: {ip.model.path.name} has no {binary}"
                break
    if why is None and shutil.which(native.MINGW_CC) is None:
        why = f"no {native.MINGW_CC} on PATH (Debian: gcc-mingw-w64-x86-64)"
    if why is None:
        return ["linux64", "win64"], None
    if asked is not None:
        raise ScenarioError(plan.scenario.file, "--platforms", f"win64 cannot be built: {why}")
    return ["linux64"], f"linux64 only, no win64 binary: {why}"


def model_description3(plan: Plan, name: str, token: str, cvars: list[ContainerVar]) -> str:
    """The container's modelDescription.xml as FMI 3.0 co-simulation (its variables Float64, Int32 and Boolean,
    with the value references of the FMI 2.0 description, and time, the independent variable, at value
    reference 0; ``token`` its instantiation token)."""
    sc = plan.scenario
    units = sorted({"s", *(v.unit for v in cvars if v.unit and v.type == "Real")})
    rows = [('    <Float64 name="time" valueReference="0" causality="independent" variability="continuous" unit="s" '
             'description="the time of the system"/>')]
    for j, v in enumerate(cvars):
        rows.append(f"    <{TYPES3[v.type]} {_attributes(j, v)} description={quoteattr(v.description)}{_typed(v)}/>")
    outs = [j + 1 for j, v in enumerate(cvars) if v.kind == "o"]
    structure = "".join(f'<Output valueReference="{r}"/>' for r in outs) + \
        "".join(f'<InitialUnknown valueReference="{r}"/>' for r in outs)
    unit_defs = ("  <UnitDefinitions>" + "".join(f"<Unit name={quoteattr(u)}/>" for u in units) +
                 "</UnitDefinitions>\n") if units else ""
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" modelName={quoteattr(name)} '
            f'instantiationToken="{token}" generationTool="wmr-cosim export-fmu" variableNamingConvention="flat"\n'
            f'  description={quoteattr(f"the system of {Path(sc.file).name} as one FMU")}>\n'
            f'  <CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="false" '
            f'fixedInternalStepSize="{sc.step!r}"/>\n' + unit_defs +
            '  <LogCategories><Category name="logEvents"/><Category name="logStatusError"/></LogCategories>\n'
            f'  <DefaultExperiment startTime="{sc.start!r}" stopTime="{sc.stop!r}" stepSize="{sc.step!r}"/>\n'
            "  <ModelVariables>\n" + "\n".join(rows) + "\n  </ModelVariables>\n"
            f"  <ModelStructure>{structure}</ModelStructure>\n"
            "</fmiModelDescription>\n")


def build_binary(guid: str, dest: Path, platform: str = "linux64", fmi: int = 2) -> None:
    """container.c (with native_loop.c; for ``fmi`` 3, container3.c around it) compiled with the compiled
    loop's flags into ``dest``: for linux64 by the system's C compiler (``CC``, else cc), for win64 by
    MinGW-w64."""
    cc = (os.environ.get("CC") or "cc") if platform == "linux64" else native.MINGW_CC
    path = shutil.which(cc)
    if path is None:
        raise CosimError(f"export-fmu needs a C compiler: no {cc} on PATH")
    source = SOURCE3 if fmi == 3 else SOURCE
    includes = [f"-I{native.fmi_headers(3)}"] if fmi == 3 else []
    flags = native.FLAGS if platform == "linux64" else [f for f in native.FLAGS if f != "-fPIC"]
    libs = ["-ldl", "-lm"] if platform == "linux64" else native.WIN64_LDFLAGS.split()
    p = subprocess.run([path, *flags, *includes, f'-DCONTAINER_GUID="{guid}"', str(source), "-o", str(dest), *libs],
                       capture_output=True, text=True, timeout=300, check=False)
    if p.returncode:
        raise CosimError(f"the C compiler {path} failed on {source.name}: {p.stderr.strip()[:300]}")


def export_fmu(plan: Plan, out: str | os.PathLike, name: str | None = None, fmi: int = 2, *,
               platforms_asked: list[str] | None = None, notes: list[str] | None = None) -> Path:
    """Write the resolved ``plan`` as one co-simulation FMU ``out`` (see the module); returns its path.
    ``name``: its model name and identifier (default: the scenario file's stem, as a C name); ``fmi``: the
    FMI version of its interface, 2 or 3 (its inner FMUs stay FMI 2.0); ``platforms_asked``: the platforms to
    build (default: each that can be, :func:`platforms`); ``notes``: a list the note on a platform not built
    is appended to."""
    if fmi not in PLATFORM_FOLDERS:
        raise CosimError(f"export-fmu writes an FMI 2.0 or 3.0 FMU, not FMI {fmi!r}")
    out = Path(out)
    if name is None:
        name = re.sub(r"\W", "_", Path(plan.scenario.file).stem) or "system"
        name = "_" + name if name[0].isdigit() else name
    refuse(plan, out, name)
    built, note = platforms(plan, platforms_asked, fmi)
    if note is not None and notes is not None:
        notes.append(note)
    layout = RowLayout.of(plan)
    wiring = Wiring(plan, layout)
    cvars = variables(plan, layout)
    tmp = Path(tempfile.mkdtemp(prefix="wmr-cosim-fmu-"))
    try:
        dirs = _unpack(plan, tmp / "resources")
        text = system_text(plan, layout, wiring, cvars, dirs)
        guid = "{" + str(uuid.UUID(hashlib.sha256((text + name).encode()).hexdigest()[:32])) + "}"
        (tmp / "resources" / "system.txt").write_text(text)
        describe = model_description3 if fmi == 3 else model_description
        (tmp / "modelDescription.xml").write_text(describe(plan, name, guid, cvars))
        for platform in built:
            folder = tmp / "binaries" / PLATFORM_FOLDERS[fmi][platform]
            folder.mkdir(parents=True)
            build_binary(guid, folder / f"{name}.{_LIB[platform]}", platform, fmi)
        (tmp / "sources").mkdir()   # (for fmi 3, the FMI 3.0 face and the standard's headers beside it)
        for src in (SOURCE, SOURCE_ITER, native.SOURCE, *((SOURCE3, *(native.fmi_headers(3) / h for h in HEADERS3)) if fmi == 3 else ())):
            shutil.copyfile(src, tmp / "sources" / src.name)
        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_name(out.name + ".part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as zf:
            for f in sorted(tmp.rglob("*")):
                if f.is_file():
                    zf.write(f, f.relative_to(tmp).as_posix())
        part.replace(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _unpack(plan: Plan, resources: Path) -> dict[str, str]:
    """Each FMU unpacked once under ``resources/fmuN``; instance -> its folder's name."""
    folders: dict[Path, str] = {}
    dirs = {}
    for n, ip in plan.instances.items():
        p = ip.model.path.resolve()
        if p not in folders:
            folders[p] = f"fmu{len(folders)}"
            safe_extract(p, resources / folders[p], plan.archive_limits)
        dirs[n] = folders[p]
    return dirs
