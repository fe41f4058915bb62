"""Run an SSP archive under third-party co-simulation masters, each as its users run it, for the interop
tests and the ``interop`` benchmark.

Peers (each in a child process of its own, ``python tests/interop.py PEER FILE.ssp``, so that a crash
of a foreign master cannot take the caller down, module caches are fresh, and CPU pinning stays local):

- ``ours``: this master (``load_ssp`` + ``resolve`` + ``run_plan``; Jacobi unless the archive says);
- ``libcosim``: libcosimpy's ``CosimExecution.from_ssp_file`` (step from the archive's OSP annotation),
  a time-series observer, ``simulate_until(stop)``;
- ``libcosim_api``: the same system built through libcosim's API (``add_local_slave``,
  ``*_initial_value`` for the parameters, ``connect_real_variables``);
- ``ecos``: ecospy's ``EcosSimulation(ssp_path, step)``, ``init(parameter_set="parameters")``, a CSV
  writer of the signals, ``step(n)`` (``step_until(stop)`` accumulates time and stops one step short);
- ``ecos_pinned``: the same, the process pinned to one core (ecos steps its models on threads; with every
  pythonfmu call serialised by the GIL the threads only contend);
- ``ecos_cli``: ecos's command-line program on the archive (a non-Python host: see :func:`ecos_cli_env`);
- ``fmpy_ssp``: FMPy's ``simulate_ssp`` (SSP 1.0 only, Jacobi, no LinearTransformation, parameters passed
  as a parameter set with names ``component.variable``, no String parameters).

Every peer returns the signals named ``instance.variable`` as float arrays, the wall time of the run
(creating the execution, initialisation and stepping, recording included; not the import of the library
nor the reading of results), and the number of steps.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from wmr_cosim.cosim import RunStatus

import numpy as np

#: What the tests and the benchmark compare: tracking errors, weights, the goal time, the position of A.
SIGNALS = ("plant.x_A", "plant.y_A", "controller.e1", "controller.e2", "controller.edot1", "controller.edot2",
           "controller.t_goal", "controller.W1", "controller.W2", "controller.W3")
PEERS = ("ours", "libcosim", "libcosim_api", "ecos", "ecos_pinned", "ecos_cli", "fmpy_ssp")
PARAMETER_SET = "parameters"


class PeerError(RuntimeError):
    """A third-party master could not run the archive (one line)."""


# ------------------------------------------------------------------------------------------ helpers
def tbb_library() -> Path | None:
    """libtbb.so.12 as installed by the ``tbb`` wheel (into <prefix>/lib, not on the loader's path)."""
    for base in (sys.prefix, sys.base_prefix):
        p = Path(base) / "lib" / "libtbb.so.12"
        if p.is_file():
            return p
    return None


def _load_ecospy():
    """Import ecospy, preloading libtbb.so.12 from the tbb wheel (ecospy's library needs it and the
    wheel puts it where the dynamic loader does not look)."""
    import ctypes
    tbb = tbb_library()
    if tbb is not None:
        ctypes.CDLL(str(tbb), mode=ctypes.RTLD_GLOBAL)
    import ecospy
    ecospy.EcosLib.set_log_level("warn")
    return ecospy


def ecos_cli_env() -> tuple[list[str], dict[str, str], Path]:
    """The ecos command line, the environment it runs in and a temporary folder the caller removes.

    The environment is empty but for ``LD_LIBRARY_PATH`` to ``libtbb.so.12``, which the program itself needs
    (the ``tbb`` wheel puts it where the loader does not look): no ``LD_PRELOAD``, no ``PATH`` or
    ``PYTHONHOME``, as a user's C host has it; our FMUs' loader finds their Python itself.  The wheel
    installs the program without its execute bit: a copy is made executable in the temporary folder,
    which is also the program's TMPDIR (its extraction folders, ecos_ssp_* and ecos_<model>_*, go there)."""
    import importlib.util
    spec = importlib.util.find_spec("ecospy")  # located, not imported (that would load its library)
    if spec is None or not spec.submodule_search_locations:
        raise PeerError("ecospy is not installed")
    src = Path(list(spec.submodule_search_locations)[0]) / "binaries" / "ecos"
    if not src.is_file():
        raise PeerError(f"{src}: ecos program not found in the ecospy wheel")
    tmp = Path(tempfile.mkdtemp(prefix="wmr-ecos-cli-"))
    exe = tmp / "ecos"
    shutil.copyfile(src, exe)
    exe.chmod(0o755)
    env: dict[str, str] = {}
    tbb = tbb_library()
    if tbb is not None:
        env["LD_LIBRARY_PATH"] = str(tbb.parent)
    env["TMPDIR"] = str(tmp)
    return [str(exe)], env, tmp


def _n_steps(start: float, stop: float, step: float) -> int:
    return int(round((stop - start) / step))


# ------------------------------------------------------------------------------------------ peers
def _ours(ssp: Path, stop: float, step: float, signals, tmp: Path, algorithm: str | None = None) -> dict[str, Any]:
    from wmr_cosim.cosim import load_ssp, resolve, run as run_plan

    t0 = time.perf_counter()
    arch = load_ssp(ssp, step=step, stop=stop, algorithm=algorithm)
    try:
        arch.scenario.record = list(signals)
        arch.scenario.csv = False  # the recording in signals.npy, as the others record in memory or one CSV
        plan = resolve(arch.scenario)
        res = run_plan(plan, tmp / "ours", progress=False)
        wall = time.perf_counter() - t0
    finally:
        arch.cleanup()
    if res.status != RunStatus.OK:
        raise PeerError(f"ours: {res.message}")
    data = np.load(tmp / "ours" / "signals.npy")
    return {"wall_s": wall, "loop_s": res.wall_s, "steps": res.steps, "t_end": res.t_end,
            "signals": {s: np.asarray(data[s], float) for s in signals}}


def _libcosim_observe(ex, names_by_slave: dict[str, int], signals, n: int):
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimObserver import CosimObserver

    obs = CosimObserver.create_time_series(buffer_size=n + 10)
    ex.add_observer(obs)
    refs = {}
    for sig in signals:
        inst, var = sig.split(".", 1)
        idx = names_by_slave[inst]
        vr = {v.name.decode(): v.reference for v in ex.slave_variables(idx)}[var]
        obs.start_time_series(idx, vr, CosimVariableType.REAL)
        refs[sig] = (idx, vr)
    return obs, refs


def _libcosim_collect(obs, refs, n):
    out = {}
    for sig, (idx, vr) in refs.items():
        _, steps, vals = obs.time_series_real_samples(idx, vr, from_step=1, sample_count=n)
        out[sig] = np.asarray(vals, float)
    return out


def _libcosim(ssp: Path, stop: float, step: float, signals, tmp: Path, api: bool = False) -> dict[str, Any]:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    ns = lambda s: int(round(s * 1e9))  # noqa: E731  (libcosim counts time in integer nanoseconds)
    n = _n_steps(0.0, stop, step)
    keep = []
    t0 = time.perf_counter()
    if not api:
        ex = CosimExecution.from_ssp_file(str(ssp))
        idx = {s.name.decode(): s.index for s in ex.slave_infos()}
    else:
        from wmr_cosim.cosim import load_model, load_ssp
        arch = load_ssp(ssp)
        keep.append(arch)
        ex = CosimExecution.from_step_size(ns(step))
        idx = {}
        for name, spec in arch.scenario.instances.items():
            slave = CosimLocalSlave(fmu_path=str(spec.fmu_path), instance_name=name)
            keep.append(slave)
            idx[name] = ex.add_local_slave(slave)
            model = load_model(spec.fmu_path)
            for pname, value in spec.parameters.items():
                v = model.variables[pname]
                setter = {"Real": ex.real_initial_value, "Integer": ex.integer_initial_value,
                          "Enumeration": ex.integer_initial_value, "Boolean": ex.boolean_initial_value,
                          "String": ex.string_initial_value}[v.type]
                if not setter(idx[name], v.vr, value):
                    raise PeerError(f"libcosim: cannot set {name}.{pname} = {value!r}")
        models = {n_: load_model(s.fmu_path) for n_, s in arch.scenario.instances.items()}
        for c in arch.scenario.connections:
            si, sv = c.src.split(".", 1)
            di, dv = c.dst.split(".", 1)
            if c.factor != 1.0 or c.offset != 0.0:
                raise PeerError("libcosim_api: linear transforms are not mapped (use the SSP peer)")
            rc = ex.connect_real_variables(idx[si], models[si].variables[sv].vr, idx[di], models[di].variables[dv].vr)
            if rc != 0:  # 0 is success here (libcosimpy returns the C status)
                raise PeerError(f"libcosim: cannot connect {c.src} -> {c.dst}")
    obs, refs = _libcosim_observe(ex, idx, signals, n)
    ok = ex.simulate_until(ns(stop))
    wall = time.perf_counter() - t0
    if not ok:
        raise PeerError("libcosim: simulate_until failed")
    t_end = ex.status().current_time / 1e9
    sig = _libcosim_collect(obs, refs, n)
    for a in keep:
        if hasattr(a, "cleanup"):
            a.cleanup()
    return {"wall_s": wall, "steps": len(next(iter(sig.values()))), "t_end": t_end, "signals": sig}


def _read_ecos_csv(path: Path, signals) -> dict[str, np.ndarray]:
    with path.open() as fh:
        head = [h.strip() for h in fh.readline().split(",")]
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    col = {h.split("[")[0].strip(): i for i, h in enumerate(head)}
    out = {}
    for s in signals:
        key = s.replace(".", "::", 1)
        if key not in col:
            raise PeerError(f"ecos: {key} not in its CSV output")
        out[s] = data[:, col[key]]
    out["time"] = data[:, col["time"]]
    return out


def _ecos(ssp: Path, stop: float, step: float, signals, tmp: Path, pinned: bool = False) -> dict[str, Any]:
    if pinned:
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    ecospy = _load_ecospy()
    n = _n_steps(0.0, stop, step)
    csv = tmp / "ecos.csv"
    t0 = time.perf_counter()
    sim = ecospy.EcosSimulation(ssp_path=str(ssp), step_size=step)
    try:
        sim.add_csv_writer(str(csv), identifiers=[s.replace(".", "::", 1) for s in signals])
        if not sim.init(parameter_set=PARAMETER_SET):
            raise PeerError(f"ecos: init failed: {ecospy.EcosLib.get_last_error()}")
        t_end = sim.step(n)
        sim.terminate()
        wall = time.perf_counter() - t0
    finally:
        sim.free()
    sig = _read_ecos_csv(csv, signals)
    sig.pop("time")
    sig = {k: v[1:] for k, v in sig.items()}  # the first row is the initial state
    return {"wall_s": wall, "steps": len(next(iter(sig.values()))), "t_end": t_end, "signals": sig}


def _ecos_cli(ssp: Path, stop: float, step: float, signals, tmp: Path) -> dict[str, Any]:
    cmd, env, ecos_tmp = ecos_cli_env()
    try:
        cfg = tmp / "CsvConfig.xml"
        by_inst: dict[str, list[str]] = {}
        for s in signals:
            i, v = s.split(".", 1)
            by_inst.setdefault(i, []).append(v)
        ns = "http://github.com/Ecos-platform/libecos/resources/schema/CsvConfig"
        cfg.write_text(f'<?xml version="1.0" encoding="UTF-8"?>\n<ecos:CsvConfig xmlns:ecos="{ns}"><ecos:components>'
                       + "".join(f'<ecos:component name="{i}">' + "".join(f'<ecos:variable name="{v}"/>' for v in vs)
                                 + "</ecos:component>" for i, vs in by_inst.items())
                       + "</ecos:components></ecos:CsvConfig>\n")
        t0 = time.perf_counter()
        p = subprocess.run(cmd + ["simulate", "--path", str(ssp), "--stepSize", repr(step), "--stopTime", repr(stop),
                                  "--parameterSet", PARAMETER_SET, "--csvConfig", str(cfg), "--logLevel", "warn"],
                           cwd=tmp, env=env, capture_output=True, text=True, timeout=600)
        wall = time.perf_counter() - t0
        if p.returncode != 0:
            tail = " ".join((p.stderr or p.stdout).strip().splitlines()[-3:])
            raise PeerError(f"ecos command line: exit {p.returncode}: {tail}")
        csvs = sorted(tmp.glob("*.csv"))
        if not csvs:
            raise PeerError("ecos command line: no CSV written")
        sig = _read_ecos_csv(csvs[0], signals)
        t = sig.pop("time")
        sig = {k: v[1:] for k, v in sig.items()}
        return {"wall_s": wall, "steps": len(t) - 1, "t_end": float(t[-1]), "signals": sig}
    finally:
        shutil.rmtree(ecos_tmp, ignore_errors=True)


def fmpy_parameter_set(ssp: Path):
    """The archive's parameters as FMPy's ``simulate_ssp`` takes them (it does not read the SSD's
    bindings): names ``component.variable``.  FMPy's runner sets only Real, Integer and Boolean values
    (a String raises in its ``set_value``; a Boolean is set as ``value != 0.0``, so it must be a bool, not
    the text 'false'): a String parameter equal to the FMU's start value is left out, any other refused."""
    from fmpy.ssp.ssd import Parameter, ParameterSet

    from wmr_cosim.cosim import load_model, load_ssp

    arch = load_ssp(ssp)
    try:
        ps = ParameterSet(name=PARAMETER_SET)
        for inst, spec in arch.scenario.instances.items():
            model = load_model(spec.fmu_path)
            for pname, value in spec.parameters.items():
                v = model.variables[pname]
                if v.type == "String":
                    if value != v.start:
                        raise PeerError(f"fmpy_ssp: FMPy's SSP runner cannot set the String parameter "
                                        f"{inst}.{pname} = {value!r}")
                    continue
                ps.parameters.append(Parameter(name=f"{inst}.{pname}", type=v.type, value=value))
        return ps
    finally:
        arch.cleanup()


def _fmpy_ssp(ssp: Path, stop: float, step: float, signals, tmp: Path) -> dict[str, Any]:
    from fmpy.ssp.simulation import simulate_ssp

    t0 = time.perf_counter()
    ps = fmpy_parameter_set(ssp)
    r = simulate_ssp(str(ssp), start_time=0.0, stop_time=stop, step_size=step, parameter_set=ps)
    wall = time.perf_counter() - t0
    missing = [s for s in signals if s not in r.dtype.names]
    if missing:
        raise PeerError(f"fmpy_ssp: {', '.join(missing)} not among the archive's connectors")
    # FMPy labels each row with the time at the START of the step whose outputs it holds
    return {"wall_s": wall, "steps": len(r), "t_end": float(r["time"][-1] + step),
            "signals": {s: np.asarray(r[s], float) for s in signals}}


_RUNNERS = {"ours": _ours, "libcosim": _libcosim,
            "libcosim_api": lambda *a: _libcosim(*a, api=True), "ecos": _ecos,
            "ecos_pinned": lambda *a: _ecos(*a, pinned=True), "ecos_cli": _ecos_cli, "fmpy_ssp": _fmpy_ssp}


def run_here(peer: str, ssp: Path, stop: float, step: float, signals=SIGNALS) -> dict[str, Any]:
    """Run ``peer`` in this process (see :func:`run_peer` for a child process)."""
    if peer not in _RUNNERS:
        raise PeerError(f"unknown peer {peer!r}: one of {', '.join(PEERS)}")
    tmp = Path(tempfile.mkdtemp(prefix=f"wmr-peer-{peer}-"))
    # every temporary file of the peer goes into tmp, removed afterwards: ecos leaves its ecos_ssp_* and
    # ecos_<model>_* extraction folders in the temporary folder (TMPDIR) otherwise
    saved = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"] = tempfile.tempdir = str(tmp)
    try:
        return _RUNNERS[peer](Path(ssp).resolve(), float(stop), float(step), tuple(signals), tmp)
    finally:
        if saved[0] is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = saved[0]
        tempfile.tempdir = saved[1]
        shutil.rmtree(tmp, ignore_errors=True)


def run_peer(peer: str, ssp: str | os.PathLike, stop: float, step: float, signals=SIGNALS,
             timeout: float = 600.0) -> dict[str, Any]:
    """Run ``peer`` on the archive in a child process; returns {'wall_s', 'steps', 't_end', 'signals'}."""
    with tempfile.TemporaryDirectory(prefix="wmr-peer-") as tmp:
        out = Path(tmp) / "result.npz"
        cmd = [sys.executable, str(Path(__file__).resolve()), peer, str(ssp), "--stop", repr(stop), "--step",
               repr(step), "--out", str(out), "--signals", ",".join(signals)]
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        if p.returncode != 0 or not out.is_file():
            tail = " ".join((p.stderr or p.stdout).strip().splitlines()[-2:])
            raise PeerError(f"{peer}: exit {p.returncode}: {tail}")
        with np.load(out) as z:
            meta = json.loads(str(z["meta"]))
            meta["signals"] = {s: z[f"sig:{s}"] for s in signals}
        return meta


def main(argv: list[str] | None = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python tests/interop.py", description=__doc__.splitlines()[0])
    ap.add_argument("peer", choices=PEERS)
    ap.add_argument("ssp", type=Path)
    ap.add_argument("--stop", type=float, required=True)
    ap.add_argument("--step", type=float, required=True)
    ap.add_argument("--signals", default=",".join(SIGNALS))
    ap.add_argument("--out", type=Path, default=None, help="write the signals and figures to this .npz")
    args = ap.parse_args(argv)
    signals = tuple(s for s in args.signals.split(",") if s)
    from wmr_cosim.exit_codes import OK, RUN_FAILED

    try:
        r = run_here(args.peer, args.ssp, args.stop, args.step, signals)
    except PeerError as exc:
        print(f"{args.peer}: {exc}", file=sys.stderr)
        return RUN_FAILED
    meta = {k: v for k, v in r.items() if k != "signals"}
    if args.out is not None:
        np.savez(args.out, meta=json.dumps(meta), **{f"sig:{k}": v for k, v in r["signals"].items()})
    print(json.dumps(meta))
    return OK


if __name__ == "__main__":
    sys.exit(main())
