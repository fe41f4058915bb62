"""One FMU instance (cosim/instances/in_process.py): what the master asks of an FMU at each step of its life cycle, what it
makes of the statuses and log messages the FMU sends back, and the error messages the user then reads.

Two kinds of FMU: a recording stand-in for FMPy's slave classes (it answers like FMPy, records every call
with its arguments, fails the calls it is told to with the FMI status given, and logs through the
callbacks it was handed, as a C FMU does), and the Modelica Association's Reference FMUs (real FMI 3.0
binaries) for the values and messages that cross the C interface.
"""
from __future__ import annotations

import itertools
from types import SimpleNamespace

import fmpy
import pytest
from fmpy.fmi1 import FMICallException

from reference_fmus import REF
from wmr_cosim.cosim.instances import in_process as instance_mod
from wmr_cosim.cosim.messages.errors import RunError
from wmr_cosim.cosim.instances.in_process import Instance, Instance3
from wmr_cosim.cosim.model.description import Variable, load_model

OK, WARNING, DISCARD, ERROR, FATAL = range(5)


class FakeSlave:
    """Stands in for FMPy's FMU2Slave / FMU3Slave."""

    def __init__(self, **kwargs) -> None:
        self.kwargs = kwargs          # what the slave was made with (guid, instanceName, ...)
        self.calls: list[tuple[str, tuple]] = []
        self.fail: dict[str, int] = {}      # FMPy method name -> the FMI status it returns
        self.values: dict[int, object] = {}  # value reference -> what a getter returns
        self.component = None
        self.instantiate_args: tuple = ()

    def _record(self, name: str, args: tuple) -> None:
        self.calls.append((name, args))
        if name in self.fail:
            raise FMICallException(name, self.fail[name])

    def instantiate(self, *args):
        if self.fail.get("instantiate") == "NULL":     # fmiInstantiate returned NULL: FMPy raises this
            self.calls.append(("instantiate", args))
            raise Exception("Failed to instantiate model")
        self._record("instantiate", args)
        self.instantiate_args = args
        self.component = 0x1234

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)

        def method(*args):
            self._record(name, args)
            if name.startswith("get"):
                return [self.values[args[0][0]]]
            return None
        return method

    def names(self) -> list[str]:
        return [c for c, _ in self.calls]

    def say2(self, status: int, category: bytes | None, message: bytes | None, env="own",
             instance_name: bytes | None = b"own") -> None:
        """Log as an FMI 2.0 FMU does: through the logger of the callbacks it got at fmi2Instantiate, with
        the componentEnvironment and instance name given there unless told otherwise."""
        cb = self.instantiate_args[1]
        cb.logger(cb.componentEnvironment if env == "own" else env,
                  self.kwargs["instanceName"].encode() if instance_name == b"own" else instance_name,
                  status, category, message)

    def say3(self, status: int, category: bytes | None, message: bytes | None) -> None:
        """Log as an FMI 3.0 FMU does: through the logMessage callback it got at instantiation."""
        self.instantiate_args[4](None, status, category, message)


def _md(categories=("logEvents", "logStatusError"), tool="Some Tool 1.0"):
    return SimpleNamespace(guid="{g}", coSimulation=SimpleNamespace(modelIdentifier="M"),
                           logCategories=[SimpleNamespace(name=c) for c in categories], generationTool=tool)


@pytest.fixture
def fake(monkeypatch):
    """make(cls, name, **kwargs) -> (instance, its FakeSlave); every instance made is shut down at the end."""
    monkeypatch.setattr(instance_mod, "FMU2Slave", FakeSlave)
    monkeypatch.setattr(fmpy.fmi3, "FMU3Slave", FakeSlave)
    made = []

    def make(cls=Instance, name="A", md=None, **kwargs):
        inst = cls(name, md or _md(), "/nowhere", **kwargs)
        made.append(inst)
        return inst, inst.fmu
    yield make
    for inst in made:
        inst.shutdown()


def var(name, vr, type_, fmi_type=None, shape=()):
    return Variable(name, vr, type_, "output", "continuous", None, None, None, None,
                    fmi_type=fmi_type or type_, shape=shape)


# ---------------------------------------------------------------- log messages (FMI 2.0)
def test_fmi2_messages_reach_the_instance_log_file_and_counters_by_status(fake, tmp_path):
    inst, fmu = fake(log_path=tmp_path / "A.log")
    inst.instantiate()
    fmu.say2(OK, b"logAll", b"below the level")
    fmu.say2(WARNING, b"logStatusWarning", b"careful")
    fmu.say2(DISCARD, b"logStatusDiscard", b"step  too\tlong")
    fmu.say2(ERROR, None, b"no category")
    fmu.say2(FATAL, b"logStatusFatal", None)
    fmu.say2(ERROR, b"caf\xe9", b"na\xefve")      # Latin-1 bytes: replaced, not a crash
    assert (inst.received, inst.n_errors, inst.log_lines) == (6, 4, 5)
    expected = ["[Warning] logStatusWarning: careful", "[Discard] logStatusDiscard: step  too\tlong",
                "[Error] : no category", "[Fatal] logStatusFatal: ", "[Error] caf\ufffd: na\ufffdve"]
    assert list(inst.log) == expected
    inst.close_log()
    assert (tmp_path / "A.log").read_text(encoding="utf-8") == "".join(ln + "\n" for ln in expected)


def test_what_an_fmu_logs_while_it_is_terminated_and_freed_reaches_the_log_file(fake, tmp_path, monkeypatch):
    """An FMU in an error state logs again when it is terminated ("Illegal call sequence"): the message
    goes to the log file like any other, not into a closed file (a traceback on stderr, the line lost)."""
    unraisable = []
    monkeypatch.setattr("sys.unraisablehook", unraisable.append)
    inst, fmu = fake(log_path=tmp_path / "A.log")
    inst.instantiate()
    inst.setup_experiment(0.0, 1.0, None)
    inst.enter_initialization()
    inst.exit_initialization()
    fmu.terminate = lambda: fmu.say2(ERROR, b"logStatusError", b"fmi2Terminate: Illegal call sequence.")
    fmu.freeInstance = lambda: fmu.say2(ERROR, b"logStatusError", b"freed")
    inst.shutdown()
    assert not unraisable, [u.exc_value for u in unraisable]
    assert (tmp_path / "A.log").read_text(encoding="utf-8") == (
        "[Error] logStatusError: fmi2Terminate: Illegal call sequence.\n[Error] logStatusError: freed\n")


def test_fmi2_level_all_keeps_ok_messages_and_names_unknown_statuses_by_number(fake):
    inst, fmu = fake(logging="all")
    inst.instantiate()
    fmu.say2(OK, b"logAll", b"fine")
    fmu.say2(5, b"c", b"pending")
    fmu.say2(6, b"c", b"odd")
    assert list(inst.log) == ["[OK] logAll: fine", "[Pending] c: pending", "[6] c: odd"]
    assert inst.n_errors == 2   # 6 and Pending (5) are counted with Discard, Error and Fatal: status >= 2


def test_one_discard_counts_as_one_error(fake):
    inst, fmu = fake(logging="error")
    inst.instantiate()
    fmu.say2(DISCARD, b"c", b"x")
    assert (inst.n_errors, inst.log_lines) == (1, 0)   # counted (a failed step explains itself), not kept
    fmu.say2(DISCARD, b"c", b"y")
    assert inst.n_errors == 2


def test_a_message_routes_by_environment_when_the_fmu_gives_no_instance_name(fake):
    inst, fmu = fake(name="B")
    inst.instantiate()
    fmu.say2(WARNING, b"c", b"by env", instance_name=None)
    fmu.say2(WARNING, b"c", b"by name", env=None)   # some tools' FMUs pass another environment
    assert list(inst.log) == ["[Warning] c: by env", "[Warning] c: by name"]


def test_a_message_from_an_fmu_the_master_did_not_make_is_printed(fake, monkeypatch, capsys):
    monkeypatch.setattr(instance_mod, "_IDS", itertools.count(1))   # the instance below gets environment 1
    inst, fmu = fake(name="C", logging="all")
    inst.instantiate()
    for status, msg in [(OK, b"hello  world"), (6, b"odd"), (WARNING, None), (ERROR, b"caf\xe9")]:
        fmu.say2(status, b"c", msg, env=None, instance_name=b"stranger")
    assert capsys.readouterr().out == "[OK] hello  world\n[6] odd\n[Warning] \n[Error] caf\ufffd\n"
    assert inst.received == 0


@pytest.mark.parametrize("tool, level, expected", [
    ("Some Tool 1.0", "all", [("setDebugLogging", (True, []))]),
    ("Some Tool 1.0", "warning", [("setDebugLogging", (True, ["logStatusWarning", "WarnMore", "logStatusError"]))]),
    ("Some Tool 1.0", "error", [("setDebugLogging", (True, ["logStatusError"]))]),
    ("Some Tool 1.0", "info", []),
    # pythonfmu reports exceptions without a category: it gets no list, the level applies on this side
    ("PythonFMU 0.6.5", "warning", []),
    ("pythonfmu", "all", [("setDebugLogging", (True, []))]),
    (None, "error", [("setDebugLogging", (True, ["logStatusError"]))]),   # no generationTool attribute value
])
def test_fmi2_debug_logging_asks_for_the_categories_of_the_level(fake, tool, level, expected):
    md = _md(("logEvents", "logStatusWarning", "WarnMore", "logStatusError"), tool=tool)
    inst, fmu = fake(md=md, logging=level)
    inst.instantiate()
    visible, callbacks, logging_on = fmu.instantiate_args
    assert (visible, logging_on) == (False, True)
    assert fmu.calls[1:] == expected


def test_fmi2_debug_logging_failure_is_named(fake):
    for level in ("all", "warning"):
        inst, fmu = fake(name=level, logging=level)
        fmu.fail["setDebugLogging"] = ERROR
        with pytest.raises(RunError, match=rf"^{level}: fmi2SetDebugLogging returned Error; "):
            inst.instantiate()
    inst, fmu = fake(name="B", md=_md(("logEvents",)), logging="error")
    inst.instantiate()
    assert fmu.calls[1:] == [("setDebugLogging", (False, []))]


# ---------------------------------------------------------------- last log and failure messages
def test_last_log_gives_the_last_three_lines_with_their_whitespace_collapsed(fake):
    inst, fmu = fake()
    assert inst.last_log() == "(the FMU logged nothing)"
    inst.instantiate()
    for i in range(5):
        fmu.say2(WARNING, b"c", f"line {i}\n  more".encode())
    assert inst.last_log() == "[Warning] c: line 2 more | [Warning] c: line 3 more | [Warning] c: line 4 more"
    assert inst.last_log(1) == "[Warning] c: line 4 more"


def test_a_failed_call_names_instance_call_status_time_and_last_log(fake):
    inst, fmu = fake(name="plant")
    inst.instantiate()
    fmu.say2(ERROR, b"logStatusError", b"bad   parameter")
    err = inst.fail_status("fmi2DoStep", ERROR, 1.23456789)
    assert isinstance(err, RunError)
    assert str(err) == ("plant: fmi2DoStep returned Error at t = 1.23457 s; "
                        "last log: [Error] logStatusError: bad parameter")
    assert (err.instance, err.time) == ("plant", 1.23456789)
    assert not inst.fatal
    err = inst.fail_status("fmi2SetupExperiment", WARNING, None)
    assert str(err) == "plant: fmi2SetupExperiment returned Warning; last log: [Error] logStatusError: bad parameter"
    assert (err.instance, err.time) == ("plant", None)
    assert str(inst.fail_status("x", OK, 0.0)).startswith("plant: x returned OK at t = 0 s;")
    assert str(inst.fail_status("x", 6, 0.0)).startswith("plant: x returned 6 at t = 0 s;")


def test_fatal_makes_the_instance_untouchable(fake):
    inst, fmu = fake()
    inst.instantiate()
    fmu.fail["setupExperiment"] = FATAL
    with pytest.raises(RunError, match=r"^A: fmi2SetupExperiment returned Fatal; last log: \(the FMU logged"):
        inst.setup_experiment(0.0, 1.0, None)
    n = len(fmu.calls)
    inst.shutdown()
    assert len(fmu.calls) == n


def test_fmi2_life_cycle_calls_and_their_failures(fake):
    inst, fmu = fake()
    inst.instantiate()
    inst.setup_experiment(0.5, 2.0, 1e-6)
    inst.enter_initialization()
    inst.exit_initialization()
    inst.shutdown()
    assert fmu.calls[1:] == [("setDebugLogging", (True, ["logStatusError"])),
                             ("setupExperiment", (1e-6, 0.5, 2.0)), ("enterInitializationMode", ()),
                             ("exitInitializationMode", ()), ("terminate", ()), ("freeInstance", ())]
    steps = [("setupExperiment", "fmi2SetupExperiment", lambda i: i.setup_experiment(0.0, None, None)),
             ("enterInitializationMode", "fmi2EnterInitializationMode", lambda i: i.enter_initialization()),
             ("exitInitializationMode", "fmi2ExitInitializationMode", lambda i: i.exit_initialization())]
    for k, (method, shown, action) in enumerate(steps):
        inst, fmu = fake(name=f"F{k}")
        inst.instantiate()
        fmu.fail[method] = ERROR
        with pytest.raises(RunError, match=rf"^F{k}: {shown} returned Error; last log: "):
            action(inst)
        assert not inst.initialised


def test_an_exception_in_a_call_names_instance_call_and_time(fake):
    inst, fmu = fake(name="P")
    inst.instantiate()
    fmu.say2(WARNING, b"c", b"before")

    def broken(x):
        raise ValueError(f"bad\n   value {x}")
    with pytest.raises(RunError) as exc:
        inst.call("fmi2DoStep", broken, 3, t=0.25)
    assert str(exc.value) == "P: fmi2DoStep failed: bad value 3; last log: [Warning] c: before"
    assert (exc.value.instance, exc.value.time) == ("P", 0.25)


@pytest.mark.parametrize("cls, version", [(Instance, 2), (Instance3, 3)])
def test_a_raw_get_that_leaves_a_python_error_behind_is_an_error_status_with_the_error_logged(fake, monkeypatch,
                                                                                          cls, version):
    """A pythonfmu FMU whose Integer no longer fits a C long returns OK with -1 and its Python error left
    set, which ctypes raises on return (the call is made through a PyDLL): the call's status is Error (the
    value is not valid), the error in the instance's log, for the stepping loop to report with its time."""
    inst, fmu = fake(cls, name="sensor")
    inst.instantiate()
    named = []

    def raw(dll, name):
        named.append(name)

        def call(*args):
            raise OverflowError("Python int too large to convert to C long")
        return call
    monkeypatch.setattr(instance_mod, "raw", raw)
    get, _ = inst.accessor("Integer" if version == 2 else "Int32", "Get")
    assert get(None, None, None, None) == ERROR
    assert named == [f"fmi{version}GetInt{'eger' if version == 2 else '32'}"]
    assert inst.n_errors == 1
    assert inst.last_log() == (f"[Error] exception: {named[0]}: OverflowError: Python int too large to convert to "
                               "C long (raised in the FMU's code)")


def test_no_fmu_state_call_reaches_an_instance_freed_already(fake):
    """FMPy unloads the FMU's library with fmi2FreeInstance: a state call after it would jump into unmapped
    memory (the execution frees its saved states before its instances; this is the instance's own guard)."""
    inst, fmu = fake(name="P")
    inst.instantiate()
    inst.shutdown()
    before = list(fmu.names())
    for call in (lambda: inst.free_state(object()), lambda: inst.set_state(object()), inst.get_state):
        with pytest.raises(RunError, match="after the instance was freed"):
            call()
    assert fmu.names() == before


# ---------------------------------------------------------------- reading values (FMI 2.0)
def test_fmi2_get_value_reads_each_type_with_its_fmi_call(fake):
    inst, fmu = fake()
    inst.instantiate()
    fmu.values = {1: 1.5, 2: 3, 3: 2, 4: True, 5: b"caf\xe9 ok"}
    got = [inst.get_value(var("r", 1, "Real")), inst.get_value(var("i", 2, "Integer")),
           inst.get_value(var("e", 3, "Enumeration")), inst.get_value(var("b", 4, "Boolean")),
           inst.get_value(var("s", 5, "String"))]
    assert got == [1.5, 3, 2, True, "caf\ufffd ok"]   # an FMU's non-UTF-8 text is replaced, not a crash
    assert [c for c in fmu.calls if c[0].startswith("get")] == [
        ("getReal", ([1],)), ("getInteger", ([2],)), ("getInteger", ([3],)), ("getBoolean", ([4],)),
        ("getString", ([5],))]


def test_fmi2_get_value_errors(fake):
    inst, fmu = fake()
    inst.instantiate()
    with pytest.raises(RunError, match=r"^A: variables of type Binary cannot be read$") as exc:
        inst.get_value(var("x", 1, "Binary"))
    assert exc.value.instance == "A"
    fmu.fail["getReal"] = ERROR
    with pytest.raises(RunError, match=r"^A: fmi2GetReal\(y\) returned Error; last log: "):
        inst.get_value(var("y", 2, "Real"))


# ---------------------------------------------------------------- FMI 3.0 life cycle
def test_fmi3_instance_defaults_keep_200_warning_lines_in_memory(fake):
    inst, fmu = fake(Instance3, name="F3")
    assert fmu.kwargs["instanceName"] == "F3" and inst.name == "F3"
    assert (inst.received, inst.n_errors, inst.log_lines) == (0, 0, 0)
    inst.shutdown()                       # never instantiated: nothing to free
    assert fmu.calls == []
    inst, fmu = fake(Instance3, name="F3b")
    inst.instantiate()
    for i in range(201):
        fmu.say3(WARNING, b"logStatusWarning", f"w{i}".encode())
    fmu.say3(OK, b"logEvents", b"dropped at the default level")
    assert (inst.received, inst.n_errors, inst.log_lines, len(inst.log)) == (202, 0, 201, 200)
    assert inst.log[0] == "[Warning] logStatusWarning: w1"


def test_fmi3_life_cycle_calls(fake, tmp_path):
    inst, fmu = fake(Instance3, name="F3", log_path=tmp_path / "F3.log")
    inst.instantiate()
    visible, logging_on, event_mode, early_return, log_message = fmu.instantiate_args
    assert (visible, logging_on, bool(event_mode), bool(early_return)) == (False, True, False, False)
    assert fmu.calls[1] == ("setDebugLogging", (True, ["logStatusError"]))
    fmu.say3(ERROR, b"logStatusError", b"\xce\xa9 too big")
    inst.setup_experiment(0.5, 2.0, 1e-6)
    inst.enter_initialization()
    inst.exit_initialization()
    assert fmu.calls[2:] == [("enterInitializationMode", (1e-6, 0.5, 2.0)), ("exitInitializationMode", ())]
    inst.shutdown()
    assert fmu.names()[-2:] == ["terminate", "freeInstance"]
    assert (tmp_path / "F3.log").read_text(encoding="utf-8") == "[Error] logStatusError: \u03a9 too big\n"


@pytest.mark.parametrize("level, expected", [
    ("all", [("setDebugLogging", (True, []))]),
    ("warning", [("setDebugLogging", (True, ["logStatusWarning", "WarnMore", "logStatusError"]))]),
    ("error", [("setDebugLogging", (True, ["logStatusError"]))]),
    ("info", []),
])
def test_fmi3_debug_logging_asks_for_the_categories_of_the_level(fake, level, expected):
    md = _md(("logEvents", "logStatusWarning", "WarnMore", "logStatusError"))
    inst, fmu = fake(Instance3, md=md, logging=level)
    inst.instantiate()
    assert fmu.calls[1:] == expected


def test_fmi3_debug_logging_off_when_no_category_fits_and_not_asked_without_categories(fake):
    inst, fmu = fake(Instance3, md=_md(("logEvents",)), logging="error")
    inst.instantiate()
    assert fmu.calls[1:] == [("setDebugLogging", (False, []))]
    inst, fmu = fake(Instance3, name="B", md=_md(()), logging="all")
    inst.instantiate()
    assert fmu.names() == ["instantiate"]
    md = _md()
    del md.logCategories                  # a description without LogCategories
    inst, fmu = fake(Instance3, name="C", md=md, logging="all")
    inst.instantiate()
    assert fmu.names() == ["instantiate"]


def test_fmi3_failures_name_the_fmi3_call(fake):
    steps = [("instantiate", "fmi3InstantiateCoSimulation", lambda i: i.instantiate()),
             ("setDebugLogging", "fmi3SetDebugLogging", lambda i: i.instantiate()),
             ("enterInitializationMode", "fmi3EnterInitializationMode", lambda i: i.enter_initialization()),
             ("exitInitializationMode", "fmi3ExitInitializationMode", lambda i: i.exit_initialization())]
    for k, (method, shown, action) in enumerate(steps):
        inst, fmu = fake(Instance3, name=f"F{k}", logging="all")
        if method not in ("instantiate", "setDebugLogging"):
            inst.instantiate()
        fmu.fail[method] = ERROR
        with pytest.raises(RunError, match=rf"^F{k}: {shown} returned Error; last log: "):
            action(inst)
    inst, fmu = fake(Instance3, name="G")
    inst.instantiate()
    fmu.fail["getInt8"] = ERROR
    with pytest.raises(RunError, match=r"^G: fmi3GetInt8\(k\) returned Error; "):
        inst.get_value(var("k", 3, "Integer", "Int8"))
    fmu.fail["getInt64"] = ERROR          # FMI 3.0 has no Enumeration functions: an Enumeration is an Int64
    with pytest.raises(RunError, match=r"^G: fmi3GetInt64\(mode\) returned Error; "):
        inst.get_value(var("mode", 4, "Enumeration", "Enumeration"))
    fmu.fail["setInt64"] = ERROR
    with pytest.raises(RunError, match=r"^G: fmi3SetInt64\(mode\) returned Error; "):
        inst.set_values([(var("mode", 4, "Enumeration", "Enumeration"), 1)])
    fmu.fail["setFloat64"] = DISCARD
    with pytest.raises(RunError, match=r"^G: fmi3SetFloat64\(x\) returned Discard; "):
        inst.set_values([(var("x", 3, "Real", "Float64"), 1.0)])


def test_fmi3_initialisation_without_an_experiment_starts_at_zero_without_stop_or_tolerance(fake):
    inst, fmu = fake(Instance3)
    inst.instantiate()
    inst.enter_initialization()
    assert fmu.calls[-1] == ("enterInitializationMode", (None, 0.0, None))


def test_both_versions_load_the_fmu_by_its_description_under_the_instance_name(fake):
    for cls in (Instance, Instance3):
        inst, fmu = fake(cls, name=f"x{cls.__name__}")
        assert fmu.kwargs == {"guid": "{g}", "unzipDirectory": "/nowhere", "modelIdentifier": "M",
                              "instanceName": f"x{cls.__name__}"}


def test_fmi3_array_values_are_set_as_one_flat_call(fake):
    inst, fmu = fake(Instance3)
    inst.instantiate()
    inst.set_values([(var("x0", 5, "Real", "Float64", shape=(2,)), [1, 2]),
                     (var("k", 6, "Integer", "Int32", shape=(3,)), (4, 5, 6)),
                     (var("on", 7, "Boolean", "Boolean"), 1)])
    assert fmu.calls[2:] == [("setFloat64", ([5], [1.0, 2.0])), ("setInt32", ([6], [4, 5, 6])),
                             ("setBoolean", ([7], [1]))]


def test_an_instance_the_fmu_refused_to_create_is_reported_and_never_freed(fake):
    for cls, shown in ((Instance, "fmi2Instantiate"), (Instance3, "fmi3InstantiateCoSimulation")):
        inst, fmu = fake(cls, name=f"n{cls.__name__}")
        fmu.fail["instantiate"] = "NULL"
        with pytest.raises(RunError) as exc:
            inst.instantiate()
        assert str(exc.value) == (f"n{cls.__name__}: {shown} failed: Failed to instantiate model; "
                                  "last log: (the FMU logged nothing)")
        inst.shutdown()
        assert fmu.names() == ["instantiate"]


def test_an_fmi2_instance_never_initialised_is_freed_without_terminate(fake):
    inst, fmu = fake()
    inst.instantiate()
    inst.enter_initialization()
    inst.shutdown()
    inst.shutdown()                        # exactly once
    assert fmu.names()[-2:] == ["enterInitializationMode", "freeInstance"]


def test_fmi3_exit_initialization_marks_the_instance_for_termination(fake):
    inst, fmu = fake(Instance3)
    inst.instantiate()
    inst.enter_initialization()
    inst.shutdown()                        # not initialised: freed without fmi3Terminate
    assert fmu.names()[-1] == "freeInstance" and "terminate" not in fmu.names()
    assert inst.initialised is False


def test_fmi3_get_value_refuses_binary_and_arrays(fake):
    inst, fmu = fake(Instance3, name="F3")
    with pytest.raises(RunError, match=r"^F3: blob \(Binary\) cannot be read as one value$") as exc:
        inst.get_value(var("blob", 1, "Binary", "Binary"))
    assert exc.value.instance == "F3"
    with pytest.raises(RunError, match=r"^F3: A \(Float64\[2, 3\]\) cannot be read as one value$"):
        inst.get_value(var("A", 2, "Real", "Float64", shape=(2, 3)))
    assert fmu.calls == []


# ---------------------------------------------------------------- a real FMI 3.0 FMU
@pytest.fixture
def feedthrough(tmp_path):
    model = load_model(REF / "fmi3" / "Feedthrough.fmu")
    inst = Instance3("ft", model.md, fmpy.extract(str(model.path), str(tmp_path / "unz")))
    yield inst, model.variables
    inst.shutdown()


def test_fmi3_values_cross_a_real_fmu_by_type(feedthrough):
    inst, v = feedthrough
    inst.instantiate()
    inst.setup_experiment(0.25, 1.0, None)
    inst.set_values([(v["Float64_continuous_input"], "2.5"), (v["Int8_input"], -3), (v["Boolean_input"], 1),
                     (v["String_input"], "h\u00e9llo"), (v["Binary_input"], "0a1bff"),
                     (v["Enumeration_input"], 2)])
    inst.enter_initialization()
    inst.exit_initialization()
    assert inst.get_value(v["time"]) == 0.25
    assert inst.get_value(v["Float64_continuous_output"]) == 2.5
    assert inst.get_value(v["Int8_output"]) == -3
    assert inst.get_value(v["Boolean_output"]) is True
    assert inst.get_value(v["String_output"]) == "h\u00e9llo"
    assert inst.get_value(v["Enumeration_output"]) == 2
    assert inst.fmu.getBinary([v["Binary_output"].vr]) == [b"\x0a\x1b\xff"]


def test_fmi3_stop_time_reaches_the_fmu(feedthrough):
    inst, v = feedthrough
    inst.instantiate()
    inst.setup_experiment(0.0, 1.0, None)
    inst.enter_initialization()
    inst.exit_initialization()
    with pytest.raises(RunError, match=r"^ft: fmi3DoStep returned Error at t = 0 s; last log: \[Error\] "
                                       r"logStatusError: .*stop"):
        inst.call("fmi3DoStep", inst.fmu.doStep, 0.0, 1.5, t=0.0)


def test_fmi3_fmu_errors_arrive_in_the_log(feedthrough):
    inst, v = feedthrough
    inst.instantiate()
    bogus = var("bogus", 999, "Real", "Float64")
    with pytest.raises(RunError) as exc:
        inst.set_values([(bogus, 1.0)])
    msg = str(exc.value)
    assert msg.startswith("ft: fmi3SetFloat64(bogus) returned Error; last log: [Error] logStatusError: ")
    assert "999" in msg
    assert (inst.received, inst.n_errors, inst.log_lines) == (1, 1, 1)


# ---------------------------------------------------------------- a real FMI 2.0 FMU
def test_fmi2_fmu_messages_arrive_formatted_in_the_log(tmp_path):
    """The C FMU's message has printf arguments: FMPy's logger proxy formats them before the master sees it."""
    model = load_model(REF / "fmi2" / "Feedthrough.fmu")
    inst = Instance("ft2", model.md, fmpy.extract(str(model.path), str(tmp_path / "unz")))
    try:
        inst.instantiate()
        inst.setup_experiment(0.0, 1.0, None)
        with pytest.raises(RunError) as exc:
            inst.set_values([(var("bogus", 999, "Real"), 1.0)])
        assert str(exc.value).startswith("ft2: fmi2SetReal(bogus) returned Error; last log: [Error] logStatusError: ")
        assert "999" in str(exc.value) and "%" not in str(exc.value)
    finally:
        inst.shutdown()


def test_variadic_fmi2_messages_are_formatted_before_they_are_logged(tmp_path):
    """The probe FMU logs with a format and arguments ("%s", message), as most C FMUs do: FMPy's logger
    proxy, registered for each instance, formats them."""
    from c_fmu_support import build_probe

    path = build_probe(tmp_path / "fmu", "LogProbe")
    model = load_model(path)
    inst = Instance("probe", model.md, fmpy.extract(str(path), str(tmp_path / "unz")), logging="all")
    try:
        inst.instantiate()
        assert list(inst.log) == ["[OK] logAll: instantiated"]
    finally:
        inst.shutdown()


def test_a_new_instance_is_not_freed(fake):
    inst, _ = fake()
    assert inst.freed is False
    inst.instantiate()
    assert inst.freed is False
    inst.shutdown()
    assert inst.freed is True


def test_the_python_view_of_a_library_is_made_once():
    """The GIL-holding view (ctypes.PyDLL) of a loaded library is cached by its handle: a second function
    from it comes from the same view."""
    import ctypes
    import ctypes.util

    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    f = instance_mod.raw(libc, "abs")
    view = instance_mod._PYDLLS[libc._handle]
    g = instance_mod.raw(libc, "labs")
    assert instance_mod._PYDLLS[libc._handle] is view
    assert f(-3) == 3 and g(-4) == 4 and f.restype is ctypes.c_int


# ---------------------------------------------------------------- state, for the algorithms that roll back
@pytest.mark.parametrize("version, isolated", [("fmi2", False), ("fmi3", False), ("fmi2", True), ("fmi3", True)])
def test_a_saved_state_restores_the_instance_so_a_step_taken_again_gives_the_same_output(tmp_path, version,
                                                                                        isolated):
    """Dahlquist (x' = -k x, x(0) = 1, Euler inside): save at t = 0.1 s, step twice, restore, step once:
    the output is that of the first step after the save, and not that of the second (rolled back)."""
    import ctypes

    from wmr_cosim.cosim.instances.isolation import IsolatedInstance

    model = load_model(REF / version / "Dahlquist.fmu")
    unz = fmpy.extract(str(model.path), str(tmp_path / "unz"))
    if isolated:
        inst = IsolatedInstance("d", model.md, unz, None, "warning", 60.0, 0)
    else:
        inst = (Instance3 if version == "fmi3" else Instance)("d", model.md, unz)
    try:
        assert inst.can_get_and_set_state
        inst.instantiate()
        inst.setup_experiment(0.0, 1.0, None)
        inst.enter_initialization()
        fp = inst.fast_path([], 0, [model.variables["x"].vr], 1)
        inst.exit_initialization()
        T, H, out, vr, n = ctypes.c_double(0.0), ctypes.c_double(0.1), (ctypes.c_double * 1)(), \
            (ctypes.c_uint * 1)(model.variables["x"].vr), ctypes.c_size_t(1)

        def step(t):
            T.value = t
            assert fp.do_step(fp.c, T, H, *fp.step_tail) == 0
            assert fp.get_real(fp.c, vr, n, out, *fp.get_tail) == 0
            return out[0]
        step(0.0)
        saved = inst.get_state()
        first, second = step(0.1), step(0.2)
        inst.set_state(saved)
        again = step(0.1)
        inst.free_state(saved)
        assert again == first != second and first == pytest.approx(0.81)
    finally:
        inst.shutdown()
