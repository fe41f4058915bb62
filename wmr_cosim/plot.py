"""``wmr-cosim plot``: recorded signals of a results folder (what ``run`` writes: signals.npy,
summary.json, scenario.json) drawn against time [s], one subplot per unit (each y label carries its
unit), the event log's actions as vertical lines.

Units come from summary.json's ``columns`` (else scenario.json's, written before the first step, so a
run still going or killed is drawn too); the events from summary.json's ``events`` (each with a
``time`` [s]; its ``kind`` and ``source``, where given, name it in the legend).
"""
from __future__ import annotations

import fnmatch
import json
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .cosim import close_names

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
    """The recording, units and events of a results folder; PlotError (one line naming the folder) when
    it does not exist, has no signals.npy, or a file of it cannot be read."""
    folder = Path(folder)
    if not folder.is_dir():
        raise PlotError(f"{folder}: {'not a folder' if folder.exists() else 'no such folder'}")
    npy = folder / "signals.npy"
    if not npy.is_file():
        raise PlotError(f"{folder}: no signals.npy (not a results folder of `wmr-cosim run`)")
    try:
        signals = np.load(npy)
    except (OSError, ValueError) as exc:
        raise PlotError(f"{npy}: cannot be read ({' '.join(str(exc).split())})") from None
    if signals.dtype.names is None or "time" not in signals.dtype.names:
        raise PlotError(f"{npy}: not a recording (no time column)")
    summary = _json(folder / "summary.json")
    columns = summary.get("columns") or _json(folder / "scenario.json").get("columns") or {}
    units = {n: (c.get("unit") if isinstance(c, dict) else None) for n, c in columns.items()}
    events = [e for e in summary.get("events") or [] if isinstance(e, dict) and _number(e.get("time"))]
    return Results(folder, signals, units, events)


def _json(path: Path) -> dict[str, Any]:
    """A JSON file of the folder ({} when absent); PlotError when it cannot be read."""
    if not path.is_file():
        return {}
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise PlotError(f"{path}: cannot be read ({' '.join(str(exc).split())})") from None
    return doc if isinstance(doc, dict) else {}


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


def draw(res: Results, variables: list[str], fig: Any = None) -> Any:
    """The figure (a matplotlib Figure; ``fig``: one to draw into): one subplot per unit, sharing the time
    axis (``time [s]``), each y label with its unit; every event inside the recorded time as a vertical
    line, named once in the legend of the first subplot."""
    from matplotlib.figure import Figure

    groups = by_unit(res, variables)
    if fig is None:
        fig = Figure(figsize=(WIDTH_IN, 1.0 + AXIS_IN * len(groups)), dpi=DPI)
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
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
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(str(res.folder), fontsize=9)
    fig.tight_layout()
    return fig


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
                 show: bool = False) -> Plotted:
    """Draw ``variables`` of the results folder (default: :func:`choose`'s) against time [s] and write the
    figure to ``out`` (default FOLDER/plot.png; the format from its suffix); ``show`` also opens a window
    where there is a display (none: the file only, and a note).  PlotError (one line) for bad input."""
    res = read_results(folder)
    chosen = choose(res, variables)
    if not len(res.signals):
        raise PlotError(f"{res.folder}: signals.npy has no rows: nothing to draw")
    path = Path(out) if out is not None else res.folder / "plot.png"
    window = show and has_display()
    plt = _pyplot() if window else None
    fig = draw(res, chosen, plt.figure(figsize=(WIDTH_IN, 1.0 + AXIS_IN * len(by_unit(res, chosen))), dpi=DPI)
               if plt is not None else None)
    _save(fig, path)
    if plt is not None:
        plt.show()
        plt.close(fig)
    note = "no display: --show opens no window; the figure is only written" if show and not window else None
    return Plotted(path, chosen, fig, note)


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
