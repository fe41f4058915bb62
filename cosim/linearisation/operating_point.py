"""Linearise a system around a point of its run: what is asked (:class:`Request`), checked against the plan
before anything runs, the run to the point, and the way the model is taken there.

* **Continuous time** when every instance is a Model Exchange FMU or memoryless (a co-simulation FMU that
  declares no state and every output of which depends, by its model structure, on its inputs alone):
  each is linearised at the point (:mod:`.jacobian`; the memoryless ones give D alone) and the blocks are
  closed through the connections (:mod:`.interconnection`).  At the point, every connected input is first
  given the value its connection carries from the outputs at that time (an exchange repeated until the
  values hold, for the algebraic loops), so that x(t) and u(t) are a consistent point of the system.
* **Discrete time** otherwise, or when asked: pulse responses with rollback realised at the communication
  step (:mod:`.realisation`); every instance must be able to save its state.

A break ``src -> dst`` opens one connection: the model is then taken from ``dst`` (the injection) to
``src`` (the return) with that connection cut, and the loop is analysed (:mod:`.loop`); a continuous loop
beside the loop the scenario's algorithm realises at its step (:mod:`.cosimulated`).  The model keeps its
operating point: the states', inputs' and outputs' values at the point.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..messages.errors import CosimError, RunError, ScenarioError
from ..model.description import MODEL_EXCHANGE, Variable
from ..plan.records import ConnectionPlan, InstancePlan, Plan, unit_of
from ..plan.resolution import INPUTS, variable
from ..runtime.execution import Execution
from ..scenario.document import split_ref
from ..stepping import table as algorithms
from .cosimulated import PHASE_BUDGET, CouplingCost, coupling_cost
from .interconnection import Link, close
from .jacobian import Signal, central_column, jacobian, linear_model, states_of
from .loop import LoopAnalysis, analyse
from .model import LinearModel
from .realisation import RELATIVE_PULSE, Injection, max_order, order_note, pulse_responses, realise

#: Sweeps of the exchange of connected values at the point before it is taken as not settling.
EXCHANGE_SWEEPS = 100
#: The default length of the pulse responses [communication steps].
DEFAULT_STEPS = 200


@dataclass
class Request:
    """What to linearise: at ``at`` [s] of the run (None: its start), from ``inputs`` to ``outputs``
    ("instance.variable"); ``breaks`` a connection to cut ("src", "dst"); ``discrete``: a realisation from
    pulse responses even where a continuous model could be taken; ``method`` of the Jacobian ("auto",
    "directional", "differences"); ``steps`` of the responses (None: :data:`DEFAULT_STEPS`) and their
    realised ``order`` (None: from the singular values), ``pulse`` their size relative to the input (None:
    :data:`.realisation.RELATIVE_PULSE`), the three a realisation's only (refused for a continuous model);
    ``states``: state values to set at the point ("instance.state": value, Model Exchange only);
    ``phase_budget`` [deg]: the phase margin the coupling may cost a continuous loop broken at ``breaks``,
    which bounds the largest step reported (None: :data:`.cosimulated.PHASE_BUDGET`; given, it is refused
    where there is no such loop)."""

    at: float | None = None
    inputs: list[str] = field(default_factory=list)
    outputs: list[str] = field(default_factory=list)
    breaks: tuple[str, str] | None = None
    discrete: bool = False
    method: str = "auto"
    steps: int | None = None           # None: DEFAULT_STEPS
    order: int | None = None
    pulse: float | None = None         # None: RELATIVE_PULSE
    states: dict[str, float] = field(default_factory=dict)
    phase_budget: float | None = None   # [deg]; None: PHASE_BUDGET


@dataclass
class Linearisation:
    """The model from the inputs to the outputs; with a break, the loop's analysis and the eigenvalues of
    the system linearised as a whole (closed), to compare with the loop's closed through the break; a
    continuous loop's ``coupling``: the loop as the co-simulation realises it at the step, its margins
    beside the continuous loop's (:mod:`.cosimulated`)."""

    model: LinearModel
    loop: LoopAnalysis | None = None
    whole_eigenvalues: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    coupling: CouplingCost | None = None


class Linearizer:
    """A request checked against a plan (:meth:`check`, before any FMU runs), then taken (:meth:`run`)."""

    def __init__(self, plan: Plan, request: Request) -> None:
        self.plan, self.req = plan, request
        self.file = plan.scenario.file
        start, stop, step = plan.scenario.times()
        self.start, self.stop, self.step = start, stop, step
        self.link: ConnectionPlan | None = None
        self.steps = DEFAULT_STEPS if request.steps is None else request.steps      # of the responses
        self.pulse = RELATIVE_PULSE if request.pulse is None else request.pulse    # relative to the input

    # ------------------------------------------------------------------ the checks
    def check(self) -> None:
        """Every check that needs no run: ScenarioError naming the field."""
        req = self.req
        for name, ip in self.plan.instances.items():   # (a linear model of a sampled system is not one)
            if ip.model.clocks:
                raise ScenarioError(self.file, f"instances.{name}", f"{name} ({ip.model.path.name}) has clocks: "
                                                                    "systems with clocks are not linearised")
        at = self.start if req.at is None else req.at
        if not (isinstance(at, (int, float)) and math.isfinite(at)) or at < self.start or at > self.stop:
            raise ScenarioError(self.file, "--at", f"t = {at} s is outside the run ({self.start:g} s to "
                                                   f"{self.stop:g} s)")
        if math.ceil((at - self.start) / self.step - 1e-9) >= self.plan.n_steps:   # (as Execution.step_to)
            raise ScenarioError(self.file, "--at", f"t = {at:.10g} s: the run ends at its stop time {self.stop:g} s "
                                                   "and frees its FMUs; take a point before its last step")
        for ref in req.inputs:
            inst, var = self._var(ref, "--inputs", INPUTS, "input")
            if var.variability == "discrete" and self.plan.instances[inst].interface == MODEL_EXCHANGE \
                    and not self.discrete():
                raise ScenarioError(self.file, "--inputs", f"{ref} is a discrete input of a Model Exchange FMU, set "
                                                           "at events only: a continuous-time model cannot take it "
                                                           "(--discrete realises one from pulse responses)")
        for ref in req.outputs:
            _, var = self._var(ref, "--outputs", None, "output")
            if var.causality != "output" and not self.discrete():
                raise ScenarioError(self.file, "--outputs", f"{ref} is {var.causality}: a continuous-time model's "
                                                            "outputs are the FMUs' outputs (--discrete reads any "
                                                            "variable)")
        if req.breaks is not None:
            src, dst = req.breaks
            self.link = next((c for c in self.plan.connections if self._ref(c.src, c.src_var) == src
                              and self._ref(c.dst, c.dst_var) == dst), None)
            if self.link is None:
                raise ScenarioError(self.file, "--break", f"no connection {src} -> {dst} in the system"
                                    + self._connections_hint())
        if isinstance(self.steps, bool) or not isinstance(self.steps, int) or self.steps < 2:
            raise ScenarioError(self.file, "--steps", f"{self.steps}: the responses need a whole number of at "
                                                      "least 2 steps")
        if not (self.pulse > 0 and math.isfinite(self.pulse)):
            raise ScenarioError(self.file, "--pulse", f"{self.pulse}: a positive size")
        if req.phase_budget is not None:
            self._check_budget(req.phase_budget)
        if self.discrete():
            if not req.inputs and req.breaks is None:
                raise ScenarioError(self.file, "--inputs", "a model from pulse responses needs the inputs to "
                                                           "inject them at (or a --break)")
            if req.method != "auto":
                raise ScenarioError(self.file, "--method", f"{req.method}: the method of a Jacobian, which a model "
                                                           "realised from pulse responses does not take")
            self._check_order()
            self._check_rollback()
        else:
            given = [(o, v) for o, v in (("--steps", req.steps), ("--order", req.order), ("--pulse", req.pulse))
                     if v is not None]
            if given:
                raise ScenarioError(self.file, given[0][0], f"{given[0][1]}: a realisation from pulse responses "
                                                            "takes it; this model is continuous-time, of the FMUs' "
                                                            "own states (--discrete realises one)")
            self._check_method()
        for ref in req.states:
            self._state_index(ref)

    def _check_budget(self, budget: Any) -> None:
        """A phase budget: a positive, finite angle, for a loop whose coupling's cost is derived."""
        if isinstance(budget, bool) or not isinstance(budget, (int, float)) or not math.isfinite(budget) \
                or budget <= 0:
            raise ScenarioError(self.file, "--phase-budget", f"{budget}: a positive, finite number of degrees")
        why = "no loop is broken (--break)" if self.req.breaks is None else \
            "the model is realised from pulse responses (an instance neither Model Exchange nor memoryless, or " \
            "--discrete)" if self.discrete() else self._coupling_unsupported()
        if why:
            raise ScenarioError(self.file, "--phase-budget", f"the coupling's cost is derived for a continuous "
                                                             f"loop under Gauss-Seidel or Jacobi at one rate; here {why}")

    def _coupling_unsupported(self) -> str | None:
        """Why the loop the co-simulation realises cannot be derived for this plan (None: it can): it is for
        one pass per step at one rate (Gauss-Seidel, Jacobi)."""
        rates = [n for n, ip in self.plan.instances.items() if ip.decimation > 1]
        if rates:
            return f"{', '.join(rates)} step at their own rates"
        name = self.plan.scenario.algorithm
        return None if algorithms.row(name).one_pass else f"the algorithm is {name}"

    def _check_order(self) -> None:
        """An order asked for: positive, and at most what the responses can realise."""
        order = self.req.order
        if order is None:
            return
        if isinstance(order, bool) or not isinstance(order, int) or order < 1:
            raise ScenarioError(self.file, "--order", f"{order}: a realisation's order is a positive whole number")
        p = len(set(self.req.outputs) | ({self.req.breaks[0]} if self.req.breaks else set()))
        m = len(set(self.req.inputs) | ({self.req.breaks[1]} if self.req.breaks else set()))
        if self.req.breaks is None:
            most = max_order(self.steps, p, m)
        else:   # (the loop's model, of one injection and one return, is realised at the order too)
            most = min(max_order(self.steps, p, m), max_order(self.steps, 1, 1))
        if order > most:
            raise ScenarioError(self.file, "--order", f"{order} is more than responses of {self.steps} steps "
                                                      f"can realise (at most {most}): take more --steps")

    def _check_method(self) -> None:
        """--method directional: every Model Exchange instance declares directional derivatives."""
        if self.req.method != "directional":
            return
        for name, ip in self.plan.instances.items():
            if ip.interface == MODEL_EXCHANGE and not getattr(ip.model.md.modelExchange,
                                                              "providesDirectionalDerivative", False):
                raise ScenarioError(self.file, "--method", f"directional: {name} ({ip.model.path.name}) declares no "
                                                           "directional derivatives (providesDirectionalDerivative): "
                                                           "take --method differences or auto")

    def _state_index(self, ref: str) -> int:
        """The place of a continuous state ("instance.state") in its instance's state vector, or ScenarioError."""
        inst, _ = split_ref(self.file, "--state", ref)
        if inst not in self.plan.instances or self.plan.instances[inst].interface != MODEL_EXCHANGE:
            raise ScenarioError(self.file, "--state", f"{ref}: states are set on Model Exchange instances only")
        names = [s.name for s in states_of(self.plan.instances[inst].model.md, inst, lambda n: "")[0]]
        if ref not in names:
            raise ScenarioError(self.file, "--state", f"{ref} is no continuous state of {inst} (its states: "
                                                      f"{', '.join(names) or 'none'})")
        return names.index(ref)

    def _connections_hint(self) -> str:
        names = [f"{self._ref(c.src, c.src_var)} -> {self._ref(c.dst, c.dst_var)}" for c in self.plan.connections]
        return f" (its connections: {', '.join(names)})" if names else " (it has no connections)"

    def _ref(self, inst: str, var: Variable) -> str:
        return f"{inst}.{self.plan.instances[inst].our_name(var)}"

    def _var(self, ref: str, fld: str, fits: Any, kind: str) -> tuple[str, Variable]:
        inst, name = split_ref(self.file, fld, ref)
        if inst not in self.plan.instances:
            raise ScenarioError(self.file, fld, f"{ref}: unknown instance {inst!r}")
        var = variable(self.file, fld, self.plan.instances[inst], name, fits)
        if not var.is_float64 or var.shape:
            raise ScenarioError(self.file, fld, f"{ref} is not a scalar real: only those are linearised")
        if kind == "input" and var.causality != "input":
            raise ScenarioError(self.file, fld, f"{ref} is {var.causality}, not an input")
        return inst, var

    def discrete(self) -> bool:
        """Whether the model is realised from pulse responses (asked, or an instance neither Model
        Exchange nor memoryless)."""
        return self.req.discrete or any(not self._continuous(n) for n in self.plan.instances)

    def _continuous(self, name: str) -> bool:
        ip = self.plan.instances[name]
        return ip.interface == MODEL_EXCHANGE or memoryless(ip.model.md)

    def _check_rollback(self) -> None:
        for name, ip in self.plan.instances.items():
            if not ip.model.declares_state(ip.interface):
                raise ScenarioError(self.file, f"instances.{name}",
                                    f"{name} ({ip.model.path.name}) cannot save and restore its state "
                                    "(canGetAndSetFMUstate): a model from pulse responses goes back to the "
                                    "point for each of them")
        if self.plan.conditions:
            raise ScenarioError(self.file, "events", "condition events: the responses go back to the point, "
                                                     "which such events do not follow")
        at = self.start if self.req.at is None else float(self.req.at)
        end = at + self.steps * self.step
        for ev in self.plan.events:
            if ev.time is not None and at <= ev.time < end:
                raise ScenarioError(self.file, "--at", f"an event acts at t = {ev.time:g} s, within the "
                                    f"{self.steps} steps of the responses from {at:g} s: choose a point "
                                    "whose responses it does not cross")
        if end > self.stop - 1e-9 * max(1.0, abs(self.stop)):   # (the run ends at its stop time: no going back)
            raise ScenarioError(self.file, "--steps", f"{self.steps} steps from t = {at:g} s reach "
                                                      f"the run's stop time {self.stop:g} s, where the run ends: "
                                                      "take fewer steps or an earlier --at")

    # ------------------------------------------------------------------ the run
    def run(self) -> Linearisation:
        """The run to the point, the model taken there (the FMUs freed after)."""
        self.check()
        plan = dataclasses.replace(self.plan, requirements=[])
        ex = Execution(plan, None)
        try:
            ex.initialize()
            at = self.start if self.req.at is None else float(self.req.at)
            ex.step_to(at)
            if ex.ended:
                why = ex.result.message if ex.result is not None and ex.result.message else ""
                raise RunError(f"the run ended at t = {ex.time:g} s, before the point t = {at:g} s"
                               + (f": {why}" if why else ""))
            return self._discrete(ex) if self.discrete() else self._continuous_model(ex)
        finally:
            ex.close()

    def _discrete(self, ex: Execution) -> Linearisation:
        req, t = self.req, ex.time
        link = self.link
        injections, units_in = [], []
        refs = list(req.inputs) + ([self._ref(link.dst, link.dst_var)] if link is not None and
                                   self._ref(link.dst, link.dst_var) not in req.inputs else [])
        for ref in refs:
            inst, var = self._var(ref, "--inputs", INPUTS, "input")
            u = float(ex.get(ref))
            scale = max(abs(u), _nominal(self.plan.instances[inst].model.md, var))
            delta = self.pulse * scale
            if not all(math.isfinite(x) for x in (u + delta, u - delta, 2.0 * delta)):
                raise ScenarioError(self.file, "--pulse", f"{self.pulse:g} times {scale:g} at {ref} (u = {u:g} at "
                                                          f"t = {t:g} s) is beyond the range of floating point numbers")
            wired = any(self._ref(c.dst, c.dst_var) == ref for c in self.plan.connections) or \
                any(self._ref(ip.instance, ip.var) == ref for ip in self.plan.inputs)
            injections.append(Injection(ref, (u + delta) - u, wired))
            units_in.append(_unit(self.plan.instances[inst], var))
        outputs = list(req.outputs)
        if link is not None and self._ref(link.src, link.src_var) not in outputs:
            outputs.append(self._ref(link.src, link.src_var))
        units_out = [_unit(self.plan.instances[r.split(".", 1)[0]], self._var(r, "--outputs", None, "output")[1])
                     for r in outputs]
        cut = self._ref(link.dst, link.dst_var) if link is not None else None
        point_u = [float(ex.get(ref)) for ref in refs]
        point_y = [float(ex.get(ref)) for ref in outputs]
        H = pulse_responses(ex, injections, outputs, self.steps, cut)
        model = realise(H, self.step, refs, outputs, order=req.order, t=t, input_units=units_in,
                        output_units=units_out)
        model.u, model.y = np.array(point_u), np.array(point_y)   # (x: the realisation's coordinates, nan)
        out = Linearisation(model)
        if req.order is not None and model.singular_values is not None:
            note = order_note(model.singular_values, req.order)
            out.notes += [note] if note else []
        if link is not None:
            j, i = refs.index(self._ref(link.dst, link.dst_var)), outputs.index(self._ref(link.src, link.src_var))
            gain = realise(H[i:i + 1, j:j + 1, :] * link.factor, self.step, [refs[j]], [outputs[i]],
                           order=req.order, t=t)
            if not gain.states:   # (L = 0: no margins, and nothing to call the closed loop stable)
                raise ScenarioError(self.file, "--break", f"the return {outputs[i]} does not respond to the injection "
                                                          f"at {refs[j]} over {self.steps} steps from t = {t:g} s "
                                                          "(every Hankel singular value 0): no loop to analyse there")
            if req.order is not None and gain.singular_values is not None and len(refs) + len(outputs) > 2:
                note = order_note(gain.singular_values, req.order)
                out.notes += [f"the loop's model: {note}"] if note else []
            out.loop = analyse(gain, outputs[i], refs[j])
            # the system as a whole: the same point of injection, the loop closed, realised at the loop's order
            closed = pulse_responses(ex, [injections[j]], [outputs[i]], self.steps)
            out.whole_eigenvalues = realise(closed, self.step, [refs[j]], [outputs[i]], order=len(gain.states),
                                            t=t).eigenvalues()
        return out

    def _continuous_model(self, ex: Execution) -> Linearisation:
        req = self.req
        for ref, value in req.states.items():
            self._set_state(ex, ref, value)
        self._exchange(ex)
        reals = [c for c in self.plan.connections if c.is_float64]
        links = [Link(self._ref(c.src, c.src_var), self._ref(c.dst, c.dst_var), c.factor) for c in reals]
        wanted_in = set(req.inputs) | {lk.dst for lk in links}
        wanted_out = set(req.outputs) | {lk.src for lk in links}
        blocks = [self._block(ex, name, wanted_in, wanted_out) for name in self.plan.order]
        asked = bool(req.inputs or req.outputs)
        link = self.link
        whole = close(blocks, links, [], []) if link is not None or not asked else None
        model = close(blocks, links, req.inputs, req.outputs) if asked else whole
        assert model is not None
        self._point(ex, model)
        out = Linearisation(model)
        out.notes += [f"{self._ref(c.src, c.src_var)} -> {self._ref(c.dst, c.dst_var)} ({c.src_var.fmi_type} to "
                      f"{c.dst_var.fmi_type}) is not a real-to-real connection: held as it is at the point, not "
                      "linearised" for c in self.plan.connections if c not in reals]
        if link is not None:
            assert whole is not None
            src, dst = self._ref(link.src, link.src_var), self._ref(link.dst, link.dst_var)
            opened = close(blocks, links, [dst], [src], broken=[Link(src, dst, link.factor)])
            self._point(ex, opened)
            if not asked:
                out.model = opened
            out.loop = analyse(dataclasses.replace(opened, C=opened.C * link.factor, D=opened.D * link.factor), src, dst)
            out.whole_eigenvalues = whole.eigenvalues()
            out.coupling = self._coupling(out, blocks, links, Link(src, dst, link.factor))
        return out

    def _block(self, ex: Execution, name: str, wanted_in: set[str], wanted_out: set[str]) -> LinearModel:
        ip, inst = self.plan.instances[name], ex.instances[name]
        ins = [v for v in ip.model.variables.values() if v.causality == "input" and self._ref(name, v) in wanted_in]
        outs = [v for v in ip.model.variables.values() if v.causality == "output" and self._ref(name, v) in wanted_out]
        md = ip.model.md
        sig_in = [Signal(self._ref(name, v), v.vr, _unit(ip, v), _nominal(md, v)) for v in ins]
        sig_out = [Signal(self._ref(name, v), v.vr, _unit(ip, v), _nominal(md, v)) for v in outs]
        if ip.interface == MODEL_EXCHANGE:
            states, ders = states_of(ip.model.md, name, lambda n: _unit(ip, ip.model.variables.get(n)))
            J, how = jacobian(inst, states, ders, sig_in, sig_out, self.req.method)
            self._finite(J, name, [s.name for s in states], [u.name for u in sig_in], [y.name for y in sig_out],
                         ex.time)
            return linear_model(J, states, sig_in, sig_out, ex.time, f"{name}: {how}")
        D = _memoryless_gain(inst, md, ins, outs)
        self._finite(D, name, [], [u.name for u in sig_in], [y.name for y in sig_out], ex.time)
        return linear_model(D, [], sig_in, sig_out, ex.time, f"{name}: central differences (memoryless)")

    def _coupling(self, out: Linearisation, blocks: list[LinearModel], links: list[Link],
                  cut: Link) -> CouplingCost | None:
        """The continuous loop against the loop the scenario's algorithm realises at its step (one pass per
        step at one rate: Gauss-Seidel, Jacobi); else None and a note saying why."""
        why = self._coupling_unsupported()
        if why:
            out.notes.append(f"the co-simulated loop is derived for one pass per step at one rate (Gauss-Seidel, "
                             f"Jacobi); here {why}: its margins are not given")
            return None
        assert out.loop is not None
        name = self.plan.scenario.algorithm
        budget = PHASE_BUDGET if self.req.phase_budget is None else self.req.phase_budget
        return coupling_cost(out.loop, blocks, links, cut, self.plan.order, name, algorithms.row(name).simultaneous,
                             self.step, budget)

    def _point(self, ex: Execution, model: LinearModel) -> None:
        """The operating point of a continuous-time ``model`` of the system: its states' values (the Model
        Exchange instances' continuous states), its inputs' and outputs' values now."""
        x: dict[str, float] = {}
        for name in self.plan.order:
            ip = self.plan.instances[name]
            if ip.interface == MODEL_EXCHANGE:
                states = states_of(ip.model.md, name, lambda n: "")[0]
                values = ex.instances[name].continuous_states()   # type: ignore[attr-defined]
                x.update(zip((st.name for st in states), map(float, values)))

        def value(ref: str, fld: str) -> float:
            inst, var = self._var(ref, fld, INPUTS if fld == "--inputs" else None, fld[2:-1])
            return _get(ex.instances[inst], var, self.plan.instances[inst].interface == MODEL_EXCHANGE)
        model.x = np.array([x.get(n, math.nan) for n in model.states])
        model.u = np.array([value(r, "--inputs") for r in model.inputs])
        model.y = np.array([value(r, "--outputs") for r in model.outputs])

    def _finite(self, J: np.ndarray, name: str, states: list[str], inputs: list[str], outputs: list[str],
                t: float) -> None:
        """RunError naming the entries of a block's [[A, B], [C, D]] that are not finite (and the states set
        by --state, where they are the cause)."""
        bad = np.argwhere(~np.isfinite(J))
        if not bad.size:
            return
        rows = [f"der({x})" for x in states] + outputs
        cols = states + inputs
        shown = ", ".join(f"d {rows[i]}/d {cols[j]} = {J[i, j]}" for i, j in bad[:3])
        more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
        given = [f"{r}={v:g}" for r, v in self.req.states.items() if r.split(".", 1)[0] == name]
        at = f" with --state {', '.join(given)}" if given else ""
        raise RunError(f"{name}: its linearisation at t = {t:g} s{at} is not finite: {shown}{more}", name, t)

    def _set_state(self, ex: Execution, ref: str, value: float) -> None:
        inst = ex.instances[ref.split(".", 1)[0]]
        x = list(inst.continuous_states())   # type: ignore[attr-defined]
        x[self._state_index(ref)] = float(value)
        inst.set_continuous_states(x)   # type: ignore[attr-defined]

    def _exchange(self, ex: Execution) -> None:
        """Every connected Real input set to what its connection carries at the point, until they hold."""
        conns = [c for c in self.plan.connections if c.is_float64]
        for _ in range(EXCHANGE_SWEEPS):
            changed = False
            for c in conns:
                me_src, me_dst = (self.plan.instances[n].interface == MODEL_EXCHANGE for n in (c.src, c.dst))
                value = c.factor * _get(ex.instances[c.src], c.src_var, me_src) + c.offset
                if _get(ex.instances[c.dst], c.dst_var, me_dst) != value:
                    _set(ex.instances[c.dst], c.dst_var, value, me_dst)
                    changed = True
            if not changed:
                return
        raise CosimError(f"the connected values at t = {ex.time:g} s do not settle after {EXCHANGE_SWEEPS} "
                         "exchanges (an algebraic loop without a fixed point)")


def memoryless(md: Any) -> bool:
    """A co-simulation FMU that declares no continuous state, no discrete variable, and every output of
    which depends on inputs alone by its model structure (declared dependencies)."""
    if md.derivatives or any(v.variability == "discrete" and v.causality in ("local", "output")
                             for v in md.modelVariables):
        return False
    return bool(md.outputs) and all(u.dependencies is not None and all(d.causality == "input" for d in u.dependencies)
                                    for u in md.outputs)


def _memoryless_gain(inst: Any, md: Any, ins: list[Variable], outs: list[Variable]) -> np.ndarray:
    """D of a memoryless co-simulation FMU by central differences of its outputs after setting its inputs."""
    def put(v: Variable) -> Callable[[float], None]:
        return lambda value: inst.set_values([(v, value)])

    D = np.zeros((len(outs), len(ins)))
    for j, v in enumerate(ins):
        D[:, j] = central_column(put(v), float(inst.get_value(v)), _nominal(md, v),
                                 lambda: [float(inst.get_value(y)) for y in outs])
    return D


def _get(inst: Any, var: Variable, me: bool) -> float:
    """A Real's value now (a Model Exchange instance: without leaving continuous-time mode)."""
    return float(inst.get_reals([var.vr])[0]) if me else float(inst.get_value(var))


def _set(inst: Any, var: Variable, value: float, me: bool) -> None:
    """Set a Real input (a Model Exchange instance: a continuous input, without an event)."""
    if me:
        inst.set_continuous_inputs([var.vr], [value])
    else:
        inst.set_values([(var, value)])


def _unit(ip: InstancePlan, var: Variable | None) -> str:
    """A variable's unit as the scenario declares it, else as its FMU does ("" where none)."""
    unit = unit_of(ip, var) if var is not None else None
    return unit.name if unit is not None else ""


def _nominal(md: Any, var: Variable) -> float:
    """The variable's declared nominal value (1 where none is declared)."""
    for v in md.modelVariables:
        if v.name == var.name:
            try:
                nominal = float(v.nominal) if v.nominal is not None else 1.0
            except (TypeError, ValueError):
                return 1.0
            return abs(nominal) if math.isfinite(nominal) and nominal != 0 else 1.0
    return 1.0
