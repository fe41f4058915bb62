"""The clocks of an FMI 3.0 FMU, read from its model description (FMPy reads neither a clock's interval
nor its priority), and the variables each clocks.

A clock's kind is its causality and ``intervalVariability``: an input clock is periodic (``constant``,
``fixed`` or ``tunable``, with ``intervalDecimal`` [s] and ``shiftDecimal`` [s] where declared),
``countdown`` (its next tick said by the FMU) or ``triggered`` (ticked by the importer); an output clock
is raised by the FMU.  Input clocks are activated in the order of their ``priority`` (0 first, FMI 3.0
2.2.8.4)."""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from xml.etree import ElementTree

#: The interval variabilities of a periodic clock (its ticks at shift + k interval).
PERIODIC = ("constant", "fixed", "tunable")


@dataclass(frozen=True)
class Clock:
    """One clock of an FMI 3.0 FMU: ``interval`` and ``shift`` [s] as declared (None: not declared),
    ``priority`` (input clocks; lower first), ``clocked``: the names of the variables it clocks."""

    name: str
    vr: int
    causality: str                  # "input" | "output"
    variability: str                # intervalVariability: constant, fixed, tunable, changing, countdown, triggered
    interval: str | None = None     # intervalDecimal as written [s]
    shift: str | None = None        # shiftDecimal as written [s]
    priority: int | None = None
    clocked: tuple[str, ...] = field(default=())

    @property
    def periodic(self) -> bool:
        return self.causality == "input" and self.variability in PERIODIC

    @property
    def kind(self) -> str:
        """The clock's kind in words (``check``)."""
        if self.causality == "output":
            return "output clock, raised by the FMU"
        if self.periodic:
            return f"periodic input clock ({self.variability})"
        return f"{self.variability} input clock"

    def grid(self, step: float) -> tuple[int, int] | None:
        """A periodic clock on the master's grid of ``step`` [s]: (its first tick, its interval) in whole
        steps, or None where its interval is not declared, not positive, or either is off the grid."""
        if self.interval is None or float(self.interval) <= 0:
            return None
        n0, k = grid_multiple(self.shift or "0", step), grid_multiple(self.interval, step)
        return None if n0 is None or not k else (n0, k)

    def describe(self) -> str:
        """One line: name, kind, interval, priority, the variables it clocks."""
        parts = [f"clock {self.name}: {self.kind}"]
        if self.interval is not None:
            parts.append(f"interval {self.interval} s" + (f", shift {self.shift} s" if self.shift else ""))
        if self.priority is not None:
            parts.append(f"priority {self.priority}")
        parts.append("clocks " + (", ".join(self.clocked) if self.clocked else "no variable"))
        return "; ".join(parts)


def read_clocks(path: Path) -> list[Clock]:
    """The clocks an FMI 3.0 FMU declares (none for FMI 2.0), in the order of the model description."""
    with zipfile.ZipFile(path) as zf:
        return clocks_of(zf.read("modelDescription.xml"))


def clocks_of(xml: bytes) -> list[Clock]:
    """The clocks a model description (its bytes, read safely by :func:`.description.fmi_version` first)
    declares."""
    root = ElementTree.fromstring(xml)
    mv = root.find("ModelVariables")
    if mv is None or not str(root.get("fmiVersion", "")).startswith("3"):
        return []
    by_vr: dict[int, list[str]] = {}
    for v in mv:
        for ref in (v.get("clocks") or "").split():
            by_vr.setdefault(int(ref), []).append(str(v.get("name")))
    out = []
    for v in mv:
        if v.tag != "Clock":
            continue
        vr = int(str(v.get("valueReference")))
        prio = v.get("priority")
        out.append(Clock(str(v.get("name")), vr, str(v.get("causality", "local")),
                         str(v.get("intervalVariability", "")), v.get("intervalDecimal"), v.get("shiftDecimal"),
                         int(prio) if prio is not None else None, tuple(by_vr.get(vr, ()))))
    return out


def grid_multiple(value: float | str | Fraction, step: float) -> int | None:
    """``value`` [s] as a whole number of master steps ``step`` [s] (exactly, in decimal: 0.002 is 2 steps
    of 0.001), else None."""
    q = Fraction(str(value)) / Fraction(str(step))
    return int(q) if q.denominator == 1 else None
