"""The C child: the step slot of an isolated C FMU served in C on both sides (isolation_slot.c beside this
module, built like the compiled loop and kept in the same cache: :mod:`.compiled`).

An isolated instance of an FMU whose binary is C (no pythonfmu FMU: :func:`..model.binary.runs_python`),
hosted as co-simulation, steps without Python between the master's loop and the FMU: in the child
process, a C function calls the FMU's fmi2SetReal/fmi2DoStep/fmi2GetReal (or FMI 3.0's) request after
request, waiting for the next over shared memory; in the master, the instance's fast path is three C
functions with FMI 2.0's signatures, which the compiled loop calls as it calls an FMU in process.  The
child's Python still loads the FMU and answers the control channel (everything but the step).  How both
sides wait (spin, spin yielding the core, block) is what the run's hand-off measures and chooses
(:mod:`.handoff`), as for the Python child; a crash, an exit or a hang is reported the same way.

``WMR_COSIM_CHILD=python`` in the environment gives every isolated instance the Python child (its step
in Python, one byte each way on a pair of pipes)."""
from __future__ import annotations

import ctypes
import os
from pathlib import Path
from typing import Any, Callable

from . import compiled

SOURCE = Path(__file__).with_name("isolation_slot.c")
FLAGS = ["-O2", "-shared", "-fPIC", "-ffp-contract=off", "-fno-strict-aliasing"]
#: Bytes of the slot's own words (requests made and answered, who sleeps), after its values.
WORDS = 128
#: Offset of the child's asleep word in them: set while the child is in Python (before its first request).
CHILD_ASLEEP = 72
#: What the master's side returns for a child that died or did not answer within the timeout, and for a wait
#: a signal's handler interrupted by raising (a second Ctrl-C): no FMI statuses.
LOST_DIED, LOST_HUNG, INTERRUPTED = 1001, 1002, 1003

_P = ctypes.c_void_p
TICK = ctypes.CFUNCTYPE(ctypes.c_long, ctypes.c_long, ctypes.c_long)
PRE = ctypes.CFUNCTYPE(ctypes.c_int)


class Parent(ctypes.Structure):
    """The master's side of one child (isolation_slot.c)."""
    _fields_ = [("head", _P), ("w", _P), ("out", _P), ("out_bytes", ctypes.c_size_t), ("step_w", ctypes.c_int),
                ("done_r", ctypes.c_int), ("timeout", ctypes.c_double), ("stepping", ctypes.c_int),
                ("fresh", ctypes.c_int), ("terminated", _P), ("last_time", _P), ("t", ctypes.c_double),
                ("lost", ctypes.c_int), ("seq", ctypes.c_uint64), ("tick", _P), ("left", ctypes.c_long),
                ("skipped", ctypes.c_long), ("ran_out", ctypes.c_long), ("backoff", ctypes.c_int * 2),
                ("gil_ensure", _P), ("gil_release", _P), ("check_signals", _P), ("err_clear", _P)]


class Served(ctypes.Structure):
    """The child's side: the FMU's functions on the slot (isolation_slot.c)."""
    _fields_ = [("head", _P), ("w", _P), ("in_", _P), ("out", _P), ("s_r", ctypes.c_int), ("d_w", ctypes.c_int),
                ("ctl_r", ctypes.c_int), ("abi", ctypes.c_int), ("c", _P), ("set", _P), ("step", _P), ("get", _P),
                ("in_vr", _P), ("n_in", ctypes.c_size_t), ("n_in_values", ctypes.c_size_t), ("out_vr", _P),
                ("n_out", ctypes.c_size_t), ("n_out_values", ctypes.c_size_t), ("no_set_prior", ctypes.c_int),
                ("pre", _P), ("last", ctypes.c_uint64), ("flags", ctypes.c_bool * 3), ("last_success", ctypes.c_double),
                ("backoff", ctypes.c_int * 2)]


_LIBS: dict[str, Any] = {}


def library_path() -> Path | None:
    """The built library, or None where isolated instances take the Python child (``WMR_COSIM_CHILD=python``,
    no C compiler, a build that does not match this module)."""
    if os.environ.get("WMR_COSIM_CHILD", "").lower() == "python":
        return None
    try:
        path = compiled.build(SOURCE, "isolation-slot", FLAGS, "the C child")
        load(str(path))
    except (compiled.NoBuild, OSError, RuntimeError):
        return None
    return path


def load(path: str, view: Any = ctypes.PyDLL) -> Any:
    """The library at ``path`` through ``view`` (PyDLL: called with the GIL held, as the compiled loop calls
    an FMU; CDLL: the GIL let go for the call), checked against this module's structures."""
    key = f"{path}\0{view.__name__}"
    lib = _LIBS.get(key)
    if lib is None:
        lib = view(path)
        lib.wmr_slot_sizes.restype = ctypes.c_size_t
        lib.wmr_slot_sizes.argtypes = [ctypes.c_int]
        if [lib.wmr_slot_sizes(i) for i in range(3)] != [WORDS, ctypes.sizeof(Parent), ctypes.sizeof(Served)]:
            raise RuntimeError("the C child's structures differ from this module's (a mismatched build)")
        for name in ("wmr_slot_set", "wmr_slot_step", "wmr_slot_get", "wmr_slot_start", "wmr_slot_finish",
                     "wmr_slot_serve"):
            getattr(lib, name).restype = ctypes.c_int
        _LIBS[key] = lib
    return lib


def for_fmu(unzipdir: str, solver: Any) -> Path | None:
    """The library where an isolated instance of the FMU extracted in ``unzipdir`` is served by the C child:
    co-simulation (``solver`` None) of an FMU with binaries, none of them pythonfmu's; else None (the Python
    child)."""
    from .in_process import runs_python

    if solver is not None or not (Path(unzipdir) / "binaries").is_dir() or runs_python(unzipdir):
        return None
    return library_path()


# ---------------------------------------------------------------------------------------- the master's side
class MasterSide:
    """The master's side of a child served in C: the :class:`Parent` over the slot at ``addr`` (its values,
    ``cap`` of each way, then its words), and the fast path's functions."""

    def __init__(self, lib_path: str, addr: int, head: int, cap: int, step_w: int, done_r: int,
                 timeout: float | None) -> None:
        """The slot at ``addr``: a header of ``head`` bytes, then ``cap`` inputs, ``cap`` outputs, the words;
        ``timeout`` [s]: the longest wait for an answer (None: no limit)."""
        self.lib = load(lib_path)
        self.released = load(lib_path, ctypes.CDLL)   # (start and finish from Python: the GIL let go)
        self.p = Parent(head=addr, w=addr + head + 16 * cap, step_w=step_w, done_r=done_r,
                        timeout=-1.0 if timeout is None else float(timeout))
        self.outputs_at = addr + head + 8 * cap
        self.tick: Any = None
        api = ctypes.pythonapi
        self.p.gil_ensure, self.p.gil_release, self.p.check_signals, self.p.err_clear = (
            _address(f) for f in (api.PyGILState_Ensure, api.PyGILState_Release, api.PyErr_CheckSignals, api.PyErr_Clear))

    def outputs(self, n_out: int) -> None:
        """The Float64 outputs: ``n_out`` values at the slot's outputs."""
        self.p.out, self.p.out_bytes = self.outputs_at, 8 * n_out

    def measured_by(self, tick: Callable[[int, int], int]) -> None:
        """``tick(skipped, ran_out) -> steps it may skip``, called before a step's request (:meth:`.handoff.Handoff.tick`)."""
        def guarded(skipped: int, ran_out: int) -> int:
            try:
                return int(tick(skipped, ran_out))
            except BaseException:   # (the measure is the run's, not the step's: the step goes on)
                return 0
        self.tick = TICK(guarded)
        self.p.tick = ctypes.cast(self.tick, _P).value or 0

    def start(self, t: float, h: float) -> int:
        """A step's request from ``t`` [s] over ``h`` [s]: 0, or LOST_*."""
        return int(self.released.wmr_slot_start(ctypes.byref(self.p), ctypes.c_double(t), ctypes.c_double(h)))

    def finish(self, spin: bool) -> int:
        """The answer to the step started: its status, or LOST_*; ``spin`` False: block at once."""
        return int(self.released.wmr_slot_finish(ctypes.byref(self.p), int(spin)))


# ---------------------------------------------------------------------------------------- the child's side
class ChildSide:
    """The child's side: the FMU's raw functions of the fast path ``fp`` (those of the library itself, FMI
    2.0 or 3.0: :attr:`.contract.FastPath.abi`) over the slot at ``addr``."""

    def __init__(self, lib_path: str, addr: int, head: int, cap: int, fds: tuple[int, int, int], fp: Any,
                 io: tuple[Any, ...], n_in: int, n_out: int) -> None:
        """The slot as :class:`MasterSide`'s; ``fds``: the step pipe's end to read, the done pipe's to write,
        the control channel's to read; ``io``: (input references, their count, output references, their
        count, ...) as ctypes values; ``n_in``, ``n_out``: the values (FMI 3.0 arrays: more than references)."""
        in_vr, nin, out_vr, nout, _ = io
        self.lib = load(lib_path)
        s_r, d_w, ctl_r = fds
        words = addr + head + 16 * cap
        self.s = Served(head=addr, w=words, in_=addr + head, out=addr + head + 8 * cap, s_r=s_r, d_w=d_w, ctl_r=ctl_r,
                        abi=fp.abi, c=fp.c.value or 0, set=_address(fp.set_real), step=_address(fp.do_step),
                        get=_address(fp.get_real), in_vr=ctypes.addressof(in_vr), n_in=nin.value,
                        n_in_values=n_in, out_vr=ctypes.addressof(out_vr), n_out=nout.value, n_out_values=n_out,
                        last=ctypes.c_uint64.from_address(words).value)
        self.keep = (in_vr, out_vr)
        self.pre: Any = None

    def serve(self, no_set_prior: bool, pre: Callable[[], int] | None) -> bool:
        """Answer the master's requests until it sends a control request (True) or goes (False);
        ``no_set_prior``: the steps' noSetFMUStatePriorToCurrentPoint; ``pre``: called once before the next
        step's DoStep, after its inputs (the inputs' derivatives)."""
        self.s.no_set_prior = int(no_set_prior)
        self.pre = PRE(pre) if pre is not None else None
        self.s.pre = ctypes.cast(self.pre, _P).value if pre is not None else None
        return bool(self.lib.wmr_slot_serve(ctypes.byref(self.s)))


def raw_path(fp: Any) -> bool:
    """The fast path's set, step and get are all the library's own functions (FMI 2.0 or 3.0 arguments)."""
    funcs = (fp.set_real, fp.do_step, fp.get_real)
    return fp.abi in (2, 3) and all(isinstance(f, ctypes._CFuncPtr) for f in funcs)   # type: ignore[attr-defined]


def _address(fn: Any) -> int:
    return ctypes.cast(fn, _P).value or 0
