"""Out-of-process instances: an FMU hosted in a child process, so that a crash (any signal, abort, exit)
or a hang inside the FMU cannot take the master down.

The child (``python -m`` this module) loads the FMU with FMPy and serves two channels:

- the **step slot**, a block of shared memory per instance: the Float64 inputs and outputs in place (the
  master's input array and the child's output array *are* this memory), the time and the step size, the
  status; a step is one byte each way on a pair of pipes ("step" from the master, "done" from the child),
  with no pickling: the master sets the inputs by writing them, the child calls fmi2SetReal, fmi2DoStep
  and fmi2GetReal and writes the outputs;
- the **control channel**, length-prefixed pickled requests on another pair of pipes, for everything else
  (instantiate, set-up, start values, initialisation, other types, state, terminate, free).

For a C FMU hosted as co-simulation the step slot is served in C on both sides instead (:mod:`.slot_c`: the
C child; the pipes carry a byte only to wake a side that sleeps); a pythonfmu FMU, a model exchange
instance, or any with ``WMR_COSIM_CHILD=python``, steps in the child's Python as above.

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
import dataclasses
import itertools
import json
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import math
from multiprocessing import shared_memory
from pathlib import Path
from typing import Any

from ..messages.errors import RunError
from ..model.binary import load_failure
from ..model.description import declares_state, fmi2_cs_declares, fmi_of
from .contract import FastPath, FmuInstance
from .failure import Call, InstanceLost
from .handoff import Handoff
from .in_process import ACCESS
from .integrators import SolverSpec
from . import slot_c

#: Header of the step slot: status (int64), t (float64), h (float64), the spin count the child waits for the
#: next request with (int64, set by the master: :class:`~.handoff.Handoff`), then inputs and outputs (float64).
_HEAD = 32
#: Polls of the other side's pipe before blocking on it (a few tens of microseconds): the answer to a step,
#: and the next step's request, usually come within that, which saves the scheduler's wake-up each way.
#: Only while every child can have a core of its own beside the master (see :func:`spin_for`): children
#: spinning on a shared core only slow each other down.  Whether to spin at all is measured as the run goes
#: (:class:`~.handoff.Handoff`: on a busy machine both sides block at once).
SPIN = 200


def spin_for(isolated: int) -> int:
    """The spin count for a run with ``isolated`` child processes on this machine: negative means spin
    yielding the core between polls (more processes than cores)."""
    return SPIN if isolated + 1 <= (os.cpu_count() or 1) else -SPIN // 4


def _address(shm: shared_memory.SharedMemory) -> int:
    """The address of a shared memory block, without keeping a buffer export alive (views made from it
    by address let the block be closed; the owner closes it only after its last use)."""
    assert shm.buf is not None
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
                 handoff: Handoff | int, slot_values: int = 4096, solver: SolverSpec | None = None,
                 c_child: Path | None = None) -> None:
        """``handoff``: the run's :class:`~.handoff.Handoff`, which chooses how both sides wait as the run
        goes, or a spin count kept (0: block at once; negative: poll yielding the core); ``c_child``: the
        library of the C child (:mod:`.slot_c`), which serves the slot where the child's instance allows
        (None: the Python child)."""
        self.name, self.step_timeout = name, step_timeout
        self.started = False      # the child has answered once
        self.c_lib = c_child
        self.c_side: slot_c.MasterSide | None = None   # the master's side of the C child, once configured
        words = slot_c.WORDS if c_child is not None else 0
        self.shm = shared_memory.SharedMemory(create=True, size=_HEAD + 16 * slot_values + words)
        self.cap = slot_values
        c_r, p_w = os.pipe()      # control: master -> child
        p_r, c_w = os.pipe()      # control: child -> master
        s_r, m_s = os.pipe()      # step: master -> child
        m_d, d_w = os.pipe()      # step: child -> master
        out: Any = open(str(log_path) + ".stdout", "wb") if log_path is not None else subprocess.DEVNULL
        self.proc = subprocess.Popen(
            [sys.executable, "-m", __name__, self.shm.name, str(c_r), str(c_w), str(s_r),
             str(d_w), fmu_dir, name, str(log_path or ""), logging,
             json.dumps(dataclasses.asdict(solver)) if solver is not None else "", str(c_child or "")],
            pass_fds=(c_r, c_w, s_r, d_w), stdin=subprocess.DEVNULL, stdout=out, stderr=out, close_fds=True)
        if out is not subprocess.DEVNULL:
            out.close()
        for fd in (c_r, c_w, s_r, d_w):
            os.close(fd)
        self.ctl_w, self.ctl_r, self.step_w, self.done_r = p_w, p_r, m_s, m_d
        os.set_blocking(m_d, False)
        self.t = 0.0   # the time of the last step (the instance sets the start time at its set-up)
        self.addr = _address(self.shm)
        if c_child is not None:   # the child is in Python until its first request: woken by a byte
            ctypes.c_int32.from_address(self.addr + _HEAD + 16 * slot_values + slot_c.CHILD_ASLEEP).value = 1
        self.status = ctypes.c_int64.from_address(self.addr)
        self.time = ctypes.c_double.from_address(self.addr + 8)
        self.h = ctypes.c_double.from_address(self.addr + 16)
        self.spin_word = ctypes.c_int64.from_address(self.addr + 24)
        self.spin = 0
        self.handoff: Handoff | None = None
        if isinstance(handoff, Handoff):
            self.handoff = handoff
            handoff.add(self)
        else:
            self.set_spin(handoff)
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

    @property
    def t(self) -> float:
        """[s] The time of the last step requested (the C child's side keeps it)."""
        return float(self.c_side.p.t) if self.c_side is not None else self._t

    @t.setter
    def t(self, value: float) -> None:
        self._t = value
        if self.c_side is not None:
            self.c_side.p.t = value

    def lost(self, status: int) -> str:
        """How the C child was lost (its side returned ``status``, one of slot_c.LOST_*): ended after a hang,
        or how it died."""
        if status == slot_c.LOST_HUNG:
            self.kill()
            return f"did not answer within {self.step_timeout:g} s (ended)"
        return self._died()

    def _died(self) -> str:
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        return _how(code)

    def set_spin(self, spin: int) -> None:
        """How both sides wait at a step from now on: poll ``abs(spin)`` times (yielding the core between
        polls where negative), then block."""
        self.spin = spin
        self.spin_word.value = spin

    # ---------------------------------------------------------------- step slot
    def configure(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int) -> tuple[Any, Any]:
        """The Float64 inputs and outputs of the step slot, as ctypes arrays over the shared memory."""
        if n_in + n_out > 2 * self.cap:
            raise RuntimeError(f"{n_in + n_out} values: more than the step slot holds")
        in_c = self.call("configure", in_vrs, n_in, out_vrs, n_out)
        self.inputs = (ctypes.c_double * max(1, n_in)).from_address(self.addr + _HEAD)
        self.outputs = (ctypes.c_double * max(1, n_out)).from_address(self.addr + _HEAD + 8 * self.cap)
        if in_c is True and self.c_lib is not None:   # (the child serves the slot in C)
            self._c_side(n_out)
        return self.inputs, self.outputs

    def _c_side(self, n_out: int) -> None:
        """The master's side of the C child, its outputs ``n_out`` values; measured by the run's hand-off."""
        side = self.c_side
        if side is None:
            assert self.c_lib is not None
            side = slot_c.MasterSide(str(self.c_lib), self.addr, _HEAD, self.cap, self.step_w, self.done_r,
                                     self.step_timeout)
            side.p.t = self._t
            handoff = self.handoff
            if handoff is not None:
                def tick(skipped: int, ran_out: int) -> int:
                    handoff.ran_out += ran_out
                    return handoff.tick(self, skipped)
                side.measured_by(tick)
            self.c_side = side
        side.outputs(n_out)

    def step(self, t: float, h: float) -> int:
        """fmi2SetReal (the inputs in place), fmi2DoStep, fmi2GetReal in the child; the status."""
        self.start(t, h)
        return self.finish()

    def start(self, t: float, h: float) -> None:
        """A step's request: the child sets the inputs (in place), steps and gets the outputs while the
        master does something else; :meth:`finish` waits for it."""
        self.time.value, self.h.value, self.t = t, h, t
        if self.handoff is not None:
            self.handoff.tick(self)
        try:
            os.write(self.step_w, b"s")
        except BrokenPipeError:
            raise ChildDied(self._died()) from None

    def finish(self, spin: bool = True) -> int:
        """The answer to the step started: its status.  ``spin`` False: block at once (while the children
        stepped at once need the cores)."""
        fd = self.done_r
        yield_ = os.sched_yield if self.spin < 0 else None
        polls = abs(self.spin) if spin else 0
        for _ in range(polls):
            if yield_ is not None:
                yield_()
            try:
                if os.read(fd, 1):
                    return self.status.value
                raise ChildDied(self._died())
            except BlockingIOError:
                pass
        if polls and self.handoff is not None:
            self.handoff.ran_out += 1
        self._read(fd, 1, self.step_timeout)
        return self.status.value

    def close(self) -> None:
        """End the child (politely, then by force) and release the memory and pipes."""
        if self.c_side is not None and self.handoff is not None:   # (the steps not ticked yet, counted)
            p = self.c_side.p
            self.handoff.settle(self, int(p.skipped))
            self.handoff.ran_out += int(p.ran_out)
            p.skipped = p.ran_out = 0
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
        self.inputs = self.outputs = None   # (the slot's views: released with the memory)
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
#: The step slot's status for a step after which the FMU ended the simulation (FMI 3.0
#: terminateSimulation with status OK): not an FMI status, a code of the slot's own.
SLOT_TERMINATED = 100


class _Server:
    """The child: one FMU instance in this process, its step slot and its control channel's operations."""

    def __init__(self, shm: shared_memory.SharedMemory, inst: Any, c_lib: str = "",
                 fds: tuple[int, int, int] = (-1, -1, -1)) -> None:
        """``c_lib``: the C child's library, where the master asks for it ("": the step in Python); ``fds``:
        the step pipe's end to read, the done pipe's to write, the control channel's to read."""
        self.shm, self.inst, self.c_lib, self.fds = shm, inst, c_lib, fds
        self.addr = _address(shm)
        self.cap = (shm.size - _HEAD - (slot_c.WORDS if c_lib else 0)) // 16
        self.c: slot_c.ChildSide | None = None   # the slot served in C (configured so)
        self.fast: Any = None                 # the instance's FastPath, once configured
        self.io: tuple[Any, ...] = ()         # (in_vr, n_in, out_vr, n_out, out_val)
        self.states: dict[int, Any] = {}      # the instance's saved states, by the key the master holds
        self.derivatives: tuple[list[int], list[float]] | None = None   # for the next step, after its inputs
        self.keys = itertools.count(1)
        self.T, self.H = ctypes.c_double(0.0), ctypes.c_double(0.0)

    def configure(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int) -> bool | None:
        """The instance's fast path over the slot: its input array is the slot's inputs.  True where the
        slot is served in C from now on (:mod:`.slot_c`)."""
        from .in_process import vr_array

        slot_in = (ctypes.c_double * max(1, n_in)).from_address(self.addr + _HEAD)
        slot_out = (ctypes.c_double * max(1, n_out)).from_address(self.addr + _HEAD + 8 * self.cap)
        self.fast = self.inst.fast_path(in_vrs, n_in, out_vrs, n_out, in_val=slot_in)
        self.io = (vr_array(in_vrs), ctypes.c_size_t(len(in_vrs)), vr_array(out_vrs), ctypes.c_size_t(len(out_vrs)),
                   slot_out)
        self.c = None
        if self.c_lib and slot_c.raw_path(self.fast) and not getattr(self.inst, "python", False):
            self.c = slot_c.ChildSide(self.c_lib, self.addr, _HEAD, self.cap, self.fds, self.fast, self.io, n_in, n_out)
            return True   # (the master's side in C too)
        return None

    def serve_c(self) -> bool:
        """The slot served in C until the master sends a control request (True) or goes (False); the
        inputs' derivatives given for the next step set there, after its inputs."""
        assert self.c is not None
        pre = None
        if self.derivatives is not None:
            vrs, values = self.derivatives

            def pre() -> int:
                self.derivatives = None
                try:
                    return int(self.inst.set_input_derivatives(vrs, values))
                except Exception:
                    return 3   # (fmi2Error)
        tail = self.fast.step_tail
        return self.c.serve(bool(tail[0]) if tail else True, pre)

    def set_inputs(self) -> int:
        """Outside the step loop (initialisation): the slot's inputs set now."""
        fp, (ivr, nin, *_rest) = self.fast, self.io
        return fp.set_real(fp.c, ivr, nin, fp.in_val, *fp.set_tail) if nin.value else 0

    def get_outputs(self) -> int:
        """Outside the step loop: the outputs into the slot now."""
        fp, (_, _, ovr, nout, oval) = self.fast, self.io
        return fp.get_real(fp.c, ovr, nout, oval, *fp.get_tail) if nout.value else 0

    def set_input_derivatives(self, vrs: list[int], values: list[float]) -> int:
        """The inputs' derivatives for the next step: set there after its inputs (in this order, as in
        process: setting an input may reset its derivative)."""
        self.derivatives = (list(vrs), list(values))
        return 0

    def step(self, t: float, h: float) -> int:
        """Set the inputs (and the derivatives given for this step), do the step, get the outputs: the
        status (or SLOT_TERMINATED, the FMU's last successful time written in the slot's time, the outputs
        not read).  After a status other than OK the outputs are not read either."""
        s = self.set_inputs()
        if s:
            return s
        if self.derivatives is not None:
            vrs, values = self.derivatives
            self.derivatives = None
            s = self.inst.set_input_derivatives(vrs, values)
            if s:
                return s
        fp = self.fast
        self.T.value, self.H.value = t, h
        s = fp.do_step(fp.c, self.T, self.H, *fp.step_tail)
        if s:
            return s
        if fp.terminated is not None and fp.terminated.value:
            # the FMU's last successful time in the slot's time; the master asks for the outputs (as in
            # process, where the loop reads them after the step): a failure to give them is its to report
            last = fp.last_time.value if fp.last_time is not None else math.nan
            ctypes.c_double.from_address(self.addr + 8).value = last if math.isfinite(last) else t + h
            return SLOT_TERMINATED
        return self.get_outputs()

    def log_state(self) -> tuple[int, int, int, list[str]]:
        self.inst.flush_log()
        return (self.inst.log_lines, self.inst.received, self.inst.n_errors, list(self.inst.log))

    def get_typed(self, fmi_type: str, vrs: list[int], nv: int) -> tuple[int, list[Any]]:
        from .in_process import vr_array

        call, ctype = self.inst.accessor(fmi_type, "Get")
        buf = (ctype * max(1, nv))()
        st = call(vr_array(vrs), ctypes.c_size_t(len(vrs)), buf, ctypes.c_size_t(nv))
        return st, list(buf[:nv])

    def set_typed(self, fmi_type: str, vrs: list[int], values: list[Any]) -> int:
        from .in_process import vr_array

        call, ctype = self.inst.accessor(fmi_type, "Set")
        buf = (ctype * max(1, len(values)))(*values)
        return call(vr_array(vrs), ctypes.c_size_t(len(vrs)), buf, ctypes.c_size_t(len(values)))

    def get_state(self) -> int:
        key = next(self.keys)
        self.states[key] = self.inst.get_state()
        return key

    def set_state(self, key: int) -> None:
        self.inst.set_state(self.states[key])

    def free_state(self, key: int) -> None:
        self.inst.free_state(self.states.pop(key))

    def answer(self, op: str, args: tuple[Any, ...]) -> tuple[str, Any]:
        """A control request's reply: ("ok", value) or ("error", one line)."""
        own = ("configure", "set_inputs", "get_outputs", "log_state", "get_typed", "set_typed", "get_state",
               "set_state", "free_state", "set_input_derivatives")   # (anything else, allow_rollback among them, is the instance's)
        try:
            return "ok", (getattr(self, op) if op in own else getattr(self.inst, op))(*args)
        except BaseException as exc:  # reported to the master as one line
            return "error", " ".join(str(exc).split()) or type(exc).__name__


def _serve(argv: list[str]) -> int:
    """The child: load the FMU, then answer the control channel and the step slot until the master
    closes them."""
    shm_name, c_r, c_w, s_r, d_w = argv[0], *map(int, argv[1:5])
    fmu_dir, name, log_path, logging = argv[5], argv[6], argv[7], argv[8]
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the master's to handle
    shm = shared_memory.SharedMemory(name=shm_name)
    try:  # the master owns the block: this process must not unlink it at exit
        from multiprocessing import resource_tracker
        resource_tracker.unregister(shm._name, "shared_memory")  # type: ignore[attr-defined]
    except Exception:
        pass
    from fmpy import read_model_description

    md = read_model_description(os.path.join(fmu_dir, "modelDescription.xml"), validate=False)
    ctl_in = os.fdopen(c_r, "rb", buffering=0)
    try:
        inst = _hosted(name, md, fmu_dir, log_path, logging, argv[9] if len(argv) > 9 else "")
    except Exception as exc:   # the binary does not load: the first request gets the loader's reason
        if len(head := ctl_in.read(8)) == 8:
            ctl_in.read(struct.unpack("<q", head)[0])
            data = pickle.dumps(("error", f"cannot load the FMU: {load_failure(exc, fmu_dir)}"))
            os.write(c_w, struct.pack("<q", len(data)) + data)
        return 1
    server = _Server(shm, inst, argv[10] if len(argv) > 10 else "", (s_r, d_w, c_r))
    return _loop(server, ctl_in, c_w, s_r, d_w)


def _hosted(name: str, md: Any, fmu_dir: str, log_path: str, logging: str, solver: str) -> FmuInstance:
    """The child's instance: the FMU extracted in ``fmu_dir`` (its model description ``md``, FMPy's) loaded
    by the class of its kind (:data:`.kinds.HOSTS`, the table the start-up reads too); ``solver``: a model
    exchange instance's integrator settings (JSON), "" for co-simulation; ``log_path`` "": no log file."""
    from .kinds import host

    spec = SolverSpec(**json.loads(solver)) if solver else None
    return host(name, md, fmi_of(md), fmu_dir, log_path or None, logging, spec)


def _loop(server: _Server, ctl_in: Any, c_w: int, s_r: int, d_w: int) -> int:
    """Answer requests on the control channel and steps on the slot until the master has gone."""
    polls = select.poll()
    polls.register(ctl_in.fileno(), select.POLLIN)
    polls.register(s_r, select.POLLIN)
    os.set_blocking(s_r, False)
    while True:
        for fd, _ in polls.poll():
            if fd == s_r:
                if not (server.serve_c() if server.c is not None else _steps(s_r, d_w, server)):
                    return 0
                continue
            head = ctl_in.read(8)
            if len(head) < 8:
                return 0
            (n,) = struct.unpack("<q", head)
            data = pickle.dumps(server.answer(*pickle.loads(ctl_in.read(n))))
            os.write(c_w, struct.pack("<q", len(data)) + data)


def _steps(s_r: int, d_w: int, server: _Server) -> bool:
    """Answer step requests while they keep coming within the spin the master asks for (the slot's spin
    word, read after each step); False when the master has gone."""
    try:
        if not os.read(s_r, 1):
            return False
    except BlockingIOError:
        return True
    addr = server.addr
    status = ctypes.c_int64.from_address(addr)
    time_ = ctypes.c_double.from_address(addr + 8)
    h_ = ctypes.c_double.from_address(addr + 16)
    spin_word = ctypes.c_int64.from_address(addr + 24)
    while True:
        status.value = server.step(time_.value, h_.value)
        os.write(d_w, b"d")
        spin = spin_word.value
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


# ---------------------------------------------------------------------------------------------- master side
class IsolatedInstance(FmuInstance):
    """An FMU instance in a child process (an implementation of :class:`.fmu_instance.FmuInstance`): the
    life cycle goes through the control channel, the step through the slot (:meth:`fast_path`)."""

    def __init__(self, name: str, md: Any, unzipdir: str, log_path: str | os.PathLike | None, logging: str,
                 step_timeout: float | None, handoff: Handoff | int, solver: SolverSpec | None = None) -> None:
        """``solver``: host the FMU as model exchange with this integrator (None: co-simulation)."""
        self.name, self.md, self.logging, self.solver = name, md, logging, solver
        self.fmi_version = fmi_of(md)
        self.log: list[str] = []   # the child's last log lines (its instance keeps at most 200)
        self.log_lines = self.received = self.n_errors = 0
        self.fatal = self.freed = False
        self.dead = ""
        self.child = Child(name, unzipdir, Path(log_path) if log_path else None, logging, step_timeout, handoff,
                           solver=solver, c_child=slot_c.for_fmu(unzipdir, solver))
        self.c = 0

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
    def died(self, exc: ChildDied, what: str, t: float | None) -> InstanceLost:
        self.dead = str(exc)
        at = f" at t = {t:.6g} s" if t is not None else ""
        return InstanceLost(f"{self.name}: the FMU's process {exc} during {what}{at} (isolated: the other "
                            "instances are terminated and freed, the recording kept)", self.name, t)

    def _call(self, what: str, op: str, *args: Any, t: float | None = None) -> Any:
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

    @property
    def can_get_and_set_state(self) -> bool:
        """The interface the child hosts declares it can save and restore its state."""
        return declares_state(self.md.coSimulation if self.solver is None else self.md.modelExchange)

    @property
    def can_interpolate_inputs(self) -> bool:
        """FMI 2.0 co-simulation that declares canInterpolateInputs (the child sets the derivatives after
        the step's inputs)."""
        return self.solver is None and fmi2_cs_declares(self.md, "canInterpolateInputs")

    def set_input_derivatives(self, vrs: list[int], values: list[float]) -> int:
        """fmi2SetRealInputDerivatives of order 1, in the child, for the next step."""
        if not self.can_interpolate_inputs:
            return super().set_input_derivatives(vrs, values)
        return int(self._call("setting input derivatives", "set_input_derivatives", list(vrs), list(values),
                              t=self.child.t))

    @property
    def provides_directional_derivative(self) -> bool:
        """FMI 2.0 co-simulation that declares providesDirectionalDerivative (asked of the child)."""
        return self.solver is None and fmi2_cs_declares(self.md, "providesDirectionalDerivative")

    def directional_derivative(self, unknowns: list[int], knowns: list[int], seed: list[float]) -> tuple[int, list[float]]:
        if not self.provides_directional_derivative:
            return super().directional_derivative(unknowns, knowns, seed)
        st, values = self._call("directional derivatives", "directional_derivative", list(unknowns), list(knowns),
                                list(seed), t=self.child.t)
        return int(st), list(values)

    def call_name(self, call: Call) -> str:
        if call is Call.DO_STEP and self.solver is not None:
            return f"the integration ({self.solver.name})"
        return super().call_name(call)

    def terminated_at(self) -> float | None:
        if self.fmi_version == 3 or self.solver is not None:
            return None
        try:
            return self.child.call("terminated_at")
        except (ChildDied, RuntimeError):
            return None

    def handled_events(self) -> list[tuple[float, str]]:
        if self.solver is None or self.dead:
            return []
        try:
            return [(float(t), str(k)) for t, k in self.child.call("handled_events")]
        except (ChildDied, RuntimeError):
            return []

    def get_state(self) -> Any:
        return self._call("saving the state", "get_state", t=self.child.t)

    def set_state(self, state: Any) -> None:
        self._call("restoring a state", "set_state", state, t=self.child.t)

    def free_state(self, state: Any) -> None:
        self._call("freeing a state", "free_state", state, t=self.child.t)

    def allow_rollback(self) -> None:
        """The child's instance steps so that its saved states stay restorable."""
        self._call("allowing rollback", "allow_rollback", t=self.child.t)

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
    def fast_path(self, in_vrs: list[int], n_in: int, out_vrs: list[int], n_out: int) -> FastPath:
        """On the step slot: the input array is the slot's; set_real is a no-op once stepping (the child
        sets the inputs with the step), do_step runs set + step + get in the child, get_real copies the
        slot's outputs.  Before the first step (initialisation), set and get are requests."""
        try:
            inputs, outputs = self.child.configure(in_vrs, n_in, out_vrs, n_out)
        except ChildDied as exc:
            raise self.died(exc, "set-up", None) from None
        except RuntimeError as exc:
            raise RunError(f"{self.name}: {exc}", self.name) from None
        child, size = self.child, 8 * n_out
        # FMI 3.0's terminateSimulation, and a model exchange FMU's
        terminated = ctypes.c_bool(False) if self.fmi_version == 3 or self.solver is not None else None
        if child.c_side is not None:
            return self._c_fast_path(child.c_side, inputs, terminated)
        # stepping: the step loop has begun (the child sets the inputs with each step); fresh: the last step
        # left the outputs in the slot (the child reads them after an OK step only; none before the first)
        mode = {"stepping": False, "fresh": False}
        step_name = self.call_name(Call.DO_STEP)
        last_time = ctypes.c_double(math.nan) if terminated is not None else None

        def set_real(*args: Any) -> int:
            if mode["stepping"]:
                return 0            # the inputs are in place: the child sets them with the step
            return self._call("setting inputs", "set_inputs")

        def start_step(c: Any, T: Any, H: Any) -> None:
            mode["stepping"] = True
            try:
                child.start(T.value, H.value)
            except ChildDied as exc:
                raise self.died(exc, step_name, T.value) from None

        def finish_step(spin: bool = True) -> int:
            try:
                s = child.finish(spin)
            except ChildDied as exc:
                raise self.died(exc, step_name, child.t) from None
            mode["fresh"] = s == 0   # (the child reads the outputs after an OK step only)
            if s == SLOT_TERMINATED and terminated is not None and last_time is not None:
                terminated.value, last_time.value = True, child.time.value   # (its outputs asked for after)
                return 0
            return s

        def do_step(c: Any, T: Any, H: Any) -> int:
            start_step(c, T, H)
            return finish_step(True)

        def get_real(c: Any, vrs: Any, n: Any, out: Any) -> int:
            if not mode["fresh"]:   # (before the first step; after a step that did not read them)
                s = self._call("getting outputs", "get_outputs")
                if s:
                    return s
            if size:
                ctypes.memmove(out, outputs, size)
            return 0
        return FastPath(ctypes.c_void_p(0), set_real, do_step, get_real, inputs, terminated=terminated,
                        last_time=last_time, start_step=start_step, finish_step=finish_step)

    def _c_fast_path(self, side: slot_c.MasterSide, inputs: Any, terminated: ctypes.c_bool | None) -> FastPath:
        """The fast path of the C child: the master's side's C functions with FMI 2.0's arguments (``c`` its
        Parent), which the compiled loop calls directly; a lost child is a status of its own
        (:meth:`fail_status` reports it), or raised by the step's halves."""
        last_time = ctypes.c_double(math.nan) if terminated is not None else None
        if terminated is not None and last_time is not None:
            side.p.terminated, side.p.last_time = ctypes.addressof(terminated), ctypes.addressof(last_time)
        step_name = self.call_name(Call.DO_STEP)
        child = self.child

        def start_step(c: Any, T: Any, H: Any) -> None:
            s = side.start(T.value, H.value)
            if s in (slot_c.LOST_DIED, slot_c.LOST_HUNG):
                raise self.died(ChildDied(child.lost(s)), step_name, T.value)

        def finish_step(spin: bool = True) -> int:
            s = side.finish(spin)
            if s == slot_c.INTERRUPTED:
                raise KeyboardInterrupt
            if s in (slot_c.LOST_DIED, slot_c.LOST_HUNG):
                raise self.died(ChildDied(child.lost(s)), step_name, child.t)
            return s
        lib = side.lib
        return FastPath(ctypes.c_void_p(ctypes.addressof(side.p)), lib.wmr_slot_set, lib.wmr_slot_step,
                        lib.wmr_slot_get, inputs, step_tail=(1,), terminated=terminated, last_time=last_time,
                        start_step=start_step, finish_step=finish_step, abi=2)

    def fail_status(self, what: str, status: int, t: float | None) -> RunError:
        """The error for a call that returned ``status``; where the C child's side returned it because the
        child is lost, the one line of a lost child (as the Python child raises it); KeyboardInterrupt where
        a second Ctrl-C interrupted its wait."""
        side = self.child.c_side
        if side is not None and status == slot_c.INTERRUPTED:   # (a second Ctrl-C during the wait)
            raise KeyboardInterrupt
        if side is not None and side.p.lost and status in (slot_c.LOST_DIED, slot_c.LOST_HUNG):
            return self.died(ChildDied(self.child.lost(status)), what, t)
        return super().fail_status(what, status, t)

    def accessor(self, fmi_type: str, op: str) -> tuple[Any, Any]:
        """(call, ctype) as :meth:`.fmu_instance.FmuInstance.accessor`, through the control channel."""
        ctype = ACCESS[self.fmi_version][fmi_type][0]

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


if __name__ == "__main__":
    sys.exit(_serve(sys.argv[1:]))
