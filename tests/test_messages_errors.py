"""The master's errors cross process boundaries whole: a worker process (the paper job's pool, a Dask
worker) raises them, and the parent gets the same class, message and fields back (an error that did not
unpickle would break a process pool)."""
from __future__ import annotations

import pickle
from concurrent.futures import ProcessPoolExecutor

import pytest

from wmr_cosim.cosim.messages.errors import (CosimError, FmuLoadError, MissingVariableError, OtherFileError, OutputError,
                                             RunError, ScenarioError)
from wmr_cosim.cosim.instances.failure import InstanceLost

ERRORS = [CosimError("one line"), ScenarioError("s.toml", "instances.a.fmu", "file not found"),
          ScenarioError("s.toml", "", "not TOML"), OtherFileError("g.toml", "a sweep file"),
          MissingVariableError("s.toml", "connections[0].to", "plant (P.fmu) has no variable 'u'", "plant.u"),
          FmuLoadError("x.fmu: not an FMU"), OutputError("out: locked"),
          RunError("plant: fmi2DoStep returned Error at t = 1 s", "plant", 1.0),
          InstanceLost("plant: the FMU's process was killed by SIGSEGV", "plant", 0.25)]
FIELDS = ("file", "field", "reason", "kind", "instance", "time", "ref")


def _same(a: BaseException, b: BaseException) -> None:
    assert type(a) is type(b) and str(a) == str(b)
    assert {f: getattr(a, f, None) for f in FIELDS} == {f: getattr(b, f, None) for f in FIELDS}


@pytest.mark.parametrize("err", ERRORS, ids=lambda e: type(e).__name__)
def test_an_error_unpickles_as_it_was(err):
    _same(pickle.loads(pickle.dumps(err)), err)


def _raise(i: int) -> None:
    raise ERRORS[i]


def test_an_error_raised_in_a_worker_process_reaches_the_parent_as_it_was():
    with ProcessPoolExecutor(1) as pool:
        for i, err in enumerate(ERRORS):
            with pytest.raises(type(err)) as got:
                pool.submit(_raise, i).result(timeout=60)
            _same(got.value, err)
