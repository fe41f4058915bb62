"""The execution: owns the instances and the clock, steps them at a fixed communication step with a
Gauss-Seidel or Jacobi algorithm, applies the scenario's events, records, and reports.

Per step k (t_k = start + k h; time is always computed as start + k h, never accumulated):
  * Gauss-Seidel, in the scenario's order: for each instance, set its inputs from the current values of
    the outputs connected to them (an instance later in the order sees the outputs its predecessors
    produced in this step), do the step, get its outputs.
  * Jacobi: set every instance's inputs from the outputs of the previous step, step all, get all.
Initialisation follows the order too: every instance enters initialisation mode; then, in order, each
gets its inputs from the connected outputs and exits initialisation mode.

The run stops at the first non-OK status of any FMU call (Warning included) or the first non-finite value
passed along a connection; non-finite values in recorded outputs stop it at the next flush of the
recording.  What was recorded up to there is on disk.  Every instance is terminated and freed exactly
once, on success, on error and on Ctrl-C, except an instance that reported Fatal (no call at all).
"""
from __future__ import annotations

import ctypes
import json
import os
import shutil
import sys
import tempfile
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .archive import safe_extract
from .errors import EXIT_INTERRUPTED, EXIT_OK, EXIT_RUN_FAILED, CosimError, RunError
from .instance import Instance, real_array, vr_array
from .observer import NpyRecorder, write_csv
from .stepper import InstanceIO, compile_loop, raw
from .system import Plan

#: Rows recorded between two flushes to disk (and progress updates).
FLUSH_ROWS = 2500


@dataclass
class RunResult:
    status: str                 # 'ok', 'failed', 'interrupted'
    message: str
    steps: int
    t_end: float
    wall_s: float               # the stepping loop, first step to last, recording included
    setup_s: float              # extraction, instantiation, initialisation
    out_dir: Path | None
    columns: list[str]
    final: dict[str, float] = field(default_factory=dict)
    fmi_s: float | None = None  # time inside FMI calls (only with timing=True)

    @property
    def exit_code(self) -> int:
        return {"ok": EXIT_OK, "interrupted": EXIT_INTERRUPTED}.get(self.status, EXIT_RUN_FAILED)


def _timed(fn: Any, acc: list[float]) -> Any:
    pc = _time.perf_counter

    def wrapped(*args: Any) -> int:
        t0 = pc()
        r = fn(*args)
        acc[0] += pc() - t0
        return r
    return wrapped


class _Wiring:
    """Where every Real input set by the master takes its value from, and the events' overrides."""

    def __init__(self, plan: Plan, out_arr: dict[str, Any], need: dict[str, list[int]]) -> None:
        self.plan = plan
        self.vrs: dict[str, list[int]] = {n: [] for n in plan.order}
        self.base: dict[tuple[str, int], tuple[Any, int, float, float]] = {}   # (inst, pos) -> source
        self.feeds: dict[tuple[str, int], tuple[str, int]] = {}                 # (inst, pos) -> output (inst, vr)
        for c in plan.connections:
            if c.dst_var.type != "Real":
                continue
            pos = self._pos(c.dst, c.dst_var.vr)
            self.base[(c.dst, pos)] = (out_arr[c.src], need[c.src].index(c.src_var.vr), c.factor, c.offset)
            self.feeds[(c.dst, pos)] = (c.src, c.src_var.vr)
        for ev in plan.events:  # an unconnected input driven by events: its start value until overridden
            if ev.var.causality == "input" and (ev.instance, self._pos(ev.instance, ev.var.vr)) not in self.base:
                start = ev.var.start if ev.var.start is not None else 0.0
                for v, val in plan.instances[ev.instance].parameters:
                    if v.vr == ev.var.vr:
                        start = val
                self.base[(ev.instance, self._pos(ev.instance, ev.var.vr))] = (real_array([float(start)]), 0, 1.0, 0.0)
        self.overrides: dict[tuple[str, int, str], tuple[str, float]] = {}

    def _pos(self, inst: str, vr: int) -> int:
        vrs = self.vrs[inst]
        if vr not in vrs:
            vrs.append(vr)
        return vrs.index(vr)

    def apply(self, ev: Any) -> None:
        key = (ev.instance, ev.var.vr, ev.var.causality)
        if ev.action == "reset":
            self.overrides.pop(key, None)
            return
        prev = self.overrides.get(key)
        if ev.action == "bias" and prev is not None:
            self.overrides[key] = (prev[0], prev[1] + ev.value)
        else:
            self.overrides[key] = (ev.action, float(ev.value))

    def copies(self, inst: str) -> list[tuple[int, Any, int, float, float]]:
        out = []
        for pos, vr in enumerate(self.vrs[inst]):
            arr, i, f, o = self.base[(inst, pos)]
            ov = self.overrides.get((inst, vr, "input"))
            if ov is None and (inst, pos) in self.feeds:
                src, svr = self.feeds[(inst, pos)]
                ov = self.overrides.get((src, svr, "output"))
                if ov is not None and ov[0] == "bias":  # a bias on the output, before the connection's transform
                    ov = ("bias", ov[1] * f)
            if ov is None:
                out.append((pos, arr, i, f, o))
            elif ov[0] == "override":
                out.append((pos, real_array([ov[1]]), 0, 1.0, 0.0))
            else:
                out.append((pos, arr, i, f, o + ov[1]))
        return out


def run(plan: Plan, out_dir: str | os.PathLike | None, progress: bool | None = None,
        timing: bool = False, check_inputs: bool = True) -> RunResult:
    """Run the plan and write its results folder ``out_dir``: signals.npy (written as the run goes),
    signals.csv, scenario.json (the scenario as resolved), logs/<instance>.log and summary.json.
    ``out_dir=None`` runs in a temporary folder that is removed afterwards (the result keeps the
    final values).  ``timing=True`` also measures the time spent inside the stepping FMI calls."""
    sc = plan.scenario
    h, t0, n_steps = sc.step, sc.start, plan.n_steps
    keep = out_dir is not None
    out = Path(out_dir) if keep else Path(tempfile.mkdtemp(prefix="wmr-cosim-out-"))
    out.mkdir(parents=True, exist_ok=True)
    (out / "logs").mkdir(exist_ok=True)
    for stale in ("signals.npy", "signals.csv", "summary.json"):
        (out / stale).unlink(missing_ok=True)
    work = Path(tempfile.mkdtemp(prefix="wmr-cosim-fmus-"))
    instances: dict[str, Instance] = {}
    recorder: NpyRecorder | None = None
    status, message = "ok", ""
    k_done = 0
    setup_s = wall_s = 0.0
    fmi_acc = [0.0]
    columns = ["time"] + [r.column for r in plan.record]
    _write_json(out / "scenario.json", _resolved(plan))
    t_setup = _time.perf_counter()
    bar = None
    stop = _Interrupt()
    try:
        try:
            # ------------------------------------------------------------ set-up
            unz: dict[Path, str] = {}
            for name, ip in plan.instances.items():
                p = ip.model.path.resolve()
                if p not in unz:
                    unz[p] = str(safe_extract(p, work / f"{len(unz)}_{p.stem}"))
                instances[name] = Instance(name, ip.model.md, unz[p])
            for name, inst in instances.items():
                inst.instantiate()
                inst.set_values(plan.instances[name].parameters)
                inst.call("fmi2SetupExperiment", inst.fmu.setupExperiment, None, t0, sc.stop)
            for inst in instances.values():
                inst.call("fmi2EnterInitializationMode", inst.fmu.enterInitializationMode)
            stop.check()

            # the row buffer: time, each instance's Real outputs that are connected or recorded, then
            # recorded Integer/Boolean outputs
            need: dict[str, list[int]] = {n: [] for n in plan.order}
            for c in plan.connections:
                if c.src_var.type == "Real" and c.src_var.vr not in need[c.src]:
                    need[c.src].append(c.src_var.vr)
            for r in plan.record:
                if r.var.type == "Real" and r.var.vr not in need[r.instance]:
                    need[r.instance].append(r.var.vr)
            offset, pos = {}, 1
            for n in plan.order:
                offset[n] = pos
                pos += len(need[n])
            n_real = pos
            extra = [r for r in plan.record if r.var.type != "Real"]
            row = (ctypes.c_double * (n_real + len(extra)))()
            out_arr = {n: (ctypes.c_double * len(need[n])).from_buffer(row, offset[n] * 8) for n in plan.order}
            rec_idx = [0] + [offset[r.instance] + need[r.instance].index(r.var.vr) if r.var.type == "Real"
                             else n_real + extra.index(r) for r in plan.record]
            wiring = _Wiring(plan, out_arr, need)
            other_conns = [c for c in plan.connections if c.dst_var.type != "Real"]

            ios: list[InstanceIO] = []
            for n in plan.order:
                inst = instances[n]
                dll = inst.fmu.dll
                ints = [(r.var.vr, rec_idx[1 + plan.record.index(r)]) for r in extra
                        if r.instance == n and r.var.type in ("Integer", "Enumeration")]
                bools = [(r.var.vr, rec_idx[1 + plan.record.index(r)]) for r in extra
                         if r.instance == n and r.var.type == "Boolean"]
                io = InstanceIO(
                    n, ctypes.c_void_p(inst.c), raw(dll, "fmi2SetReal"), raw(dll, "fmi2DoStep"), raw(dll, "fmi2GetReal"),
                    raw(dll, "fmi2GetInteger"), raw(dll, "fmi2GetBoolean"),
                    vr_array(wiring.vrs[n]), (ctypes.c_double * max(1, len(wiring.vrs[n])))(),
                    ctypes.c_size_t(len(wiring.vrs[n])), vr_array(need[n]), out_arr[n], ctypes.c_size_t(len(need[n])),
                    wiring.copies(n),
                    (vr_array([v for v, _ in ints]), (ctypes.c_int * len(ints))(), ctypes.c_size_t(len(ints)),
                     [s for _, s in ints]) if ints else None,
                    (vr_array([v for v, _ in bools]), (ctypes.c_int * len(bools))(), ctypes.c_size_t(len(bools)),
                     [s for _, s in bools]) if bools else None,
                    [_other_setter(instances, c) for c in other_conns if c.dst == n])
                if timing:
                    io.set_real, io.do_step, io.get_real = (_timed(f, fmi_acc) for f in (io.set_real, io.do_step, io.get_real))
                ios.append(io)

            # initialisation in order: inputs from the connected outputs, then exit initialisation mode
            chunk: list[bytes] = []
            for io in ios:
                inst = instances[io.name]
                for pos_, arr, i, f, o in io.copies:
                    io.in_val[pos_] = arr[i] * f + o if (f != 1.0 or o != 0.0) else arr[i]
                if io.n_in.value:
                    _check(inst, "fmi2SetReal", io.set_real(io.c, io.in_vr, io.n_in, io.in_val), t0)
                for fn in io.other:
                    _check(inst, "fmi2SetInteger/Boolean", fn(), t0)
                inst.call("fmi2ExitInitializationMode", inst.fmu.exitInitializationMode)
                inst.initialised = True
                if io.n_out.value:
                    _check(inst, "fmi2GetReal", io.get_real(io.c, io.out_vr, io.n_out, io.out_val), t0)
            setup_s = _time.perf_counter() - t_setup

            recorder = NpyRecorder(out / "signals.npy", columns)
            row[0] = t0
            _record_extra(ios, instances, row, t0)
            chunk.append(bytes(row))
            rec_cols = np.asarray(rec_idx)

            # ------------------------------------------------------------ stepping
            events = list(plan.events)
            ev_i = 0
            dec = sc.decimation
            block = FLUSH_ROWS * dec
            bar = _progress(progress, n_steps)
            loop = None
            wall0 = _time.perf_counter()
            try:
                k = 0
                while k < n_steps:
                    changed = loop is None
                    while ev_i < len(events) and events[ev_i].step <= k:
                        wiring.apply(events[ev_i])
                        ev_i += 1
                        changed = True
                    if changed:
                        for io in ios:
                            io.copies = wiring.copies(io.name)
                        loop = compile_loop(ios, sc.algorithm, t0, h, dec, n_steps, row, chunk, check_inputs)
                    k_end = min(n_steps, k + block - (k % block))
                    if ev_i < len(events):
                        k_end = min(k_end, max(events[ev_i].step, k + 1))
                    fail = loop(k, k_end)
                    stop.check()
                    if fail is not None:
                        kf, name, what, val = fail
                        k_done = kf if what != "fmi2GetReal" and not what.startswith("fmi2Get") else kf - 1
                        inst = instances[name]
                        tf = t0 + kf * h
                        if what == "inputs":
                            raise _bad_input(plan, name, ios[plan.order.index(name)], tf)
                        raise inst.fail_status(what, int(val), tf)
                    k_done = k = k_end
                    if len(chunk) >= FLUSH_ROWS or k == n_steps:
                        try:
                            _flush(recorder, chunk, rec_cols, columns)
                        except RunError as exc:
                            k_done = int(round((exc.time - t0) / h))
                            raise
                        finally:
                            chunk.clear()
                    if bar is not None:
                        bar.update(k_done - bar.n)
            except KeyboardInterrupt:
                if chunk:  # the steps completed inside the interrupted segment, from the last recorded row
                    k_done = max(k_done, int(round((float(np.frombuffer(chunk[-1], "<f8", 1)[0]) - t0) / h)))
                raise
            finally:
                wall_s = _time.perf_counter() - wall0
                if bar is not None:
                    bar.close()
                if chunk and recorder is not None:
                    try:
                        _flush(recorder, chunk, rec_cols, columns)
                    except RunError as exc:
                        status, message = "failed", str(exc)
                        k_done = min(k_done, int(round((exc.time - t0) / h)))
                    chunk.clear()
        except KeyboardInterrupt:
            status, message = "interrupted", f"interrupted by the user at t = {t0 + k_done * h:.6g} s"
    except RunError as exc:
        status, message = "failed", str(exc)
    except CosimError as exc:
        status, message = "failed", str(exc)
    finally:
        stop.restore()
        for inst in instances.values():
            inst.shutdown()
        if recorder is not None:
            recorder.close()
        shutil.rmtree(work, ignore_errors=True)

    final: dict[str, float] = {}
    if recorder is not None and recorder.rows:
        data = np.load(out / "signals.npy")
        final = {c: float(data[c][-1]) for c in columns}
        if keep and sc.csv:
            write_csv(out / "signals.npy", out / "signals.csv")
    for n, inst in instances.items():
        (out / "logs" / f"{n}.log").write_text("\n".join(inst.all_log) + ("\n" if inst.all_log else ""))
    res = RunResult(status, message, k_done, t0 + k_done * h, wall_s, setup_s, out if keep else None, columns,
                    final, fmi_acc[0] if timing else None)
    _write_json(out / "summary.json", {
        "status": status, "message": message, "steps": k_done, "n_steps": n_steps, "t_end": res.t_end,
        "step": h, "algorithm": sc.algorithm, "wall_s": round(wall_s, 6), "setup_s": round(setup_s, 6),
        "us_per_step": round(wall_s / k_done * 1e6, 3) if k_done else None, "rows": recorder.rows if recorder else 0,
        "instances": {n: {"fmu": str(ip.model.path), "model": ip.model.model_name} for n, ip in plan.instances.items()},
        "final": final,
    })
    if not keep:
        shutil.rmtree(out, ignore_errors=True)
    return res


# ---------------------------------------------------------------------- helpers
class _Interrupt:
    """Ctrl-C during a run: a Python KeyboardInterrupt raised inside an FMU's own Python code (a pythonfmu
    slave runs in this interpreter) would make that FMU report Fatal.  So the first SIGINT only sets a
    flag, checked between loop segments (every few hundredths of a second); a second one interrupts at once."""

    def __init__(self) -> None:
        self.flag = False
        self.old = None
        import signal
        import threading
        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, self._handler)

    def _handler(self, signum, frame) -> None:
        if self.flag:
            raise KeyboardInterrupt
        self.flag = True

    def check(self) -> None:
        if self.flag:
            raise KeyboardInterrupt

    def restore(self) -> None:
        if self.old is not None:
            import signal
            signal.signal(signal.SIGINT, self.old)
            self.old = None


def _bad_input(plan: Plan, name: str, io: InstanceIO, t: float) -> RunError:
    """The first non-finite value the master was about to set on an input of ``name`` (or an overflow of
    their sum, reported as such)."""
    ip = plan.instances[name]
    by_vr = {v.vr: v for v in ip.model.variables.values()}
    vrs = list(io.in_vr)
    for pos, arr, i, f, o in io.copies:
        v = arr[i] * f + o if (f != 1.0 or o != 0.0) else arr[i]
        if v - v != 0.0:
            var = by_vr.get(vrs[pos])
            label = f"{name}.{ip.our_name(var)}" if var is not None else f"{name} input {vrs[pos]}"
            return RunError(f"{label} would receive the non-finite value {v!r} at t = {t:.6g} s", name, t)
    return RunError(f"{name}: the inputs' values overflow (their sum is not finite) at t = {t:.6g} s", name, t)


def _check(inst: Instance, what: str, status: int, t: float) -> None:
    if status:
        raise inst.fail_status(what, status, t)


def _other_setter(instances: dict[str, Instance], c: Any):
    """A closure copying one Integer/Boolean output to an input (get + set: two FMI calls)."""
    src, dst = instances[c.src], instances[c.dst]
    svr, dvr = vr_array([c.src_var.vr]), vr_array([c.dst_var.vr])
    buf = (ctypes.c_int * 1)()
    one = ctypes.c_size_t(1)
    if c.src_var.type == "Integer":
        get, put = raw(src.fmu.dll, "fmi2GetInteger"), raw(dst.fmu.dll, "fmi2SetInteger")
    else:
        get, put = raw(src.fmu.dll, "fmi2GetBoolean"), raw(dst.fmu.dll, "fmi2SetBoolean")
    sc, dc = ctypes.c_void_p(src.c), ctypes.c_void_p(dst.c)

    def copy() -> int:
        return get(sc, svr, one, buf) or put(dc, dvr, one, buf)
    return copy


def _record_extra(ios: list[InstanceIO], instances: dict[str, Instance], row: Any, t: float) -> None:
    """Recorded Integer/Boolean outputs into their row slots (as floats)."""
    for io in ios:
        for spec, getter, what in ((io.rec_int, io.get_integer, "fmi2GetInteger"),
                                   (io.rec_bool, io.get_boolean, "fmi2GetBoolean")):
            if spec is not None:
                vr, buf, n, slots = spec
                _check(instances[io.name], what, getter(io.c, vr, n, buf), t)
                for j, slot in enumerate(slots):
                    row[slot] = float(buf[j])


def _flush(recorder: NpyRecorder, chunk: list[bytes], cols: np.ndarray, columns: list[str]) -> None:
    if not chunk:
        return
    raw_ = np.frombuffer(b"".join(chunk), dtype="<f8")
    block = raw_.reshape(len(chunk), -1)[:, cols]
    finite = np.isfinite(block)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        recorder.append(block[: r + 1])
        raise RunError(f"{columns[c]} is {float(block[r, c])!r} at t = {block[r, 0]:.6g} s (a non-finite output)",
                       columns[c].split(".", 1)[0], float(block[r, 0]))
    recorder.append(block)


def _progress(enabled: bool | None, total: int):
    if enabled is None:
        enabled = sys.stderr.isatty() and total > 5000
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="step", unit_scale=True, leave=False, file=sys.stderr, mininterval=0.5)


def _resolved(plan: Plan) -> dict[str, Any]:
    sc = plan.scenario
    return {"file": sc.file, "experiment": {"start": sc.start, "stop": sc.stop, "step": sc.step,
                                            "algorithm": sc.algorithm, "order": sc.order},
            "instances": {n: {"fmu": str(ip.model.path), "model": ip.model.model_name,
                              "parameters": {v.name: val for v, val in ip.parameters},
                              "names": ip.spec.names, "units": ip.spec.units}
                          for n, ip in plan.instances.items()},
            "connections": [{"from": c.spec.src, "to": c.spec.dst, "factor": c.factor, "offset": c.offset}
                            for c in plan.connections],
            "record": [r.column for r in plan.record], "decimation": sc.decimation,
            "events": [{"time": e.time, "variable": e.ref, "action": e.action, "value": e.value} for e in plan.events],
            "document": sc.data}


def _write_json(path: Path, obj: Any) -> None:
    path.write_text(json.dumps(obj, indent=2, default=str) + "\n")
