"""The fixed-step loop in C (native_loop.c beside this module: Gauss-Seidel and Jacobi, at one rate or with
instances at their own rates): built with the system's C compiler the first
time it is needed and kept in a cache folder under the hash of its source and the compiler, loaded with
ctypes, and given the same wiring the generated Python loop takes (:mod:`.generated`): each instance's
fast path (its FMI functions called directly where they are the library's own, else a callback into
Python), its copies, tables and other connections, the clock, and the recording's row.

Why this route (docs/architecture.md): no build step at install (a machine without a compiler installs and
runs the Python loop, and the run says so), one C file that does not change with the system (the
system is data: a new set of copies after an event costs no compile), and the per-step calls made from C
with no interpreter between them.  The library is called with the GIL held, as the Python loop calls the
FMUs: an FMU's Python code (pythonfmu) and the log callbacks take it recursively.

``WMR_COSIM_LOOP=python`` in the environment makes every run take the Python loop; ``CC`` names the compiler
(default ``cc``); ``WMR_COSIM_CACHE`` the cache folder (default ``$XDG_CACHE_HOME/wmr-cosim``, else
``~/.cache/wmr-cosim``).
"""
from __future__ import annotations

import ctypes
import os
from pathlib import Path
from typing import Any, Callable

from ..instances import compiled
from ..instances.failure import Call, Failure
from ..messages.errors import CosimError
from .algorithm import Clock, InstanceIO, NativeRecording, StepDone

SOURCE = Path(__file__).with_name("native_loop.c")
FLAGS = ["-O2", "-shared", "-fPIC", "-ffp-contract=off", "-fno-strict-aliasing"]
#: The win64 toolchain every build of a Windows binary uses (the container's, plan/container.py; the FMUs',
#: fmus/build.py and fmus/cplant_build.py): the MinGW-w64 cross compilers (the C one builds the DLLs; FMPy's
#: CMake project also asks for a C++ one) and the linker flags (libgcc kept out of a DLL's imports: KERNEL32
#: and msvcrt only; no symbols).
MINGW_CC, MINGW_CXX = "x86_64-w64-mingw32-gcc", "x86_64-w64-mingw32-g++"
WIN64_LDFLAGS = "-static-libgcc -s"


def fmi_headers(fmi: int = 2) -> Path:
    """The folder of the FMI 2.0 or 3.0 standard's headers FMPy ships (fmi2Functions.h / fmi3Functions.h and
    the files they include), which every C build of ours compiles against (the container's FMI 3.0 face, the
    FMUs' loaders)."""
    import fmpy

    folder = Path(fmpy.__file__).parent / "c-code"
    if not (folder / f"fmi{fmi}Functions.h").is_file():
        raise CosimError(f"{folder}: FMPy's FMI {fmi}.0 headers not found (fmpy >= 0.3.20 ships them)")
    return folder
#: What the loop names a run's stepping by (summary.json "stepping": "loop").
NATIVE, PYTHON = "compiled (C)", "Python"
_CALLS = {1: Call.TABLE_INPUTS, 2: Call.NON_FINITE_INPUT, 3: Call.SET_REAL, 4: Call.CONNECTION, 5: Call.DO_STEP,
          6: Call.GET_REAL, 7: Call.GET_RECORDED, 8: Call.TERMINATED}
_P = ctypes.c_void_p


class Inst(ctypes.Structure):
    _fields_ = [("abi", ctypes.c_int), ("c", _P), ("set", _P), ("step", _P), ("get", _P),
                ("raw_set", ctypes.c_int), ("raw_step", ctypes.c_int), ("raw_get", ctypes.c_int),
                ("in_vr", _P), ("n_in", ctypes.c_size_t), ("in_val", _P), ("n_in_values", ctypes.c_size_t),
                ("out_vr", _P), ("n_out", ctypes.c_size_t), ("out_val", _P), ("n_out_values", ctypes.c_size_t),
                ("no_set_prior", ctypes.c_int), ("flags", _P * 3), ("last_success", _P), ("terminated", _P),
                ("last_time", _P), ("n_copies", ctypes.c_int), ("pos", _P), ("src", _P), ("slot", _P),
                ("factor", _P), ("offset", _P), ("plain", _P), ("feed", _P), ("n_other", ctypes.c_int),
                ("other", _P), ("dec", ctypes.c_long), ("taken", ctypes.c_long), ("spent", ctypes.c_double)]


class Loop(ctypes.Structure):
    _fields_ = [("n", ctypes.c_int), ("inst", _P), ("simultaneous", ctypes.c_int), ("check_inputs", ctypes.c_int),
                ("t0", ctypes.c_double), ("h", ctypes.c_double), ("h_last", ctypes.c_double),
                ("k_last", ctypes.c_long), ("row", _P), ("row_bytes", ctypes.c_size_t),
                ("decimation", ctypes.c_long), ("n_steps", ctypes.c_long), ("has_stop", ctypes.c_int),
                ("stop", ctypes.c_double), ("getters", _P), ("rec", _P), ("rec_cap", ctypes.c_long),
                ("rec_n", ctypes.c_long), ("f_step", ctypes.c_long), ("f_inst", ctypes.c_int),
                ("f_call", ctypes.c_int), ("f_value", ctypes.c_double), ("f_time", ctypes.c_double),
                ("multirate", ctypes.c_int), ("n_cols", ctypes.c_int), ("col_src", _P), ("col_kind", _P),
                ("col_dst", _P), ("rec_bytes", ctypes.c_size_t), ("bad_row", ctypes.c_long), ("bad_col", ctypes.c_int)]


_IO = ctypes.CFUNCTYPE(ctypes.c_int)
_STEP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_double, ctypes.c_double)
_FEED = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_long)
_TAKE = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_long, ctypes.c_int)


_LIB: Any = None
_WHY_NOT: str | None = None


def library() -> tuple[Any, str | None]:
    """(the loop's library, None), or (None, why the Python loop is taken)."""
    global _LIB, _WHY_NOT
    if os.environ.get("WMR_COSIM_LOOP", "").lower() == "python":
        return None, "WMR_COSIM_LOOP=python"
    if _LIB is None and _WHY_NOT is None:
        try:
            _LIB = _load(_build())
        except _NoLoop as exc:
            _WHY_NOT = str(exc)
    return _LIB, _WHY_NOT


class _NoLoop(Exception):
    pass


def _build() -> Path:
    """The library, compiled once per source and compiler into the cache folder (:mod:`..instances.compiled`)."""
    try:
        return compiled.build(SOURCE, "native-loop", FLAGS, "the compiled loop")
    except compiled.NoBuild as exc:
        raise _NoLoop(str(exc)) from None


def _load(path: Path) -> Any:
    lib = ctypes.PyDLL(str(path))
    lib.wmr_loop.argtypes = [ctypes.POINTER(Loop), ctypes.c_long, ctypes.c_long]
    lib.wmr_loop.restype = ctypes.c_int
    lib.wmr_loop_sizes.argtypes = [ctypes.c_int]
    lib.wmr_loop_sizes.restype = ctypes.c_size_t
    if (lib.wmr_loop_sizes(0), lib.wmr_loop_sizes(1)) != (ctypes.sizeof(Inst), ctypes.sizeof(Loop)):
        raise _NoLoop("the compiled loop's structures differ from this module's (a mismatched build)")
    return lib


def _address(obj: Any) -> int:
    """The address of a ctypes object, or of what a ``byref`` points at."""
    inner = getattr(obj, "_obj", None)
    return ctypes.addressof(inner if inner is not None else obj)


def _raw(fn: Any) -> bool:
    """An FMI function of the library itself (not a Python callable)."""
    return isinstance(fn, ctypes._CFuncPtr)   # type: ignore[attr-defined]


class NativeLoop:
    """``loop(k0, k1) -> Failure | None`` over these instances as the generated loop's, in C; with
    ``rates`` (each instance's decimation), as the multi-rate algorithm's (:mod:`.multirate`), whose
    failures carry their time and whose steps taken and their wall time are counted (:meth:`counts`)."""

    def __init__(self, lib: Any, ios: list[InstanceIO], simultaneous: bool, clock: Clock, done: StepDone,
                 check_inputs: bool, rates: list[int] | None = None) -> None:
        self.lib, self.ios, self.done = lib, ios, done
        self.error: BaseException | None = None
        self.failure: Failure | None = None
        self.keep: list[Any] = []          # every object the C structures point into
        self.insts = (Inst * max(1, len(ios)))()
        for i, io in enumerate(ios):
            self._instance(self.insts[i], io)
        L = self.L = Loop(n=len(ios), inst=ctypes.addressof(self.insts), simultaneous=int(simultaneous),
                          check_inputs=int(check_inputs), t0=float(clock.start), h=float(clock.step))
        L.k_last, L.h_last = (clock.n_steps - 1, float(clock.length(clock.n_steps - 1))) if clock.stop is not None \
            else (-1, float(clock.step))
        L.multirate = int(rates is not None)
        for i, d in enumerate(rates or [1] * len(ios)):
            self.insts[i].dec = d
        self._recording(done, clock)

    # ------------------------------------------------------------------ set-up
    def _instance(self, p: Inst, io: InstanceIO) -> None:
        f = io.fast
        p.abi, p.c = f.abi, f.c.value or 0
        p.in_vr, p.n_in, p.in_val = ctypes.addressof(io.in_vr), io.n_in.value, ctypes.addressof(f.in_val)
        p.out_vr, p.n_out, p.out_val = ctypes.addressof(io.out_vr), io.n_out.value, ctypes.addressof(io.out_val)
        native = f.abi in (2, 3)
        p.raw_set = int(native and _raw(f.set_real))
        p.raw_step = int(native and _raw(f.do_step))
        p.raw_get = int(native and _raw(f.get_real))
        p.set = self._fn(f.set_real) if p.raw_set else \
            self._cb(_IO, lambda: f.set_real(f.c, io.in_vr, io.n_in, f.in_val, *f.set_tail))
        p.get = self._fn(f.get_real) if p.raw_get else \
            self._cb(_IO, lambda: f.get_real(f.c, io.out_vr, io.n_out, io.out_val, *f.get_tail))
        if p.raw_step:
            p.step = self._fn(f.do_step)
        else:
            t, h = ctypes.c_double(), ctypes.c_double()
            self.keep += [t, h]

            def step(tv: float, hv: float) -> int:
                t.value, h.value = tv, hv
                return f.do_step(f.c, t, h, *f.step_tail)
            p.step = self._cb(_STEP, step)
        if f.abi == 3:
            p.n_in_values, p.n_out_values = f.set_tail[0].value, f.get_tail[0].value
        if native and p.raw_step:
            p.no_set_prior = int(bool(f.step_tail[0]))
            if f.abi == 3:
                for j in range(3):
                    p.flags[j] = _address(f.step_tail[1 + j])
                p.last_success = _address(f.step_tail[4])
        if f.terminated is not None and f.last_time is not None:
            p.terminated, p.last_time = ctypes.addressof(f.terminated), ctypes.addressof(f.last_time)
        self._copies(p, io)
        if io.feed is not None:
            feed = io.feed
            p.feed = self._cb(_FEED, lambda k: feed(k))
        if io.other:
            others = (_P * len(io.other))(*[self._cb(_IO, fn) for fn in io.other])
            self.keep.append(others)
            p.n_other, p.other = len(io.other), ctypes.addressof(others)

    def _copies(self, p: Inst, io: InstanceIO) -> None:
        n = len(io.copies)
        if not n:
            return
        arrays = ((ctypes.c_int * n)(*[c.pos for c in io.copies]),
                  (_P * n)(*[ctypes.addressof(c.src) for c in io.copies]),
                  (ctypes.c_long * n)(*[c.slot for c in io.copies]),
                  (ctypes.c_double * n)(*[c.factor for c in io.copies]),
                  (ctypes.c_double * n)(*[c.offset for c in io.copies]),
                  (ctypes.c_int * n)(*[int(c.factor == 1.0 and c.offset == 0.0) for c in io.copies]))
        self.keep += [*arrays, *(c.src for c in io.copies)]
        p.n_copies = n
        p.pos, p.src, p.slot, p.factor, p.offset, p.plain = (ctypes.addressof(a) for a in arrays)

    def _recording(self, done: StepDone, clock: Clock) -> None:
        """The rows written as the records of the recording, in its buffer, where it gives their layout
        (``rec.records``); else the row copied into a buffer the recording takes after the segment; or, for a
        ``done`` that gives no row to copy, ``done`` called after every step."""
        L = self.L
        rec: NativeRecording | None = getattr(done, "native", None)
        self.rec = rec
        self.buf = ctypes.create_string_buffer(0)
        if rec is None:
            L.decimation, L.n_steps = 1, clock.n_steps
            L.getters = self._failing(lambda k, ended: done(k, bool(ended)))
            return
        L.row, L.row_bytes = ctypes.addressof(rec.buf), rec.row_bytes
        L.decimation, L.n_steps = rec.decimation, rec.n_steps
        L.has_stop, L.stop = int(rec.stop is not None), float(rec.stop or 0.0)
        read = rec.read_others
        if read is not None:
            L.getters = self._failing(lambda k, ended: read(k))
        if rec.records is not None:
            cols = rec.records.columns
            arrays = tuple((ctypes.c_int * len(cols))(*[c[j] for c in cols]) for j in range(3))
            self.keep += arrays
            L.n_cols, L.rec_bytes = len(cols), rec.records.record_bytes
            L.col_src, L.col_kind, L.col_dst = (ctypes.addressof(a) for a in arrays)

    def _failing(self, fn: Callable[[int, int], Failure | None]) -> int:
        """A C callback ``(k, ended)`` of ``fn``, whose Failure is kept for the segment's end (status 1)."""
        def call(k: int, ended: int) -> int:
            self.failure = fn(k, ended)
            return 1 if self.failure is not None else 0
        return self._cb(_TAKE, call)

    def _fn(self, fn: Any) -> int:
        self.keep.append(fn)
        return ctypes.cast(fn, _P).value or 0

    def _cb(self, kind: Any, fn: Callable[..., int]) -> int:
        """A C callback of ``fn``: an exception in it is kept and stops the segment (status -1)."""
        def guarded(*args: Any) -> int:
            try:
                return int(fn(*args))
            except BaseException as exc:   # (raised again by __call__, outside the C loop)
                self.error = exc
                return -1
        cb = kind(guarded)
        self.keep.append(cb)
        return ctypes.cast(cb, _P).value or 0

    # ------------------------------------------------------------------ the loop
    def __call__(self, k0: int, k1: int) -> Failure | None:
        L, rec = self.L, self.rec
        if rec is not None:
            need = (k1 - k0) // max(1, L.decimation) + 2
            if L.n_cols:   # (written where the recording keeps them)
                assert rec.records is not None
                L.rec, L.rec_cap, L.rec_n, L.bad_row = rec.records.reserve(need), need, 0, -1
            else:
                if ctypes.sizeof(self.buf) < need * L.row_bytes:
                    self.buf = ctypes.create_string_buffer(need * L.row_bytes)
                L.rec, L.rec_cap, L.rec_n = ctypes.addressof(self.buf), need, 0
        self.error = self.failure = None
        code = self.lib.wmr_loop(ctypes.byref(L), k0, k1)
        if rec is not None and L.rec_n:
            if L.n_cols:
                assert rec.records is not None
                rec.records.took(L.rec_n, L.bad_row, L.bad_col)
            else:
                rec.extend(self.buf.raw[:L.rec_n * L.row_bytes], L.rec_n)
        if code == 0:
            return None
        if code == 2:
            if self.error is not None:
                err, self.error = self.error, None
                raise err
            return self.failure
        io = self.ios[L.f_inst]
        call = _CALLS[L.f_call]
        value = float(L.f_value) if call is Call.NON_FINITE_INPUT or call is Call.TERMINATED else int(L.f_value)
        if L.multirate and call is not Call.TERMINATED:
            return Failure(L.f_step, io.name, call, value, float(L.f_time))
        return Failure(L.f_step, io.name, call, value)

    def counts(self) -> list[tuple[int, float]]:
        """Multi-rate: each instance's steps taken and their wall time [s] since the last call (then zeroed)."""
        out = []
        for p in self.insts[:len(self.ios)]:
            out.append((int(p.taken), float(p.spent)))
            p.taken, p.spent = 0, 0.0
        return out
