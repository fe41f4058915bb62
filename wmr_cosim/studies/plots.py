"""The figures of a sweep: each chosen metric against each swept parameter."""
from __future__ import annotations

from pathlib import Path

from .sweep_file import SweepSpec


def plot_sweep(df, spec: SweepSpec, out: Path, units: dict[str, str | None] | None = None) -> list[Path]:
    """Each chosen metric against each swept parameter (failed points marked); ``units``: the sweep file's
    metrics' units (the robot's are known here)."""
    units = units or {}
    from matplotlib.figure import Figure   # (no pyplot: the process's backend is left as it is)

    out.mkdir(parents=True, exist_ok=True)
    params = []
    for key in list(spec.grid) + list(spec.random):
        params.append(key.split("+")[0])
    metrics = spec.metrics or [m.name for m in spec.measures][:2] or \
        [c for c in ("foam.rmse_e1", "learn.rmse_e1", "gamma_star") if c in df.columns][:2]
    files = []
    for m in metrics:
        if m not in df.columns:
            continue
        for p in params:
            fig = Figure(figsize=(5.5, 3.8))
            ax = fig.subplots()
            ok = df["status"] == "ok"
            ax.plot(df.loc[ok, p], df.loc[ok, m], "o", ms=4, label="ok")
            if (~ok).any():
                ax.plot(df.loc[~ok, p], df.loc[~ok, m].fillna(0.0), "x", color="C3", label="failed / diverged")
            ax.set_xlabel(f"{p} [{_unit(p)}]")
            ax.set_ylabel(f"{m} [{units.get(m) or _unit(m)}]")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
            fig.tight_layout()
            f = out / f"{m}_vs_{p}.png".replace("/", "_")
            fig.savefig(f, dpi=100)
            files.append(f)
    return files


_UNITS = {"rmse_e": "rad", "rmse_edot": "rad/s", "final_x": "m", "final_y": "m", "t_goal": "s", "goal_distance": "m",
          "gamma": "-", "gain": "-", "foam_rise": "N.m", "foam_da": "N.m", "foam_t_on": "s", "l1": "m", "r": "m",
          "a5": "N.m", "a6": "N.m", "goal_": "m", "W": "-"}


def _unit(name: str) -> str:
    last = name.rsplit(".", 1)[-1]
    for k, u in _UNITS.items():
        if last.startswith(k):
            return u
    return "-"
