"""``wmr-cosim export-fmu ARCHIVE.ssp``: an SSP archive (here one ``export-ssp`` wrote of a scenario of
Reference C FMUs, with a factor, an offset and a parameter) exported as one FMU whose outputs in FMPy equal
``wmr-cosim run`` of the same archive bit for bit, Gauss-Seidel and Jacobi."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from wmr_cosim.cli import main

from cosim_support import write_document
from reference_fmus import REF

STOP, STEP = 2.0, 0.05


def chain(algorithm: str) -> dict:
    ft = str(REF / "fmi2" / "Feedthrough.fmu")
    return {"experiment": {"start": 0.0, "stop": STOP, "step": STEP, "algorithm": algorithm},
            "instances": {"d": {"fmu": str(REF / "fmi2" / "Dahlquist.fmu"), "parameters": {"k": 0.75}},
                          "f1": {"fmu": ft}, "f2": {"fmu": ft}},
            "connections": [{"from": "d.x", "to": "f1.Float64_continuous_input", "factor": 2.0, "offset": 1.0},
                            {"from": "f1.Float64_continuous_output", "to": "f2.Float64_continuous_input"}],
            "record": {"variables": ["d.x", "f1.Float64_continuous_output", "f2.Float64_continuous_output"]}}


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_an_ssp_archive_exported_as_one_fmu_equals_the_run_of_the_archive(algorithm: str, tmp_path: Path) -> None:
    import fmpy

    sc = write_document(tmp_path / "chain.toml", chain(algorithm))
    ssp = tmp_path / "chain.ssp"
    assert main(["export-ssp", str(sc), "--out", str(ssp)]) == 0
    out = tmp_path / "Chain.fmu"
    assert main(["export-fmu", str(ssp), "--out", str(out)]) == 0
    assert main(["run", str(ssp), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    ref = np.load(tmp_path / "run" / "signals.npy")
    got = fmpy.simulate_fmu(str(out), stop_time=STOP, output_interval=STEP)
    assert got.dtype.names == ref.dtype.names
    assert {"d.x", "f2.Float64_continuous_output"} <= set(ref.dtype.names)
    assert len(ref) == round(STOP / STEP) + 1 and len(np.unique(ref["f2.Float64_continuous_output"])) > 5
    for name in ref.dtype.names:
        assert np.array_equal(got[name], ref[name]), (name, np.max(np.abs(got[name] - ref[name])))
    from fmpy import read_model_description
    params = {v.name: v.start for v in read_model_description(str(out)).modelVariables if v.causality == "parameter"}
    assert float(params["d.k"]) == 0.75                      # (the archive's parameter set, carried)


def test_an_archive_the_container_cannot_hold_is_refused_in_one_line(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    doc = chain("gauss-seidel")
    doc["experiment"]["stop"] = STOP + STEP / 2              # (off the step's grid: whole steps only)
    sc = write_document(tmp_path / "chain.toml", doc)
    ssp = tmp_path / "chain.ssp"
    assert main(["export-ssp", str(sc), "--out", str(ssp)]) == 0
    capsys.readouterr()
    before = sorted(tmp_path.iterdir())
    assert main(["export-fmu", str(ssp), "--out", str(tmp_path / "Chain.fmu")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wmr-cosim: error: ") and "\n" not in err, err
    assert "chain.ssp: experiment.stop: " in err, err
    assert sorted(tmp_path.iterdir()) == before
