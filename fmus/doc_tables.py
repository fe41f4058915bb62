"""The FMUs' interface tables (one per FMU: name, causality, type, unit, start, range, meaning), generated
from their model descriptions, and what a user needs to run the FMUs outside this project.

``python -m wmr_cosim.fmus.doc_tables --out docs/fmu-interfaces.md`` builds the FMUs if needed and writes
the document (to stdout without ``--out``); a test checks that docs/fmu-interfaces.md is what it generates.
"""
from __future__ import annotations

import sys
from pathlib import Path

DBL_MAX = sys.float_info.max
DBL_MIN = sys.float_info.min

_INTRO = """# The FMUs' interfaces

`wmr-cosim build [--out DIR]` builds three FMI 2.0 co-simulation FMUs (pythonfmu): `WmrPlant.fmu`,
`WmrSensor.fmu`, `WmrController.fmu`, by default into `build/fmus/` of a source checkout (git-ignored) or,
installed from a wheel, into the per-user cache `~/.cache/wmr-cosim/fmus/`. Each is a thin slave over the
component of the same name in `components/`; the tables below are generated from their model
descriptions (`python -m wmr_cosim.fmus.doc_tables --out docs/fmu-interfaces.md`).

Conventions:

- Parameters have the names of the components' parameter fields; the controller's tuples become scalars
  (`W_init` -> `W1_init`..`W3_init`, `P_init` -> `P11_init`, `P12_init`, `P13_init`, `P22_init`,
  `P23_init`, `P33_init`). Choices (`task`, `friction_form`, `filter_form`, the decisions of
  [decisions.md](decisions.md), ...) are **String** parameters whose allowed values are listed in their
  meaning; flags are Boolean, counts and powers Integer, everything else Real with a unit.
- Every Real and Integer parameter declares min/max, so a master can refuse a bad value before
  instantiating: "> 0" is written as min = DBL_MIN, "finite" as min = -DBL_MAX, max = DBL_MAX. Checks
  that a range cannot express (M positive definite, P_init positive definite, a goal away from the start,
  a choice) are made when the FMU leaves initialization mode: it logs one line naming the parameter and
  the value and fails (fmi2Fatal, the only failure status pythonfmu has during initialisation).
- Parameters are `fixed` except the `tunable` ones (the plant's friction change `foam_da1`, `foam_da2`;
  the controller's goal and adaptation switch and window), which a master may change between steps:
  they act from the next step. Setting a fixed parameter or an output after initialisation is refused.
- A failure inside a step (a non-finite input, an overflow, a bad tunable value) is logged with its cause
  and reported as fmi2Discard; every later step is refused the same way; terminate and free work.
- Outputs list their true direct-feedthrough dependencies: none for the plant (its inputs are held over
  the step), the own wheel's angle for the sensor (it samples its inputs at the end of the step), the
  subsets shown below for the controller.
- Semantics (Gauss-Seidel plant -> sensor -> controller, the direct loop's order): plant
  `do_step(t, h)` = `Plant.step(t, h, u1, u2, tau_d1, tau_d2)`; sensor `Sensor.reset(alpha1, alpha2)` on
  leaving initialization mode, then `Sensor.step(h, alpha1, alpha2)`; controller
  `Controller.reset(t_start, inputs)`, then `Controller.step(t + h, h, inputs)`. A time within 1e-9
  (relative) of a whole multiple of the step, and a step within 1e-9 of the previous one, are snapped to
  them, so masters that accumulate time reproduce the direct loop bit for bit. Any step size is accepted.
- State: `fmi2GetFMUstate`/`SetFMUstate` and serialisation save every variable and the component's whole
  internal state (integrator, filters, encoder counts, RLS matrices, planner phase); the learned weights
  are also outputs (`W1`..`W3`, `P11`..`P33`), to start a later run from them via `W*_init`, `P*_init`.
- Default experiment: 0 to 50 s, step 2 ms (a default, not a constant).
"""

_OUTSIDE = """## Running the FMUs outside this project

An FMU file is self-contained apart from Python itself: its `resources/` hold the slave script, a copy
of the component code under a package name unique to the build (`wmrfmu_<component>_<hash8>`), the
paper's constants (`paper_results.json`) and pythonfmu's Python part. Any FMI 2.0 host on Linux x86-64
(the only platform built) loads it, Python or not, with nothing set up; the machine needs the Python
version the FMUs were built with (its shared library and standard library only, no numpy), and the
environment variable `WMR_FMU_LIBPYTHON` selects another: see [hosts.md](hosts.md).
After an fmi2Fatal (only possible during initialisation, or on a refused call) the host must not call
the instance again, not even to free it: leak it and stop. Two instances of the same FMU, or FMUs of
different builds, can live in one process: every build's modules have their own names.
"""


def _range(v) -> str:
    lo = None if v.min is None else float(v.min)
    hi = None if v.max is None else float(v.max)
    if lo is None and hi is None:
        return ""
    if lo == -DBL_MAX and hi == DBL_MAX:
        return "finite"
    if lo == -DBL_MAX and hi is None:
        return "not NaN, may be +inf"
    if lo == DBL_MIN and hi == DBL_MAX:
        return "> 0"
    if lo == 0.0 and hi == DBL_MAX:
        return ">= 0"

    def fmt(x: float | None) -> str:
        if x is None:
            return ""
        return str(int(x)) if v.type == "Integer" else f"{x:g}"

    return f"[{fmt(lo)}, {fmt(hi)}]"


def _deps(u) -> str:
    names = [d.name for d in u.dependencies] if u.dependencies is not None else None
    if names is None:
        return "all inputs"
    return ", ".join(names) if names else "none"


def interface_table(fmu: Path) -> str:
    """Markdown: the FMU's description and one table of all its variables."""
    from fmpy import read_model_description

    md = read_model_description(str(fmu))
    deps = {u.variable.name: _deps(u) for u in md.outputs}
    lines = [f"## {md.modelName}", "", md.description or "", "",
             "| name | causality | type | unit | start | range | meaning |",
             "|---|---|---|---|---|---|---|"]
    order = {"parameter": 0, "input": 1, "output": 2}
    for v in sorted(md.modelVariables, key=lambda v: order.get(v.causality, 3)):
        caus = v.causality if v.causality != "parameter" else f"parameter ({v.variability})"
        meaning = v.description or ""
        if v.causality == "output":
            meaning += f" (direct feedthrough: {deps[v.name]})"
        start = "" if v.start is None else str(v.start)
        lines.append(f"| `{v.name}` | {caus} | {v.type} | {v.unit or ''} | {start} | {_range(v)} | {meaning} |")
    return "\n".join(lines) + "\n"


def document(fmus: dict[str, Path]) -> str:
    parts = [_INTRO]
    for model in ("WmrPlant", "WmrSensor", "WmrController"):
        parts.append(interface_table(fmus[model]))
    parts.append(_OUTSIDE)
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    import argparse

    from .build import build_all

    ap = argparse.ArgumentParser(prog="python -m wmr_cosim.fmus.doc_tables", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="write the Markdown here, e.g. docs/fmu-interfaces.md "
                    "(default: stdout)")
    ap.add_argument("--fmus", type=Path, default=None, help="folder of the built FMUs (default: build/fmus)")
    args = ap.parse_args(argv)
    text = document(build_all(args.fmus))
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
