"""Which class hosts an instance: the table of instance kinds (cosim.instances.kinds) and its two readers,
the start-up (an instance in the master's process) and the isolation child (the same instance in a child
process), which must host every kind by the same class with the same arguments."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from wmr_cosim.cosim.instances import isolation, kinds
from wmr_cosim.cosim.instances.integrators import SolverSpec
from wmr_cosim.cosim.instances.model_exchange import ModelExchange
from wmr_cosim.cosim.model.description import CO_SIMULATION, MODEL_EXCHANGE, SCHEDULED_EXECUTION
from wmr_cosim.cosim.runtime import startup

ALL_KINDS = [(CO_SIMULATION, 2), (CO_SIMULATION, 3), (MODEL_EXCHANGE, 2), (MODEL_EXCHANGE, 3)]
#: Hosted in the master's process only (``check`` refuses to isolate it).
IN_PROCESS_ONLY = [(SCHEDULED_EXECUTION, 3)]


def test_every_kind_has_the_class_of_its_interface_and_fmi_version():
    assert sorted(kinds.HOSTS) == sorted(ALL_KINDS + IN_PROCESS_ONLY)
    for (interface, fmi), cls in kinds.HOSTS.items():
        assert cls.fmi_version == fmi, cls
        assert issubclass(cls, ModelExchange) == (interface == MODEL_EXCHANGE), cls


@pytest.mark.parametrize("kind", ALL_KINDS, ids=lambda k: f"{k[0]}-fmi{k[1]}")
def test_the_start_up_and_the_isolation_child_host_a_kind_alike(kind, monkeypatch):
    """Each kind's class replaced by a stub that keeps its arguments: the start-up's and the child's
    instance are that stub, made with the same arguments."""
    stubs = {}
    for k in ALL_KINDS:
        stubs[k] = type(f"Stub_{k[0]}_{k[1]}", (), {"__init__": lambda self, *args: setattr(self, "args", args)})
        monkeypatch.setitem(kinds.HOSTS, k, stubs[k])
    interface, fmi = kind
    md = SimpleNamespace(fmiVersion="2.0" if fmi == 2 else "3.0")
    solver = SolverSpec("cvode", 1e-6) if interface == MODEL_EXCHANGE else None
    ip = SimpleNamespace(spec=SimpleNamespace(isolate=False, logging="all"), solver=solver, interface=interface,
                         model=SimpleNamespace(md=md, fmi=fmi, path=Path("m.fmu")))
    here = startup._host("p", ip, "/unz", Path("/logs/p.log"), None)
    there = isolation._hosted("p", md, "/unz", "/logs/p.log", "all",
                              json.dumps(dataclasses.asdict(solver)) if solver is not None else "")
    assert type(here) is type(there) is stubs[kind]
    assert [str(a) if isinstance(a, Path) else a for a in here.args] == list(there.args)
