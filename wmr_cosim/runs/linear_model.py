"""``wmr-cosim linearize``: a linear model of an FMU or of a scenario's system around a point of its run,
its eigenvalues and, with a break, the loop's margins, printed and written to a folder (linear.npz,
linear.mat, linear.json, bode.png and nyquist.png).  The master's linearisation does the work
(``cosim.linearisation``); this module loads what is named, words the result and writes the files.

    from wmr_cosim.runs.linear_model import linearize
    lin = linearize("g1_learn.toml", at=20.0, breaks=("controller.u1", "plant.u1"))
    lin.model.statespace()            # python-control StateSpace
    lin.loop.gain_margin, lin.loop.phase_margin
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..cosim import MODEL_EXCHANGE, Linearisation, Linearizer, Request, ScenarioError, load_model
from .loop_plot import plot_loop

#: linear.json: the model's figures beside the matrices' files.
SUMMARY_FILE = "linear.json"


def linearize(target: str | Path, *, at: float | None = None, inputs: Sequence[str] = (),
              outputs: Sequence[str] = (), breaks: tuple[str, str] | None = None, discrete: bool = False,
              method: str = "auto", steps: int | None = None, order: int | None = None, pulse: float | None = None,
              states: dict[str, float] | None = None, overrides: dict[str, Any] | None = None,
              limits: Any = None, phase_budget: float | None = None) -> Linearisation:
    """Linearise ``target`` (a scenario file of one run, a shipped scenario's name, or an FMU run alone)
    around t = ``at`` [s] of its run (see :class:`wmr_cosim.cosim.linearisation.Request` for the rest).
    An FMU alone runs as Model Exchange where it has that interface (unless ``discrete``), from every Real
    input to every Real output unless they are named.  ScenarioError for bad input; RunError when the run
    to the point fails."""
    from ..runner import fmu_plan, is_fmu, load_plan
    from ..scenario_files import scenario_path

    import control  # noqa: F401  (python-control: where it is missing, refused before the run, not after it)

    path = scenario_path(str(target))
    req = Request(at=at, inputs=list(inputs), outputs=list(outputs), breaks=breaks, discrete=discrete,
                  method=method, steps=steps, order=order, pulse=pulse, states=dict(states or {}),
                  phase_budget=phase_budget)
    if is_fmu(path):
        model = load_model(path)
        fields = {"interface": MODEL_EXCHANGE} if model.has_me and not discrete else {}
        plan = fmu_plan(path, overrides, limits=limits, fields=fields)
        name = plan.order[0]
        ip = plan.instances[name]
        if not req.inputs and breaks is None:   # (a Model Exchange FMU's discrete inputs change at events only)
            continuous = ip.interface == MODEL_EXCHANGE
            req.inputs = [f"{name}.{ip.our_name(v)}" for v in ip.model.variables.values()
                          if _real(v, "input") and not (continuous and v.variability == "discrete")]
        if not req.outputs:
            req.outputs = [f"{name}.{ip.our_name(v)}" for v in ip.model.variables.values() if _real(v, "output")]
    else:
        plan = load_plan(path, overrides, limits=limits)
        if plan.scenario.runs:
            raise ScenarioError(str(path), "runs", "a protocol (several runs): linearise the scenario of one run")
    return Linearizer(plan, req).run()


def _real(v: Any, causality: str) -> bool:
    return v.causality == causality and v.fmi_type in ("Real", "Float64") and not v.shape


def summary(lin: Linearisation) -> dict[str, Any]:
    """linear.json: the model's signals, eigenvalues, method, time and operating point (x, u, y with their
    names and units); the loop's margins at every crossover and the open-loop poles on or outside the
    stability boundary."""
    m = lin.model
    out: dict[str, Any] = {"time": m.t, "dt": m.dt, "continuous": m.continuous, "method": m.method,
                           "states": m.states, "inputs": m.inputs, "outputs": m.outputs,
                           "state_units": m.state_units, "input_units": m.input_units, "output_units": m.output_units,
                           "eigenvalues": _complex(m.eigenvalues()), "operating_point": m.operating_point()}
    if m.singular_values is not None:
        out["hankel_singular_values"] = [float(s) for s in m.singular_values]
    if lin.loop is not None:
        out["loop"] = lin.loop.summary()
        out["loop"]["closed_eigenvalues"] = _complex(lin.loop.closed_eigenvalues)
        out["loop"]["order"] = len(lin.loop.gain.states)
    if lin.whole_eigenvalues is not None:
        out["whole_eigenvalues"] = _complex(lin.whole_eigenvalues)
    if lin.coupling is not None:
        out["coupling"] = lin.coupling.summary()
    out["notes"] = list(lin.notes)
    return out


def _complex(values: np.ndarray) -> list[list[float]]:
    """Eigenvalues as [real, imaginary] pairs, sorted by real part then imaginary part."""
    return [[float(v.real), float(v.imag)] for v in sorted(np.asarray(values, dtype=complex),
                                                          key=lambda z: (z.real, z.imag))]


def write(lin: Linearisation, out: str | Path) -> list[Path]:
    """The folder ``out``: linear.npz, linear.mat, linear.json; with a break, bode.png and nyquist.png."""
    out = Path(out)
    files = list(lin.model.save(out))
    (out / SUMMARY_FILE).write_text(json.dumps(summary(lin), indent=2) + "\n")
    files.append(out / SUMMARY_FILE)
    if lin.loop is not None:
        files += plot_loop(lin.loop, out)
    return files


def report(lin: Linearisation) -> list[str]:
    """What the command prints: the model, its eigenvalues, the singular values of a realisation, the loop."""
    m = lin.model
    kind = "continuous time" if m.continuous else f"discrete time, dt = {m.dt:g} s"
    lines = [f"linear model at t = {m.t:g} s ({kind}; {m.method}): {len(m.states)} states, "
             f"{len(m.inputs)} inputs, {len(m.outputs)} outputs",
             "  inputs:  " + (", ".join(_named(m.inputs, m.input_units)) or "none"),
             "  outputs: " + (", ".join(_named(m.outputs, m.output_units)) or "none")]
    if m.singular_values is not None:
        sv = m.singular_values
        shown = ", ".join(f"{s:.3g}" for s in sv[:max(len(m.states) + 3, 6)])
        lines.append(f"  Hankel singular values: {shown}{' ...' if len(sv) > len(m.states) + 3 else ''} "
                     f"(order {len(m.states)})")
    lines.append("  eigenvalues: " + (", ".join(_z(z) for z in sorted(m.eigenvalues(), key=lambda z: (z.real, z.imag)))
                                      or "none"))
    lines += [f"  note: {n}" for n in lin.notes]
    if lin.loop is not None:
        lines += _loop_lines(lin.loop)
    if lin.coupling is not None:
        lines += _coupling_lines(lin.coupling)
    return lines


def _coupling_lines(c: Any) -> list[str]:
    """The continuous loop's margins beside the co-simulated loop's, the cost, the largest step."""
    s = c.summary()
    a, b = s["continuous"], s["cosimulated"]
    lines = [f"the loop as {c.algorithm} realises it at the step {c.step:g} s (the blocks held over each step), "
             "beside the continuous loop:",
             f"  phase margin: continuous {_num(a['phase_margin_deg'])} deg at {_num(a['gain_crossover_rad_s'])} rad/s, "
             f"co-simulated {_num(b['phase_margin_deg'])} deg at {_num(b['gain_crossover_rad_s'])} rad/s: the "
             f"coupling costs {_num(s['phase_cost_deg'])} deg",
             f"  upper gain margin: continuous {_num(a['upper_gain_margin'])}, co-simulated "
             f"{_num(b['upper_gain_margin'])}; lower: continuous {_num(a['lower_gain_margin'])}, co-simulated "
             f"{_num(b['lower_gain_margin'])}; co-simulated closed loop "
             f"{'stable' if b['closed_loop_stable'] else 'UNSTABLE'}"]
    if isinstance(s["largest_step_s"], float) and s["largest_step_s"] > 0:
        lines.append(f"  the largest step that keeps the cost within {c.budget:g} deg: {_num(s['largest_step_s'])} s "
                     f"(bounded by {s['largest_step_limit']})")
    else:
        lines.append(f"  the largest step within {c.budget:g} deg: none ({s['largest_step_limit']})")
    return lines


def _loop_lines(loop: Any) -> list[str]:
    """The loop's printout: every crossover, the upper and lower gain margins, the poles on or outside the
    stability boundary (a warning), the closed loop."""
    s = loop.summary()
    lines = [f"loop broken at {s['break']} (L = -G, G from the injection to the return):"]
    lines.append(f"  gain margin {_num(s['gain_margin'])} ({_num(s['gain_margin_db'])} dB) at "
                 f"{_num(s['phase_crossover_rad_s'])} rad/s; phase margin {_num(s['phase_margin_deg'])} deg at "
                 f"{_num(s['gain_crossover_rad_s'])} rad/s; stability margin {_num(s['stability_margin'])}")
    crossings = [f"{_num(c['gain_margin'])} ({_num(c['gain_margin_db'])} dB, {c['kind']}) at {_num(c['rad_s'])} rad/s"
                 for c in s["phase_crossovers"]]
    lines.append("  every phase crossover (gain margin): " + ("; ".join(crossings) or "none"))
    pms = [f"{_num(c['phase_margin_deg'])} deg at {_num(c['rad_s'])} rad/s" for c in s["gain_crossovers"]]
    lines.append("  every gain crossover (phase margin): " + ("; ".join(pms) or "none"))
    lines.append(f"  upper gain margin {_num(s['upper_gain_margin'])}, lower gain margin {_num(s['lower_gain_margin'])} "
                 "(the factors the loop gain may rise to and fall to before a crossover reaches -1)")
    if s["open_loop_poles_on_or_outside"]:
        where = "in the closed right half plane (Re s >= -" if loop.gain.continuous else \
            "on or outside the unit circle (|z| >= 1 - "
        tol = s["pole_tolerance"]

        def side(z: complex) -> str:
            off = z.real if loop.gain.continuous else abs(z) - 1.0
            return "on it, within the accuracy" if abs(off) <= tol else "outside"
        poles = ", ".join(f"{_z(z)} ({side(z)})" for z in (complex(*p) for p in s["open_loop_poles_on_or_outside"]))
        lines.append(f"  warning: open-loop poles {where}{_num(s['pole_tolerance'])}, the model's accuracy): {poles}; "
                     "the margins at w = 0 depend on the side they lie (an integrator, or an unstable pole the "
                     "feedback stabilises, which a lower gain margin bounds)")
    lines.append(f"  closed loop {'stable' if s['closed_loop_stable'] else 'UNSTABLE'}; its eigenvalues: "
                 + ", ".join(_z(z) for z in sorted(loop.closed_eigenvalues, key=lambda z: (z.real, z.imag))))
    return lines


def _named(names: list[str], units: list[str]) -> list[str]:
    return [f"{n} [{u}]" if u else n for n, u in zip(names, units)]


def _z(z: complex) -> str:
    z = complex(z)
    return f"{z.real:.6g}" if z.imag == 0 else f"{z.real:.6g}{z.imag:+.6g}j"


def _num(x: Any) -> str:
    return f"{x:.4g}" if isinstance(x, float) and math.isfinite(x) else str(x)
