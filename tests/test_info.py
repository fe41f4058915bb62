"""``wmr-cosim info`` describes any FMU whose model description it can read (Model Exchange only, FMI 1.0,
no binary for this platform) with one line on what would stop a run, or how it runs here; exit 2 only for
an unreadable one."""
from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest

from reference_fmus import REF
from wmr_cosim.cli import main

BB, FT = REF / "fmi2" / "BouncingBall.fmu", REF / "fmi2" / "Feedthrough.fmu"

FMI1 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="1.0" modelName="Old" modelIdentifier="Old"
    guid="{8c4e810f-3df3-4a00-8276-176fa3c9f000}" numberOfContinuousStates="0" numberOfEventIndicators="0">
  <DefaultExperiment startTime="0" stopTime="2"/>
  <ModelVariables>
    <ScalarVariable name="k" valueReference="0" variability="parameter" causality="input" description="gain">
      <Real start="1.0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="1" causality="output"><Real/></ScalarVariable>
  </ModelVariables>
  <Implementation><CoSimulation_StandAlone><Capabilities/></CoSimulation_StandAlone></Implementation>
</fmiModelDescription>
"""


def _copy(src: Path, dst: Path, edit=None, drop: str | None = None, md: str | None = None) -> Path:
    """``src`` copied to ``dst``: its model description edited (or replaced by ``md``), entries under
    ``drop`` left out."""
    with zipfile.ZipFile(src) as zi, zipfile.ZipFile(dst, "w") as zo:
        for info in zi.infolist():
            if drop and info.filename.startswith(drop):
                continue
            data = zi.read(info)
            if info.filename == "modelDescription.xml":
                data = (md if md is not None else edit(data.decode())).encode()
            zo.writestr(info, data)
    return dst


def _info(capsys, fmu: Path) -> tuple[int, str, str]:
    code = main(["info", str(fmu)])
    out, err = capsys.readouterr()
    return code, out, err


def _cannot(out: str) -> list[str]:
    return [line.strip() for line in out.splitlines() if line.strip().startswith("cannot run here:")]


def test_a_model_exchange_only_fmu_is_described(tmp_path, capsys):
    me = _copy(BB, tmp_path / "ME.fmu", edit=lambda t: re.sub(r"<CoSimulation[^>]*?/>|<CoSimulation.*?</CoSimulation>",
                                                               "", t, flags=re.S))
    code, out, err = _info(capsys, me)
    assert code == 0, err
    assert "(FMI 2.0; model exchange (ME); identifier BouncingBall)" in out and "platforms: linux64" in out
    assert _cannot(out) == []       # (the master integrates a Model Exchange FMU)
    assert "\n  runs here as: model exchange, integrated by the master (cvode; " in out, out
    assert ("\n  model exchange: get/set state: True; serialize state: True; needsCompletedIntegratorStep: True; "
            "event indicators: 1; continuous states: 2\n") in out and "\n  co-simulation:" not in out, out
    assert re.search(r"\n  e +parameter +tunable +Real +0.5 +1 +0.7 +Coefficient of restitution\n", out), out


def test_an_fmu_without_a_binary_for_this_platform_is_described(tmp_path, capsys):
    code, out, err = _info(capsys, _copy(BB, tmp_path / "NoBin.fmu", edit=lambda t: t, drop="binaries/"))
    assert code == 0, err
    assert "co-simulation (CS), model exchange (ME)" in out and "platforms: no binaries; sources included" in out
    assert _cannot(out) == ["cannot run here: no binary for this platform (linux64): the FMU has binaries for no "
                            "platform (a source-only or other-platform FMU cannot run here)"]
    assert "default experiment: start 0, stop 3, step 1e-2" in out


def test_an_fmi1_fmu_is_described(tmp_path, capsys):
    code, out, err = _info(capsys, _copy(BB, tmp_path / "Old.fmu", md=FMI1, drop="binaries/"))
    assert code == 0, err
    assert "model Old (FMI 1.0; co-simulation (CS); identifier Old)" in out
    assert _cannot(out) == ["cannot run here: FMI 1.0 (the master runs FMI 2.0 and 3.0 FMUs)"]
    assert re.search(r"\n  k +parameter +fixed +Real +1.0 +gain\n", out), out


def test_a_runnable_fmu_says_nothing_would_stop_it(capsys):
    code, out, _ = _info(capsys, FT)
    assert code == 0 and _cannot(out) == []
    header = next(line for line in out.splitlines() if line.strip().startswith("name "))
    assert header.split() == ["name", "causality", "variability", "type", "unit", "min", "max", "start", "description"]
    assert re.search(r"\n  Float64_tunable_parameter +parameter +tunable ", out)
    assert re.search(r"\n  Float64_fixed_parameter +parameter +fixed ", out)


def test_an_unbounded_range_shows_nothing(tmp_path, capsys):
    big = "1.7976931348623157e+308"
    fmu = _copy(BB, tmp_path / "Big.fmu", edit=lambda t: t.replace(
        '<Real start="-9.81" declaredType="Acceleration"/>',
        f'<Real start="-9.81" declaredType="Acceleration" min="-{big}" max="{big}"/>', 1))
    with zipfile.ZipFile(fmu) as zf:
        assert big in zf.read("modelDescription.xml").decode()   # (the edit took)
    code, out, err = _info(capsys, fmu)
    assert code == 0, err
    assert "e+308" not in out and re.search(r"\n  g +parameter +fixed +Real +m/s2 +-9.81 +Gravity", out), out


@pytest.mark.parametrize("what, edit, words", [
    ("not well-formed", lambda t: t[:t.index("<fmiModelDescription")], "modelDescription.xml is not well-formed XML"),
    ("truncated", lambda t: t.replace("</fmiModelDescription>", ""), "cannot read modelDescription.xml"),
    ("unreadable", lambda t: re.sub(r"<ModelVariables>.*</ModelVariables>", "<ModelVariables><ScalarVariable/>"
                                    "</ModelVariables>", t, flags=re.S), "cannot read modelDescription.xml"),
])
def test_a_broken_description_is_one_line_and_exit_2(what, edit, words, tmp_path, capsys):
    fmu = _copy(BB, tmp_path / "Broken.fmu", edit=edit)
    code, out, err = _info(capsys, fmu)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and words in err and str(fmu) in err and "Traceback" not in err, err
