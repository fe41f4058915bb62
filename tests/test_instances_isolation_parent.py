"""The master's side of an isolated FMU (cosim/instances/isolation.py: Child, IsolatedInstance), against a fake child
process: a short stdlib script started in place of ``python -m wmr_cosim.cosim.instances.isolation`` with the same
arguments, pipes and shared memory, that answers the same requests as the real child and can be told
to fail (an error answer, an exit, a signal, a hang, a slow or piecewise answer).  Its model, in the step
slot: y[0] = sum of the inputs, y[1] = t, y[2] = h, y[j] = j beyond.  It writes every request it gets to
its log file (the instance's log), as an FMU's log would show the calls.

These tests run the master's code in the test process (what the real child does is tested end to end in
tests/test_instances_isolation.py)."""
from __future__ import annotations

import ctypes
import json
import os
import signal
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from wmr_cosim.cosim.instances import isolation
from wmr_cosim.cosim.messages.errors import RunError
from wmr_cosim.cosim.instances.failure import InstanceLost
from wmr_cosim.cosim.instances.isolation import Child, ChildDied, IsolatedInstance, spin_for

FAKE_CHILD = r'''
import json, mmap, os, pickle, select, signal, stat, struct, sys, time

shm_name, c_r, c_w, s_r, d_w = sys.argv[1], *map(int, sys.argv[2:6])
mode = json.loads(sys.argv[6])
name, log_path, logging = sys.argv[7:10]
log = open(log_path, "a") if log_path else None


def note(*words):
    if log is not None:
        log.write(" ".join(map(str, words)) + "\n")
        log.flush()


note("start", name, logging)
try:
    note("stdin", "pipe" if stat.S_ISFIFO(os.fstat(0).st_mode) else "other")
except OSError:
    note("stdin", "closed")
print("stdout of", name, flush=True)
print("stderr of", name, file=sys.stderr, flush=True)
fd = os.open("/dev/shm/" + shm_name, os.O_RDWR)
mem = mmap.mmap(fd, 0)
os.close(fd)
cap = (len(mem) - 32) // 16
io = {"n_in": 0, "n_out": 0, "u": [], "t": 0.0, "h": 0.0}
typed = {}


def act(what):
    kind = what[0]
    if kind == "exit":
        sys.exit(what[1])
    if kind == "signal":
        signal.signal(what[1], signal.SIG_DFL)
        os.kill(os.getpid(), what[1])
        time.sleep(10)
    if kind in ("hang", "slow"):
        time.sleep(what[1])
    if kind == "close":      # the pipes closed, the process still there for a while
        for f in (c_r, c_w, s_r, d_w):
            os.close(f)
        time.sleep(what[1])
        sys.exit(0)


def read_inputs():
    io["u"] = list(struct.unpack_from(f"<{io['n_in']}d", mem, 32))


def write_outputs():
    y = [sum(io["u"]), io["t"], io["h"]] + [float(j) for j in range(3, io["n_out"])]
    for j in range(io["n_out"]):
        struct.pack_into("<d", mem, 32 + 8 * cap + 8 * j, y[j])


def handle(op, args):
    if op == "configure":
        io["n_in"], io["n_out"] = args[1], args[3]
        return None
    if op == "set_inputs":
        read_inputs()
        return 0
    if op == "get_outputs":
        write_outputs()
        return 0
    if op == "echo":
        return args
    if op == "log_state":
        return tuple(mode.get("log", (0, 0, 0, [])))
    if op == "set_typed":
        for vr, v in zip(args[1], args[2]):
            typed[(args[0], vr)] = v
        return 0
    if op == "get_typed":
        return 0, [typed.get((args[0], vr), 0) for vr in args[1]][:args[2]]
    if op == "terminated_at":
        return mode.get("terminated_at")
    if op == "get_value":
        return mode.get("value")
    if op in ("instantiate", "setup_experiment", "set_values", "enter_initialization", "exit_initialization",
              "shutdown"):
        return None
    raise KeyError(op)


SENT = [0]


def send(reply):
    data = pickle.dumps(reply)
    data = struct.pack("<q", len(data)) + data
    SENT[0] += 1
    if mode.get("stall_body") and SENT[0] > 1:   # after the first answer: the length, then nothing for a while
        os.write(c_w, data[:8])
        time.sleep(mode["stall_body"])
        os.write(c_w, data[8:])
    elif mode.get("piecewise"):
        for a, b in ((0, 3), (3, 11), (11, len(data))):
            os.write(c_w, data[a:b])
            time.sleep(0.01)
    else:
        os.write(c_w, data)


def read_exact(f, n):
    out = b""
    while len(out) < n:
        chunk = os.read(f, n - len(out))
        if not chunk:
            sys.exit(0)
        out += chunk
    return out


polls = select.poll()
polls.register(c_r, select.POLLIN)
polls.register(s_r, select.POLLIN)
k = 0
while True:
    for f, _ in polls.poll():
        if f == s_r:
            if not os.read(s_r, 1):
                sys.exit(0)
            k += 1
            io["t"], io["h"] = struct.unpack_from("<dd", mem, 8)
            read_inputs()
            note("step", k, io["t"], io["h"])
            what = mode.get("steps", {}).get(str(k))
            status = 0
            if what is not None and what[0] == "status":
                status = what[1]
            elif what is not None:
                act(what)
            write_outputs()
            struct.pack_into("<q", mem, 0, status)
            os.write(d_w, b"d")
            continue
        (n,) = struct.unpack("<q", read_exact(c_r, 8))
        op, args = pickle.loads(read_exact(c_r, n))
        note("call", op, *map(repr, args))
        what = mode.get("replies", {}).get(op)
        if what is not None and what[0] in ("error", "ok"):
            send(tuple(what))
            continue
        if what is not None:
            act(what)
        try:
            send(("ok", handle(op, args)))
        except KeyError:
            send(("error", f"no operation {op}"))
'''

def _entry(inst, *args):
    """The fast path's set_real, do_step, get_real and input array."""
    fp = inst.fast_path(*args)
    return fp.set_real, fp.do_step, fp.get_real, fp.in_val


MD2 = SimpleNamespace(fmiVersion="2.0")
MD3 = SimpleNamespace(fmiVersion="3.0")
TAIL = "(isolated: the other instances are terminated and freed, the recording kept)"


@pytest.fixture
def fake(tmp_path, monkeypatch):
    """Children started by the code under test run the fake child; every Child and IsolatedInstance made
    through ``fake.child``/``fake.instance`` is closed at the end."""
    script = tmp_path / "bin" / "fake_child.py"
    script.parent.mkdir()
    script.write_text(FAKE_CHILD)
    real = subprocess.Popen

    def popen(argv, **kw):
        if list(argv[1:3]) != ["-m", "wmr_cosim.cosim.instances.isolation"]:
            return real(argv, **kw)
        return real([argv[0], "-I", "-S", str(script), *argv[3:]], **kw)

    monkeypatch.setattr(isolation.subprocess, "Popen", popen)
    made: list = []

    def child(mode: dict | None = None, log: Path | None = None, timeout: float | None = 5.0,
              spin: int = 0) -> Child:
        c = Child("d", json.dumps(mode or {}), log, "warning", timeout, spin)
        made.append(c)
        return c

    def instance(mode: dict | None = None, log: Path | None = None, md=MD2, timeout: float | None = 5.0,
                 spin: int = 0) -> IsolatedInstance:
        inst = IsolatedInstance("d", md, json.dumps(mode or {}), log, "warning", timeout, spin)
        made.append(inst.child)
        return inst

    yield SimpleNamespace(child=child, instance=instance)
    for c in made:
        c.kill()
        c.close()


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def _started(log: Path) -> None:
    """Wait (at most 30 s) until the fake child has started: its log has its first lines.  Before a
    short timeout, so that the time the child takes to start does not count."""
    import time

    for _ in range(3000):
        if log.is_file() and len(_lines(log)) >= 2:
            return
        time.sleep(0.01)
    raise AssertionError("the fake child did not start")


# ------------------------------------------------------------------------------------------ the child
def test_the_childs_output_goes_to_a_file_beside_its_log(fake, tmp_path, capfd):
    log = tmp_path / "d.log"
    c = fake.child(log=log)
    assert c.call("echo", 1) == (1,)
    c.close()
    out = (tmp_path / "d.log.stdout").read_text()
    assert "stdout of d" in out and "stderr of d" in out
    captured = capfd.readouterr()
    assert "of d" not in captured.out + captured.err
    assert _lines(log)[0] == "start d warning"


def test_without_a_log_the_child_writes_no_file(fake, tmp_path, monkeypatch, capfd):
    """No file, no output and no warning on the master's side (a user would see a warning on stderr)."""
    import warnings

    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c = fake.child(log=None)
    assert c.call("echo", "x") == ("x",)
    c.close()
    assert os.listdir(tmp_path / "cwd") == []
    captured = capfd.readouterr()
    assert "of d" not in captured.out + captured.err    # the child's output is dropped


def test_the_child_cannot_read_the_masters_stdin(fake, tmp_path):
    """An FMU that reads its standard input must not take the master's (here a pipe)."""
    r, w = os.pipe()
    saved = os.dup(0)
    os.dup2(r, 0)
    try:
        c = fake.child(log=tmp_path / "d.log")
    finally:
        os.dup2(saved, 0)
        for f in (saved, r, w):
            os.close(f)
    c.call("echo")
    c.close()
    assert "stdin pipe" not in _lines(tmp_path / "d.log") and "stdin other" in _lines(tmp_path / "d.log")


@pytest.mark.parametrize("piecewise", [False, True])
def test_a_request_and_its_answer(fake, piecewise):
    """The answer is the child's, also when it arrives in pieces."""
    c = fake.child({"piecewise": piecewise})
    assert c.call("echo", 1, "a", [2.5, -1.0]) == (1, "a", [2.5, -1.0])
    assert c.call("echo", "second") == ("second",)


def test_an_error_answer_is_an_exception_with_the_childs_message(fake):
    c = fake.child()
    with pytest.raises(RuntimeError) as exc:
        c.call("frobnicate", 1)
    assert str(exc.value) == "no operation frobnicate"
    assert c.call("echo", 2) == (2,)      # the child is still there


@pytest.mark.parametrize("what, how", [(["exit", 3], "exited with code 3"), (["exit", 0], "exited with code 0"),
                                       (["signal", int(signal.SIGSEGV)], "was killed by SIGSEGV"),
                                       (["signal", 40], "was killed by signal 40")])
def test_a_child_that_dies_during_a_request(fake, what, how):
    """How it died, in words; later requests and steps say the same (the pipe is broken)."""
    c = fake.child({"replies": {"instantiate": what}})
    with pytest.raises(ChildDied) as exc:
        c.call("instantiate")
    assert str(exc.value) == how
    with pytest.raises(ChildDied) as exc:
        c.call("echo")
    assert str(exc.value) == how
    with pytest.raises(ChildDied) as exc:
        c.step(0.0, 0.1)
    assert str(exc.value) == how


def test_a_child_that_closes_its_pipes_but_does_not_end(fake):
    """It did not answer; at the end it is ended by force.  (Its grace period of a few seconds is
    simulated: the wait with a timeout times out at once.)"""
    c = fake.child({"replies": {"instantiate": ["close", 3.0]}})
    real_wait = c.proc.wait

    def wait(timeout=None):
        if timeout is not None:
            raise subprocess.TimeoutExpired("fake child", timeout)
        return real_wait()

    c.proc.wait = wait
    with pytest.raises(ChildDied) as exc:
        c.call("instantiate")
    assert str(exc.value) == "did not answer"
    c.close()
    assert real_wait() == -signal.SIGKILL


@pytest.mark.parametrize("spin, timeout, slow", [(0, 5.0, 0), (0, None, 0.05), (50, 5.0, 0), (50, None, 0.05),
                                                 (-5, 5.0, 0.02), (10 ** 6, None, 0)])
def test_a_step_runs_in_the_child_on_the_slot(fake, spin, timeout, slow):
    """The inputs written in place reach the child, with the time and step size; the outputs and the
    status come back in place, whether the master spins, blocks or waits with a timeout."""
    steps = {"1": ["slow", slow], "2": ["status", 2]} if slow else {"2": ["status", 2]}
    c = fake.child({"steps": steps}, timeout=timeout, spin=spin)
    inputs, outputs = c.configure([1, 2], 2, [10, 11, 12, 13], 4)
    assert (len(inputs), len(outputs)) == (2, 4)
    inputs[0], inputs[1] = 1.5, 2.25
    assert c.step(0.5, 0.25) == 0
    assert list(outputs) == [3.75, 0.5, 0.25, 3.0]
    inputs[1] = -1.0
    assert c.step(0.75, 0.125) == 2
    assert list(outputs) == [0.5, 0.75, 0.125, 3.0]
    none = fake.child()
    assert [len(a) for a in none.configure([], 0, [], 0)] == [1, 1]


def test_the_step_slot_holds_8192_values(fake):
    c = fake.child()
    with pytest.raises(RuntimeError) as exc:
        c.configure(list(range(4097)), 4097, list(range(4096)), 4096)
    assert str(exc.value) == "8193 values: more than the step slot holds"
    inputs, outputs = c.configure(list(range(4096)), 4096, list(range(4096)), 4096)
    inputs[4095] = 7.0
    c.step(0.0, 1.0)
    assert outputs[0] == 7.0 and outputs[4095] == 4095.0
    c2 = fake.child()
    inputs, outputs = c2.configure(list(range(8192)), 8192, [], 0)
    assert len(inputs) == 8192


@pytest.mark.parametrize("where, spin", [("request", 0), ("step", 0), ("step", 20)])
def test_a_hang_is_ended_after_the_timeout(fake, tmp_path, where, spin):
    mode = {"replies": {"instantiate": ["hang", 5.0]}} if where == "request" else {"steps": {"1": ["hang", 5.0]}}
    c = fake.child(mode, log=tmp_path / "d.log", timeout=1.0, spin=spin)
    _started(tmp_path / "d.log")
    c.configure([], 0, [], 0)
    with pytest.raises(ChildDied) as exc:
        c.call("instantiate") if where == "request" else c.step(0.0, 0.1)
    assert str(exc.value) == "did not answer within 1 s (ended)"
    assert c.proc.poll() == -signal.SIGKILL


def test_the_first_answer_may_take_the_startup_time_and_later_ones_the_step_timeout(fake, tmp_path, monkeypatch):
    """The child's first answer (its start) is held to STARTUP_TIMEOUT when that is longer than the step
    timeout; every later answer to the step timeout; a child that never answers is ended after the
    startup time, not waited for."""
    monkeypatch.setattr(isolation, "STARTUP_TIMEOUT", 3.0)
    c = fake.child({"replies": {"configure": ["slow", 1.5], "instantiate": ["hang", 5.0]}}, timeout=0.5)
    c.configure([], 0, [], 0)                               # 1.5 s: more than the step timeout, answered
    assert c.started
    with pytest.raises(ChildDied) as exc:
        c.call("instantiate")
    assert str(exc.value) == "did not answer within 0.5 s (ended)"
    silent = fake.child({"replies": {"configure": ["hang", 30.0]}}, timeout=0.5)
    t0 = time.monotonic()
    with pytest.raises(ChildDied) as exc:
        silent.configure([], 0, [], 0)
    assert str(exc.value) == "did not answer within 3 s (ended)" and time.monotonic() - t0 < 20


def test_an_answer_whose_body_does_not_follow_its_length_is_ended_after_the_timeout(fake):
    c = fake.child({"stall_body": 30.0}, timeout=0.5)
    c.configure([], 0, [], 0)    # (the first answer comes whole)
    t0 = time.monotonic()
    with pytest.raises(ChildDied) as exc:
        c.call("echo", 1)
    assert str(exc.value) == "did not answer within 0.5 s (ended)" and time.monotonic() - t0 < 20


@pytest.mark.parametrize("spin", [0, 10 ** 7])
def test_a_death_inside_a_step(fake, spin):
    c = fake.child({"steps": {"2": ["signal", int(signal.SIGABRT)]}}, spin=spin)
    c.configure([], 0, [], 0)
    assert c.step(0.0, 0.1) == 0
    with pytest.raises(ChildDied) as exc:
        c.step(0.1, 0.1)
    assert str(exc.value) == "was killed by SIGABRT"


def test_spin_only_while_every_child_has_a_core(monkeypatch):
    """Spin (a positive count) while the children and the master have a core each; else a negative
    count: yield the core between polls."""
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    assert spin_for(3) == isolation.SPIN and spin_for(0) == isolation.SPIN
    yielding = spin_for(4)
    assert isinstance(yielding, int) and 0 < -yielding < isolation.SPIN
    monkeypatch.setattr(os, "cpu_count", lambda: None)     # unknown: one core
    assert spin_for(0) == isolation.SPIN and spin_for(1) == yielding


# ------------------------------------------------------------------------------------------ the instance
def test_life_cycle_requests_reach_the_child(fake, tmp_path):
    log = tmp_path / "d.log"
    inst = fake.instance({"value": 4.5}, log=log)
    inst.instantiate()
    inst.setup_experiment(0.5, 2.0, 1e-6)
    inst.set_values([("p", 2.5)])
    assert inst.get_value(SimpleNamespace(name="x")) == 4.5
    inst.enter_initialization()
    inst.exit_initialization()
    inst.shutdown()
    assert inst.child.proc.poll() == 0
    inst.shutdown()                       # once only
    calls = [ln for ln in _lines(log) if ln.startswith("call")]
    ops = [ln.split()[1] for ln in calls]
    assert [o for o in ops if o != "log_state"] == ["instantiate", "setup_experiment", "set_values", "get_value",
                                                    "enter_initialization", "exit_initialization", "shutdown"]
    assert "call setup_experiment 0.5 2.0 1e-06" in calls and "call set_values [('p', 2.5)]" in calls
    assert (tmp_path / "d.log.stdout").is_file()


def _requests(inst: IsolatedInstance) -> list:
    return [("instantiate", "instantiate", inst.instantiate, None),
            ("setup_experiment", "set-up", lambda: inst.setup_experiment(0.5, 2.0, None), 0.5),
            ("set_values", "setting values", lambda: inst.set_values([]), None),
            ("get_value", "reading x", lambda: inst.get_value(SimpleNamespace(name="x")), None),
            ("enter_initialization", "initialisation", inst.enter_initialization, 0.5),
            ("exit_initialization", "initialisation", inst.exit_initialization, 0.5)]


OPS = ("instantiate", "setup_experiment", "set_values", "get_value", "enter_initialization", "exit_initialization")


@pytest.mark.parametrize("k", range(6))
def test_a_failed_request_names_the_instance_what_it_was_doing_and_when(fake, k):
    op = OPS[k]
    inst = fake.instance({"replies": {op: ["error", f"{op}  went\nwrong"]}})
    if op in ("enter_initialization", "exit_initialization"):
        inst.setup_experiment(0.5, 2.0, None)
    _, what, call, t = _requests(inst)[k]
    with pytest.raises(RunError) as exc:
        call()
    assert str(exc.value) == f"d: {what}: {op} went wrong"
    assert (exc.value.instance, exc.value.time) == ("d", t) and not isinstance(exc.value, InstanceLost)

    dead = fake.instance({"replies": {op: ["exit", 3]}})
    if op in ("enter_initialization", "exit_initialization"):
        dead.setup_experiment(0.5, 2.0, None)
    _, what, call, t = _requests(dead)[k]
    with pytest.raises(RunError) as exc:
        call()
    at = " at t = 0.5 s" if t is not None else ""
    assert str(exc.value) == f"d: the FMU's process exited with code 3 during {what}{at} {TAIL}"
    assert (exc.value.instance, exc.value.time, isinstance(exc.value, InstanceLost)) == ("d", t, True)


def test_the_last_log_lines_come_from_the_child(fake):
    inst = fake.instance({"log": [7, 9, 2, ["first", "a  b\n c", "d", "e"]]})
    assert inst.last_log() == "a b c | d | e"
    assert inst.last_log(1) == "e" and inst.last_log(10) == "first | a b c | d | e"
    assert (inst.log_lines, inst.received, inst.n_errors) == (7, 9, 2)
    inst.close_log()
    quiet = fake.instance()
    assert quiet.last_log() == "(the FMU logged nothing)"


def test_an_instance_whose_child_died_at_once(fake):
    inst = fake.instance({"replies": {"instantiate": ["exit", 1]}, "log": [7, 9, 2, ["x"]]})
    assert (inst.log_lines, inst.received, inst.n_errors) == (0, 0, 0)
    with pytest.raises(RunError):
        inst.instantiate()
    assert inst.last_log() == "(the FMU logged nothing)"
    assert (inst.log_lines, inst.received, inst.n_errors) == (0, 0, 0)
    inst.shutdown()


def test_a_non_ok_status_is_reported_as_in_process(fake, tmp_path):
    from wmr_cosim.cosim.instances.in_process import Instance

    inst = fake.instance({"log": [1, 1, 1, ["bad  input"]]}, log=tmp_path / "d.log")
    err = inst.fail_status("fmi2DoStep", 3, 0.5)
    assert str(err) == "d: fmi2DoStep returned Error at t = 0.5 s; last log: bad input"
    assert (err.instance, err.time) == ("d", 0.5) and not inst.fatal
    ref = SimpleNamespace(name="d", fatal=False, last_log=lambda: "bad input")
    assert str(Instance.fail_status(ref, "fmi2DoStep", 3, 0.5)) == str(err)
    assert str(inst.fail_status("fmi2Terminate", 2, None)) == "d: fmi2Terminate returned Discard; last log: bad input"
    inst.fail_status("fmi2DoStep", 4, 0.5)
    assert inst.fatal
    inst.shutdown()                       # after a Fatal: nothing is called in the FMU
    assert not any(ln.startswith("call shutdown") for ln in _lines(tmp_path / "d.log"))
    assert inst.child.proc.poll() == 0


def test_a_dead_instance_is_not_asked_to_shut_down(fake, tmp_path):
    inst = fake.instance({"replies": {"instantiate": ["exit", 3]}}, log=tmp_path / "d.log")
    with pytest.raises(RunError):
        inst.instantiate()
    inst.shutdown()
    assert inst.child.proc.poll() == 3


@pytest.mark.parametrize("md, expected", [(MD2, 0.75), (MD3, None)])
def test_terminated_at(fake, md, expected):
    """FMI 2.0: the time the FMU asked to terminate at (fmi2GetRealStatus), from the child; FMI 3.0 says so in
    the step's flags instead."""
    assert fake.instance({"terminated_at": 0.75}, md=md).terminated_at() == expected


def test_the_fast_path_before_and_after_the_first_step(fake, tmp_path):
    """Before the first step (initialisation) set and get are requests; from the first step on, the
    inputs go with the step and the outputs come back with it."""
    log = tmp_path / "d.log"
    inst = fake.instance(log=log)
    set_real, do_step, get_real, inputs = _entry(inst, [1, 2], 2, [10, 11, 12], 3)
    x = -1.2345678901234567   # every byte of it non-zero: a copy past the outputs shows
    out = (ctypes.c_double * 5)(*[x] * 5)
    inputs[0], inputs[1] = 1.0, 2.0
    assert set_real(None, None, None, inputs) == 0
    assert get_real(None, None, None, out) == 0
    assert list(out) == [3.0, 0.0, 0.0, x, x]
    inputs[0] = 5.0
    assert set_real(None, None, None, inputs) == 0
    n_calls = len(_lines(log))
    assert do_step(None, ctypes.c_double(0.0), ctypes.c_double(0.1)) == 0
    assert get_real(None, None, None, out) == 0
    assert list(out) == [7.0, 0.0, 0.1, x, x]
    inputs[1] = 0.5
    set_real(None, None, None, inputs)
    do_step(None, ctypes.c_double(0.1), ctypes.c_double(0.1))
    get_real(None, None, None, out)
    assert list(out) == [5.5, 0.1, 0.1, x, x]
    assert [ln.split()[0] for ln in _lines(log)[n_calls:]] == ["step", "step"]   # no requests


@pytest.mark.parametrize("op, what", [("set_inputs", "setting inputs"), ("get_outputs", "getting outputs")])
def test_set_and_get_before_the_first_step_report_failures(fake, op, what):
    inst = fake.instance({"replies": {op: ["error", "it broke"]}})
    set_real, _, get_real, _ = _entry(inst, [1], 1, [2], 1)
    out = (ctypes.c_double * 1)()
    with pytest.raises(RunError) as exc:
        set_real() if op == "set_inputs" else get_real(None, None, None, out)
    assert str(exc.value) == f"d: {what}: it broke"
    status = fake.instance({"replies": {op: ["ok", 3]}})
    set_real, _, get_real, _ = _entry(status, [1], 1, [2], 1)
    assert (set_real() if op == "set_inputs" else get_real(None, None, None, out)) == 3


def test_a_fast_path_that_cannot_be_set_up(fake):
    big = fake.instance()
    with pytest.raises(RunError) as exc:
        _entry(big, list(range(9000)), 9000, [], 0)
    assert str(exc.value) == "d: 9000 values: more than the step slot holds"
    assert (exc.value.instance, exc.value.time) == ("d", None)
    dead = fake.instance({"replies": {"configure": ["exit", 3]}})
    with pytest.raises(RunError) as exc:
        _entry(dead, [], 0, [], 0)
    assert str(exc.value) == f"d: the FMU's process exited with code 3 during set-up {TAIL}"
    assert (exc.value.instance, exc.value.time, isinstance(exc.value, InstanceLost)) == ("d", None, True)


@pytest.mark.parametrize("md, call", [(MD2, "fmi2DoStep"), (MD3, "fmi3DoStep")])
def test_a_death_inside_do_step(fake, md, call):
    inst = fake.instance({"steps": {"2": ["signal", int(signal.SIGSEGV)]}}, md=md)
    _, do_step, _, _ = _entry(inst, [], 0, [], 0)
    assert do_step(None, ctypes.c_double(0.0), ctypes.c_double(0.25)) == 0
    with pytest.raises(RunError) as exc:
        do_step(None, ctypes.c_double(0.25), ctypes.c_double(0.25))
    assert str(exc.value) == f"d: the FMU's process was killed by SIGSEGV during {call} at t = 0.25 s {TAIL}"
    assert (exc.value.instance, exc.value.time, isinstance(exc.value, InstanceLost)) == ("d", 0.25, True)


def test_a_hang_inside_do_step_is_ended_after_the_step_timeout(fake, tmp_path):
    inst = fake.instance({"steps": {"1": ["hang", 5.0]}}, log=tmp_path / "d.log", timeout=1.0)
    _started(tmp_path / "d.log")
    _, do_step, _, _ = _entry(inst, [], 0, [], 0)
    with pytest.raises(RunError) as exc:
        do_step(None, ctypes.c_double(0.5), ctypes.c_double(0.25))
    assert str(exc.value) == f"d: the FMU's process did not answer within 1 s (ended) during fmi2DoStep at t = 0.5 s {TAIL}"


def test_fmi3_terminate_simulation_from_the_child(fake):
    """The child's status 100 is fmi3DoStep's terminateSimulation flag, with status OK."""
    inst = fake.instance({"steps": {"1": ["status", 100], "2": ["status", 2]}}, md=MD3)
    fp = inst.fast_path([], 0, [], 0)
    assert fp.step_tail == () and not fp.terminated.value
    assert fp.do_step(None, ctypes.c_double(0.0), ctypes.c_double(0.1)) == 0
    assert fp.terminated.value
    fp.terminated.value = False
    assert fp.do_step(None, ctypes.c_double(0.1), ctypes.c_double(0.1)) == 2
    assert not fp.terminated.value
    assert fake.instance(md=MD2).fast_path([], 0, [], 0).terminated is None   # FMI 2.0: Discard and fmi2GetBooleanStatus


@pytest.mark.parametrize("md, fmi_type, ctype, values", [(MD2, "Integer", ctypes.c_int, [4, -5]),
                                                         (MD3, "Float64", ctypes.c_double, [0.5, 2.5])])
def test_values_of_other_types_through_the_control_channel(fake, md, fmi_type, ctype, values):
    inst = fake.instance(md=md)
    set_, ct = inst.accessor(fmi_type, "Set")
    get, _ = inst.accessor(fmi_type, "Get")
    assert ct is ctype
    vrs = (ctypes.c_uint * 2)(3, 4)
    assert set_(vrs, ctypes.c_size_t(2), (ctype * 2)(*values), ctypes.c_size_t(2)) == 0
    buf = (ctype * 2)()
    assert get(vrs, ctypes.c_size_t(2), buf, ctypes.c_size_t(2)) == 0
    assert list(buf) == values
    one = (ctype * 2)()
    assert get((ctypes.c_uint * 1)(4), ctypes.c_size_t(1), one, ctypes.c_size_t(1)) == 0
    assert list(one) == [values[1], 0]


@pytest.mark.parametrize("op", ["Set", "Get"])
def test_a_death_while_reading_or_writing_other_types(fake, op):
    inst = fake.instance({"replies": {f"{op.lower()}_typed": ["exit", 3]}})
    _, do_step, _, _ = _entry(inst, [], 0, [], 0)
    do_step(None, ctypes.c_double(0.25), ctypes.c_double(0.25))
    call, ctype = inst.accessor("Integer", op)
    with pytest.raises(RunError) as exc:
        call((ctypes.c_uint * 1)(3), ctypes.c_size_t(1), (ctype * 1)(), ctypes.c_size_t(1))
    assert str(exc.value) == f"d: the FMU's process exited with code 3 during fmi{op}Integer at t = 0.25 s {TAIL}"
    assert (exc.value.instance, exc.value.time, isinstance(exc.value, InstanceLost)) == ("d", 0.25, True)


def test_the_instances_child_writes_beside_its_log(fake, tmp_path, monkeypatch):
    inst = fake.instance(log=str(tmp_path / "d.log"))
    inst.instantiate()
    inst.shutdown()
    assert "stdout of d" in (tmp_path / "d.log.stdout").read_text()
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    quiet = fake.instance(log=None)
    quiet.instantiate()
    quiet.shutdown()
    assert os.listdir(tmp_path / "cwd") == []


def test_a_death_before_the_first_step_is_at_the_start_time(fake):
    """A value of another type set during initialisation, at the start time 2.5 s: the child's death
    is reported at 2.5 s."""
    inst = fake.instance({"replies": {"set_typed": ["exit", 3]}})
    inst.setup_experiment(2.5, 3.0, None)
    call, ctype = inst.accessor("Integer", "Set")
    with pytest.raises(RunError) as exc:
        call((ctypes.c_uint * 1)(3), ctypes.c_size_t(1), (ctype * 1)(7), ctypes.c_size_t(1))
    assert str(exc.value) == f"d: the FMU's process exited with code 3 during fmiSetInteger at t = 2.5 s {TAIL}"
