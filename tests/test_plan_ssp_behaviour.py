"""SSP 1.0 export and import (cosim/plan/ssp.py) on small FMUs made here: a model description and an empty
binary in a zip, which is all that export and import read (nothing is simulated), so every test runs in a
fraction of a second.  What a user of the master sees: the archive's entries and XML content, the scenario
an archive turns into, and the exact one-line error for an archive this master cannot run."""
from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import pytest
from lxml import etree as ET

from reference_fmus import PLATFORM, REF
from wmr_cosim.cosim.scenario import document as scenario
from wmr_cosim.cosim.plan import ssp
from wmr_cosim import cosim
from wmr_cosim.cosim.messages.errors import CosimError, ScenarioError
from wmr_cosim.cosim.plan.ssp import NS, OSP_NS, OWN_NS, export_ssp, is_ssp, load_ssp, validate_xml

SSD_NS = NS["ssd"]
UNITS = ('<Unit name="m"><BaseUnit m="1"/></Unit>'
         '<Unit name="deg"><BaseUnit rad="1" factor="0.017453292519943295"/></Unit>'
         '<Unit name="degC"><BaseUnit K="1" offset="273.15"/></Unit>'
         '<Unit name="one"/>')
COLOR = ('<TypeDefinitions><SimpleType name="Color"><Enumeration><Item name="red" value="1"/>'
         '<Item name="green" value="2"/></Enumeration></SimpleType></TypeDefinitions>')


def _stub_binary(version: str) -> bytes:
    """A shared library of this platform that exports the FMI functions (the Reference FMU Dahlquist's): a
    binary check reads its header and exports; these FMUs are exported, never run."""
    with zipfile.ZipFile(REF / version / "Dahlquist.fmu") as zf:
        return zf.read(f"binaries/{PLATFORM[version]}/Dahlquist.so")


def _fmu2(path: Path, variables: list[tuple[str, str, str, str, str]]) -> Path:
    """An FMI 2.0 co-simulation FMU with ``variables`` (name, type, causality, variability, extra
    attributes of the type element) and another FMU's binary (enough to load it, not to run it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    ident = path.stem
    rows, outs = [], []
    for i, (name, typ, caus, var, attrs) in enumerate(variables, 1):
        rows.append(f'<ScalarVariable name="{name}" valueReference="{i}" causality="{caus}" variability="{var}">'
                    f'<{typ} {attrs}/></ScalarVariable>')
        if caus == "output":
            outs.append(f'<Unknown index="{i}"/>')
    md = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" modelName="{ident}" '
          f'guid="{{0}}"><CoSimulation modelIdentifier="{ident}"/><UnitDefinitions>{UNITS}</UnitDefinitions>'
          f'{COLOR}<DefaultExperiment startTime="0" stopTime="1" stepSize="0.125"/>'
          f'<ModelVariables>{"".join(rows)}</ModelVariables>'
          f'<ModelStructure><Outputs>{"".join(outs)}</Outputs></ModelStructure></fmiModelDescription>')
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("modelDescription.xml", md)
        zf.writestr(f"binaries/linux64/{ident}.so", _stub_binary("fmi2"))
    return path


def _fmu3(path: Path, variables: list[tuple[str, str, str, str, str]]) -> Path:
    """An FMI 3.0 co-simulation FMU (arrays: a ``<Dimension start=.../>`` in the extra content)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    ident = path.stem
    rows, outs = [], []
    for i, (name, typ, caus, var, inner) in enumerate(variables, 1):
        attrs, _, dims = inner.partition("|")
        rows.append(f'<{typ} name="{name}" valueReference="{i}" causality="{caus}" variability="{var}" {attrs}>'
                    f'{dims}</{typ}>')
        if caus == "output":
            outs.append(f'<Output valueReference="{i}"/>')
    md = (f'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="3.0" modelName="{ident}" '
          f'instantiationToken="{{0}}" variableNamingConvention="structured"><CoSimulation modelIdentifier="{ident}"/>'
          f'<DefaultExperiment startTime="0" stopTime="1" stepSize="0.125"/>'
          f'<ModelVariables>{"".join(rows)}</ModelVariables>'
          f'<ModelStructure>{"".join(outs)}</ModelStructure></fmiModelDescription>')
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("modelDescription.xml", md)
        zf.writestr(f"binaries/x86_64-linux/{ident}.so", _stub_binary("fmi3"))
    return path


#: The FMU most tests use: a Real input and output with units, parameters of every type.
GAIN = [("u", "Real", "input", "continuous", 'unit="m" start="0"'),
        ("u2", "Real", "input", "continuous", 'start="0"'),
        ("y", "Real", "output", "continuous", 'unit="m"'),
        ("ang", "Real", "output", "continuous", 'unit="deg"'),
        ("t", "Real", "output", "continuous", 'unit="degC"'),
        ("n", "Real", "output", "continuous", 'unit="one"'),
        ("plain", "Real", "output", "continuous", ""),
        ("flag", "Boolean", "output", "discrete", ""),
        ("count", "Integer", "output", "discrete", ""),
        ("color", "Enumeration", "output", "discrete", 'declaredType="Color"'),
        ("label", "String", "output", "discrete", ""),
        ("flag_in", "Boolean", "input", "discrete", 'start="false"'),
        ("count_in", "Integer", "input", "discrete", 'start="0"'),
        ("color_in", "Enumeration", "input", "discrete", 'declaredType="Color" start="1"'),
        ("k", "Real", "parameter", "fixed", 'unit="m" start="1"'),
        ("r", "Real", "parameter", "fixed", 'start="1"'),
        ("on", "Boolean", "parameter", "fixed", 'start="true"'),
        ("off", "Boolean", "parameter", "fixed", 'start="true"'),
        ("num", "Integer", "parameter", "fixed", 'start="1"'),
        ("col", "Enumeration", "parameter", "fixed", 'declaredType="Color" start="1"'),
        ("name", "String", "parameter", "fixed", 'start="x"')]


@pytest.fixture
def gain(tmp_path) -> Path:
    return _fmu2(tmp_path / "fmus" / "Gain.fmu", GAIN)


def _plan(tmp_path: Path, doc: dict[str, Any], file: str | None = None) -> cosim.Plan:
    doc = {"experiment": {"start": 0.0, "stop": 1.0, "step": 0.25}, **doc}
    return cosim.resolve(scenario.parse(doc, str(tmp_path / "scen.toml") if file is None else file))


def _ssd(archive: Path) -> Any:
    with zipfile.ZipFile(archive) as zf:
        return ET.fromstring(zf.read("SystemStructure.ssd"))


def _connectors(root, comp: str) -> dict[str, tuple[str, str, str | None]]:
    """Connector name -> (kind, type element, unit) of component ``comp``."""
    c = root.find(f"ssd:System/ssd:Elements/ssd:Component[@name='{comp}']", NS)
    return {k.get("name"): (k.get("kind"), ET.QName(k[0]).localname, k[0].get("unit"))
            for k in c.findall("ssd:Connectors/ssd:Connector", NS)}


# ---------------------------------------------------------------------------------------------- export
def test_export_declares_connectors_with_their_types_kinds_and_units(tmp_path, gain):
    doc = {"instances": {"a": {"fmu": str(gain), "parameters": {"k": 2.5, "u2": 0.5, "name": "z"}},
                         "b": {"fmu": str(gain)}},
           "connections": [{"from": f"a.{v}", "to": f"b.{w}"}
                           for v, w in (("y", "u"), ("flag", "flag_in"), ("count", "count_in"),
                                        ("color", "color_in"))],
           "record": {"variables": ["a.ang", "a.t", "a.n", "a.plain", "b.u2"]}}
    out = export_ssp(_plan(tmp_path, doc), tmp_path / "x.ssp")
    root = _ssd(out)
    assert root.get("generationTool") == "wmr-cosim"
    assert _connectors(root, "a") == {
        "y": ("output", "Real", "m"), "flag": ("output", "Boolean", None), "count": ("output", "Integer", None),
        "color": ("output", "Integer", None), "ang": ("output", "Real", "deg"), "t": ("output", "Real", "degC"),
        "n": ("output", "Real", None),          # a unit without base units is not declared
        "plain": ("output", "Real", None), "name": ("parameter", "String", None),
        "k": ("parameter", "Real", "m"),
        "u2": ("input", "Real", None)}          # an input given a value is an input connector
    assert _connectors(root, "b") == {
        "u": ("input", "Real", "m"), "flag_in": ("input", "Boolean", None), "count_in": ("input", "Integer", None),
        "color_in": ("input", "Integer", None),
        "u2": ("input", "Real", None)}          # a recorded input is a connector
    # the units the connectors use, with their base units, factor and offset (written only when not 1 and 0)
    units = {u.get("name"): dict(u.find("ssc:BaseUnit", NS).attrib) for u in root.findall("ssd:Units/ssc:Unit", NS)}
    assert units == {"deg": {"rad": "1", "factor": "0.017453292519943295"}, "degC": {"K": "1", "offset": "273.15"},
                     "m": {"m": "1"}}
    # Units come before the DefaultExperiment (the schema's order)
    tags = [ET.QName(e).localname for e in root if isinstance(e.tag, str)]
    assert tags.index("Units") < tags.index("DefaultExperiment")


def test_export_without_units_and_without_parameters(tmp_path):
    fmu = _fmu2(tmp_path / "P.fmu", [("x", "Real", "output", "continuous", ""),
                                     ("v", "Real", "input", "continuous", 'start="0"')])
    out = export_ssp(_plan(tmp_path, {"instances": {"p": {"fmu": str(fmu)}},
                                      "record": {"variables": ["p.x"]}}), tmp_path / "plain.ssp")
    root = _ssd(out)
    assert root.find("ssd:Units", NS) is None
    assert _connectors(root, "p") == {"x": ("output", "Real", None)}
    assert zipfile.ZipFile(out).namelist().count("resources/p.ssv") == 0
    assert root.find("ssd:System/ssd:Elements/ssd:Component/ssd:ParameterBindings", NS) is None


def test_export_writes_the_declared_unit_of_a_renamed_variable(tmp_path, gain):
    doc = {"instances": {"a": {"fmu": str(gain), "names": {"plain": "speed", "u2": "w"},
                               "units": {"speed": "m"}},           # by the scenario's name
                         "b": {"fmu": str(gain), "names": {"plain": "speed"},
                               "units": {"plain": "deg", "u2": "furlong"}}},   # by the FMU's name
           "record": {"variables": ["a.speed", "b.speed", "b.u2"]}}
    root = _ssd(export_ssp(_plan(tmp_path, doc), tmp_path / "u.ssp"))
    assert _connectors(root, "a")["plain"] == ("output", "Real", "m")
    assert _connectors(root, "b")["plain"] == ("output", "Real", "deg")
    assert _connectors(root, "b")["u2"] == ("input", "Real", None)  # a unit of unknown base: not declared


def test_export_writes_parameter_sets_that_come_back(tmp_path, gain):
    params = {"k": 2.5, "r": -0.125, "on": True, "off": False, "num": -7, "col": 2, "name": "hello"}
    doc = {"instances": {"a": {"fmu": str(gain), "parameters": params}, "b": {"fmu": str(gain)}},
           "record": {"variables": ["a.y"]}}
    out = export_ssp(_plan(tmp_path, doc), tmp_path / "p.ssp")
    with zipfile.ZipFile(out) as zf:
        assert "resources/b.ssv" not in zf.namelist()
        ssv = ET.fromstring(zf.read("resources/a.ssv"))
    assert ssv.get("name") == "parameters" and ssv.get("generationTool") == "wmr-cosim"
    got = {p.get("name"): (ET.QName(p[0]).localname, dict(p[0].attrib))
           for p in ssv.findall("ssv:Parameters/ssv:Parameter", NS)}
    assert got == {"k": ("Real", {"value": "2.5", "unit": "m"}), "r": ("Real", {"value": "-0.125"}),
                   "on": ("Boolean", {"value": "true"}), "off": ("Boolean", {"value": "false"}),
                   "num": ("Integer", {"value": "-7"}), "col": ("Integer", {"value": "2"}),
                   "name": ("String", {"value": "hello"})}
    binding = _ssd(out).find("ssd:System/ssd:Elements/ssd:Component[@name='a']/ssd:ParameterBindings/"
                             "ssd:ParameterBinding", NS)
    assert binding.get("source") == "resources/a.ssv"
    arch = load_ssp(out)
    try:
        assert arch.scenario.instances["a"].parameters == params
        assert [type(v) for v in arch.scenario.instances["a"].parameters.values()] == [type(v) for v in params.values()]
    finally:
        arch.cleanup()


def test_export_default_experiment_carries_the_step_algorithm_and_order(tmp_path, gain):
    doc = {"experiment": {"start": 0.5, "stop": 2.0, "step": 0.25, "algorithm": "gauss-seidel", "order": ["b", "a"]},
           "instances": {"a": {"fmu": str(gain)}, "b": {"fmu": str(gain)}},
           "connections": [{"from": "a.y", "to": "b.u", "factor": 2.0}]}
    out = export_ssp(_plan(tmp_path, doc), tmp_path / "de.ssp")
    text = zipfile.ZipFile(out).read("SystemStructure.ssd").decode()
    root = ET.fromstring(text.encode())
    # the annotations' namespaces are declared once, on the root element (libcosim needs this)
    assert root.nsmap["osp"] == OSP_NS and root.nsmap["wmr"] == OWN_NS
    assert text.count(f'xmlns:osp="{OSP_NS}"') == 1 and text.count(f'xmlns:wmr="{OWN_NS}"') == 1
    de = root.find("ssd:DefaultExperiment", NS)
    assert (de.get("startTime"), de.get("stopTime")) == ("0.5", "2.0")
    assert de.find(f".//{{{OSP_NS}}}FixedStepAlgorithm").get("baseStepSize") == "0.25"
    assert dict(de.find(f".//{{{OWN_NS}}}Experiment").attrib) == {"step": "0.25", "algorithm": "gauss-seidel",
                                                                  "order": "b a"}
    arch = load_ssp(out)
    try:
        sc = arch.scenario
        assert (sc.start, sc.stop, sc.step, sc.algorithm, sc.order) == (0.5, 2.0, 0.25, "gauss-seidel", ["b", "a"])
        assert [(c.src, c.dst, c.factor, c.offset) for c in sc.connections] == [("a.y", "b.u", 2.0, 0.0)]
    finally:
        arch.cleanup()


def test_export_names_the_system_after_the_scenario_file(tmp_path, gain):
    doc = {"instances": {"a": {"fmu": str(gain)}}, "record": {"variables": ["a.y"]}}
    assert _ssd(export_ssp(_plan(tmp_path, doc), tmp_path / "1.ssp")).get("name") == "scen"
    assert _ssd(export_ssp(_plan(tmp_path, doc), tmp_path / "2.ssp", name="mine")).get("name") == "mine"
    assert _ssd(export_ssp(_plan(tmp_path, doc, file=""), tmp_path / "3.ssp")).get("name") == "system"


def test_export_makes_the_folder_and_leaves_only_the_archive(tmp_path, gain):
    doc = {"instances": {"a": {"fmu": str(gain)}}, "record": {"variables": ["a.y"]}}
    target = tmp_path / "new" / "deeper" / "x.ssp"
    target.parent.mkdir(parents=True)
    (target.parent / "x.ssp.part").write_text("left by an interrupted export")
    out = export_ssp(_plan(tmp_path, doc), target)
    assert out == target and sorted(p.name for p in target.parent.iterdir()) == ["x.ssp"]
    out2 = export_ssp(_plan(tmp_path, doc), tmp_path / "a" / "b" / "y.ssp")
    assert zipfile.is_zipfile(out2)


def test_export_packs_each_fmu_file_once_under_a_unique_name(tmp_path):
    vars_ = [("y", "Real", "output", "continuous", "")]
    f1 = _fmu2(tmp_path / "d1" / "Gain.fmu", vars_)
    f2 = _fmu2(tmp_path / "d2" / "gain.fmu", vars_)
    f3 = _fmu2(tmp_path / "d3" / "Gain.fmu", vars_)
    f4 = _fmu2(tmp_path / "d4" / "Other.fmu", vars_)
    doc = {"instances": {"a": {"fmu": str(f1)}, "b": {"fmu": str(f1)}, "c": {"fmu": str(f2)},
                         "d": {"fmu": str(f3)}, "e": {"fmu": str(f4)}},
           "record": {"variables": ["a.y"]}}
    out = export_ssp(_plan(tmp_path, doc), tmp_path / "r.ssp")
    root = _ssd(out)
    sources = {c.get("name"): c.get("source") for c in root.findall("ssd:System/ssd:Elements/ssd:Component", NS)}
    assert sources == {"a": "resources/Gain.fmu", "b": "resources/Gain.fmu", "c": "resources/gain_2.fmu",
                       "d": "resources/Gain_3.fmu", "e": "resources/Other.fmu"}
    with zipfile.ZipFile(out) as zf:
        fmus = sorted(n for n in zf.namelist() if n.endswith(".fmu"))
        assert fmus == ["resources/Gain.fmu", "resources/Gain_3.fmu", "resources/Other.fmu", "resources/gain_2.fmu"]
        assert zf.read("resources/gain_2.fmu") == f2.read_bytes() and zf.read("resources/Gain_3.fmu") == f3.read_bytes()


def test_export_refuses_events_with_one_line(tmp_path, gain):
    doc = {"instances": {"a": {"fmu": str(gain)}}, "record": {"variables": ["a.y"]},
           "events": [{"time": 0.5, "variable": "a.u", "value": 1.0}]}
    plan = _plan(tmp_path, doc)
    with pytest.raises(ScenarioError) as ei:
        export_ssp(plan, tmp_path / "ev.ssp")
    assert str(ei.value) == (f"{tmp_path / 'scen.toml'}: events: events cannot be expressed in SSP 1.0 (timed or on "
                             "conditions): export a scenario without [[events]]")
    assert not list(tmp_path.glob("ev.ssp*"))


# ---------------------------------------------------------------------------------------------- import
def _archive(tmp_path: Path, *, system: str = "", components: str | None = None, connections: str = "",
             experiment: str = '<ssd:DefaultExperiment startTime="0" stopTime="1"/>',
             fmu: Path | None = None, extra: dict[str, bytes] | None = None, name: str = "in.ssp") -> Path:
    """An SSP archive with a hand-written SSD: components ``a`` and ``b`` of the FMU ``fmu`` (resources/Gain.fmu)
    declaring the connectors y (output) and u (input) unless ``components`` says otherwise."""
    if components is None:
        components = "".join(
            f'<ssd:Component name="{n}" type="application/x-fmu-sharedlibrary" source="resources/Gain.fmu">'
            '<ssd:Connectors><ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector>'
            '<ssd:Connector name="u" kind="input"><ssc:Real unit="m"/></ssd:Connector></ssd:Connectors>'
            '</ssd:Component>' for n in ("a", "b"))
    conns = f"<ssd:Connections>{connections}</ssd:Connections>" if connections else ""
    ssd = (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription xmlns:ssd="{NS["ssd"]}" '
           f'xmlns:ssc="{NS["ssc"]}" xmlns:ssv="{NS["ssv"]}" xmlns:osp="{OSP_NS}" xmlns:wmr="{OWN_NS}" '
           f'xmlns:o="urn:other" name="t" version="1.0"><ssd:System name="root">{system}'
           f'{f"<ssd:Elements>{components}</ssd:Elements>" if components else ""}{conns}</ssd:System>{experiment}'
           '</ssd:SystemStructureDescription>')
    path = tmp_path / name
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        zf.writestr("resources/Gain.fmu", (fmu or _fmu2(tmp_path / "src" / "Gain.fmu", GAIN)).read_bytes())
        for entry, data in (extra or {}).items():
            zf.writestr(entry, data)
    return path


def _load(path: Path, **kw):
    arch = load_ssp(path, **kw)
    arch.cleanup()
    return arch.scenario


def _error(path: Path, **kw) -> str:
    try:
        load_ssp(path, **kw).cleanup()
    except ScenarioError as exc:
        return str(exc)
    raise AssertionError(f"{path} was read without an error")


OK = '<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="u"/>'


@pytest.mark.parametrize("conn, reason", [
    ('<ssd:Connection startConnector="y" endElement="b" endConnector="u"/>',
     "connections to the system's own connectors are not supported"),
    ('<ssd:Connection startElement="a" startConnector="y" endConnector="u"/>',
     "connections to the system's own connectors are not supported"),
    ('<ssd:Connection startElement="zz" startConnector="y" endElement="b" endConnector="u"/>',
     "unknown component 'zz'"),
    ('<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="nope"/>',
     "unknown connector b.nope (not declared by the component)"),
    ('<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="u">'
     '<ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>'
     '</ssc:BooleanMappingTransformation></ssd:Connection>',
     "only LinearTransformation is supported"),
    ('<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="u" '
     'suppressUnitConversion="true"/>', "suppressUnitConversion is not supported"),
    ('<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="u" '
     'suppressUnitConversion="1"/>', "suppressUnitConversion is not supported"),
])
def test_a_connection_the_master_cannot_make_is_named_in_one_line(tmp_path, conn, reason):
    path = _archive(tmp_path, connections=OK + conn)
    assert _error(path) == f"{path}: Connection[1]: {reason}"


def test_a_linear_transformation_defaults_to_factor_one_and_offset_zero(tmp_path):
    path = _archive(tmp_path, connections=(
        '<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="u">'
        '<ssc:LinearTransformation offset="0.5"/></ssd:Connection>'
        '<ssd:Connection startElement="b" startConnector="y" endElement="a" endConnector="u" '
        'suppressUnitConversion="false"><ssc:LinearTransformation factor="3"/></ssd:Connection>'))
    sc = _load(path)
    assert [(c.src, c.dst, c.factor, c.offset) for c in sc.connections] == [("a.y", "b.u", 1.0, 0.5),
                                                                            ("b.y", "a.u", 3.0, 0.0)]
    assert sc.instances["b"].units == {"u": "m"}        # the connector's unit, declared for the scenario
    assert sc.record == ["a.y", "b.y"]                   # the output connectors are recorded


def _inline(params: str, prefix: str = "") -> str:
    pre = f' prefix="{prefix}"' if prefix else ""
    return (f'<ssd:ParameterBindings><ssd:ParameterBinding{pre}><ssd:ParameterValues>'
            f'<ssv:ParameterSet version="1.0" name="s"><ssv:Parameters>{params}</ssv:Parameters></ssv:ParameterSet>'
            '</ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>')


def _param(name: str, kind: str, value: str) -> str:
    return f'<ssv:Parameter name="{name}"><ssv:{kind} value="{value}"/></ssv:Parameter>'


def test_parameter_values_of_every_type_are_read(tmp_path):
    values = [("a.k", "Real", "2.5"), ("a.num", "Integer", "-3"), ("a.col", "Enumeration", "2"),
              ("a.on", "Boolean", "true"), ("a.off", "Boolean", "false"), ("b.on", "Boolean", "1"),
              ("b.off", "Boolean", "0"), ("b.name", "String", "hi there")]
    path = _archive(tmp_path, system=_inline("".join(_param(*v) for v in values)))
    sc = _load(path)
    assert sc.instances["a"].parameters == {"k": 2.5, "num": -3, "col": 2, "on": True, "off": False}
    assert sc.instances["b"].parameters == {"on": True, "off": False, "name": "hi there"}
    assert type(sc.instances["a"].parameters["num"]) is int and type(sc.instances["a"].parameters["col"]) is int


@pytest.mark.parametrize("param, where, reason", [
    (_param("a.col", "Enumeration", "red"), "Parameter a.col", "'red' is not a valid Enumeration"),
    (_param("a.name", "Binary", "0a0b"), "Parameter a.name", "parameters of type Binary are not supported"),
    (_param("", "Real", "1"), "Parameter ''", "a parameter needs a name"),
])
def test_a_parameter_the_master_cannot_read_is_named_in_one_line(tmp_path, param, where, reason):
    path = _archive(tmp_path, system=_inline(param))
    assert _error(path) == f"{path}: {where}: {reason}"


def test_a_parameter_file_error_names_the_file(tmp_path):
    ssv = (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="{NS["ssv"]}" version="1.0" '
           f'name="s"><ssv:Parameters>{_param("k", "Enumeration", "red")}</ssv:Parameters></ssv:ParameterSet>')
    comps = ('<ssd:Component name="a" type="application/x-fmu-sharedlibrary" source="resources/Gain.fmu">'
             '<ssd:ParameterBindings><ssd:ParameterBinding source="resources/a.ssv"/></ssd:ParameterBindings>'
             '</ssd:Component>')
    path = _archive(tmp_path, components=comps, extra={"resources/a.ssv": ssv.encode()})
    assert _error(path) == f"{path}: resources/a.ssv: Parameter k: 'red' is not a valid Enumeration"


def _experiment(annotations: str, start: str = "0", stop: str = "1") -> str:
    return (f'<ssd:DefaultExperiment startTime="{start}" stopTime="{stop}"><ssd:Annotations>{annotations}'
            '</ssd:Annotations></ssd:DefaultExperiment>')


OWN = '<ssc:Annotation type="org.wmr-cosim.experiment"><wmr:Experiment {}/></ssc:Annotation>'
OSP = ('<ssc:Annotation type="com.opensimulationplatform"><osp:Algorithm>'
       '<osp:FixedStepAlgorithm baseStepSize="{}"/></osp:Algorithm></ssc:Annotation>')
OTHER = '<ssc:Annotation type="other"><o:Thing step="9" baseStepSize="9" algorithm="x" order="a"/></ssc:Annotation>'


@pytest.mark.parametrize("annotations, expected", [
    # this master's annotation first: step, algorithm, order (the FMU's default step is 0.125)
    (OWN.format('step="0.25" algorithm="gauss-seidel" order="b a"') + OSP.format("0.5") + OTHER,
     (0.25, "gauss-seidel", ["b", "a"])),
    (OWN.format('algorithm="gauss-seidel"') + OSP.format("0.5") + OTHER, (0.5, "gauss-seidel", ["a", "b"])),
    (OWN.format('step="fast" order=""') + OSP.format("0.5"), (0.5, "jacobi", ["a", "b"])),
    (OSP.format("0.5") + OTHER, (0.5, "jacobi", ["a", "b"])),     # Open Simulation Platform's step
    (OSP.format("bad"), (None, "jacobi", ["a", "b"])),      # else none (resolve takes the FMUs' default)
    (OTHER, (None, "jacobi", ["a", "b"])),
])
def test_the_step_algorithm_and_order_come_from_the_annotations(tmp_path, annotations, expected):
    sc = _load(_archive(tmp_path, experiment=_experiment(annotations)))
    assert (sc.step, sc.algorithm, sc.order) == expected


def test_the_step_stop_and_algorithm_given_override_the_archive(tmp_path):
    path = _archive(tmp_path, experiment=_experiment(OWN.format('step="0.25" algorithm="gauss-seidel"')))
    sc = _load(path, step=0.5, stop=3.0, algorithm="jacobi")
    assert (sc.step, sc.stop, sc.algorithm) == (0.5, 3.0, "jacobi")



def test_a_step_or_stop_given_that_is_not_a_number_is_named_in_one_line(tmp_path):
    """From Python, load_ssp(step="fast"): the value given is checked like the archive's own (the schema
    check already makes the archive's times numbers)."""
    path = _archive(tmp_path)
    assert _error(path, step="fast") == f"{path}: DefaultExperiment.step: 'fast' is not a number"
    assert _error(path, stop="1 s") == f"{path}: DefaultExperiment.stop: '1 s' is not a number"
    assert _load(path, step="0.25", stop="2").step == 0.25

# ------------------------------------------------------------------------------- FMI 3.0 arrays as elements
ARRAY = [("x", "Float64", "parameter", "fixed", 'start="1 2 3 4 5 6"|<Dimension start="2"/><Dimension start="3"/>'),
         ("s[1].v", "Float64", "parameter", "fixed", 'start="1 2"|<Dimension start="2"/>'),
         ("a[1]", "Float64", "parameter", "fixed", 'start="0"'),
         ("k]", "Float64", "parameter", "fixed", 'start="0"'),
         ("sc", "Float64", "parameter", "fixed", 'start="0"'),
         ("y", "Float64", "output", "continuous", "")]


def _array_archive(tmp_path: Path, params: list[tuple[str, str]]) -> Path:
    fmu = _fmu3(tmp_path / "src" / "Gain.fmu", ARRAY)
    comps = ('<ssd:Component name="a" type="application/x-fmu-sharedlibrary" source="resources/Gain.fmu">'
             + _inline("".join(_param(n, "Real", v) for n, v in params)) + '</ssd:Component>')
    return _archive(tmp_path, components=comps, fmu=fmu)


def test_array_elements_are_joined_into_the_array(tmp_path):
    elems = [(f"x[{i},{j}]", str(10 * i + j)) for i in (1, 2) for j in (1, 2, 3)]
    path = _array_archive(tmp_path, elems[::-1] + [("s[1].v[1]", "7"), ("s[1].v[2]", "8"), ("a[1]", "5"),
                                                   ("k]", "6"), ("sc[2]", "4")])
    sc = _load(path)
    assert sc.instances["a"].parameters == {"x": [11.0, 12.0, 13.0, 21.0, 22.0, 23.0], "s[1].v": [7.0, 8.0],
                                            "a[1]": 5.0, "k]": 6.0, "sc[2]": 4.0}


@pytest.mark.parametrize("params, missing", [
    ([("x[1,1]", "1"), ("x[2,3]", "2")], "x[1,2], x[1,3], x[2,1], x[2,2]"),
    ([(f"x[{i},{j}]", "1") for i in (1, 2) for j in (1, 2, 3)] + [("x", "3")], "none"),
])
def test_an_array_given_in_part_is_named_in_one_line(tmp_path, params, missing):
    path = _array_archive(tmp_path, params)
    assert _error(path) == (f"{path}: parameter a.x: an array parameter is given either whole or as every element "
                            f"(6); missing: {missing}")


# ------------------------------------------------------------------------------- small contracts
def test_is_ssp_goes_by_the_extension_in_any_case():
    assert is_ssp("run.ssp") and is_ssp(Path("dir/RUN.SSP")) and is_ssp("a.Ssp")
    assert not is_ssp("run.toml") and not is_ssp("ssp") and not is_ssp("run.ssp.zip")


def test_cleanup_can_be_called_twice(tmp_path):
    arch = load_ssp(_archive(tmp_path))
    assert arch.folder.is_dir()
    arch.cleanup()
    arch.cleanup()
    assert not arch.folder.exists()


def test_the_schemas_come_from_pyssp_standard(monkeypatch, tmp_path):
    import importlib.util

    ssd = zipfile.ZipFile(_archive(tmp_path)).read("SystemStructure.ssd")
    monkeypatch.setitem(ssp._schema.__dict__, "cache", {})   # located afresh, not from an earlier test
    validate_xml(ssd, "ssd", "x")
    with pytest.raises(ScenarioError, match=r"^y: line 2: not valid against the SSP 1.0 schema: "):
        validate_xml(ssd.replace(b"<ssd:Elements>", b"<ssd:Bogus/><ssd:Elements>"), "ssd", "y")
    monkeypatch.setitem(ssp._schema.__dict__, "cache", {})
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pyssp_standard" else real(name, *a))
    with pytest.raises(CosimError) as ei:
        validate_xml(ssd, "ssd", "x")
    assert str(ei.value) == "pyssp-standard is not installed (pip install pyssp-standard): it provides the SSP schemas"


# ------------------------------------------------------------------------------- components and bindings
def _comp(name: str = "a", attrs: str = 'source="resources/Gain.fmu"', inner: str = "") -> str:
    return f'<ssd:Component name="{name}" type="application/x-fmu-sharedlibrary" {attrs}>{inner}</ssd:Component>'


@pytest.mark.parametrize("components, where, reason", [
    (_comp() + _comp(), "Component a", "two components with this name"),
    (_comp(attrs='source="resources/Gain.fmu" type="application/x-other"').replace(
        'type="application/x-fmu-sharedlibrary" ', ""),
     "Component a", "type 'application/x-other': only FMUs (application/x-fmu-sharedlibrary) are supported"),
    (_comp(attrs='source="resources/Gain.fmu" implementation="ModelExchange"'),
     "Component a", "implementation 'ModelExchange': resources/Gain.fmu has no model exchange interface (it has "
                    "co-simulation only)"),
    (_comp(attrs='source="https://example.org/Gain.fmu"'), "Component a.source",
     "'https://example.org/Gain.fmu': only FMUs inside the archive are supported"),
    (_comp(attrs='source="/resources/Gain.fmu"'), "Component a.source",
     "'/resources/Gain.fmu': only FMUs inside the archive are supported"),
    (_comp(attrs='source="resources/../../Gain.fmu"'), "Component a.source",
     "'resources/../../Gain.fmu': only FMUs inside the archive are supported"),
    (_comp(attrs='source="resources/Gain.fmu#a"'), "Component a.source",
     "'resources/Gain.fmu#a': only FMUs inside the archive are supported"),
    (_comp(attrs='source="resources/Other.fmu"'), "Component a.source",
     "resource 'resources/Other.fmu' is missing from the archive"),
    (_comp(attrs='source="resources"'), "Component a.source", "resource 'resources' is missing from the archive"),
])
def test_a_component_the_master_cannot_load_is_named_in_one_line(tmp_path, components, where, reason):
    path = _archive(tmp_path, components=components)
    assert _error(path) == f"{path}: {where}: {reason}"


def test_a_component_may_be_any_implementation_and_its_source_relative(tmp_path):
    comps = (_comp("a", 'source="./resources/Gain.fmu" implementation="any"')
             + _comp("b", 'source="resources/Gain.fmu" implementation="CoSimulation"'))
    sc = _load(_archive(tmp_path, components=comps))
    assert list(sc.instances) == ["a", "b"] and sc.instances["a"].fmu_path.name == "Gain.fmu"
    assert sc.record == ["*.*"]                      # no output connectors: everything is recorded


def _binding(attrs: str = "", inner: str = "") -> str:
    return f"<ssd:ParameterBindings><ssd:ParameterBinding {attrs}>{inner}</ssd:ParameterBinding></ssd:ParameterBindings>"


SSV_FILE = (f'<?xml version="1.0" encoding="UTF-8"?>\n<ssv:ParameterSet xmlns:ssv="{NS["ssv"]}" version="1.0" '
            'name="s"><ssv:Parameters>{}</ssv:Parameters></ssv:ParameterSet>')


@pytest.mark.parametrize("binding, reason", [
    (_binding('type="application/x-other" source="resources/a.ssv"'),
     "type 'application/x-other' is not supported (only application/x-ssp-parameter-set)"),
    (_binding('source="resources/a.ssv"', '<ssd:ParameterMapping source="resources/a.ssm"/>'),
     "parameter mappings (.ssm) are not supported"),
    (_binding('source="resources/a.ssv" sourceBase="component"'),
     'resources/a.ssv: sourceBase="component" is not supported'),
    (_binding('source="resources/none.ssv"'), "parameter file 'resources/none.ssv' is missing from the archive"),
    (_binding('source="resources"'), "parameter file 'resources' is missing from the archive"),
    (_binding('source="../in.ssp"'), "parameter file '../in.ssp' is missing from the archive"),
])
def test_a_parameter_binding_the_master_cannot_read_is_named_in_one_line(tmp_path, binding, reason):
    ssv = SSV_FILE.format(_param("k", "Real", "1")).encode()
    path = _archive(tmp_path, components=_comp(inner=binding), extra={"resources/a.ssv": ssv})
    assert _error(path) == f"{path}: ParameterBinding: {reason}"


def test_parameter_bindings_on_the_system_and_components_with_prefixes(tmp_path):
    ssv = SSV_FILE.format(_param("k", "Real", "1") + _param("r", "Real", "2")).encode()
    ssv_pre = SSV_FILE.format(_param("pre.num", "Integer", "4") + _param("other.num", "Integer", "5")).encode()
    comps = (_comp("a", inner=_binding('source="resources/a.ssv" sourceBase="SSD"'))
             + _comp("b", inner=_binding('source="resources/b.ssv" prefix="pre."')))
    system = _inline(_param("sys.a.r", "Real", "7") + _param("b.k", "Real", "8") + _param("x.b.k", "Real", "9"),
                     prefix="sys.")
    path = _archive(tmp_path, components=comps, system=system,
                    extra={"resources/a.ssv": ssv, "resources/b.ssv": ssv_pre})
    sc = _load(path)
    # the system's values come after the components' own (the later binding wins)
    assert sc.instances["a"].parameters == {"k": 1.0, "r": 7.0}
    assert sc.instances["b"].parameters == {"num": 4}
    sc = _load(path, overrides={"b.num": 6})
    assert sc.instances["b"].parameters == {"num": 6}


def test_a_system_binding_may_read_a_parameter_file(tmp_path):
    ssv = SSV_FILE.format(_param("a.k", "Real", "3") + _param("b.r", "Real", "4")).encode()
    path = _archive(tmp_path, system=_binding('source="resources/sys.ssv"'), extra={"resources/sys.ssv": ssv})
    sc = _load(path)
    assert sc.instances["a"].parameters == {"k": 3.0} and sc.instances["b"].parameters == {"r": 4.0}


def test_a_component_fmu_that_does_not_load_is_named_by_its_source(tmp_path):
    """The reason is the FMU loader's, without the temporary folder the archive was extracted to."""
    bad = tmp_path / "Bad.fmu"
    with zipfile.ZipFile(bad, "w") as zf:
        zf.writestr("binaries/readme.txt", "no model description")
    path = _archive(tmp_path, components=_comp(attrs='source="resources/Bad.fmu"'),
                    extra={"resources/Bad.fmu": bad.read_bytes()})
    assert _error(path) == f"{path}: Component a.source: resources/Bad.fmu: no modelDescription.xml: not an FMU"


@pytest.mark.parametrize("pname", ["k", "zz.k"])
def test_a_system_parameter_naming_no_component_is_named_in_one_line(tmp_path, pname):
    path = _archive(tmp_path, system=_inline(_param(pname, "Real", "1")))
    assert _error(path) == (f'{path}: parameter {pname}: names no component of the system (expected '
                            '"component.variable")')


# ------------------------------------------------------------------------------- the archive and its SSD
def test_an_archive_that_is_missing_or_whose_system_is_nested_is_named_in_one_line(tmp_path):
    assert _error(tmp_path / "none.ssp") == f"{tmp_path / 'none.ssp'}: file not found"
    nested = _archive(tmp_path, components=_comp() + '<ssd:System name="sub"/>')
    assert _error(nested) == f"{nested}: System: nested systems are not supported"
    sigdict = _archive(tmp_path, components=_comp() + '<ssd:SignalDictionaryReference name="s" dictionary="d"/>',
                       name="sd.ssp")
    assert _error(sigdict) == f"{sigdict}: System: signal dictionaries are not supported"


def test_a_system_without_components_is_named_in_one_line(tmp_path):
    path = _archive(tmp_path, components="")
    assert _error(path) == f"{path}: System: no components"


def _with_ssd(tmp_path: Path, ssd: bytes) -> Path:
    path = tmp_path / "raw.ssp"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("SystemStructure.ssd", ssd)
    return path


def test_an_ssd_that_is_not_well_formed_or_declares_entities_is_refused_in_one_line(tmp_path):
    path = _with_ssd(tmp_path, b"<a>\n  <b></a>")
    msg = _error(path)   # the parser's reason, with its line, on one line
    assert msg.startswith(f"{path}: SystemStructure.ssd: not well-formed XML (Opening and ending tag mismatch: b "
                          "line 2 and a, line 2, column ") and msg.endswith(")") and "\n" not in msg
    path = _with_ssd(tmp_path, b'<?xml version="1.0"?>\n<!DOCTYPE x [<!ENTITY e "boom">]>\n<x>&e;</x>')
    assert _error(path) == (f"{path}: SystemStructure.ssd: declares the XML entity 'e': refused (entities can "
                            "read local files or expand without bound)")


def test_the_experiment_times_and_an_order_that_does_not_fit(tmp_path):
    path = _archive(tmp_path, experiment=_experiment(OWN.format('order="a"'), start="0.5", stop="2.5"))
    sc = _load(path)
    assert (sc.start, sc.stop, sc.order) == (0.5, 2.5, ["a", "b"])     # an order that misses b is ignored
    sc = _load(_archive(tmp_path, experiment="", name="nodefault.ssp"))
    assert (sc.start, sc.stop, sc.step, sc.algorithm) == (None, None, None, "jacobi")


def test_an_archive_that_is_not_an_ssp_is_named_in_one_line(tmp_path):
    path = tmp_path / "nossd.ssp"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("resources/SystemStructure.ssd", "<x/>")
    assert _error(path) == f"{path}: no SystemStructure.ssd at the top of the archive: not an SSP file"
    path = tmp_path / "text.ssp"
    path.write_text("not an archive")
    assert _error(path).startswith(f"{path}: ") and "not a zip archive" in _error(path)
    assert str(path) not in _error(path)[len(str(path)):]           # the file is named once
    bad_fmu = _archive(tmp_path, extra={"resources/Bad.fmu": b"not a zip"}, name="badfmu.ssp")
    assert _error(bad_fmu) == f"{bad_fmu}: resources/Bad.fmu: not a zip archive (File is not a zip file)"


@pytest.mark.parametrize("root, found", [
    ('<x:SystemStructureDescription xmlns:x="urn:other" name="t" version="1.0"/>', "in urn:other"),
    ('<SystemStructureDescription name="t" version="1.0"/>', "in no namespace"),
])
def test_an_ssd_of_another_standard_is_named_in_one_line(tmp_path, root, found):
    path = _with_ssd(tmp_path, root.encode())
    assert _error(path) == (f"{path}: SystemStructure.ssd: root element SystemStructureDescription {found}: not an "
                            "SSP 1.0 system structure (only SSP 1.0 is supported)")


def test_an_ssd_saying_another_version_is_read_as_ssp_1_with_a_warning(tmp_path):
    src = _archive(tmp_path, experiment=_experiment(OWN.format('step="0.25"')))
    path = tmp_path / "oms.ssp"
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(path, "w") as zo:
        for info in zi.infolist():
            data = zi.read(info)
            if info.filename == "SystemStructure.ssd":
                data = data.replace(b'name="t" version="1.0"', b'name="t" version="2.0"', 1)
            zo.writestr(info, data)
    arch = load_ssp(path)
    arch.cleanup()
    assert arch.warnings == [f"{path}: the SSD says version '2.0' but uses the SSP 1.0 namespaces: read as SSP 1.0"]
    assert (list(arch.scenario.instances), arch.scenario.step) == (["a", "b"], 0.25)
    assert _load(src).step == 0.25
    arch = load_ssp(src)
    arch.cleanup()
    assert arch.warnings == []


def test_the_document_an_ssp_becomes_names_its_archive_and_its_ssd(tmp_path):
    """The scenario read from an SSP keeps the archive's path and the SSD's name (they go into scenario.json's
    document, which says what was run)."""
    path = _archive(tmp_path)
    sc = _load(path)
    assert sc.data["ssp"] == str(path) and sc.data["name"] == "t"



def test_a_component_source_whose_name_the_system_cannot_look_up_is_refused_in_one_line(tmp_path, capsys):
    """A source of 5,000 characters (longer than a file name may be) is a resource missing from the archive,
    said in one line (was an OSError traceback)."""
    from cosim_support import edited_fmu
    from wmr_cosim.cli import main

    (tmp_path / "e.toml").write_text(f'[experiment]\nstop = 0.05\nstep = 0.01\n[instances.d]\n'
                                     f'fmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n')
    assert main(["export-ssp", str(tmp_path / "e.toml"), "--out", str(tmp_path / "e.ssp")]) == 0
    capsys.readouterr()
    long_name = "resources/" + "x" * 5000 + ".fmu"

    def edit(name: str, data: bytes) -> bytes:
        if name == "SystemStructure.ssd":
            data = data.replace(b'source="resources/Dahlquist.fmu"', f'source="{long_name}"'.encode())
            assert long_name.encode() in data
        return data
    bad = edited_fmu(tmp_path / "e.ssp", tmp_path / "bad.ssp", edit)
    assert main(["check", str(bad)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "bad.ssp" in lines[0] and "missing from the archive" in lines[0], lines
