"""The wiring (cosim.plan.wiring) without FMUs: the value each Real input receives through its copies as events
override, bias and reset it; the start value an event-driven input holds; the message naming a non-finite
value and where it came from; and the discrete copies of non-Float64 connections against a fake FMU that
reads and writes its buffers as the C side would (as the declared element type, ``n_values`` of them)."""
from __future__ import annotations

import ctypes
from types import SimpleNamespace

import pytest

from wmr_cosim.cosim.instances.in_process import real_array
from wmr_cosim.cosim.model.description import Variable
from wmr_cosim.cosim.scenario.document import ConnectionSpec
from wmr_cosim.cosim.plan.records import ConnectionPlan, EventPlan, InstancePlan
from wmr_cosim.cosim.plan.wiring import RowLayout, Wiring, discrete_copier


def _v(name: str, vr: int, causality: str, fmi_type: str = "Float64", start=None, type_: str | None = None
       ) -> Variable:
    kinds = {"Float64": "Real", "Float32": "Real", "Real": "Real", "Int8": "Integer", "Int16": "Integer",
             "Integer": "Integer", "Boolean": "Boolean", "String": "String"}
    return Variable(name=name, vr=vr, type=type_ or kinds[fmi_type], causality=causality,
                    variability="continuous", unit=None, min=None, max=None, start=start, fmi_type=fmi_type)


def _spec() -> ConnectionSpec:
    return ConnectionSpec("a.y", "b.u")


# --- a small system: a.y (vr 1) -> b.u (vr 5) with factor 2 and offset 0.5; b.w (vr 7) driven by events ----

A_VARS = {"y_alias": _v("y_alias", 1, "local"), "z": _v("z", 3, "output"), "y": _v("y", 1, "output")}
B_VARS = {"u": _v("u", 5, "input"), "w": _v("w", 7, "input", start=2.5), "q": _v("q", 9, "input"),
          "out": _v("out", 11, "output")}


def _event(inst: str, var: Variable, action: str = "override", value=0.0) -> EventPlan:
    return EventPlan(time=1.0, step=1, instance=inst, var=var, action=action, value=value, ref=f"{inst}.{var.name}")


def _system(factor: float = 2.0, offset: float = 0.5, events=(), parameters=()):
    conn = ConnectionPlan("a", A_VARS["y"], "b", B_VARS["u"], factor, offset, _spec())
    instances = {
        "a": InstancePlan("a", None, SimpleNamespace(variables=A_VARS), theirs_to_ours={"y": "speed"}),
        "b": InstancePlan("b", None, SimpleNamespace(variables=B_VARS), theirs_to_ours={"u": "cmd"},
                          parameters=list(parameters)),
    }
    plan = SimpleNamespace(order=["a", "b"], instances=instances, connections=[conn], record=[], watched=[],
                           inputs=[], events=list(events), conditions=[])
    layout = RowLayout.of(plan)
    wiring = Wiring(plan, layout)
    src = layout.out_arr["a"]
    return wiring, src


def _received(copies) -> dict[int, float]:
    """The value each position receives: source * factor + offset."""
    return {pos: arr[i] * f + o for pos, arr, i, f, o in copies}


def test_events_override_bias_and_reset_an_input():
    w, src = _system()
    src[0] = 10.0
    assert _received(w.copies("b")) == {0: 20.5}
    key = ("b", 5, "input")
    assert w.act(*key, "bias", 1.0) is True
    assert _received(w.copies("b")) == {0: 21.5}
    assert w.act(*key, "bias", 2.0) is True            # bias on a bias adds up
    assert _received(w.copies("b")) == {0: 23.5}
    assert w.act(*key, "override", 3.0) is True        # an override after a bias: new copies
    copies = w.copies("b")
    assert _received(copies) == {0: 3.0}
    src[0] = 99.0                                      # the override no longer reads the source
    assert _received(copies) == {0: 3.0}
    # a new override, then a bias on it: written in place, the copies in use see it, nothing to rebuild
    assert w.act(*key, "override", 5.0) is False
    assert _received(copies) == {0: 5.0}
    assert w.act(*key, "bias", 1.5) is False
    assert _received(copies) == {0: 6.5}
    assert _received(w.copies("b")) == {0: 6.5}
    assert w.act(*key, "reset", None) is True
    assert _received(w.copies("b")) == {0: 198.5}
    assert w.act(*key, "reset", None) is False         # nothing in force: nothing changes


def test_a_bias_on_the_output_acts_before_the_connection_transform():
    w, src = _system()
    src[0] = 10.0
    assert w.act("a", 1, "output", "bias", 1.0) is True
    assert _received(w.copies("b")) == {0: 22.5}        # 2 * (10 + 1) + 0.5
    assert w.act("a", 1, "output", "override", 4.0) is True
    assert _received(w.copies("b")) == {0: 4.0}


def test_is_wired_tells_outputs_feeding_connections_from_inputs_the_master_sets():
    w, _ = _system(events=[_event("b", B_VARS["w"])])
    assert w.is_wired("a", 1, "output") and not w.is_wired("a", 3, "output")
    assert w.is_wired("b", 5, "input") and w.is_wired("b", 7, "input") and not w.is_wired("b", 9, "input")
    assert not w.is_wired("b", 5, "output") and not w.is_wired("b", 7, "output")


@pytest.mark.parametrize("start, parameters, held", [
    (2.5, (), 2.5),            # the variable's start value
    (None, (), 0.0),           # no start value: zero
    (2.5, "set", 4.0),         # a parameter of the instance sets it: that value
])
def test_an_input_driven_only_by_events_holds_its_start_until_the_first(start, parameters, held):
    var = _v("w", 7, "input", start=start)
    params = [(_v("other", 8, "parameter"), -1.0), (var, 4.0)] if parameters == "set" else []
    w, _ = _system(events=[_event("b", var, "bias", 1.0)], parameters=params)
    assert _received(w.copies("b")) == {0: 0.5, 1: held}     # position 0: b.u fed by a.y (0)


# --- the non-finite value -------------------------------------------------------------------------------

def test_a_non_finite_value_names_the_output_that_produced_it():
    w, src = _system(factor=2.0, offset=0.0)
    src[0] = 1e308                                       # finite; times 2 it is not
    err = w.bad_input("b", None, w.copies("b"), 1.5)
    assert str(err) == "a.speed produced 1e+308; b.cmd would receive the non-finite value inf at t = 1.5 s"
    assert (err.instance, err.time) == ("a", 1.5)


def test_a_non_finite_value_from_the_offset():
    w, src = _system(factor=1.0, offset=1e308)
    src[0] = 1.7e308
    err = w.bad_input("b", None, w.copies("b"), 0.25)
    assert str(err) == "a.speed produced 1.7e+308; b.cmd would receive the non-finite value inf at t = 0.25 s"


def test_a_non_finite_source_without_a_transform():
    w, src = _system(factor=1.0, offset=0.0)
    src[0] = float("-inf")
    err = w.bad_input("b", None, w.copies("b"), 3.0)
    assert str(err) == "a.speed produced -inf; b.cmd would receive the non-finite value -inf at t = 3 s"
    src[0] = float("nan")
    assert "would receive the non-finite value nan" in str(w.bad_input("b", None, w.copies("b"), 3.0))


def test_a_non_finite_value_not_from_a_connection_names_the_input_only():
    w, src = _system(events=[_event("b", B_VARS["w"], "bias", 1.0)])
    src[0] = 1.0
    w.act("b", 7, "input", "override", float("nan"))
    err = w.bad_input("b", None, w.copies("b"), 2.0)
    assert str(err) == "b.w would receive the non-finite value nan at t = 2 s"
    assert (err.instance, err.time) == ("b", 2.0)


def test_an_input_the_model_does_not_name_is_named_by_its_value_reference():
    w, src = _system()
    src[0] = 1.0
    copies = [(0, real_array([float("inf")]), 0, 1.0, 0.0)]
    w.plan.instances["b"].model = SimpleNamespace(variables={})
    err = w.bad_input("b", None, copies, 2.0)
    assert str(err) == "a.speed produced inf; b input 5 would receive the non-finite value inf at t = 2 s"


def test_finite_values_whose_sum_overflows():
    w, src = _system()
    src[0] = 1.0
    err = w.bad_input("b", None, w.copies("b"), 4.0)
    assert str(err) == "b: the inputs' values overflow (their sum is not finite) at t = 4 s"
    assert (err.instance, err.time) == ("b", 4.0)


# --- discrete copies -------------------------------------------------------------------------------------

CTYPES = {"Float64": ctypes.c_double, "Float32": ctypes.c_float, "Int8": ctypes.c_int8, "Int16": ctypes.c_int16,
          "Integer": ctypes.c_int, "Boolean": ctypes.c_bool, "Boolean2": ctypes.c_int, "String": ctypes.c_char_p}


class FakeFmu:
    """An instance whose get/set act on ``values`` (vr -> list) and read/write the buffers as raw memory of
    the declared element type, ``n_values`` elements, as an FMI 3.0 C function does."""

    def __init__(self, values: dict[int, list], fmi2_boolean: bool = False) -> None:
        self.values = values
        self.fmi2_boolean = fmi2_boolean
        self.calls: list[str] = []

    def accessor(self, fmi_type: str, op: str):
        if fmi_type == "Boolean" and self.fmi2_boolean:
            fmi_type = "Boolean2"
        ctype = CTYPES[fmi_type]

        def call(vrs, n, buf, nv) -> int:
            count = nv.value                              # a None here is a crash in C
            per = count // n.value                        # values per value reference
            size = ctypes.sizeof(ctype) * count
            if op == "Get":
                raw = (ctype * count)(*[x for vr in vrs[:n.value] for x in self.values[vr]])
                ctypes.memmove(buf, raw, size)
            else:
                have = min(size, ctypes.sizeof(buf))
                raw = ctypes.string_at(ctypes.addressof(buf), have) + b"\0" * (size - have)
                got = list((ctype * count).from_buffer_copy(raw))
                for j, vr in enumerate(vrs[:n.value]):
                    self.values[vr] = got[j * per:(j + 1) * per]
            self.calls.append(f"{op}{fmi_type}")
            return 0
        return call, ctype


def _copy(sv: Variable, dv: Variable, src_values: list, factor=1.0, offset=0.0, threshold=0.5,
          fmi2_boolean_src=False):
    a, b = FakeFmu({sv.vr: src_values}, fmi2_boolean=fmi2_boolean_src), FakeFmu({dv.vr: []})
    spec = SimpleNamespace(threshold=threshold)
    c = ConnectionPlan("a", sv, "b", dv, factor, offset, spec)
    copy = discrete_copier({"a": a, "b": b}, c)
    assert copy() == 0
    return b.values[dv.vr], a.calls + b.calls


def _arr(v: Variable, n: int) -> Variable:
    v.shape = (n,)
    return v


def test_float32_to_float32_goes_through_the_factor_and_offset():
    got, calls = _copy(_arr(_v("y", 1, "output", "Float32"), 2), _arr(_v("u", 2, "input", "Float32"), 2),
                       [2.5, -1.0], factor=2.0, offset=0.25)
    assert got == [5.25, -1.75] and calls == ["GetFloat32", "SetFloat32"]


def test_float32_to_float64_and_back():
    got, _ = _copy(_v("y", 1, "output", "Float32"), _v("u", 2, "input", "Float64"), [1.5], factor=3.0)
    assert got == [4.5]
    got, _ = _copy(_v("y", 1, "output", "Float64"), _v("u", 2, "input", "Float32"), [1.5], offset=-1.0)
    assert got == [0.5]


def test_integers_of_other_widths_are_converted_element_by_element():
    got, calls = _copy(_arr(_v("n", 1, "output", "Int8"), 3), _arr(_v("m", 2, "input", "Int16"), 3), [3, -4, 127])
    assert got == [3, -4, 127] and calls == ["GetInt8", "SetInt16"]


def test_integers_of_one_width_are_copied_as_they_are():
    got, calls = _copy(_arr(_v("n", 1, "output", "Int16"), 2), _arr(_v("m", 2, "input", "Int16"), 2), [-300, 7])
    assert got == [-300, 7] and calls == ["GetInt16", "SetInt16"]


@pytest.mark.parametrize("flag, expected", [(1, 1.75), (0, 0.25), (5, 1.75)])
def test_boolean_to_real_is_zero_or_one_through_the_factor(flag, expected):
    got, _ = _copy(_v("b", 1, "output", "Boolean"), _v("u", 2, "input", "Float64"), [flag], factor=1.5,
                   offset=0.25, fmi2_boolean_src=True)
    assert got == [expected]


@pytest.mark.parametrize("x, expected", [(0.5, False), (0.5000001, True), (-3.0, False), (2.0, True)])
def test_real_to_boolean_is_true_above_the_threshold(x, expected):
    got, _ = _copy(_v("y", 1, "output", "Float64"), _v("b", 2, "input", "Boolean"), [x], threshold=0.5)
    assert got == [expected]


@pytest.mark.parametrize("flag, expected", [(1, True), (0, False), (-1, True)])
def test_an_fmi2_boolean_to_an_fmi3_boolean_keeps_any_nonzero_value_true(flag, expected):
    got, _ = _copy(_v("b", 1, "output", "Boolean"), _v("c", 2, "input", "Boolean"), [flag],
                   fmi2_boolean_src=True)
    assert got == [expected]


def test_strings_are_copied():
    got, _ = _copy(_v("s", 1, "output", "String"), _v("t", 2, "input", "String"), [b"hello"])
    assert got == [b"hello"]



# --- the row layout ---------------------------------------------------------------------------------------

def _rec(inst: str, var: Variable, elem: int = 0):
    from wmr_cosim.cosim.plan.records import RecordPlan
    return RecordPlan(inst, var, f"{inst}.{var.name}", elem)


def test_the_row_holds_time_then_each_instances_float64_outputs_then_the_other_reals_then_integers():
    a_y, a_z = _v("y", 1, "output"), _arr(_v("z", 3, "output"), 3)
    a_f = _v("f", 4, "output", "Float32")
    a_n, b_flag = _v("n", 6, "output", "Int16"), _v("flag", 8, "output", "Boolean")
    b_out, b_watch = _v("out", 11, "output"), _v("watch", 12, "output")
    b_in = _v("u", 5, "input")
    conn = ConnectionPlan("a", a_y, "b", b_in, 1.0, 0.0, _spec())
    record = [_rec("b", b_out), _rec("a", a_n), _rec("a", a_z, 2), _rec("a", a_f), _rec("b", b_flag),
              _rec("a", a_y), _rec("a", a_z, 0)]
    cond = SimpleNamespace(reads={"b.watch": ("b", b_watch), "b.u": ("b", b_in)})
    plan = SimpleNamespace(order=["a", "b"], connections=[conn], record=record, conditions=[cond],
                           watched=[("b", b_watch), ("b", b_in)])
    lay = RowLayout.of(plan)
    # a: y (1 value) and z (3 values) at slots 1..4; b: out and watch at 5, 6 (the watched input is not kept)
    assert lay.reals == {"a": [(1, 1), (3, 3)], "b": [(11, 1), (12, 1)]}
    assert lay.offset == {"a": 1, "b": 5} and lay.n_real == 7
    assert [lay.slot(r) for r in record] == [5, 8, 4, 7, 9, 1, 2]    # Float32 after the doubles, then integers
    assert (lay.n_double, lay.n_int) == (8, 2)
    assert lay.index("a", 3, 2) == 3 and lay.index("b", 12) == 1
    with pytest.raises(KeyError):
        lay.index("b", 99)
    # one buffer: the doubles, then the integers; the instances' views are windows on it
    assert ctypes.sizeof(lay.buf) == 8 * 10 and len(lay.row) == 8 and len(lay.irow) == 2
    lay.out_arr["a"][3] = 2.5
    lay.out_arr["b"][0] = -1.0
    assert lay.row[4] == 2.5 and lay.row[5] == -1.0
    lay.write(8, 42)
    lay.write(9, 1)
    lay.write(7, 0.25)
    assert list(lay.irow) == [42, 1] and lay.row[7] == 0.25
    assert ctypes.c_int64.from_buffer(lay.buf, 8 * 8).value == 42


def test_a_row_without_integers_still_has_an_integer_view():
    a_y = _v("y", 1, "output")
    plan = SimpleNamespace(order=["a"], connections=[], record=[_rec("a", a_y)], watched=[])
    lay = RowLayout.of(plan)
    assert (lay.n_real, lay.n_double, lay.n_int) == (2, 2, 0)
    assert ctypes.sizeof(lay.buf) == 16 and len(lay.irow) == 1 and len(lay.out_arr["a"]) == 1


# --- tabulated inputs -------------------------------------------------------------------------------------

def _plan_input(inst: str, var: Variable, values):
    import numpy as np
    from wmr_cosim.cosim.scenario.inputs import InputPlan
    return InputPlan(inst, var, f"{inst}.{var.name}", "hold", np.asarray(values))


def test_tabulated_real_inputs_are_copied_from_the_table_row_of_each_step():
    import numpy as np
    from wmr_cosim.cosim.plan.wiring import table_feeder
    b_u, b_q = B_VARS["u"], B_VARS["q"]
    b_f, b_n, b_s = _v("f", 21, "input", "Float32"), _v("n", 22, "input", "Int16"), _v("s", 23, "input", "String")
    b_k = _v("k", 24, "input", "Int16")
    inputs = [_plan_input("b", b_q, [1.0, 2.0, 3.0]), _plan_input("b", b_f, [0.5, 1.5, 2.5]),
              _plan_input("b", b_n, [7, 8, 9]), _plan_input("b", b_s, np.array(["x", "y", "z"], dtype=object)),
              _plan_input("b", b_k, [-1, -2, -3])]
    conn = ConnectionPlan("a", A_VARS["y"], "b", b_u, 2.0, 0.5, _spec())
    instances = {"a": InstancePlan("a", None, SimpleNamespace(variables=A_VARS)),
                 "b": InstancePlan("b", None, SimpleNamespace(variables=B_VARS))}
    plan = SimpleNamespace(order=["a", "b"], instances=instances, connections=[conn], record=[], watched=[],
                           inputs=inputs, events=[], conditions=[])
    lay = RowLayout.of(plan)
    w = Wiring(plan, lay)
    assert "a" not in w.tables
    fmu = FakeFmu({})
    feed = table_feeder(fmu, w.tables.get("b"), [ip for ip in inputs if ip.var.fmi_type != "Float64"])
    lay.out_arr["a"][0] = 10.0
    assert feed(2) == 0
    assert _received(w.copies("b")) == {0: 20.5, 1: 3.0}            # b.u from a.y; b.q from the table
    assert fmu.values == {21: [2.5], 22: [9], 24: [-3], 23: [b"z"]}
    assert fmu.calls == ["SetFloat32", "SetInt16", "SetString"]     # one call per FMI type, sorted
    assert feed(0) == 0 and fmu.values == {21: [0.5], 22: [7], 24: [-1], 23: [b"x"]}
    assert _received(w.copies("b")) == {0: 20.5, 1: 1.0}


def test_a_feeder_of_reals_only_and_none_without_tabulated_inputs():
    from wmr_cosim.cosim.plan.wiring import table_feeder
    import numpy as np
    arr = (ctypes.c_double * 2)()
    feed = table_feeder(FakeFmu({}), (arr, np.array([[1.0, 2.0], [3.0, 4.0]])), [])
    assert feed(1) == 0 and list(arr) == [3.0, 4.0]
    assert table_feeder(FakeFmu({}), None, []) is None


def test_a_feeder_stops_at_the_first_failing_set():
    from wmr_cosim.cosim.plan.wiring import table_feeder
    fmu = FakeFmu({})
    inputs = [_plan_input("b", _v("f", 21, "input", "Float32"), [0.5]), _plan_input("b", _v("n", 22, "input", "Int16"), [7])]
    calls = []

    def accessor(fmi_type, op):
        def call(vrs, n, buf, nv):
            calls.append(fmi_type)
            return 3 if fmi_type == "Float32" else 0
        return call, CTYPES[fmi_type]
    fmu.accessor = accessor
    import numpy as np
    arr = (ctypes.c_double * 1)()
    feed = table_feeder(fmu, (arr, np.array([[1.0]])), inputs)
    assert feed(0) == 3 and calls == ["Float32"] and list(arr) == [1.0]


def test_a_row_with_one_integer():
    plan = SimpleNamespace(order=["a"], connections=[], record=[_rec("a", _v("n", 6, "output", "Int16"))],
                           watched=[])
    lay = RowLayout.of(plan)
    assert (lay.n_double, lay.n_int) == (1, 1) and ctypes.sizeof(lay.buf) == 16 and len(lay.irow) == 1
    lay.write(1, -7)
    assert ctypes.c_int64.from_buffer(lay.buf, 8).value == -7


def test_array_connections_copy_every_element_or_the_one_named():
    a_z = _arr(_v("z", 3, "output"), 3)
    b_v, b_s = _arr(_v("v", 30, "input"), 3), _v("s", 31, "input")
    conns = [ConnectionPlan("a", a_z, "b", b_v, 1.0, 0.0, _spec()),
             ConnectionPlan("a", a_z, "b", b_s, 10.0, 0.0, _spec(), src_elem=1)]
    instances = {"a": InstancePlan("a", None, SimpleNamespace(variables={"z": a_z})),
                 "b": InstancePlan("b", None, SimpleNamespace(variables={"v": b_v, "s": b_s}))}
    plan = SimpleNamespace(order=["a", "b"], instances=instances, connections=conns, record=[], watched=[],
                           inputs=[], events=[], conditions=[])
    lay = RowLayout.of(plan)
    w = Wiring(plan, lay)
    lay.out_arr["a"][:] = [1.0, 2.0, 3.0]
    assert _received(w.copies("b")) == {0: 1.0, 1: 2.0, 2: 3.0, 3: 20.0}
    assert w.values["b"] == [(30, 0), (30, 1), (30, 2), (31, 0)]
    assert w.vrs == {"a": [], "b": [30, 31]}                   # an array's value reference once
    assert w.is_wired("a", 3, "output") and w.is_wired("b", 30, "input")


def test_only_events_acting_on_an_unconnected_real_input_give_it_a_start_value():
    b_n = _v("n", 40, "input", "Integer")
    events = [EventPlan(time=2.0, step=2, instance=None, var=None, action="stop", value=None, ref=None),
              _event("b", B_VARS["q"], "set", 1.0),              # a set: on the FMU directly
              _event("b", B_VARS["out"], "override", 1.0),       # an output: not an input the master sets
              _event("b", b_n, "override", 1),                  # not Real
              _event("b", B_VARS["u"], "override", 9.0),         # connected: keeps its connection
              _event("b", B_VARS["w"], "bias", 1.0)]
    w, src = _system(events=events[:3])
    w2, src2 = _system(events=events[3:])
    src[0] = src2[0] = 1.0
    assert _received(w.copies("b")) == {0: 2.5} and w.vrs["b"] == [5]
    assert _received(w2.copies("b")) == {0: 2.5, 1: 2.5} and w2.vrs["b"] == [5, 7]
    w3, _ = _system(events=[])
    w3.plan.conditions = [events[5]]
    assert _received(Wiring(w3.plan, RowLayout.of(w3.plan)).copies("b"))[1] == 2.5   # condition events too


def test_apply_puts_an_events_action_in_force():
    w, src = _system()
    src[0] = 10.0
    assert w.apply(_event("b", B_VARS["u"], "override", 3.0)) is True
    assert _received(w.copies("b")) == {0: 3.0}
    assert w.apply(_event("a", A_VARS["y"], "reset", None)) is False
    assert w.apply(_event("b", B_VARS["u"], "reset", None)) is True
    assert _received(w.copies("b")) == {0: 20.5}
