"""Out-of-process instances: an FMU hosted in a child process, so that a crash (any signal, abort, exit)
or a hang inside the FMU cannot take the master down.

The child (``python -m wmr_cosim.cosim.isolation``) loads the FMU with FMPy and serves two channels:

- the **step slot**, a block of shared memory per instance: the Float64 inputs and outputs in place (the
  master's input array and the child's output array *are* this memory), the time and the step size, the
  status; a step is one byte each way on a pair of pipes ("step" from the master, "done" from the child),
  with no pickling: the master sets the inputs by writing them, the child calls fmi2SetReal, fmi2DoStep
  and fmi2GetReal and writes the outputs;
- the **control channel**, length-prefixed pickled requests on another pair of pipes, for everything else
  (instantiate, set-up, start values, initialisation, other types, state, terminate, free).

A child that dies is seen at once (end of file on its pipe): the master reports the instance, the time
and how it died (the signal's name, or the exit code). A step that takes longer than ``step_timeout``
seconds ends the child (SIGKILL) and is reported the same way; the child's first answer (its interpreter
starting, its imports, the FMU loaded) may take up to ``STARTUP_TIMEOUT`` seconds whatever the step
timeout, so that a short step timeout does not end a child that a loaded machine starts slowly. The
child's standard output and error go
to a file beside the instance's log, so an FMU writing junk to stdout cannot disturb anything.
"""
from __future__ import annotations

import ctypes
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
from multiprocessing import shared_memory
from pathlib import Path
from typing import Any

#: Header of the step slot: status (int64), t (float64), h (float64), then inputs and outputs (float64).
_HEAD = 24
#: Polls of the other side's pipe before blocking on it (a few tens of microseconds): the answer to a step,
#: and the next step's request, usually come within that, which saves the scheduler's wake-up each way.
#: Only while every child can have a core of its own beside the master (see :func:`spin_for`): children
#: spinning on a shared core only slow each other down.
SPIN = 200


def spin_for(isolated: int) -> int:
    """The spin count for a run with ``isolated`` child processes on this machine: negative means spin
    yielding the core between polls (more processes than cores)."""
    return SPIN if isolated + 1 <= (os.cpu_count() or 1) else -SPIN // 4


def _address(shm: shared_memory.SharedMemory) -> int:
    """The address of a shared memory block, without keeping a buffer export alive (views made from it
    by address let the block be closed; the owner closes it only after its last use)."""
    probe = ctypes.c_char.from_buffer(shm.buf)
    addr = ctypes.addressof(probe)
    del probe
    return addr


class ChildDied(Exception):
    """The child process ended (crash, abort, exit) or was ended after a hang; the message says how."""


def _how(code: int | None) -> str:
    if code is None:
        return "did not answer"
    if code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with code {code}"


#: Seconds the child may take to give its first answer (start, imports, FMU loaded) when the step timeout
#: is shorter.
STARTUP_TIMEOUT = 60.0


class Child:
    """The master's side of one child process."""

    def __init__(self, name: str, fmu_dir: str, log_path: Path | None, logging: str, step_timeout: float | None,
                 spin: int, slot_values: int = 4096) -> None:
        self.name, self.step_timeout, self.spin = name, step_timeout, spin
        self.started = False      # the child has answered once
        self.shm = shared_memory.SharedMemory(create=True, size=_HEAD + 16 * slot_values)
        self.cap = slot_values
        c_r, p_w = os.pipe()      # control: master -> child
        p_r, c_w = os.pipe()      # control: child -> master
        s_r, m_s = os.pipe()      # step: master -> child
        m_d, d_w = os.pipe()      # step: child -> master
        out = open(str(log_path) + ".stdout", "wb") if log_path is not None else subprocess.DEVNULL
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "wmr_cosim.cosim.isolation", self.shm.name, str(c_r), str(c_w), str(s_r),
             str(d_w), fmu_dir, name, str(log_path or ""), logging, str(spin)],
            pass_fds=(c_r, c_w, s_r, d_w), stdin=subprocess.DEVNULL, stdout=out, stderr=out, close_fds=True)
        if out is not subprocess.DEVNULL:
            out.close()
        for fd in (c_r, c_w, s_r, d_w):
            os.close(fd)
        self.ctl_w, self.ctl_r, self.step_w, self.done_r = p_w, p_r, m_s, m_d
        os.set_blocking(m_d, False)
        self.t = 0.0   # the time of the last step (the instance sets the start time at its set-up)
        self.addr = _address(self.shm)
        self.status = ctypes.c_int64.from_address(self.addr)
        self.time = ctypes.c_double.from_address(self.addr + 8)
        self.h = ctypes.c_double.from_address(self.addr + 16)
        self.inputs: Any = None
        self.outputs: Any = None

    # ---------------------------------------------------------------- control channel
    def call(self, op: str, *args: Any) -> Any:
        """A request on the control channel; returns the child's answer, raises ChildDied."""
        data = pickle.dumps((op, args))
        try:
            os.write(self.ctl_w, struct.pack("<q", len(data)) + data)
        except BrokenPipeError:
            raise ChildDied(self._died()) from None
        timeout = self.step_timeout
        if not self.started and timeout is not None:
            timeout = max(timeout, STARTUP_TIMEOUT)
        head = self._read(self.ctl_r, 8, timeout)
        (n,) = struct.unpack("<q", head)
        kind, value = pickle.loads(self._read(self.ctl_r, n, timeout))
        self.started = True
        if kind == "error":
            raise RuntimeError(value)
        return value

    def _read(self, fd: int, n: int, timeout: float | None) -> bytes:
        out = b""
        while len(out) < n:
            if timeout is not None or fd == self.done_r:   # (done_r is non-blocking)
                ready, _, _ = select.select([fd], [], [], timeout)
                if not ready:
                    self.kill()
                    raise ChildDied(f"did not answer within {timeout:g} s (ended)")
            chunk = os.read(fd, n - len(out))
            if not chunk:
                raise ChildDied(self._died())
            out += chunk
        return out

    def _died(self) -> str:
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        return _how(code)

    # ---------------------------------------------------------------- step slot
    def configure(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int) -> tuple[Any, Any]:
        """The Float64 inputs and outputs of the step slot, as ctypes arrays over the shared memory."""
        if n_in + n_out > 2 * self.cap:
            raise RuntimeError(f"{n_in + n_out} values: more than the step slot holds")
        self.call("configure", in_vrs, n_in, out_vrs, n_out)
        self.inputs = (ctypes.c_double * max(1, n_in)).from_address(self.addr + _HEAD)
        self.outputs = (ctypes.c_double * max(1, n_out)).from_address(self.addr + _HEAD + 8 * self.cap)
        return self.inputs, self.outputs

    def step(self, t: float, h: float) -> int:
        """fmi2SetReal (the inputs in place), fmi2DoStep, fmi2GetReal in the child; the status."""
        self.time.value, self.h.value, self.t = t, h, t
        try:
            os.write(self.step_w, b"s")
        except BrokenPipeError:
            raise ChildDied(self._died()) from None
        fd = self.done_r
        yield_ = os.sched_yield if self.spin < 0 else None
        for _ in range(abs(self.spin)):
            if yield_ is not None:
                yield_()
            try:
                if os.read(fd, 1):
                    return self.status.value
                raise ChildDied(self._died())
            except BlockingIOError:
                pass
        self._read(fd, 1, self.step_timeout)
        return self.status.value

    def close(self) -> None:
        """End the child (politely, then by force) and release the memory and pipes."""
        for fd in (self.ctl_w, self.step_w):
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.kill()
        for fd in (self.ctl_r, self.done_r):
            try:
                os.close(fd)
            except OSError:
                pass
        self.status = self.time = self.h = self.inputs = self.outputs = None
        try:
            self.shm.close()
        except BufferError:  # a view still alive: released with the process
            pass
        try:
            self.shm.unlink()
        except FileNotFoundError:
            pass

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


# ---------------------------------------------------------------------------------------------- child side
def _serve(argv: list[str]) -> int:
    """The child: load the FMU, then answer the control channel and the step slot until the master
    closes them."""
    shm_name, c_r, c_w, s_r, d_w = argv[0], *map(int, argv[1:5])
    fmu_dir, name, log_path, logging, spin = argv[5], argv[6], argv[7], argv[8], int(argv[9])
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the master's to handle
    shm = shared_memory.SharedMemory(name=shm_name)
    try:  # the master owns the block: this process must not unlink it at exit
        from multiprocessing import resource_tracker
        resource_tracker.unregister(shm._name, "shared_memory")  # type: ignore[attr-defined]
    except Exception:
        pass
    from fmpy import read_model_description

    from .instance import Instance3, raw
    from .instance import Instance as Instance2

    md = read_model_description(os.path.join(fmu_dir, "modelDescription.xml"), validate=False)
    fmi3 = md.fmiVersion.startswith("3")
    inst = (Instance3 if fmi3 else Instance2)(name, md, fmu_dir, log_path or None, logging)
    state: dict[str, Any] = {}

    addr = _address(shm)

    def configure(in_vrs, n_in, out_vrs, n_out):
        from .instance import vr_array
        cap = (shm.size - _HEAD) // 16
        state["in"] = (vr_array(in_vrs), ctypes.c_size_t(len(in_vrs)),
                       (ctypes.c_double * max(1, n_in)).from_address(addr + _HEAD), ctypes.c_size_t(n_in))
        state["out"] = (vr_array(out_vrs), ctypes.c_size_t(len(out_vrs)),
                        (ctypes.c_double * max(1, n_out)).from_address(addr + _HEAD + 8 * cap), ctypes.c_size_t(n_out))
        return None

    def set_inputs():   # outside the step loop (initialisation): the slot's inputs set now
        ivr, nin, ival, nvin = state["in"]
        setr, c = state["fns"][0], state["c"]
        if not nin.value:
            return 0
        return setr(c, ivr, nin, ival, nvin) if fmi3 else setr(c, ivr, nin, ival)

    def get_outputs():  # outside the step loop: the outputs into the slot now
        ovr, nout, oval, nvout = state["out"]
        getr, c = state["fns"][2], state["c"]
        if not nout.value:
            return 0
        return getr(c, ovr, nout, oval, nvout) if fmi3 else getr(c, ovr, nout, oval)

    def log_state():
        if inst._log_fh is not None:
            inst._log_fh.flush()
        return (inst.log_lines, inst.received, inst.n_errors, list(inst.log))

    def get_typed(fmi_type, vrs, nv):
        from .instance import accessor, vr_array
        call, ctype = accessor(inst, fmi_type, "Get")
        buf = (ctype * max(1, nv))()
        st = call(vr_array(vrs), ctypes.c_size_t(len(vrs)), buf, ctypes.c_size_t(nv))
        return st, list(buf[:nv])

    def set_typed(fmi_type, vrs, values):
        from .instance import accessor, vr_array
        call, ctype = accessor(inst, fmi_type, "Set")
        buf = (ctype * max(1, len(values)))(*values)
        return call(vr_array(vrs), ctypes.c_size_t(len(vrs)), buf, ctypes.c_size_t(len(values)))

    ops = {"configure": configure, "log_state": log_state, "get_typed": get_typed, "set_typed": set_typed,
           "set_inputs": set_inputs, "get_outputs": get_outputs}
    ctl_in = os.fdopen(c_r, "rb", buffering=0)
    polls = select.poll()
    polls.register(c_r, select.POLLIN)
    polls.register(s_r, select.POLLIN)
    status = ctypes.c_int64.from_address(addr)
    time_ = ctypes.c_double.from_address(addr + 8)
    h_ = ctypes.c_double.from_address(addr + 16)
    os.set_blocking(s_r, False)
    while True:
        for fd, _ in polls.poll():
            if fd == s_r:
                if not _steps(s_r, d_w, inst, state, status, time_, h_, fmi3, spin):
                    return 0
                continue
            head = ctl_in.read(8)
            if len(head) < 8:
                return 0
            (n,) = struct.unpack("<q", head)
            op, args = pickle.loads(ctl_in.read(n))
            try:
                fn = ops.get(op) or getattr(inst, op)
                reply = ("ok", fn(*args))
            except BaseException as exc:  # reported to the master as one line
                reply = ("error", " ".join(str(exc).split()) or type(exc).__name__)
            if op == "configure" and reply[0] == "ok":
                fmi = 3 if fmi3 else 2
                names = ("fmi3SetFloat64", "fmi3DoStep", "fmi3GetFloat64") if fmi3 else \
                    ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal")
                state["fns"] = [raw(inst.fmu.dll, f) for f in names]
                state["c"] = ctypes.c_void_p(inst.c)
                state["fmi"] = fmi
            data = pickle.dumps(reply)
            os.write(c_w, struct.pack("<q", len(data)) + data)


def _steps(s_r: int, d_w: int, inst: Any, state: dict[str, Any], status: Any, time_: Any, h_: Any,
           fmi3: bool, spin: int) -> bool:
    """Answer step requests while they keep coming within the spin; False when the master has gone."""
    try:
        if not os.read(s_r, 1):
            return False
    except BlockingIOError:
        return True
    while True:
        status.value = _step(inst, state, time_.value, h_.value, fmi3)
        os.write(d_w, b"d")
        for _ in range(abs(spin)):
            if spin < 0:
                os.sched_yield()
            try:
                if not os.read(s_r, 1):
                    return False
                break
            except BlockingIOError:
                continue
        else:
            return True


def _step(inst: Any, state: dict[str, Any], t: float, h: float, fmi3: bool) -> int:
    setr, dostep, getr = state["fns"]
    c = state["c"]
    ivr, nin, ival, nvin = state["in"]
    ovr, nout, oval, nvout = state["out"]
    if fmi3:
        s = setr(c, ivr, nin, ival, nvin) if nin.value else 0
        if s:
            return s
        flags = [ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()]
        s = dostep(c, ctypes.c_double(t), ctypes.c_double(h), True, *(ctypes.byref(f) for f in flags))
        if s:
            return s
        if flags[1].value:
            return 100   # terminateSimulation: see IsolatedInstance
        return getr(c, ovr, nout, oval, nvout) if nout.value else 0
    s = setr(c, ivr, nin, ival) if nin.value else 0
    if s:
        return s
    s = dostep(c, ctypes.c_double(t), ctypes.c_double(h), 1)
    if s:
        return s
    return getr(c, ovr, nout, oval) if nout.value else 0


if __name__ == "__main__":
    sys.exit(_serve(sys.argv[1:]))


# ---------------------------------------------------------------------------------------------- master side
class IsolatedInstance:
    """An FMU instance in a child process, with the interface of :class:`.instance.Instance`: the
    execution drives it through the same calls, and the generated loop through the entry points of
    :meth:`entry_points`, which work on the step slot."""

    def __init__(self, name: str, md: Any, unzipdir: str, log_path: str | os.PathLike | None, logging: str,
                 step_timeout: float | None, spin: int) -> None:
        self.name, self.md, self.logging = name, md, logging
        self.fmi = 3 if md.fmiVersion.startswith("3") else 2
        self.log: list[str] = []   # the child's last log lines (its instance keeps at most 200)
        self.log_lines = self.received = self.n_errors = 0
        self.fatal = self.freed = False
        self.dead = ""
        self.child = Child(name, unzipdir, Path(log_path) if log_path else None, logging, step_timeout, spin)
        self.c = 0
        self.fmu = None

    # ------------------------------------------------------------------ log
    def _sync_log(self) -> None:
        if self.dead:
            return
        try:
            self.log_lines, self.received, self.n_errors, self.log = self.child.call("log_state")
        except (ChildDied, RuntimeError):
            pass

    def last_log(self, n: int = 3) -> str:
        self._sync_log()
        lines = list(self.log)[-n:]
        return " | ".join(" ".join(ln.split()) for ln in lines) if lines else "(the FMU logged nothing)"

    def close_log(self) -> None:
        self._sync_log()

    # ------------------------------------------------------------------ life cycle (control channel)
    def fail_status(self, what: str, status: int, t: float | None) -> Any:
        from .instance import Instance

        return Instance.fail_status(self, what, status, t)   # the same rule and message as in process

    def died(self, exc: ChildDied, what: str, t: float | None) -> Any:
        from .errors import RunError

        self.dead = str(exc)
        at = f" at t = {t:.6g} s" if t is not None else ""
        err = RunError(f"{self.name}: the FMU's process {exc} during {what}{at} (isolated: the other "
                       "instances are terminated and freed, the recording kept)", self.name, t)
        err.died = True  # type: ignore[attr-defined]
        return err

    def _call(self, what: str, op: str, *args: Any, t: float | None = None) -> Any:
        from .errors import RunError

        try:
            return self.child.call(op, *args)
        except ChildDied as exc:
            raise self.died(exc, what, t) from None
        except RuntimeError as exc:
            raise RunError(f"{self.name}: {what}: {exc}", self.name, t) from None

    def instantiate(self) -> None:
        self._call("instantiate", "instantiate")

    def setup_experiment(self, start: float, stop: float | None, tolerance: float | None) -> None:
        self.child.t = start   # the time of a failure before the first step
        self._call("set-up", "setup_experiment", start, stop, tolerance, t=start)

    def set_values(self, pairs: list) -> None:
        self._call("setting values", "set_values", pairs)

    def get_value(self, var: Any) -> Any:
        """The current value of one variable (through the control channel)."""
        return self._call(f"reading {var.name}", "get_value", var)

    def enter_initialization(self) -> None:
        self._call("initialisation", "enter_initialization", t=self.child.t)

    def exit_initialization(self) -> None:
        self._call("initialisation", "exit_initialization", t=self.child.t)

    def terminated_at(self) -> float | None:
        if self.fmi == 3:
            return None
        try:
            return self.child.call("terminated_at")
        except (ChildDied, RuntimeError):
            return None

    def shutdown(self) -> None:
        """Terminate and free in the child (nothing after a Fatal, nothing if it died), then end it."""
        if self.freed:
            return
        self.freed = True
        if not self.dead and not self.fatal:
            try:
                self.child.call("shutdown")
            except (ChildDied, RuntimeError):
                pass
        self._sync_log()
        self.child.close()

    # ------------------------------------------------------------------ the generated loop's entry points
    def entry_points(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int) -> tuple:
        """(set_real, do_step, get_real, input array): set_real is a no-op (the input array is the step
        slot's), do_step runs set + step + get in the child, get_real copies the slot's outputs."""
        from .errors import RunError

        try:
            inputs, outputs = self.child.configure(in_vrs, n_in, out_vrs, n_out)
        except ChildDied as exc:
            raise self.died(exc, "set-up", None) from None
        except RuntimeError as exc:
            raise RunError(f"{self.name}: {exc}", self.name) from None
        child, size = self.child, 8 * n_out
        mode = {"stepping": False}   # before the first step (initialisation), set and get are requests

        def set_real(*args: Any) -> int:
            if mode["stepping"]:
                return 0            # the inputs are in place: the child sets them with the step
            return self._call("setting inputs", "set_inputs")

        def do_step(c: Any, T: Any, H: Any, flag: Any, *refs: Any) -> int:
            mode["stepping"] = True
            try:
                s = child.step(T.value, H.value)
            except ChildDied as exc:
                raise self.died(exc, "fmi2DoStep" if self.fmi == 2 else "fmi3DoStep", T.value) from None
            if s == 100:           # FMI 3.0 terminateSimulation
                refs[1]._obj.value = True
                return 0
            return s

        def get_real(c: Any, vrs: Any, n: Any, out: Any, *nv: Any) -> int:
            if not mode["stepping"]:
                s = self._call("getting outputs", "get_outputs")
                if s:
                    return s
            if size:
                ctypes.memmove(out, outputs, size)
            return 0
        return set_real, do_step, get_real, inputs

    def accessor(self, fmi_type: str, op: str) -> tuple[Any, Any]:
        """(call, ctype) as :func:`.instance.accessor`, through the control channel."""
        from .instance import _ACCESS

        ctype = _ACCESS[self.fmi][fmi_type][0]

        def call(vrs: Any, n: Any, buf: Any, nv: Any) -> int:
            try:
                if op == "Get":
                    status, values = self.child.call("get_typed", fmi_type, list(vrs), nv.value)
                    buf[:len(values)] = values
                    return status
                return self.child.call("set_typed", fmi_type, list(vrs), list(buf[:nv.value]))
            except ChildDied as exc:
                raise self.died(exc, f"fmi{op}{fmi_type}", self.child.t) from None
        return call, ctype
