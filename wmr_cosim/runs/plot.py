"""``wmr-cosim plot``: recorded signals of a results folder (what ``run`` writes: signals.npy,
summary.json, scenario.json) drawn against time [s], one subplot per unit (each y label carries its
unit), the event log's actions as vertical lines; with requirements named, each one's robustness over
time (requirements.npy) in a subplot below the signals its formula names, zero and its first violation
marked, the values that violate it shaded red, those that satisfy an ``eventually`` green.

Units come from summary.json's ``columns`` (else scenario.json's, written before the first step, so a
run still going or killed is drawn too); the events from summary.json's ``events`` (each with a
``time`` [s]; its ``kind`` and ``source``, where given, name it in the legend).
"""
from __future__ import annotations

import fnmatch
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..cosim import close_names

#: How many recorded columns are drawn when no variable is named.
DEFAULT_COUNT = 4
#: How many recorded names an error message lists before "...".
LISTED = 8
#: The figure's width [in] and the height of one subplot [in]; its resolution [dots per inch].
WIDTH_IN, AXIS_IN, DPI = 9.0, 2.4, 100


class PlotError(ValueError):
    """Bad input to ``plot`` (a folder, a variable, an output file); the message is one line."""


@dataclass
class Results:
    """A results folder read for drawing: the recording, each column's unit (None: not known) and the
    event log."""

    folder: Path
    signals: np.ndarray
    units: dict[str, str | None] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)
    requirements: dict[str, dict[str, Any]] = field(default_factory=dict)   # summary.json's, by name
    robustness: np.ndarray | None = None   # requirements.npy: time and each requirement's robustness
    note: str | None = None   # signals.npy cut short: how many of the rows its header gives were read

    @property
    def columns(self) -> list[str]:
        """The recorded columns, time first, in the order of summary.json's ``columns``."""
        names = list(self.signals.dtype.names or ())
        return [n for n in self.units if n in names] + [n for n in names if n not in self.units]


@dataclass
class Plotted:
    """What :func:`plot_results` drew: the file, the variables (in drawing order) and the figure."""

    path: Path
    variables: list[str]
    figure: Any
    note: str | None = None   # said on stderr (--show without a display)


def read_results(folder: str | Path) -> Results:
    """The recording, units and events of a results folder; PlotError (one line naming the folder or the
    file) when it does not exist, has no signals.npy, or a file of it cannot be read
    (:func:`.cosim.read_signals`: a recording cut short is read up to its last whole row, and a note
    says so)."""
    from ..cosim import ResultsError, read_json, read_signals

    folder = Path(folder)
    if not folder.is_dir():
        raise PlotError(f"{folder}: {'not a folder' if folder.exists() else 'no such folder'}")
    npy = folder / "signals.npy"
    if not npy.is_file():
        raise PlotError(f"{folder}: no signals.npy (not a results folder of `wmr-cosim run`)")
    shapes: dict[str, type | tuple[type, ...]] = {"columns": dict, "events": list, "requirements": list}
    try:
        recording = read_signals(npy)
        summary = read_json(folder / "summary.json", shapes)
        columns = summary.get("columns") or read_json(folder / "scenario.json", shapes).get("columns") or {}
        robustness = None
        if (folder / "requirements.npy").is_file():
            robustness = read_signals(folder / "requirements.npy").signals
    except ResultsError as exc:
        raise PlotError(str(exc)) from None
    units = {n: (c.get("unit") if isinstance(c, dict) else None) for n, c in columns.items()}
    events = [e for e in summary.get("events") or [] if isinstance(e, dict) and _number(e.get("time"))]
    reqs = {r["name"]: r for r in summary.get("requirements") or [] if isinstance(r, dict) and "name" in r}
    return Results(folder, recording.signals, units, events, reqs, robustness, recording.note)


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def choose(res: Results, variables: list[str] | None) -> list[str]:
    """The columns to draw: ``variables`` (names, or patterns such as ``controller.W*`` where no name
    matches exactly), or by default the first :data:`DEFAULT_COUNT` recorded columns after time.
    PlotError naming a variable that was not recorded, the recorded ones (shortened) and a close name."""
    recorded = [c for c in res.columns if c != "time"]
    if not variables:
        if not recorded:
            raise PlotError(f"{res.folder}: only time was recorded: nothing to draw")
        return recorded[:DEFAULT_COUNT]
    chosen: list[str] = []
    for v in variables:
        found = [v] if v in recorded else fnmatch.filter(recorded, v) if any(ch in v for ch in "*?[") else []
        if not found:
            best = close_names(v, recorded)
            listed = ", ".join(recorded[:LISTED]) + (f", ... ({len(recorded)} in all)" if len(recorded) > LISTED else "")
            raise PlotError(f"{res.folder}: {v!r} was not recorded"
                            + (f" (did you mean {best[0]!r}?)" if best else "") + f"; recorded: {listed}")
        chosen += [f for f in found if f not in chosen]
    return chosen


def requirement_names(res: Results, names: list[str]) -> list[str]:
    """The requirements to draw, checked against the folder's (PlotError naming the known ones)."""
    if res.robustness is None or not res.requirements:
        raise PlotError(f"{res.folder}: no requirements.npy (the run's scenario declared no [[requirements]])")
    for n in names:
        if n not in res.requirements or n not in (res.robustness.dtype.names or ()):
            best = close_names(n, list(res.requirements))
            raise PlotError(f"{res.folder}: no requirement {n!r}" + (f" (did you mean {best[0]!r}?)" if best else "")
                            + f"; the run's: {', '.join(res.requirements)}")
    return names


def by_unit(res: Results, variables: list[str]) -> list[tuple[str | None, list[str]]]:
    """The variables grouped by unit, in the order each unit first appears: one subplot each."""
    groups: dict[str | None, list[str]] = {}
    for v in variables:
        groups.setdefault(res.units.get(v), []).append(v)
    return list(groups.items())


def event_label(event: dict[str, Any]) -> str:
    """The legend's name of an event: its ``kind`` and ``source`` where given, else its action."""
    kind, source = event.get("kind"), event.get("source")
    if kind or source:
        return " ".join(str(p) for p in (kind, f"({source})" if kind and source else source) if p)
    return f"event: {event['action']}" if event.get("action") else "event"


def draw(res: Results, variables: list[str], fig: Any = None, requirements: list[str] | None = None) -> Any:
    """The figure (a matplotlib Figure; ``fig``: one to draw into): one subplot per unit, sharing the time
    axis (``time [s]``), each y label with its unit; then one subplot per requirement named, its robustness
    over time; every event inside the recorded time as a vertical line, named once in the legend of the
    first subplot."""
    from matplotlib.figure import Figure

    groups = by_unit(res, variables)
    reqs = requirements or []
    if fig is None:
        fig = Figure(figsize=(WIDTH_IN, 1.0 + AXIS_IN * (len(groups) + len(reqs))), dpi=DPI)
    axes = fig.subplots(len(groups) + len(reqs), 1, sharex=True, squeeze=False)[:, 0]
    for ax, name in zip(axes[len(groups):], reqs):
        _draw_robustness(res, name, ax)
    axes[-1].set_xlabel("time [s]")
    axes = axes[:len(groups)] if groups else axes
    t = np.asarray(res.signals["time"], dtype=float)
    for ax, (unit, names) in zip(axes, groups):
        for n in names:
            y = np.asarray(res.signals[n])
            ax.plot(t, y.astype(float), lw=1.0, label=n,
                    drawstyle="default" if y.dtype.kind == "f" else "steps-post")
        what = names[0] if len(names) == 1 else ""
        ax.set_ylabel(f"{what} [{unit}]".strip() if unit else f"{what} (no unit)".strip())
        ax.grid(True, alpha=0.3)
    _mark_events(res, axes, t)
    for ax in axes:
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(str(res.folder), fontsize=9)
    fig.tight_layout()
    return fig


def _draw_robustness(res: Results, name: str, ax: Any) -> None:
    """One requirement's robustness over time (NaN where a window the run cut leaves it unknown), zero,
    what decides its verdict shaded (:func:`_shade`), its first violation and the time its robustness
    refers to marked (red when negative, else green)."""
    assert res.robustness is not None
    v = res.requirements[name]
    t, r = np.asarray(res.robustness["time"], dtype=float), np.asarray(res.robustness[name], dtype=float)
    ax.plot(t, r, lw=1.0, color="k", label=f"robustness of {name!r} ({v.get('verdict')})")
    ax.axhline(0.0, color="C2", lw=0.8)
    window = v.get("window")
    if isinstance(window, list) and len(window) == 2 and _number(window[0]):   # the times not judged, greyed
        end = window[1] if _number(window[1]) else t[-1]
        if window[0] > t[0]:
            ax.axvspan(t[0], window[0], color="0.85", lw=0, label="not judged")
        if end < t[-1]:
            ax.axvspan(end, t[-1], color="0.85", lw=0, label="_nolegend_" if window[0] > t[0] else "not judged")
    _shade(ax, t, r, v)
    if _number(v.get("first_violation")):
        ax.axvline(v["first_violation"], color="C3", lw=1.0, label=f"first violation, t = {v['first_violation']:.6g} s")
    if _number(v.get("at")) and _number(v.get("robustness")):
        ax.plot([v["at"]], [v["robustness"]], "o", color=VIOLATING if v["robustness"] < 0 else SATISFYING, ms=4, label=f"{v['robustness']:.4g} at t = {v['at']:.6g} s")
    unit = v.get("unit")
    ax.set_ylabel(f"{name} [{unit}]" if unit else name)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")


#: The colours of the values that violate a requirement and of those that satisfy an ``eventually``.
VIOLATING, SATISFYING = "C3", "C2"


def _shade(ax: Any, t: np.ndarray, r: np.ndarray, v: dict[str, Any]) -> None:
    """Shade what decides the verdict, inside the window judged: for an ``always`` (or a formula without a
    temporal operator) every negative value, red: each one violates it; for an ``eventually`` the values
    >= 0, green: each one satisfies it, and red the window's values only when it is violated (none was
    >= 0; a negative value alone violates nothing); for another formula its value at the start, red
    when negative."""
    from ..cosim import FormulaError, formula_fold

    try:
        fold = formula_fold(str(v.get("formula", "")))
    except FormulaError:   # (a summary.json not written by this version: shade as for an always)
        fold = "min"
    window = v.get("window")
    lo = float(window[0]) if isinstance(window, list) and len(window) == 2 and _number(window[0]) else t[0]
    hi = float(window[1]) if isinstance(window, list) and len(window) == 2 and _number(window[1]) else t[-1]
    eps = 1e-9 * max(1.0, abs(t[-1]))
    inside = np.isfinite(r) & (t >= lo - eps) & (t <= hi + eps)
    if fold == "max":
        ax.fill_between(t, 0.0, np.maximum(r, 0.0), where=inside & (r >= 0), color=SATISFYING, alpha=0.3, lw=0,
                        label="satisfies it")
        if v.get("verdict") != "violated":
            return
    ax.fill_between(t, np.minimum(r, 0.0), 0.0, where=inside & (r < 0), color=VIOLATING, alpha=0.3, lw=0,
                    label="violates it")


def _mark_events(res: Results, axes: Any, t: np.ndarray) -> None:
    """The events inside the recorded time as dashed vertical lines on every subplot: one colour and one
    legend entry (on the first subplot) per label, the lines of a label drawn as one collection (a model
    exchange FMU may log thousands of events)."""
    times: dict[str, list[float]] = {}
    for e in res.events:
        if t[0] <= e["time"] <= t[-1]:
            times.setdefault(event_label(e), []).append(float(e["time"]))
    for k, (label, at) in enumerate(times.items()):
        for i, ax in enumerate(axes):
            ax.vlines(at, 0, 1, transform=ax.get_xaxis_transform(), colors=f"C{(k + 3) % 10}", linestyles="--",
                      lw=0.8, label=label if i == 0 else "_nolegend_")


def has_display() -> bool:
    """Whether a window can open: on Linux and other Unix, an X11 or Wayland display is set."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def plot_results(folder: str | Path, variables: list[str] | None = None, out: str | Path | None = None,
                 show: bool = False, requirements: list[str] | None = None) -> Plotted:
    """Draw ``variables`` of the results folder (default: :func:`choose`'s, or with ``requirements`` the
    variables their formulas name) against time [s], then each requirement's robustness, and write the
    figure to ``out`` (default FOLDER/plot.png; the format from its suffix); ``show`` also opens a window
    where there is a display (none: the file only, and a note).  PlotError (one line) for bad input."""
    res = read_results(folder)
    reqs = requirement_names(res, requirements) if requirements else []
    if reqs and not variables:
        named = [n for r in reqs for n in res.requirements[r].get("variables", [])]
        variables = [n for i, n in enumerate(named) if n not in named[:i]]
    chosen = choose(res, variables) if variables or not reqs else []
    if not len(res.signals):
        raise PlotError(f"{res.folder}: signals.npy has no rows: nothing to draw")
    path = Path(out) if out is not None else res.folder / "plot.png"
    window = show and has_display()
    plt = _pyplot() if window else None
    n_axes = len(by_unit(res, chosen)) + len(reqs)
    fig = draw(res, chosen, plt.figure(figsize=(WIDTH_IN, 1.0 + AXIS_IN * n_axes), dpi=DPI) if plt is not None
               else None, reqs)
    _save(fig, path)
    if plt is not None:
        plt.show()
        plt.close(fig)
    notes = [res.note, "no display: --show opens no window; the figure is only written" if show and not window
             else None]
    note = "; ".join(n for n in notes if n) or None
    return Plotted(path, chosen + [f"robustness of {r}" for r in reqs], fig, note)


def _pyplot() -> Any:
    """matplotlib.pyplot with its own choice of backend (an interactive one where a toolkit is installed)."""
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: Path) -> None:
    """Write the figure; PlotError naming the file for a format matplotlib does not write or a folder
    that cannot be written."""
    fmt = path.suffix.lstrip(".").lower()
    supported = fig.canvas.get_supported_filetypes()
    if fmt not in supported:
        raise PlotError(f"--out {path}: the file name must end in one of "
                        f"{', '.join('.' + s for s in sorted(supported))}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, format=fmt)
    except OSError as exc:
        raise PlotError(f"--out {path}: cannot write there ({exc.strerror or exc})") from None
