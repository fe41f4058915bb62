"""SSP 1.0 (System Structure and Parameterization) archives: export a resolved plan, import an archive.

Generic: nothing here knows the FMUs it packs.

**Export** (:func:`export_ssp`) writes, with the ``pyssp-standard`` library:

- ``resources/<file>.fmu``: every FMU of the plan (one copy per file);
- ``SystemStructure.ssd``: one System with one Component per instance (``application/x-fmu-sharedlibrary``;
  ``implementation="ModelExchange"`` for an instance run as model exchange, whose integrator's settings SSP
  1.0 cannot say), its Connectors (the connected inputs and outputs, the recorded outputs and the parameters
  set, under the FMU's own variable names, Real ones with their units, defined in the SSD's Units), the
  Connections with a ``LinearTransformation`` where the scenario gives a factor or an offset (unit
  conversion is left to the connectors' units, as SSP prescribes), and a DefaultExperiment (start, stop)
  whose annotations carry the step: Open Simulation Platform's ``osp:FixedStepAlgorithm baseStepSize`` (read
  by libcosim and by this module) and this master's own ``algorithm``/``order``/``step`` (and ``workers``).
  The System's annotations: OpenModelica's ``oms:SimulationInformation`` with a ``FixedStepMaster`` at the
  step (OMSimulator takes the system's type from it and aborts without one; its master is a Jacobi one),
  then this master's own annotation holding the String parameters left out of the parameter sets
  (:func:`held_strings`);
- ``resources/<instance>.ssv``: the parameter values as one SSV parameter set named ``parameters``, one
  file per component, bound to the component (names without prefix).  This is the form that libcosim and
  ecos both apply (neither applies a system-level binding nor a prefix; measured).  A String parameter
  whose value is the FMU's default is left out of it and of the connectors (OMSimulator imports neither a
  String connector nor a String parameter); :func:`export_remarks` says what an export changes for other
  tools.

Both XML files are validated against the SSP 1.0 schemas before the archive is written.

**Import** (:func:`load_ssp`) reads an SSP 1.0 archive written by this module or another tool into the
master's :class:`~.scenario.Scenario` (so :func:`.resolution.resolve` checks it against the FMUs and
``runtime.execution.run`` runs it): the archive is checked for unsafe entries before anything is extracted,
the SSD is validated against the schema, components must be FMUs inside the archive (a component's
``implementation`` CoSimulation or ModelExchange is the instance's ``interface``; "any" leaves it to the
FMU, see :func:`.resolution.resolve`), parameter bindings (inline or in .ssv files, on the system or on
components, with or without prefix) become parameters, and so do the String parameters that this module's
export held back into its own annotation on the system, connections (with their LinearTransformation)
become connections, connector units become declared units, the DefaultExperiment gives start and stop, the
step comes from the annotations or from the FMUs' default experiments (or ``step=``).  Every problem is a one-line :class:`~.errors.ScenarioError`.
"""
from __future__ import annotations

import os
import shutil
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from ..messages.errors import CosimError, FmuLoadError, ScenarioError
from ..model.archive import ArchiveLimits, LimitOverrides, check_archive, check_entries, check_sizes, safe_extract
from ..model.description import CO_SIMULATION, INTERFACE_NAMES, MODEL_EXCHANGE, SCHEDULED_EXECUTION, load_model
from ..model.kinds import FileKind, file_kind
from ..scenario.document import Scenario, apply_overrides, parse
from ..stepping import table as algorithms
from .records import Plan, unit_of

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
#: This master's annotation: the step, the algorithm and the order of a Gauss-Seidel run, the workers that
#: step instances at once.
OWN_TYPE = "org.wmr-cosim.experiment"
OWN_NS = "https://wmr-cosim.invalid/ssp/experiment"
#: OMSimulator's annotation on ``ssd:System``: it takes a system's type (here its fixed-step co-simulation
#: master ``oms-ma``, a Jacobi master) and step only from it, and aborts without one.  It matches the
#: prefixes literally (``ssc:Annotation``, ``oms:Annotations``, ``oms:FixedStepMaster``) and reads only the
#: first annotation of the system: this one is written first, under the prefix ``oms``.
OMS_TYPE = "org.openmodelica"
OMS_NS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
#: This master's annotation on ``ssd:System`` holding the String parameters left out of the parameter sets
#: (see :func:`held_strings`), so that importing the archive here loses none of them.
OWN_PARAMETERS_TYPE = "org.wmr-cosim.parameters"
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
    from ..model.units import BASES

    d: dict[str, Any] = {b: e for b, e in zip(BASES, unit.exps) if e}
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
    if var.is_integer:
        return "Integer", {"value": str(int(value))}
    return "String", {"value": str(value)}


def export_ssp(plan: Plan, out: str | os.PathLike, name: str | None = None) -> Path:
    """Write the resolved ``plan`` as an SSP 1.0 archive ``out``; returns its path.

    Refuses (ScenarioError) what SSP 1.0 cannot express: timed events, Integer/Boolean connections
    with a linear transform (already refused by the master), scheduled execution, and clocks other than
    periodic input clocks (those tick from the FMU's own declaration).
    """
    sc = plan.scenario
    out = Path(out)
    if plan.events or plan.conditions:
        raise ScenarioError(sc.file, "events", "events cannot be expressed in SSP 1.0 (timed or on conditions): "
                                                "export a scenario without [[events]]")
    for n, ip in plan.instances.items():   # (its clock_ticks have no place in SSP 1.0: the archive could not run)
        if ip.interface == SCHEDULED_EXECUTION:
            raise ScenarioError(sc.file, f"instances.{n}", f"{ip.model.path.name} runs as scheduled execution, which "
                                                           "cannot be exported to SSP yet (its clock_ticks have no "
                                                           "place in SSP 1.0)")
        if any(not (c.periodic and c.causality == "input") for c in ip.model.clocks):
            # (periodic input clocks alone need nothing of the system: the FMU's own declaration ticks them)
            raise ScenarioError(sc.file, f"instances.{n}", f"{ip.model.path.name} has clocks, which cannot be exported "
                                                           "to SSP yet (SSP 1.0 has no connections between clocks)")
    name = name or Path(sc.file).stem or "system"
    resources = _resource_names(plan)
    conns, params = _connectors(plan)
    held = held_strings(plan)
    params = [p for p in params if not any(p[0] == i and p[1] is v for i, v, _ in held)]
    for inst, var, _ in held:  # (a String can be neither connected nor recorded: the connector is the parameter's)
        conns[inst].pop(var.name, None)
    tmp = Path(tempfile.mkdtemp(prefix="wmr-cosim-ssp-"))
    try:
        ssd_path = tmp / "SystemStructure.ssd"
        _write_ssd(plan, name, resources, conns, {i for i, _, _ in params}, held, ssd_path)
        validate_xml(ssd_path.read_bytes(), "ssd", f"{out}: SystemStructure.ssd (as written)")
        ssvs = _write_ssvs(plan, params, tmp, out)
        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_name(out.name + ".part")
        part.unlink(missing_ok=True)
        from pyssp_standard import SSP

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


def held_strings(plan: Plan) -> list[tuple[str, Any, str]]:
    """The String parameters that the export leaves out of the parameter sets and the connectors, as
    (instance, Variable, value): the scalar ones whose value is the FMU's own start value.

    OMSimulator (2.1) imports neither a String connector nor an ``ssv:String`` parameter (it logs an error
    for each); left out, every tool runs such a parameter alike (at the FMU's default), and this master reads
    it back from its own annotation (:data:`OWN_PARAMETERS_TYPE`).  A String parameter set to any other value
    stays in the parameter set, where libcosim, ecos and this master apply it (see :func:`export_remarks`)."""
    return [(n, var, value) for n, ip in plan.instances.items() for var, value in ip.parameters
            if var.type == "String" and not var.shape and value == var.start]


def export_remarks(plan: Plan) -> list[tuple[str, str]]:
    """What an export of ``plan`` changes for other tools, as (kind, one line); kind 'warning' or 'note'.

    - each String parameter: left out of the parameter set (its value is the FMU's default) or kept there
      (OMSimulator cannot set it, and runs with the FMU's default);
    - a Gauss-Seidel scenario: OMSimulator's fixed-step master is a Jacobi master;
    - an instance run as model exchange: the archive says so, not with which integrator."""
    out: list[tuple[str, str]] = []
    for n, ip in plan.instances.items():
        if ip.interface == MODEL_EXCHANGE:
            out.append(("note", f"{n} runs as model exchange ({ip.describe()}): the archive says "
                                "implementation=\"ModelExchange\"; SSP 1.0 has no place for the integrator's "
                                "settings (other tools use their own)"))
    held = {(i, v.name) for i, v, _ in held_strings(plan)}
    for n, ip in plan.instances.items():
        for var, value in ip.parameters:
            if var.type != "String":
                continue
            what = f"{n}.{var.name} = {value!r} (String)"
            if (n, var.name) in held:
                out.append(("warning", f"{what} is left out of the parameter set and the connectors (OMSimulator "
                                       f"cannot import a String); it is the FMU's default, so every tool runs "
                                       f"with it, and this master reads it back from its own annotation"))
            else:
                out.append(("warning", f"{what} stays in the parameter set (libcosim, ecos and this master apply "
                                       f"it); OMSimulator cannot set a String parameter: it logs an error and "
                                       f"runs with the FMU's default {var.start!r}"))
    sc = plan.scenario
    if algorithms.row(sc.algorithm).settings:
        out.append(("note", f"algorithm = \"{sc.algorithm}\" and its settings are kept in this master's own "
                            f"annotation ({OWN_TYPE}), which only this master reads: SSP 1.0 has no place for a "
                            f"master's coupling iteration or step-size control, and other tools run the system "
                            f"with their own fixed-step master (OMSimulator's oms-ma, libcosim's fixed step)"))
    if plan.scenario.algorithm == algorithms.GAUSS_SEIDEL:
        out.append(("note", "OMSimulator runs the archive as Jacobi (its fixed-step master, oms-ma): its results "
                            f"equal this master's run with algorithm = {algorithms.quoted(algorithms.JACOBI)}, not "
                            "this Gauss-Seidel run"))
    return out


def _connectors(plan: Plan) -> tuple[dict[str, dict[str, tuple[str, Any]]], list[tuple[str, Any, Any]]]:
    """Per instance, FMU variable name -> (connector kind, Variable): the connected inputs and outputs, the
    recorded ones and the parameters set; and the parameters as (instance, Variable, value)."""
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
            conns[n].setdefault(var.name, ("input" if var.causality == "input" else "parameter", var))
            params.append((n, var, value))
    return conns, params


def _write_ssd(plan: Plan, name: str, resources: dict[Path, str], conns, with_params: set[str],
               held: list[tuple[str, Any, str]], path: Path) -> None:
    """SystemStructure.ssd: components with their connectors, connections, the system's annotations
    (OMSimulator's master and step, then the String parameters held back), units, default experiment."""
    from pyssp_standard.common_content_ssc import TypeBoolean, TypeInteger, TypeReal, TypeString
    from pyssp_standard.ssd import Component, Connector, ParameterBinding, System
    from pyssp_standard.unit import BaseUnit, Unit

    units: dict[str, Any] = {}
    with _ordered_ssd()(path, mode="w") as ssd:
        ssd.name, ssd.version = name, SSP_VERSION
        ssd.top_level_metadata.generationTool = "wmr-cosim"
        system = System(name=name)
        for inst, ip in plan.instances.items():
            comp = _RatedComponent(ip.spec.step if ip.decimation > 1 else None)
            comp.name, comp.component_type, comp.source = inst, FMU_MIME, resources[ip.model.path.resolve()]
            if ip.interface == MODEL_EXCHANGE:
                comp.implementation = "ModelExchange"
            for vname, (kind, var) in conns[inst].items():
                if var.type == "Real":
                    u = unit_of(ip, var)
                    typ = TypeReal(u.name if u is not None and u.exps else None)
                    if u is not None and u.exps:
                        units[u.name] = u
                else:
                    typ = {"Boolean": TypeBoolean, "Integer": TypeInteger, "Enumeration": TypeInteger}.get(
                        var.type, TypeString)()
                comp.connectors.append(Connector(name=vname, kind=kind, type_=typ))
            if inst in with_params:
                comp.parameter_bindings = [ParameterBinding(source=f"resources/{inst}.ssv")]
            system.elements.append(comp)
        for c in plan.connections:
            system.connections.append(_LinearConnection(
                start_element=c.src, start_connector=c.src_var.name, end_element=c.dst,
                end_connector=c.dst_var.name, factor=c.spec.factor, offset=c.spec.offset))
        for a in _system_annotations(plan.scenario, held):
            system.annotations.add_annotation(a)
        ssd.system = system
        ssd.default_experiment = _default_experiment(plan.scenario)
        for u in units.values():
            ssd.units.add_unit(Unit(u.name, base_unit=BaseUnit(_unit_base(u))))


def _RatedComponent(step: float | None):
    """A pyssp-standard Component that also writes OSP's StepSizeHint annotation for an instance with a
    step of its own (libcosim takes its decimation factor from it; this master reads it back)."""
    from lxml import etree as ET
    from pyssp_standard.common_content_ssc import Annotation, Annotations
    from pyssp_standard.ssd import Component

    class Rated(Component):
        def as_element(self):
            element = super().as_element()
            if step is not None:
                osp = Annotation(OSP_TYPE)
                ET.SubElement(osp.root, f"{{{OSP_NS}}}StepSizeHint", value=_fmt(step))
                annotations = Annotations("ssd")
                annotations.add_annotation(osp)
                element.append(annotations.element())
            return element

    return Rated()


def _system_annotations(sc: Scenario, held: list[tuple[str, Any, str]]) -> list:
    """The System's annotations: OMSimulator's first (the only one it reads), with its fixed-step master
    (``oms-ma``, Jacobi) at the scenario's step [s]; then, if any, the String parameters held back from the
    parameter sets (:func:`held_strings`), for this master."""
    from lxml import etree as ET
    from pyssp_standard.common_content_ssc import Annotation

    oms = Annotation(OMS_TYPE)
    info = ET.SubElement(ET.SubElement(oms.root, f"{{{OMS_NS}}}Annotations"), f"{{{OMS_NS}}}SimulationInformation")
    ET.SubElement(info, f"{{{OMS_NS}}}FixedStepMaster", description="oms-ma", stepSize=_fmt(sc.times()[2]))
    out = [oms]
    if held:
        own = Annotation(OWN_PARAMETERS_TYPE)
        for inst, var, value in held:
            ET.SubElement(own.root, f"{{{OWN_NS}}}String", component=inst, name=var.name, value=str(value))
        out.append(own)
    return out


def _default_experiment(sc: Scenario):
    """The DefaultExperiment (start, stop) with the step in OSP's annotation and this master's own."""
    from lxml import etree as ET
    from pyssp_standard.common_content_ssc import Annotation
    from pyssp_standard.ssd import DefaultExperiment

    de = DefaultExperiment()
    de.start_time, de.stop_time = sc.start, sc.stop
    osp = Annotation(OSP_TYPE)
    alg = ET.SubElement(osp.root, f"{{{OSP_NS}}}Algorithm")
    ET.SubElement(alg, f"{{{OSP_NS}}}FixedStepAlgorithm", baseStepSize=_fmt(sc.times()[2]))
    own = Annotation(OWN_TYPE)
    exp = ET.SubElement(own.root, f"{{{OWN_NS}}}Experiment", step=_fmt(sc.times()[2]), algorithm=sc.algorithm,
                        order=" ".join(sc.order))
    if sc.workers > 1:
        exp.set("workers", str(sc.workers))
    for t in algorithms.TABLES:
        spec = sc.settings.get(t.name)
        if spec is not None:
            ET.SubElement(exp, f"{{{OWN_NS}}}{t.tag}",
                          {k: (_fmt(v) if isinstance(v, float) else str(v))
                           for k, v in spec.as_dict().items() if v is not None})
    de.annotations.add_annotation(osp)
    de.annotations.add_annotation(own)
    return de


def _write_ssvs(plan: Plan, params: list[tuple[str, Any, Any]], tmp: Path, out: Path) -> dict[str, bytes]:
    """One parameter set per component with parameters: archive entry -> the validated SSV document."""
    from pyssp_standard import SSV

    class _SSV(SSV):
        def __write__(self):  # pyssp-standard 0.9 never writes the top-level metadata of an SSV
            super().__write__()
            self.root.set("generationTool", "wmr-cosim")

    ssvs: dict[str, bytes] = {}
    for inst in plan.order:
        mine = [(var, value) for i, var, value in params if i == inst]
        if not mine:
            continue
        ssv_path = tmp / f"{inst}.ssv"
        with _SSV(ssv_path, mode="w") as ssv:
            ssv.ssv_elem.name = PARAMETER_SET  # (pyssp-standard 0.9's property setter drops it)
            for var, value in mine:
                # SSP 1.0 has no array values: an FMI 3.0 array travels as one parameter per element,
                # named as FMI 3.0 names them (x[1], A[1,2], ...); load_ssp joins them back
                items = zip(var.element_names(), value) if var.shape else [(var.name, value)]
                for name, x in items:
                    typ, attrs = _ssv_value(var, x)
                    ssv.add_parameter(name, typ, value=attrs["value"], unit=attrs.get("unit"))
                    # pyssp-standard 0.9 keeps unit=None as an attribute of a Real and fails writing it
                    pt = ssv.parameters[-1]["type_value"]
                    pt.parameter = {k: v for k, v in dict(pt.parameter).items() if v is not None}
        ssvs[f"resources/{inst}.ssv"] = ssv_path.read_bytes()
        validate_xml(ssvs[f"resources/{inst}.ssv"], "ssv", f"{out}: resources/{inst}.ssv (as written)")
    return ssvs


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
            # declaration on its osp:Algorithm element for an algorithm and fails; OMSimulator finds its
            # elements by the prefix "oms" (as it finds every SSP element by its usual prefix)
            ET.cleanup_namespaces(self.root, top_nsmap={"osp": OSP_NS, "wmr": OWN_NS, "oms": OMS_NS})

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
    warnings: list[str] = field(default_factory=list)

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
    v = elem.get("value")  # required by the schema, for every type
    try:
        if kind == "Real":
            return float(v)
        if kind in ("Integer", "Enumeration"):
            return int(v)
        if kind == "Boolean":
            if v.strip() not in ("true", "false", "1", "0"):
                raise ValueError
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
        if not pname:
            raise ScenarioError(where, f"Parameter {pname!r}", "a parameter needs a name")
        value = next(k for k in p if isinstance(k.tag, str))  # the schema requires one
        out.append((pname, _typed(value, where, f"Parameter {pname}")))
    return out


def _bindings(owner, folder: Path, where: str) -> list[tuple[str, Any]]:
    """(name, value) of every ParameterBinding of a System or Component; names with the binding's prefix
    removed.  ``folder``: the extracted archive; a source is relative to the SSD (sourceBase="SSD"),
    which is at the archive's top.  ``where``: the archive, as errors name it."""
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
            if b.get("sourceBase") == "component":  # (the default, "SSD", is the one supported)
                raise ScenarioError(where, "ParameterBinding", f"{src}: sourceBase=\"component\" is not supported")
            f = folder / src
            if ".." in PurePosixPath(src).parts or not f.is_file():
                raise ScenarioError(where, "ParameterBinding", f"parameter file {src!r} is missing from the archive")
            data = f.read_bytes()
            validate_xml(data, "ssv", f"{where}: {src}")
            sets.append((_parse_xml(data, f"{where}: {src}"), f"{where}: {src}"))
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


def _join_array_elements(instances: dict[str, dict[str, Any]], where: str, limits: ArchiveLimits) -> None:
    """Parameters named as elements of an FMI 3.0 array (x[1], A[1,2], ...: how export_ssp writes an array,
    SSP 1.0 having no array values) joined into the array's list, row-major; every element must be given."""
    for inst, d in instances.items():
        params = d["parameters"]
        bases = {n[:n.rindex("[")] for n in params if n.endswith("]") and "[" in n}
        if not bases:
            continue
        model = load_model(d["fmu"], limits)
        for base in sorted(bases):
            var = model.variables.get(base)
            if var is None or not var.shape:
                continue  # a scalar whose name has brackets (an FMI 2.0 x[1]): as it is
            names = var.element_names()
            missing = [n for n in names if n not in params]
            if missing or base in params:
                raise ScenarioError(where, f"parameter {inst}.{base}", "an array parameter is given either whole or "
                                    f"as every element ({len(names)}); missing: {', '.join(missing) or 'none'}")
            params[base] = [params.pop(n) for n in names]


def _with_version(root) -> bytes:
    """The SSD with its version attribute set to 1.0 (for the schema check of an SSP 1.0 document)."""
    from lxml import etree as ET

    root.set("version", SSP_VERSION)
    return ET.tostring(root)


#: The keys of this master's annotations of the algorithms' settings that are integers, and those that are
#: words (the others are numbers).
_INTEGER_KEYS = frozenset().union(*(t.integers for t in algorithms.TABLES))
_WORD_KEYS = frozenset().union(*(t.words for t in algorithms.TABLES))


def _stepping_tables(exp, where: str) -> dict[str, dict[str, Any]]:
    """The algorithms' tables of settings (``experiment.iteration``, ``experiment.adaptive``) of this
    master's annotation (its Iteration and Adaptive elements), values typed as the scenario reader takes
    them."""
    out: dict[str, dict[str, Any]] = {}
    for t in algorithms.TABLES:
        tag, key = t.tag, t.name
        el = exp.find(f"{{{OWN_NS}}}{tag}")
        if el is None:
            continue
        table: dict[str, Any] = {}
        for k, v in el.attrib.items():
            try:
                table[k] = v if k in _WORD_KEYS else int(v) if k in _INTEGER_KEYS else float(v)
            except ValueError:
                raise ScenarioError(where, f"Annotation {OWN_TYPE}: {tag}.{k}", f"{v!r} is not a number") from None
        out[key] = table
    return out


def _step_from_annotations(root, where: str = "") -> tuple[float | None, str | None, list[str] | None,
                                                          dict[str, Any]]:
    step = algorithm = order = None
    tables: dict[str, Any] = {}
    for de in root.findall("ssd:DefaultExperiment", NS):
        for a in de.iter(f"{{{OWN_NS}}}Experiment"):
            try:
                step = float(a.get("step"))
            except (TypeError, ValueError):
                pass
            algorithm = a.get("algorithm")
            order = a.get("order", "").split() or None
            settings: dict[str, Any] = dict(_stepping_tables(a, where))
            if a.get("workers") is not None:   # (the scenario's check refuses a value it cannot take)
                try:
                    settings["workers"] = int(a.get("workers"))
                except ValueError:
                    raise ScenarioError(where, f"Annotation {OWN_TYPE}: Experiment.workers",
                                        f"{a.get('workers')!r} is not an integer") from None
            tables = settings
        if step is None:
            for a in de.iter(f"{{{OSP_NS}}}FixedStepAlgorithm"):
                try:
                    step = float(a.get("baseStepSize"))
                except (TypeError, ValueError):
                    pass
    return step, algorithm, order, tables


def load_ssp(path: str | os.PathLike, *, step: float | None = None, stop: float | None = None,
             algorithm: str | None = None, overrides: dict[str, Any] | None = None,
             limits: LimitOverrides | None = None) -> SspArchive:
    """Read an SSP 1.0 archive into a Scenario (FMUs extracted into a temporary folder).

    ``step``, ``stop``, ``algorithm`` override what the archive says; ``overrides`` ({'inst.param': value})
    override its parameter values.  The step, when neither given nor annotated, is the FMUs' common
    default experiment step.  ``limits``: the caller's archive limits (over the defaults) for the archive,
    the FMUs inside it and the scenario's ``archive_limits``.  Raises ScenarioError (one line) for anything
    unsafe, foreign or missing.
    """
    path = Path(path)
    where = str(path)
    lim = limits.over() if limits is not None else ArchiveLimits()
    root, warnings = _read_ssd(path, lim)

    system = root.find("ssd:System", NS)   # (the schema check made sure there is one)
    if system.find("ssd:Elements/ssd:System", NS) is not None:
        raise ScenarioError(where, "System", "nested systems are not supported")
    if system.find("ssd:Elements/ssd:SignalDictionaryReference", NS) is not None:
        raise ScenarioError(where, "System", "signal dictionaries are not supported")

    folder = Path(tempfile.mkdtemp(prefix="wmr-cosim-ssp-"))
    ok = False
    try:
        try:
            safe_extract(path, folder / "archive", lim)
        except FmuLoadError as exc:
            raise ScenarioError(where, "", str(exc)) from None
        doc = _document(root, system, path, folder / "archive", step, stop, algorithm, lim)
        doc = apply_overrides(doc, overrides, where)
        sc = parse(doc, where, limits=limits)
        ok = True
        return SspArchive(sc, folder, warnings)
    finally:
        if not ok:
            shutil.rmtree(folder, ignore_errors=True)


def _read_ssd(path: Path, limits: ArchiveLimits) -> tuple[Any, list[str]]:
    """The archive checked (entries, and the FMUs inside) and its SSD parsed and validated, with the
    warnings of reading it."""
    from lxml import etree as ET

    where = str(path)
    if not path.is_file():
        raise ScenarioError(where, "", "file not found")
    try:
        infos = check_archive(path, limits)
    except FmuLoadError as exc:
        raise ScenarioError(where, "", str(exc).replace(f"{path}: ", "", 1)) from None
    if "SystemStructure.ssd" not in {i.filename for i in infos}:
        raise ScenarioError(where, "", "no SystemStructure.ssd at the top of the archive: not an SSP file")
    with zipfile.ZipFile(path) as zf:
        ssd_bytes = zf.read("SystemStructure.ssd")
        for info in infos:  # the FMUs inside are archives too: every one checked before anything is extracted
            if file_kind(info.filename) is FileKind.FMU:
                try:  # their directories read through a stream, not into memory
                    with zf.open(info) as stream, zipfile.ZipFile(stream) as inner:
                        check_entries(f"{info.filename} in the archive", inner.infolist())
                        check_sizes(f"{info.filename} in the archive", inner.infolist(), info.file_size, limits)
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
    warnings: list[str] = []
    if root.get("version") != SSP_VERSION:  # OMSimulator writes version "2.0" with the SSP 1.0 namespaces
        warnings.append(f"{where}: the SSD says version {root.get('version')!r} but uses the SSP {SSP_VERSION} "
                        f"namespaces: read as SSP {SSP_VERSION}")
        ssd_bytes = _with_version(root)
        root = _parse_xml(ssd_bytes, f"{where}: SystemStructure.ssd")
    validate_xml(ssd_bytes, "ssd", f"{where}: SystemStructure.ssd")
    return root, warnings


def _document(root, system, path: Path, arch: Path, step: float | None, stop: float | None,
              algorithm: str | None, limits: ArchiveLimits) -> dict[str, Any]:
    """The scenario document an SSD describes: the same document a TOML file gives, so the one parser
    and the one resolver check both."""
    where = str(path)
    instances, connectors, comp_params = _components(system, path, arch, limits)
    # String parameters this module's export held back from the parameter sets (the bindings come after)
    for a in system.findall("ssd:Annotations/ssc:Annotation", NS):
        if a.get("type") == OWN_PARAMETERS_TYPE:
            for e in a.iter(f"{{{OWN_NS}}}String"):
                inst, pname, value = e.get("component"), e.get("name"), e.get("value")
                if inst not in instances:
                    raise ScenarioError(where, f"Annotation {OWN_PARAMETERS_TYPE}",
                                        f"String parameter {pname!r}: component {inst!r} is not in the system")
                if not pname or value is None:
                    raise ScenarioError(where, f"Annotation {OWN_PARAMETERS_TYPE}",
                                        f"a String parameter of {inst} without a name or a value")
                instances[inst]["parameters"][pname] = value
    # parameters: system-level bindings address "component.variable"; component-level ones the variable
    for pname, value in _bindings(system, arch, where):
        inst, dot, var = pname.partition(".")
        if not dot or inst not in instances:
            raise ScenarioError(where, f"parameter {pname}", "names no component of the system (expected "
                                                              "\"component.variable\")")
        comp_params.append((inst, var, value))
    for inst, var, value in comp_params:
        instances[inst]["parameters"][var] = value
    _join_array_elements(instances, where, limits)
    a_step, a_alg, a_order, tables = _step_from_annotations(root, where)
    de = root.find("ssd:DefaultExperiment", NS)
    # (the archive's own master runs it as Jacobi, as OMSimulator's and libcosim's fixed-step masters do)
    experiment: dict[str, Any] = {"algorithm": algorithm or a_alg or algorithms.JACOBI}
    if experiment["algorithm"] == a_alg:   # (the settings of the algorithm the archive names, if it is run)
        experiment.update(tables)
    for key, value in (("start", de.get("startTime") if de is not None else None),
                       ("stop", stop if stop is not None else de.get("stopTime") if de is not None else None),
                       ("step", step if step is not None else a_step)):
        if value is not None:
            try:
                experiment[key] = float(value)
            except ValueError:
                raise ScenarioError(where, f"DefaultExperiment.{key}", f"{value!r} is not a number") from None
    if a_order and sorted(a_order) == sorted(instances):
        experiment["order"] = a_order
    outs = [f"{i}.{n}" for (i, n), con in connectors.items() if con.get("kind") == "output"]
    return {"experiment": experiment, "instances": instances,
            "connections": _connections(system, instances, connectors, where),
            "record": {"variables": outs or ["*.*"]}, "ssp": where, "name": root.get("name")}


def _components(system, path: Path, arch: Path, limits: ArchiveLimits
                ) -> tuple[dict[str, Any], dict[tuple[str, str], Any], list]:
    """The components as scenario instances (FMU inside the archive, connector units), their connectors,
    and their own parameter bindings as (component, name, value)."""
    where = str(path)
    comps = system.findall("ssd:Elements/ssd:Component", NS)
    if not comps:
        raise ScenarioError(where, "System", "no components")
    instances: dict[str, Any] = {}
    connectors: dict[tuple[str, str], Any] = {}
    comp_params: list[tuple[str, str, Any]] = []
    for comp in comps:
        cname = comp.get("name")
        fld = f"Component {cname}"
        if cname in instances:
            raise ScenarioError(where, fld, "two components with this name")
        ctype = comp.get("type", FMU_MIME)
        if ctype != FMU_MIME:
            raise ScenarioError(where, fld, f"type {ctype!r}: only FMUs ({FMU_MIME}) are supported")
        implementation = comp.get("implementation", "any")
        if implementation not in IMPLEMENTATIONS:
            raise ScenarioError(where, fld, f"implementation {implementation!r}: one of "
                                            f"{', '.join(IMPLEMENTATIONS)}")
        src = comp.get("source") or ""     # (relative to the archive's top; "./" is dropped by the path)
        if "://" in src or src.startswith("/") or ".." in PurePosixPath(src).parts or "#" in src:
            raise ScenarioError(where, f"{fld}.source", f"{src!r}: only FMUs inside the archive are supported")
        fmu = arch / src
        try:
            present = bool(src) and fmu.is_file()
        except OSError:   # a name the system cannot look up (too long): no such entry was extracted
            present = False
        if not present:
            raise ScenarioError(where, f"{fld}.source", f"resource {src[:100]!r} is missing from the archive")
        try:
            model = load_model(fmu, limits)
        except FmuLoadError as exc:
            raise ScenarioError(where, f"{fld}.source", f"{src}: {str(exc).replace(f'{fmu}: ', '', 1)}") from None
        units: dict[str, str] = {}
        for con in comp.findall("ssd:Connectors/ssd:Connector", NS):
            cn = con.get("name")
            if cn not in model.variables:
                raise ScenarioError(where, f"{fld}.Connector {cn}", f"unknown connector: {src} has no variable {cn!r}")
            connectors[(cname, cn)] = con
            real = con.find("ssc:Real", NS)
            if real is not None and real.get("unit"):
                units[cn] = real.get("unit")
        instances[cname] = {"fmu": str(fmu), "parameters": {}, "units": units,
                            **_implementation(where, fld, src, model, implementation), **_step_hint(comp, where, fld)}
        comp_params += [(cname, p, v) for p, v in _bindings(comp, arch, where)]

    return instances, connectors, comp_params


def _step_hint(comp, where: str, fld: str) -> dict[str, float]:
    """The instance's own ``step`` from OSP's StepSizeHint annotation on the component ({} without one)."""
    for hint in comp.iterfind(f"ssd:Annotations/ssc:Annotation[@type='{OSP_TYPE}']/{{{OSP_NS}}}StepSizeHint", NS):
        try:
            return {"step": float(hint.get("value"))}
        except (TypeError, ValueError):
            raise ScenarioError(where, f"{fld}.StepSizeHint", f"{hint.get('value')!r} is not a number") from None
    return {}


#: An SSD component's ``implementation`` -> the instance's ``interface`` ("any", the default: none given,
#: so the instance runs as co-simulation where the FMU has it, else as model exchange).
IMPLEMENTATIONS = {"any": None, "CoSimulation": CO_SIMULATION, "ModelExchange": MODEL_EXCHANGE}


def _implementation(where: str, fld: str, src: str, model: Any, implementation: str) -> dict[str, str]:
    """The instance's ``interface`` an SSD component's ``implementation`` asks for ({} for "any"), or
    ScenarioError when its FMU lacks that interface."""
    interface = IMPLEMENTATIONS[implementation]
    if interface is None:
        return {}
    if interface not in model.interfaces:
        raise ScenarioError(where, fld, f"implementation {implementation!r}: {src} has no "
                                        f"{INTERFACE_NAMES[interface]} interface (it has "
                                        f"{' and '.join(INTERFACE_NAMES[i] for i in model.interfaces)} only)")
    return {"interface": interface}


def _connections(system, instances: dict[str, Any], connectors: dict[tuple[str, str], Any], where: str
                 ) -> list[dict[str, Any]]:
    from lxml import etree as ET

    out = []
    for i, c in enumerate(system.findall("ssd:Connections/ssd:Connection", NS)):
        fld = f"Connection[{i}]"
        se, scn, ee, ecn = (c.get(k) for k in ("startElement", "startConnector", "endElement", "endConnector"))
        if se is None or ee is None:
            raise ScenarioError(where, fld, "connections to the system's own connectors are not supported")
        for el, cn in ((se, scn), (ee, ecn)):
            if el not in instances:
                raise ScenarioError(where, fld, f"unknown component {el!r}")
            if (el, cn) not in connectors:
                raise ScenarioError(where, fld, f"unknown connector {el}.{cn} (not declared by the component)")
        conn: dict[str, Any] = {"from": f"{se}.{scn}", "to": f"{ee}.{ecn}"}
        lt = c.find("ssc:LinearTransformation", NS)
        if lt is not None:  # (factor and offset are xs:double: the schema check made sure they are numbers)
            conn["factor"], conn["offset"] = float(lt.get("factor", 1.0)), float(lt.get("offset", 0.0))
        elif len([k for k in c if isinstance(k.tag, str) and ET.QName(k).localname.endswith("Transformation")]):
            raise ScenarioError(where, fld, "only LinearTransformation is supported")
        if c.get("suppressUnitConversion", "").strip() in ("true", "1"):  # an xs:boolean
            raise ScenarioError(where, fld, "suppressUnitConversion is not supported")
        out.append(conn)
    return out


def is_ssp(path: str | os.PathLike) -> bool:
    return file_kind(path) is FileKind.SSP


__all__ = ["export_ssp", "load_ssp", "SspArchive", "validate_xml", "is_ssp", "CosimError"]
