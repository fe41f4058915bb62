"""From a plan to instances ready to step: each FMU extracted once, each instance hosted (in this process
or in a child), instantiated, set up and initialised with its inputs at their fixed point, and each one's
view for the algorithm (:class:`.algorithm.InstanceIO`).

Life cycle, in the order FMPy and libcosim use (some tools' FMUs, 20-sim's among them, reset their
parameters in fmi2SetupExperiment, so values set before it would be lost): instantiate, set up the
experiment, set parameters and start values, enter initialisation mode, exchange outputs to inputs until
nothing changes, exit initialisation mode.
"""
from __future__ import annotations

import ctypes
import os
import time as _time
from pathlib import Path
from typing import Any, Callable

from ..instances.clocked import Clocked3, ClockedME3, ClockEvents
from ..instances.contract import FmuInstance
from ..instances.handoff import Handoff
from ..instances.in_process import vr_array
from ..instances.integrators import SolverSpec
from ..instances.kinds import host
from ..instances.scheduled import ScheduledExecution3
from ..messages.errors import CosimError, FmuLoadError
from ..model.archive import run_members, safe_extract
from ..model.binary import load_failure
from ..model.description import CO_SIMULATION, MODEL_EXCHANGE, PLATFORMS
from ..plan.records import InstancePlan, Plan
from ..plan.wiring import RowLayout, Wiring, discrete_copier, table_feeder
from ..stepping.algorithm import InstanceIO
from .observers import RecordedGetter


def handoff_for(plan: Plan) -> Handoff | None:
    """How the run's child processes and the master wait for each other (None: no instance isolated)."""
    n_isolated = sum(q.spec.isolate for q in plan.instances.values())
    if not n_isolated:
        return None
    from ..instances.isolation import spin_for
    return Handoff(spin_for(n_isolated))


def load_instances(plan: Plan, work: Path, logs: Path, handoff: Handoff | None = None) -> dict[str, FmuInstance]:
    """Extract every FMU file once (into ``work``; what a run needs of it: :func:`..model.archive.run_members`) and host each instance of the plan: in a child process
    where it says ``isolate`` (waiting for each other as ``handoff`` chooses; None: a new one,
    :func:`handoff_for`), else in this one; as co-simulation or, where the plan says, as model exchange with
    its integrator; its log goes to ``logs/<instance>.log``."""
    unz: dict[Path, str] = {}
    instances: dict[str, FmuInstance] = {}
    handoff = handoff if handoff is not None else handoff_for(plan)
    for name, ip in plan.instances.items():
        p = ip.model.path.resolve()
        if p not in unz:
            unz[p] = str(safe_extract(p, work / f"{len(unz)}_{p.stem}", plan.archive_limits,
                                      run_members(PLATFORMS[ip.model.fmi])))
        instances[name] = _host(name, ip, unz[p], logs / f"{name}.log", handoff, plan.scenario.times())
    for lk in plan.clock_links:   # (the instances with clocks in co-simulation)
        dst, src = instances[lk.dst], instances[lk.src]
        assert isinstance(dst, ClockEvents) and isinstance(src, ClockEvents)
        dst.connect_clock(lk.dst_clock, src, lk.src_clock)
    return instances


def _host(name: str, ip: InstancePlan, unzipdir: str, log: Path, handoff: Handoff | None,
          plan_times: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> FmuInstance:
    """Instance ``name`` hosted: in a child process, or here by the class of its kind (co-simulation, or
    model exchange where the plan gives it an integrator; FMI 2.0 or 3.0: :data:`.instances.kinds.HOSTS`,
    the table the isolation child reads too).  A binary
    the loader refuses (``check`` reads its header and exports, not what it links against) ends the run
    with one line naming the instance, the FMU and the loader's reason; FMPy changes the working folder to
    the binary's for the load and leaves it there when the load fails: it is restored here."""
    cwd = os.getcwd()
    try:
        if ip.spec.isolate:
            from ..instances.isolation import IsolatedInstance
            assert handoff is not None   # (handoff_for gives one where an instance is isolated)
            return IsolatedInstance(name, ip.model.md, unzipdir, log, ip.spec.logging,
                                    ip.spec.step_timeout or 60.0, handoff, ip.solver)
        if getattr(ip.model, "clocks", None) and ip.interface in (CO_SIMULATION, MODEL_EXCHANGE):   # clocks on the grid
            clocked: Clocked3 | ClockedME3 = Clocked3(name, ip.model.md, unzipdir, log, ip.spec.logging) \
                if ip.interface == CO_SIMULATION else \
                ClockedME3(name, ip.model.md, unzipdir, log, ip.spec.logging, ip.solver or SolverSpec())
            start, _, step = plan_times
            clocked.schedule(start, step, ip.spec.clock_ticks)
            return clocked
        inst = host(name, ip.model.md, ip.model.fmi, unzipdir, log, ip.spec.logging, ip.solver, ip.interface)
        if isinstance(inst, ScheduledExecution3):   # its scheduler on the master's grid
            start, _, step = plan_times
            inst.schedule(start, step, ip.spec.clock_ticks)
        return inst
    except CosimError:
        raise
    except Exception as exc:   # FMPy raises a plain Exception when the library does not load
        os.chdir(cwd)
        raise FmuLoadError(f"{name}: {ip.model.path.name}: {load_failure(exc, unzipdir)}") from None


def recorded_types(plan: Plan) -> list[str]:
    """The FMI type of each recorded column, time first (an FMI 3.0 Enumeration is recorded as its Int64)."""
    return ["Real"] + ["Int64" if r.var.fmi_type == "Enumeration" and plan.instances[r.instance].model.fmi == 3
                       else r.var.fmi_type for r in plan.record]


def set_up(plan: Plan, instances: dict[str, FmuInstance]) -> None:
    """Instantiate, set up the experiment, set parameters and start values, enter initialisation mode."""
    sc = plan.scenario
    assert sc.start is not None   # (resolved)
    for name, inst in instances.items():
        inst.instantiate()
        inst.setup_experiment(sc.start, sc.stop, plan.instances[name].tolerance)
        inst.set_values(plan.instances[name].parameters)
    for inst in instances.values():
        inst.enter_initialization()


def instance_io(plan: Plan, name: str, inst: FmuInstance, layout: RowLayout, wiring: Wiring,
                instances: dict[str, FmuInstance], timing: list[float] | None = None) -> InstanceIO:
    """The algorithm's view of instance ``name``: its fast path, input and output arrays, copies, tables and
    other connections; ``timing``: accumulate the time inside its step calls there."""
    vrs, nvals = wiring.vrs[name], len(wiring.values[name])
    out_vrs = [vr for vr, _ in layout.reals[name]]
    fast = inst.fast_path(vrs, nvals, out_vrs, sum(size for _, size in layout.reals[name]))
    discrete = [c for c in plan.connections if c.dst == name and not c.is_float64]
    if timing is not None:
        fast.set_real, fast.do_step, fast.get_real = (timed(f, timing) for f in (fast.set_real, fast.do_step,
                                                                                  fast.get_real))
    return InstanceIO(
        name, fast, in_vr=vr_array(vrs), n_in=ctypes.c_size_t(len(vrs)), out_vr=vr_array(out_vrs),
        out_val=layout.out_arr[name], n_out=ctypes.c_size_t(len(layout.reals[name])), copies=wiring.copies(name),
        other=[discrete_copier(instances, c) for c in discrete], reads=tuple(c.src for c in discrete),
        feed=table_feeder(inst, wiring.tables.get(name),
                          [ip for ip in plan.inputs if ip.instance == name and not ip.var.is_float64]),
        can_roll_back=inst.can_get_and_set_state, get_state=inst.get_state, set_state=inst.set_state, free_state=inst.free_state,
        allow_rollback=inst.allow_rollback, set_input_derivatives=inst.set_input_derivatives,
        directional_derivative=inst.directional_derivative, decimation=plan.instances[name].decimation)


def recorded_getters(plan: Plan, instances: dict[str, FmuInstance], lay: RowLayout) -> list[RecordedGetter]:
    """For the recording, in the plan's order: one getter per instance and FMI type of its recorded outputs
    that are not Float64 (the Float64 ones are in the row buffer already)."""
    out = []
    for name in plan.order:
        inst, recs = instances[name], [r for r in lay.extra if r.instance == name]
        for t in sorted({r.var.fmi_type for r in recs}):
            mine = [r for r in recs if r.var.fmi_type == t]
            vars_ = list({r.var.vr: r.var for r in mine}.values())
            start = {}
            i = 0
            for v in vars_:
                start[v.vr] = i
                i += v.size
            get, ctype = inst.accessor(t, "Get")
            out.append(RecordedGetter(name, get, vr_array([v.vr for v in vars_]), ctypes.c_size_t(len(vars_)),
                                      (ctype * i)(), ctypes.c_size_t(i),
                                      [(start[r.var.vr] + r.elem, lay.slot(r)) for r in mine], inst.fail_status))
    return out


def exchange_initial(ios: list[InstanceIO], instances: dict[str, FmuInstance], wiring: Wiring, layout: RowLayout,
                     t0: float, check_inputs: bool) -> None:
    """In initialisation mode: outputs to inputs in the plan's order, pass after pass, until no input
    changes (a chain of N instances settles in at most N passes, whatever the order)."""
    read_outputs(ios, instances, t0)
    last: list[float] | None = None
    for _ in range(len(ios) + 1):
        values: list[float] = []
        for io in ios:
            inst = instances[io.name]
            if io.feed is not None:
                check(inst, "fmi2Set (tabulated inputs)", io.feed(0), t0)
            for pos, arr, i, f, o in io.copies:
                io.in_val[pos] = arr[i] * f + o if (f != 1.0 or o != 0.0) else arr[i]
                values.append(io.in_val[pos])
            if check_inputs and any(v - v != 0.0 for v in io.in_val[:len(wiring.values[io.name])]):
                raise wiring.bad_input(io.name, io.in_vr, io.copies, t0)
            if io.n_in.value:
                check(inst, "set inputs", io.set_inputs(), t0)
            for fn in io.other:
                check(inst, "set inputs (a connection)", fn(), t0)
            if io.n_out.value:
                check(inst, "get outputs", io.get_outputs(), t0)
        if values == last:
            break
        last = values


def read_outputs(ios: list[InstanceIO], instances: dict[str, FmuInstance], t: float) -> None:
    """Every instance's Float64 outputs into the row."""
    for io in ios:
        if io.n_out.value:
            check(instances[io.name], "get outputs", io.get_outputs(), t)


def check(inst: FmuInstance, what: str, status: int, t: float) -> None:
    """A non-OK status of ``what`` as the instance's RunError."""
    if status:
        raise inst.fail_status(what, status, t)


def timed(fn: Callable[..., int], acc: list[float]) -> Callable[..., int]:
    """``fn`` with the time spent inside it added to ``acc[0]`` [s]."""
    pc = _time.perf_counter

    def wrapped(*args: Any) -> int:
        t0 = pc()
        r = fn(*args)
        acc[0] += pc() - t0
        return r
    return wrapped
