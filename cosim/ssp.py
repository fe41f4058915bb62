"""SSP 1.0 (System Structure and Parameterization) archives: export a resolved plan, import an archive.

Generic: nothing here knows the FMUs it packs.

**Export** (:func:`export_ssp`) writes, with the ``pyssp-standard`` library:

- ``resources/<file>.fmu``: every FMU of the plan (one copy per file);
- ``SystemStructure.ssd``: one System with one Component per instance (``application/x-fmu-sharedlibrary``),
  its Connectors (the connected inputs and outputs, the recorded outputs and the parameters set, under the
  FMU's own variable names, Real ones with their units, defined in the SSD's Units), the Connections with a
  ``LinearTransformation`` where the scenario gives a factor or an offset (unit conversion is left to the
  connectors' units, as SSP prescribes), and a DefaultExperiment (start, stop) whose annotations carry the
  step: Open Simulation Platform's ``osp:FixedStepAlgorithm baseStepSize`` (read by libcosim and by this
  module) and this master's own ``algorithm``/``order``/``step``;
- ``resources/<instance>.ssv``: the parameter values as one SSV parameter set named ``parameters``, one
  file per component, bound to the component (names without prefix).  This is the form that libcosim and
  ecos both apply (neither applies a system-level binding nor a prefix; measured).

Both XML files are validated against the SSP 1.0 schemas before the archive is written.

**Import** (:func:`load_ssp`) reads an SSP 1.0 archive written by this module or another tool into the
master's :class:`~.scenario.Scenario` (so :func:`.system.resolve` checks it against the FMUs and
:func:`.execution.run` runs it): the archive is checked for unsafe entries before anything is extracted,
the SSD is validated against the schema, components must be FMUs inside the archive, parameter bindings
(inline or in .ssv files, on the system or on components, with or without prefix) become parameters,
connections (with their LinearTransformation) become connections, connector units become declared units,
the DefaultExperiment gives start and stop, the step comes from the annotations or from the FMUs'
default experiments (or ``step=``).  Every problem is a one-line :class:`~.errors.ScenarioError`.
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from .archive import check_archive, check_entries, check_sizes, safe_extract
from .errors import CosimError, FmuLoadError, ScenarioError
from .scenario import ConnectionSpec, InstanceSpec, Scenario
from .system import Plan

SSP_VERSION = "1.0"
FMU_MIME = "application/x-fmu-sharedlibrary"
SSV_MIME = "application/x-ssp-parameter-set"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "ssm": "http://ssp-standard.org/SSP1/SystemStructureParameterMapping",
}
#: Open Simulation Platform's annotation (libcosim reads the fixed step from it).
OSP_TYPE = "com.opensimulationplatform"
OSP_NS = "http://opensimulationplatform.com/SSP/OSPAnnotations"
#: This master's annotation: the step, the algorithm and the order of a Gauss-Seidel run.
OWN_TYPE = "org.wmr-cosim.experiment"
OWN_NS = "https://wmr-cosim.invalid/ssp/experiment"
#: The name of the parameter set written (one .ssv per component, all with this set name: ecos applies a
#: parameter set by name, ``init(parameter_set="parameters")``; libcosim and this master apply them all).
PARAMETER_SET = "parameters"


# ---------------------------------------------------------------------------------------------- export
def _schema_dir() -> Path:
    """The SSP 1.0 XML schemas shipped with pyssp-standard (located, not imported: importing it costs
    a quarter of a second)."""
    import importlib.util

    spec = importlib.util.find_spec("pyssp_standard")
    if spec is None or not spec.submodule_search_locations:
        raise CosimError("pyssp-standard is not installed (pip install pyssp-standard): it provides the SSP schemas")
    return Path(list(spec.submodule_search_locations)[0]) / "resources"


_SCHEMA_FILES = {"ssd": "SystemStructureDescription.xsd", "ssv": "SystemStructureParameterValues.xsd"}


def _schema(kind: str):
    """The SSP 1.0 schema of an SSD ('ssd') or SSV ('ssv') document (lxml, cached)."""
    from lxml import etree as ET

    cache = _schema.__dict__.setdefault("cache", {})
    if kind not in cache:
        cache[kind] = ET.XMLSchema(ET.parse(str(_schema_dir() / _SCHEMA_FILES[kind])))
    return cache[kind]


def validate_xml(data: bytes, kind: str, where: str) -> None:
    """Validate an SSD ('ssd') or SSV ('ssv') document against the SSP 1.0 schema; ScenarioError (the
    first violation, with its line) if it is not valid."""
    schema = _schema(kind)
    root = _parse_xml(data, where)
    if not schema.validate(root):
        e = schema.error_log[0]
        raise ScenarioError(where, f"line {e.line}",
                            f"not valid against the SSP 1.0 schema: {' '.join(e.message.split())}")


def _fmt(v: float) -> str:
    return repr(float(v))


def _unit_base(unit) -> dict[str, Any]:
    """pyssp-standard BaseUnit attributes of a master Unit (exponents, factor, offset)."""
    from .units import _BASES

    d: dict[str, Any] = {b: e for b, e in zip(_BASES, unit.exps) if e}
    if unit.factor != 1.0:
        d["factor"] = unit.factor
    if unit.offset != 0.0:
        d["offset"] = unit.offset
    return d


def _resource_names(plan: Plan) -> dict[Path, str]:
    """FMU file -> archive entry ``resources/<name>.fmu`` (file names made unique)."""
    out: dict[Path, str] = {}
    used: set[str] = set()
    for ip in plan.instances.values():
        p = ip.model.path.resolve()
        if p in out:
            continue
        stem, name, i = p.stem, p.name, 1
        while name.lower() in used:
            i += 1
            name = f"{stem}_{i}.fmu"
        used.add(name.lower())
        out[p] = f"resources/{name}"
    return out


def _ssv_value(var, value) -> tuple[str, dict[str, str]]:
    t = var.type
    if t == "Real":
        d = {"value": _fmt(value)}
        if var.unit is not None and var.unit.exps:
            d["unit"] = var.unit.name
        return "Real", d
    if t == "Boolean":
        return "Boolean", {"value": "true" if value else "false"}
    if t in ("Integer", "Enumeration"):
        return "Integer", {"value": str(int(value))}
    return "String", {"value": str(value)}


def export_ssp(plan: Plan, out: str | os.PathLike, name: str | None = None) -> Path:
    """Write the resolved ``plan`` as an SSP 1.0 archive ``out``; returns its path.

    Refuses (ScenarioError) what SSP 1.0 cannot express: timed events, and Integer/Boolean connections
    with a linear transform (already refused by the master).
    """
    from lxml import etree as ET
    from pyssp_standard import SSP, SSV
    from pyssp_standard.common_content_ssc import (Annotation, TypeBoolean, TypeInteger, TypeReal,
                                                   TypeString)
    from pyssp_standard.ssd import Component, Connector, DefaultExperiment, ParameterBinding, System
    from pyssp_standard.unit import BaseUnit, Unit

    sc = plan.scenario
    out = Path(out)
    if plan.events:
        raise ScenarioError(sc.file, "events", "timed events cannot be expressed in SSP 1.0: export a scenario "
                                                "without [[events]]")
    name = name or Path(sc.file).stem or "system"
    resources = _resource_names(plan)

    # connectors per instance: FMU variable name -> (kind, Variable)
    conns: dict[str, dict[str, tuple[str, Any]]] = {n: {} for n in plan.order}
    for c in plan.connections:
        conns[c.src].setdefault(c.src_var.name, ("output", c.src_var))
        conns[c.dst].setdefault(c.dst_var.name, ("input", c.dst_var))
    for r in plan.record:
        if r.var.causality in ("output", "input"):
            conns[r.instance].setdefault(r.var.name, (r.var.causality, r.var))
    params: list[tuple[str, Any, Any]] = []
    for n, ip in plan.instances.items():
        for var, value in ip.parameters:
            kind = "input" if var.causality == "input" else "parameter"
            conns[n].setdefault(var.name, (kind, var))
            params.append((n, var, value))

    def unit_of(inst: str, var) -> Any:
        ip = plan.instances[inst]
        declared = ip.spec.units.get(ip.our_name(var)) or ip.spec.units.get(var.name)
        if declared:
            from .units import lookup, units_of
            return lookup(declared, units_of(ip.model.md))
        return var.unit

    tmp = Path(tempfile.mkdtemp(prefix="wmr-cosim-ssp-"))
    try:
        ssd_path = tmp / "SystemStructure.ssd"
        units: dict[str, Any] = {}
        with _ordered_ssd()(ssd_path, mode="w") as ssd:
            ssd.name, ssd.version = name, SSP_VERSION
            ssd.top_level_metadata.generationTool = "wmr-cosim"
            system = System(name=name)
            for inst, ip in plan.instances.items():
                comp = Component()
                comp.name, comp.component_type, comp.source = inst, FMU_MIME, resources[ip.model.path.resolve()]
                for vname, (kind, var) in conns[inst].items():
                    if var.type == "Real":
                        u = unit_of(inst, var)
                        typ = TypeReal(u.name if u is not None and u.exps else None)
                        if u is not None and u.exps:
                            units[u.name] = u
                    elif var.type == "Boolean":
                        typ = TypeBoolean()
                    elif var.type in ("Integer", "Enumeration"):
                        typ = TypeInteger()
                    else:
                        typ = TypeString()
                    comp.connectors.append(Connector(name=vname, kind=kind, type_=typ))
                if any(i == inst for i, _, _ in params):
                    comp.parameter_bindings = [ParameterBinding(source=f"resources/{inst}.ssv")]
                system.elements.append(comp)
            for c in plan.connections:
                system.connections.append(_LinearConnection(
                    start_element=c.src, start_connector=c.src_var.name, end_element=c.dst,
                    end_connector=c.dst_var.name, factor=c.spec.factor, offset=c.spec.offset))
            ssd.system = system
            de = DefaultExperiment()
            de.start_time, de.stop_time = sc.start, sc.stop
            osp = Annotation(OSP_TYPE)
            alg = ET.SubElement(osp.root, f"{{{OSP_NS}}}Algorithm")
            ET.SubElement(alg, f"{{{OSP_NS}}}FixedStepAlgorithm", baseStepSize=_fmt(sc.step))
            own = Annotation(OWN_TYPE)
            ET.SubElement(own.root, f"{{{OWN_NS}}}Experiment", step=_fmt(sc.step),
                          algorithm=sc.algorithm, order=" ".join(sc.order))
            de.annotations.add_annotation(osp)
            de.annotations.add_annotation(own)
            ssd.default_experiment = de
            for u in units.values():
                ssd.units.add_unit(Unit(u.name, base_unit=BaseUnit(_unit_base(u))))
        validate_xml(ssd_path.read_bytes(), "ssd", f"{out}: SystemStructure.ssd (as written)")

        ssvs: dict[str, bytes] = {}
        for inst in plan.order:
            mine = [(var, value) for i, var, value in params if i == inst]
            if not mine:
                continue
            ssv_path = tmp / f"{inst}.ssv"
            with SSV(ssv_path, mode="w") as ssv:
                ssv.ssv_elem.name = PARAMETER_SET  # (pyssp-standard 0.9's property setter drops it)
                ssv.ssv_elem.top_level_metadata.generationTool = "wmr-cosim"
                for var, value in mine:
                    typ, attrs = _ssv_value(var, value)
                    ssv.add_parameter(var.name, typ, value=attrs["value"], unit=attrs.get("unit"))
            ssvs[f"resources/{inst}.ssv"] = ssv_path.read_bytes()
            validate_xml(ssvs[f"resources/{inst}.ssv"], "ssv", f"{out}: resources/{inst}.ssv (as written)")

        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_name(out.name + ".part")
        part.unlink(missing_ok=True)
        with SSP(part, mode="w") as ssp:
            shutil.copyfile(ssd_path, ssp.get_file_temp_path("SystemStructure.ssd"))
            ssp.mark_changed()
            for src, entry in resources.items():
                ssp.add_file_contents(src.read_bytes(), PurePosixPath(entry))
            for entry, data in ssvs.items():
                ssp.add_file_contents(data, PurePosixPath(entry))
        os.replace(part, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _ordered_ssd():
    """pyssp-standard's SSD, writing Units before DefaultExperiment as the SSP 1.0 schema requires
    (pyssp-standard 0.9 writes them after it)."""
    from lxml import etree as ET
    from pyssp_standard.ssd import SSD

    class _SSD(SSD):
        def __write__(self):
            super().__write__()
            units = self.root.find("ssd:Units", NS)
            de = self.root.find("ssd:DefaultExperiment", NS)
            if units is not None and de is not None:
                de.addprevious(units)
            # the annotations' namespaces declared once, at the root: libcosim takes a namespace
            # declaration on its osp:Algorithm element for an algorithm and fails
            ET.cleanup_namespaces(self.root, top_nsmap={"osp": OSP_NS, "wmr": OWN_NS})

    return _SSD


class _LinearConnection:
    """A pyssp-standard Connection that also writes its LinearTransformation (pyssp-standard 0.9 drops
    it when writing)."""

    def __new__(cls, *, factor: float, offset: float, **kw):
        from lxml import etree as ET
        from pyssp_standard.ssd import Connection

        class _C(Connection):
            def as_element(self):
                el = super().as_element()
                if factor != 1.0 or offset != 0.0:
                    ET.SubElement(el, f"{{{NS['ssc']}}}LinearTransformation", factor=_fmt(factor), offset=_fmt(offset))
                return el

        return _C(**kw)


# ---------------------------------------------------------------------------------------------- import
@dataclass
class SspArchive:
    """An imported SSP archive: the scenario it describes and the folder it was extracted into (the
    caller removes it with :meth:`cleanup` once the run is over)."""

    scenario: Scenario
    folder: Path

    def cleanup(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def _parse_xml(data: bytes, where: str):
    from lxml import etree as ET

    try:
        root = ET.fromstring(data, ET.XMLParser(resolve_entities=False, no_network=True))
    except ET.XMLSyntaxError as exc:
        raise ScenarioError(where, "", f"not well-formed XML ({' '.join(str(exc).split())})") from None
    # an external entity can read a local file, nested internal ones expand without bound; SSP needs neither
    dtd = root.getroottree().docinfo.internalDTD
    entities = list(dtd.iterentities()) if dtd is not None else []
    if entities:
        raise ScenarioError(where, "", f"declares the XML entity {entities[0].name!r}: refused (entities can read "
                                       "local files or expand without bound)")
    return root


def _typed(elem, where: str, fld: str) -> Any:
    """The value of an ssv:Real/Integer/Boolean/String/Enumeration element as a Python value."""
    from lxml import etree as ET

    kind = ET.QName(elem).localname
    v = elem.get("value")
    if v is None:
        raise ScenarioError(where, fld, f"{kind} without a value")
    try:
        if kind == "Real":
            return float(v)
        if kind in ("Integer", "Enumeration"):
            return int(v)
        if kind == "Boolean":
            if v.strip() not in ("true", "false", "1", "0"):
                raise ValueError(v)
            return v.strip() in ("true", "1")
        if kind == "String":
            return v
    except ValueError:
        raise ScenarioError(where, fld, f"{v!r} is not a valid {kind}") from None
    raise ScenarioError(where, fld, f"parameters of type {kind} are not supported")


def _parameter_set(root, where: str) -> list[tuple[str, Any]]:
    out = []
    for p in root.findall("ssv:Parameters/ssv:Parameter", NS):
        pname = p.get("name")
        kids = [k for k in p if isinstance(k.tag, str)]
        if not pname or not kids:
            raise ScenarioError(where, f"Parameter {pname!r}", "a parameter needs a name and a value")
        out.append((pname, _typed(kids[0], where, f"Parameter {pname}")))
    return out


def _bindings(owner, archive: Path, folder: Path, where: str, base: str) -> list[tuple[str, Any]]:
    """(name, value) of every ParameterBinding of a System or Component; names with the binding's prefix
    removed.  ``base`` is the folder of the SSD inside the archive (sourceBase="SSD")."""
    out: list[tuple[str, Any]] = []
    for b in owner.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        typ = b.get("type", SSV_MIME)
        if typ != SSV_MIME:
            raise ScenarioError(where, "ParameterBinding", f"type {typ!r} is not supported (only {SSV_MIME})")
        if b.find("ssd:ParameterMapping", NS) is not None:
            raise ScenarioError(where, "ParameterBinding", "parameter mappings (.ssm) are not supported")
        prefix = b.get("prefix") or ""
        src = b.get("source")
        sets = []
        if src is not None:
            if b.get("sourceBase", "SSD") == "component":
                raise ScenarioError(where, "ParameterBinding", f"{src}: sourceBase=\"component\" is not supported")
            entry = (PurePosixPath(base) / src).as_posix() if base else src
            f = folder / entry
            if ".." in PurePosixPath(entry).parts or not f.is_file():
                raise ScenarioError(where, "ParameterBinding", f"parameter file {src!r} is missing from the archive")
            data = f.read_bytes()
            validate_xml(data, "ssv", f"{archive}: {entry}")
            sets.append((_parse_xml(data, f"{archive}: {entry}"), f"{archive}: {entry}"))
        for inline in b.findall("ssd:ParameterValues/ssv:ParameterSet", NS):
            sets.append((inline, where))
        for root, w in sets:
            for pname, value in _parameter_set(root, w):
                if prefix:
                    if not pname.startswith(prefix):
                        continue
                    pname = pname[len(prefix):]
                out.append((pname, value))
    return out


def _step_from_annotations(root) -> tuple[float | None, str | None, list[str] | None]:
    step = algorithm = order = None
    for de in root.findall("ssd:DefaultExperiment", NS):
        for a in de.iter(f"{{{OWN_NS}}}Experiment"):
            try:
                step = float(a.get("step"))
            except (TypeError, ValueError):
                pass
            algorithm = a.get("algorithm")
            order = (a.get("order") or "").split() or None
        if step is None:
            for a in de.iter(f"{{{OSP_NS}}}FixedStepAlgorithm"):
                try:
                    step = float(a.get("baseStepSize"))
                except (TypeError, ValueError):
                    pass
    return step, algorithm, order


def load_ssp(path: str | os.PathLike, *, step: float | None = None, stop: float | None = None,
             algorithm: str | None = None, overrides: dict[str, Any] | None = None) -> SspArchive:
    """Read an SSP 1.0 archive into a Scenario (FMUs extracted into a temporary folder).

    ``step``, ``stop``, ``algorithm`` override what the archive says; ``overrides`` ({'inst.param': value})
    override its parameter values.  The step, when neither given nor annotated, is the FMUs' common
    default experiment step.  Raises ScenarioError (one line) for anything unsafe, foreign or missing.
    """
    from lxml import etree as ET

    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise ScenarioError(where, "", "file not found")
    try:
        infos = check_archive(path)
    except FmuLoadError as exc:
        raise ScenarioError(where, "", str(exc).replace(f"{path}: ", "", 1)) from None
    names = {i.filename for i in infos}
    if "SystemStructure.ssd" not in names:
        raise ScenarioError(where, "", "no SystemStructure.ssd at the top of the archive: not an SSP file")
    with zipfile.ZipFile(path) as zf:
        ssd_bytes = zf.read("SystemStructure.ssd")
        # the FMUs inside are archives too: every one checked before anything is extracted (their
        # directories read through a stream, not into memory)
        for info in infos:
            if info.filename.lower().endswith(".fmu"):
                try:
                    with zf.open(info) as stream, zipfile.ZipFile(stream) as inner:
                        check_entries(f"{info.filename} in the archive", inner.infolist())
                        check_sizes(f"{info.filename} in the archive", inner.infolist(), info.file_size)
                except zipfile.BadZipFile as exc:
                    raise ScenarioError(where, info.filename, f"not a zip archive ({exc})") from None
                except FmuLoadError as exc:
                    raise ScenarioError(where, "", str(exc)) from None
    root = _parse_xml(ssd_bytes, f"{where}: SystemStructure.ssd")
    if root.tag != _q("ssd", "SystemStructureDescription"):
        ns = ET.QName(root).namespace or "no namespace"
        raise ScenarioError(where, "SystemStructure.ssd",
                            f"root element {ET.QName(root).localname} in {ns}: not an SSP 1.0 system structure "
                            f"(only SSP {SSP_VERSION} is supported)")
    version = root.get("version")
    if version != SSP_VERSION:
        raise ScenarioError(where, "SystemStructure.ssd",
                            f"SSP version {version!r}: only SSP {SSP_VERSION} is supported")
    validate_xml(ssd_bytes, "ssd", f"{where}: SystemStructure.ssd")

    system = root.find("ssd:System", NS)
    if system is None:
        raise ScenarioError(where, "System", "no System element")
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise ScenarioError(where, "System", "nested systems are not supported")
    if system.find("ssd:Elements/ssd:SignalDictionaryReference", NS) is not None:
        raise ScenarioError(where, "System", "signal dictionaries are not supported")

    folder = Path(tempfile.mkdtemp(prefix="wmr-cosim-ssp-"))
    ok = False
    try:
        try:
            safe_extract(path, folder / "archive")
        except FmuLoadError as exc:
            raise ScenarioError(where, "", str(exc)) from None
        arch = folder / "archive"
        sc = Scenario(file=where)
        sc.data = {"ssp": where, "name": root.get("name")}
        comps = system.findall("ssd:Elements/ssd:Component", NS)
        if not comps:
            raise ScenarioError(where, "System", "no components")
        connectors: dict[tuple[str, str], Any] = {}
        models: dict[str, Any] = {}
        comp_params: list[tuple[str, str, Any]] = []
        for comp in comps:
            cname = comp.get("name")
            fld = f"Component {cname}"
            if not cname or not cname.isidentifier():
                raise ScenarioError(where, fld, "a component name must be an identifier for this master")
            if cname in sc.instances:
                raise ScenarioError(where, fld, "two components with this name")
            ctype = comp.get("type", FMU_MIME)
            if ctype != FMU_MIME:
                raise ScenarioError(where, fld, f"type {ctype!r}: only FMUs ({FMU_MIME}) are supported")
            if comp.get("implementation", "CoSimulation") not in ("CoSimulation", "any"):
                raise ScenarioError(where, fld, f"implementation {comp.get('implementation')!r}: only co-simulation "
                                                "is supported")
            src = comp.get("source") or ""
            entry = src[2:] if src.startswith("./") else src
            if "://" in entry or entry.startswith("/") or ".." in PurePosixPath(entry).parts or "#" in entry:
                raise ScenarioError(where, f"{fld}.source", f"{src!r}: only FMUs inside the archive are supported")
            fmu = arch / entry
            if not entry or not fmu.is_file():
                raise ScenarioError(where, f"{fld}.source", f"resource {src!r} is missing from the archive")
            try:
                from .model import load_model
                model = load_model(fmu)
            except FmuLoadError as exc:
                raise ScenarioError(where, f"{fld}.source", f"{src}: {str(exc).replace(f'{fmu}: ', '', 1)}") from None
            units: dict[str, str] = {}
            for con in comp.findall("ssd:Connectors/ssd:Connector", NS):
                cn = con.get("name")
                if cn not in model.variables:
                    raise ScenarioError(where, f"{fld}.Connector {cn}",
                                        f"unknown connector: {src} has no variable {cn!r}")
                connectors[(cname, cn)] = con
                real = con.find("ssc:Real", NS)
                if real is not None and real.get("unit"):
                    units[cn] = real.get("unit")
            sc.instances[cname] = InstanceSpec(cname, str(fmu), fmu, {}, {}, units)
            models[cname] = model
            for pname, value in _bindings(comp, path, arch, where, ""):
                comp_params.append((cname, pname, value))

        # parameters: system-level bindings address "component.variable"; component-level ones the variable
        for pname, value in _bindings(system, path, arch, where, ""):
            inst, dot, var = pname.partition(".")
            if not dot or inst not in sc.instances:
                raise ScenarioError(where, f"parameter {pname}", "names no component of the system (expected "
                                                                  "\"component.variable\")")
            comp_params.append((inst, var, value))
        for inst, var, value in comp_params:
            if var not in models[inst].variables:
                raise ScenarioError(where, f"parameter {inst}.{var}", f"{inst} has no variable {var!r}")
            sc.instances[inst].parameters[var] = value
        for ref, value in (overrides or {}).items():
            inst, dot, var = ref.partition(".")
            if not dot or inst not in sc.instances:
                raise ScenarioError(where, f"--set {ref}", f"unknown instance {inst!r}")
            sc.instances[inst].parameters[var] = value

        for i, c in enumerate(system.findall("ssd:Connections/ssd:Connection", NS)):
            fld = f"Connection[{i}]"
            se, scn, ee, ecn = (c.get(k) for k in ("startElement", "startConnector", "endElement", "endConnector"))
            if se is None or ee is None:
                raise ScenarioError(where, fld, "connections to the system's own connectors are not supported")
            for el, cn in ((se, scn), (ee, ecn)):
                if el not in sc.instances:
                    raise ScenarioError(where, fld, f"unknown component {el!r}")
                if (el, cn) not in connectors:
                    raise ScenarioError(where, fld, f"unknown connector {el}.{cn} (not declared by the component)")
            factor, offset = 1.0, 0.0
            lt = c.find("ssc:LinearTransformation", NS)
            if lt is not None:
                factor, offset = float(lt.get("factor", 1.0)), float(lt.get("offset", 0.0))
            elif len([k for k in c if isinstance(k.tag, str) and ET.QName(k).localname.endswith("Transformation")]):
                raise ScenarioError(where, fld, "only LinearTransformation is supported")
            if c.get("suppressUnitConversion") == "true":
                raise ScenarioError(where, fld, "suppressUnitConversion is not supported")
            sc.connections.append(ConnectionSpec(f"{se}.{scn}", f"{ee}.{ecn}", factor, offset, i))

        a_step, a_alg, a_order = _step_from_annotations(root)
        de = root.find("ssd:DefaultExperiment", NS)
        sc.start = float(de.get("startTime", 0.0)) if de is not None else 0.0
        sc.stop = stop if stop is not None else (float(de.get("stopTime")) if de is not None and de.get("stopTime")
                                                 else math.nan)
        if not math.isfinite(sc.stop):
            steps = {m.md.defaultExperiment.stopTime for m in models.values() if m.md.defaultExperiment is not None}
            sc.stop = float(next(iter(steps))) if len(steps) == 1 and None not in steps else math.nan
        if not math.isfinite(sc.stop) or sc.stop <= sc.start:
            raise ScenarioError(where, "DefaultExperiment", "no stop time after the start (give one with --stop)")
        h = step if step is not None else a_step
        if h is None:
            defaults = {m.default_step for m in models.values()}
            defaults.discard(None)
            if len(defaults) != 1:
                raise ScenarioError(where, "DefaultExperiment", "no communication step in the archive and the FMUs "
                                                                 "declare no common default: give one with --step")
            h = defaults.pop()
        if not h > 0:
            raise ScenarioError(where, "DefaultExperiment", f"step {h!r}: must be > 0")
        sc.step = float(h)
        n = (sc.stop - sc.start) / sc.step
        if abs(n - round(n)) > 1e-6 * max(1.0, n):
            raise ScenarioError(where, "DefaultExperiment", f"step {sc.step!r} s does not divide the run "
                                                             f"{sc.start!r}..{sc.stop!r} s into whole steps")
        sc.algorithm = algorithm or a_alg or "jacobi"
        if sc.algorithm not in ("gauss-seidel", "jacobi"):
            raise ScenarioError(where, "algorithm", f"{sc.algorithm!r}: must be gauss-seidel or jacobi")
        sc.order = a_order if a_order and sorted(a_order) == sorted(sc.instances) else list(sc.instances)
        # record every connector that is an output (what other SSP tools report), else all outputs
        outs = [f"{i}.{n}" for (i, n), con in connectors.items() if con.get("kind") == "output"]
        sc.record = outs or ["*.*"]
        ok = True
        return SspArchive(sc, folder)
    finally:
        if not ok:
            shutil.rmtree(folder, ignore_errors=True)


def is_ssp(path: str | os.PathLike) -> bool:
    return str(path).lower().endswith(".ssp")


__all__ = ["export_ssp", "load_ssp", "SspArchive", "validate_xml", "is_ssp", "CosimError"]
