"""A live run: the thread that steps the run (the caller's) and what the server's threads ask of it.

The run is stepped here, in chunks of communication steps that each take about :data:`FRAME_S` of wall
time (the master's loop runs uninterrupted inside a chunk, so a live run as fast as possible is as fast as
a plain one); between chunks, at a communication point, the commands the server queued are carried out
(pause, resume, step, stop, rate, set), the state is updated and the row of that point is handed to the
stream: so rows reach the clients decimated to about 1 / FRAME_S per second of wall time.

A value set is given to the master as a timed event at the communication point where the command is
carried out (:meth:`wmr_cosim.cosim.Execution.give`), exactly what a timed ``[[events]]`` entry at that
time does; the events given are what :func:`replay_document` writes into the scenario of ``replay.toml``.
Pauses, steps and pacing change when steps are taken, never what they compute.
"""
from __future__ import annotations

import concurrent.futures
import math
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

from ..cosim import CosimError, Execution, RunStatus, ScenarioError
from .scene import goal_refs, xy_of

#: The wall time [s] of one chunk of steps: the state and the stream are updated this often (20 per second).
FRAME_S = 0.05

#: The wall time [s] over which the achieved real-time factor is measured.
RATE_WINDOW_S = 1.0


class Refused(Exception):
    """A command the run refuses (a value that cannot be set, a run that has ended): its one-line reason
    and the HTTP status it is answered with (400 bad input, 409 the run has ended)."""

    def __init__(self, reason: str, status: int = 400) -> None:
        super().__init__(reason)
        self.reason, self.status = reason, status


@dataclass
class Command:
    """One request of a client: ``kind`` (pause, resume, step, stop, rate, set) and its arguments; its
    answer (the state after it, or Refused) comes through ``reply``."""

    kind: str
    args: dict[str, Any] = field(default_factory=dict)
    reply: concurrent.futures.Future[dict[str, Any]] = field(default_factory=concurrent.futures.Future)


def _finite(x: float) -> float | None:
    """A float JSON can carry (None for NaN and the infinities)."""
    return x if math.isfinite(x) else None


class LiveSession:
    """The live run of one :class:`~wmr_cosim.cosim.Execution` (initialised): :meth:`drive` steps it in the
    calling thread; :meth:`submit`, :meth:`state` and :meth:`subscribe` are what the server's threads call.

    ``paused``: the run starts paused; ``factor``: the real-time factor it is paced at (None: as fast as
    possible)."""

    def __init__(self, ex: Execution, paused: bool = False, factor: float | None = None) -> None:
        self.ex = ex
        self.paused, self.factor = paused, factor
        self.commands: queue.Queue[Command] = queue.Queue()
        self.given: list[dict[str, Any]] = []     # the events given, as [[events]] entries (replay.toml)
        self._lock = threading.Lock()
        self._sinks: list[Callable[[dict[str, Any] | None], None]] = []
        self._steps_left = 0                       # steps a step command still asks for
        self._stepping: Command | None = None      # that command, answered when they are done
        self._per_step = 0.0                       # [s] of wall time a step took in the last chunk
        self._published = -1                       # the step whose row was streamed last
        self._last_row: list[float | None] | None = None   # ... and that row
        self._rate: deque[tuple[float, float]] = deque()   # (wall [s], time [s]) at the chunks' ends
        plan = ex.plan
        columns = plan.columns()
        self.variables = [{"name": c, "unit": columns.get(c, {}).get("unit")} for c in ex.columns]
        self.settable = _settable(plan)
        self.xy = xy_of(plan)                      # [live] xy and the task's goals (None: no path drawn)
        self._goal_refs = goal_refs(plan) if self.xy is not None else []
        self._goals: list[list[float]] = []
        self._read_goals()
        self._events_sent = len(ex.events)        # the event table's entries streamed so far
        self._verdicts: list[dict[str, Any]] = []  # the requirements' verdicts as last streamed
        self._state: dict[str, Any] = {}
        self._ended = False
        if factor is not None:
            ex.pace(factor)
        self._update_state()

    # ------------------------------------------------------------------ the server's side (any thread)
    def state(self) -> dict[str, Any]:
        """The state as last updated (at the last communication point the run stopped at)."""
        with self._lock:
            return dict(self._state)

    def submit(self, kind: str, **args: Any) -> concurrent.futures.Future[dict[str, Any]]:
        """Queue a command for the next communication point; its future gives the state after it (or raises
        :class:`Refused`)."""
        cmd = Command(kind, args)
        with self._lock:
            if self._ended:
                cmd.reply.set_exception(Refused(self._ended_reason(), 409))
                return cmd.reply
            self.commands.put(cmd)
        return cmd.reply

    def subscribe(self, sink: Callable[[dict[str, Any] | None], None]) -> Callable[[], None]:
        """Call ``sink(message)`` (from the stepping thread: it must not block) with each row, and
        ``sink(None)`` when the run has ended; the function returned ends the subscription."""
        with self._lock:
            if self._ended:
                sink(None)
                return lambda: None
            self._sinks.append(sink)

        def unsubscribe() -> None:
            with self._lock:
                if sink in self._sinks:
                    self._sinks.remove(sink)
        return unsubscribe

    def header(self) -> dict[str, Any]:
        """The stream's first message: the columns of the rows and their units, the event table so far, the
        row of the communication point last streamed (None before the first)."""
        return {"type": "columns", "columns": [v["name"] for v in self.variables],
                "units": [v["unit"] for v in self.variables], "events": self.ex.events, "row": self._last_row}

    # ------------------------------------------------------------------ the stepping thread
    def drive(self) -> None:
        """Step the run to its end, carrying out the commands between chunks of steps; the run ends (its
        result set) on return, also on a Ctrl-C (status interrupted) or a failure (status failed)."""
        ex = self.ex
        try:
            self._publish()   # (the row of the start: what the stream's header gives a client of a paused run)
            while not ex.ended:
                self._handle(block=self.paused and not self._steps_left)
                if ex.ended:
                    break
                if self._steps_left:
                    n = min(self._steps_left, self._chunk())
                    self._advance(n)
                    self._steps_left -= n
                    if not self._steps_left or ex.ended:
                        self._steps_done()
                elif not self.paused:
                    self._advance(self._chunk())
                self._publish()
        except (CosimError, KeyboardInterrupt) as exc:
            if not ex.ended:   # (a Ctrl-C while paused: inside a step the execution has ended the run)
                if isinstance(exc, KeyboardInterrupt):
                    ex.stop(f"interrupted by the user at t = {ex.time:.6g} s", RunStatus.INTERRUPTED)
                else:
                    raise
        finally:
            if not ex.ended:
                ex.close()
            self._end()

    def _advance(self, n: int) -> None:
        """``n`` steps; the wall time of a step measured for the next chunk."""
        wall0 = time.perf_counter()
        k0 = self.ex.k_done
        try:
            self.ex.step(n)
        except CosimError:
            pass   # the run has ended: its status and message say how
        done = self.ex.k_done - k0
        if done:
            self._per_step = (time.perf_counter() - wall0) / done

    def _chunk(self) -> int:
        """The steps of the next chunk: about FRAME_S of wall time at the last chunk's pace (one step at
        first; at most four times the last chunk), up to the stop time."""
        left = self.ex.clock.n_steps - self.ex.k_done
        if self._per_step <= 0.0:
            return 1
        return max(1, min(left, int(FRAME_S / self._per_step) or 1))

    def _handle(self, block: bool) -> None:
        """Carry out the commands queued (waiting for one while ``block``, so that a paused run answers at
        once and a Ctrl-C still reaches it)."""
        while True:
            try:
                cmd = self.commands.get(timeout=0.1) if block else self.commands.get_nowait()
            except queue.Empty:
                if block and not self.ex.ended:
                    continue
                return
            try:
                self._carry_out(cmd)
            except Refused as exc:
                cmd.reply.set_exception(exc)
            else:
                if cmd is not self._stepping and not cmd.reply.done():
                    self._update_state()
                    cmd.reply.set_result(self.state())
            if self.ex.ended:
                return
            block = self.paused and not self._steps_left

    def _carry_out(self, cmd: Command) -> None:
        ex, a = self.ex, cmd.args
        if cmd.kind == "pause":
            self.paused = True
            self._cancel_steps()
        elif cmd.kind == "resume":
            self._cancel_steps()
            self.paused = False
            if self.factor is not None:
                ex.pace(self.factor)   # (the wall clock starts again: a pause does not make the run late)
        elif cmd.kind == "step":
            self._cancel_steps()
            self.paused = True
            self._steps_left = min(int(a["steps"]), ex.clock.n_steps - ex.k_done)
            self._stepping = cmd
            if not self._steps_left:
                self._steps_done()
        elif cmd.kind == "stop":
            self._cancel_steps()
            ex.stop(f"stopped from the live view at t = {ex.time:.6g} s")
        elif cmd.kind == "rate":
            f = float(a["factor"])
            self.factor = None if f == 0 else f
            ex.pace(self.factor)
            self._per_step = 0.0
        elif cmd.kind == "set":
            self._set(str(a["variable"]), a["value"])
        else:
            raise Refused(f"unknown command {cmd.kind!r}")
        if cmd.kind != "set":
            self._rate.clear()   # (the factor achieved is measured again from here)

    def _set(self, ref: str, value: Any) -> None:
        """Give ``ref`` the value at this communication point, as a timed event (checked as one)."""
        try:
            ev = self.ex.give(ref, value, "live")
        except ScenarioError as exc:
            raise Refused(f"{ref}: {exc.reason}" if not exc.reason.startswith(ref) else exc.reason) from None
        except CosimError as exc:
            raise Refused(str(exc), 409) from None
        self.given.append({"time": ev.time, "variable": ref, "action": ev.action, "value": ev.value})

    def _cancel_steps(self) -> None:
        """A step command still going is answered (with the steps done) and ends."""
        self._steps_left = 0
        self._steps_done()

    def _steps_done(self) -> None:
        cmd, self._stepping = self._stepping, None
        if cmd is not None:
            self._update_state()
            cmd.reply.set_result(self.state())

    def _publish(self) -> None:
        """The state updated and the row of this communication point handed to every subscriber."""
        events = self.ex.events
        new = events[self._events_sent:]
        if new and self._goal_refs:   # (an event may have moved a goal)
            self._read_goals()
        self._update_state()
        k = self.ex.k_done
        if k == self._published:
            return
        self._published = k
        msg: dict[str, Any] = {"type": "row", "row": [_finite(x) for x in self.ex.last_row()]}   # (also after the end)
        self._last_row = msg["row"]
        if new:   # the event table's new entries, as they happen
            msg["events"] = new
            self._events_sent = len(events)
        verdicts = self._state.get("requirements") or []
        if verdicts != self._verdicts:        # the requirements' verdicts, where they changed
            msg["requirements"] = verdicts
            self._verdicts = verdicts
        with self._lock:
            sinks = list(self._sinks)
        for sink in sinks:
            sink(msg)

    def _update_state(self) -> None:
        ex = self.ex
        now = time.perf_counter()
        if not self.paused or self._steps_left:
            self._rate.append((now, ex.time))
            while len(self._rate) > 2 and now - self._rate[1][0] >= RATE_WINDOW_S:
                self._rate.popleft()
        achieved = None
        if len(self._rate) >= 2 and self._rate[-1][0] > self._rate[0][0]:
            achieved = (self._rate[-1][1] - self._rate[0][1]) / (self._rate[-1][0] - self._rate[0][0])
        r = ex.result
        state = {"time": ex.time, "stop_time": ex.clock.time(ex.clock.n_steps), "step": ex.clock.step,
                 "steps": ex.k_done, "n_steps": ex.clock.n_steps, "paused": self.paused,
                 "rate": self.factor or 0.0, "real_time_factor": achieved,
                 "status": "running" if r is None else str(r.status), "message": "" if r is None else r.message,
                 "events": [e for e in ex.events if e.get("source") == "live"],
                 "requirements": ex.verdicts(), "mode": "live",
                 "variables": self.variables, "settable": self.settable,
                 "xy": None if self.xy is None else {**self.xy, "goals": self._goals}}
        with self._lock:
            self._state = state

    def _read_goals(self) -> None:
        """The task's goals [m] as the run has them now (an event setting one moves it: read again between
        chunks when the event table has grown, never while the run steps)."""
        goals = []
        for gx, gy in self._goal_refs:
            try:
                goals.append([float(self.ex.get(gx)), float(self.ex.get(gy))])
            except (CosimError, TypeError, ValueError):
                return   # (the run has ended: the goals as last read)
        self._goals = goals

    def _ended_reason(self) -> str:
        r = self.ex.result
        return f"the run has ended ({r.status}: {r.message or 'at its stop time'})" if r is not None \
            else "the run has ended"

    def _end(self) -> None:
        """The run has ended: the last state, every command still queued refused, the stream closed."""
        self._update_state()
        with self._lock:
            self._ended = True
            sinks, self._sinks = self._sinks, []
        reason = self._ended_reason()
        if self._stepping is not None:
            self._stepping.reply.set_result(self.state())
            self._stepping = None
        while True:
            try:
                cmd = self.commands.get_nowait()
            except queue.Empty:
                break
            cmd.reply.set_exception(Refused(reason, 409))
        for sink in sinks:
            sink(None)


def _settable(plan: Any) -> list[dict[str, Any]]:
    """The variables a client may set: every scalar tunable parameter and input, with its type, unit, start,
    min and max (as the model description declares them)."""
    out = []
    for name, ip in plan.instances.items():
        for var in ip.model.variables.values():
            if var.shape or not (var.causality == "input" or (var.causality == "parameter"
                                                                and var.variability == "tunable")):
                continue
            start = var.start
            unit = var.unit
            out.append({"name": f"{name}.{ip.our_name(var)}", "causality": var.causality, "type": var.type,
                        "unit": getattr(unit, "name", unit), "start": start if isinstance(start, (int, float, str, bool)) else None,
                        "min": var.min, "max": var.max})
    return out
