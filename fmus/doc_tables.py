"""The FMUs' interface tables (one per FMU: name, causality, type, unit, start, range, meaning), generated
from their model descriptions, and what a user needs to run the FMUs outside this project.

``python -m wmr_cosim.fmus.doc_tables --out docs/fmu-interfaces.md`` builds the FMUs if needed and writes
the document (to stdout without ``--out``); ``--fmi 3 --out docs/fmu-interfaces-fmi3.md`` the same for the
FMI 3.0 FMUs.  A test checks that both documents are what it generates.
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

_INTRO3 = """# The FMI 3.0 FMUs' interfaces

`wmr-cosim build --fmi 3 [--out DIR]` builds three FMI 3.0 co-simulation FMUs (pythonfmu3):
`WmrPlant3.fmu`, `WmrSensor3.fmu`, `WmrController3.fmu`, beside the FMI 2.0 ones (same folder). A scenario
names them by model name (`fmu = "WmrController3"`), alone or mixed with FMI 2.0 FMUs. They are built from
the same slave scripts, declarations and components as the FMI 2.0 FMUs of
[fmu-interfaces.md](fmu-interfaces.md), whose conventions hold here too; G1 through them is bit for bit
G1 through the FMI 2.0 FMUs. The tables below are generated from their model descriptions
(`python -m wmr_cosim.fmus.doc_tables --fmi 3 --out docs/fmu-interfaces-fmi3.md`).

What differs from the FMI 2.0 FMUs:

- Types: Real is **Float64**, Integer is **Int32**; Boolean and String as in FMI 2.0 (the choices stay
  String parameters with the same values, so a scenario sets them alike).
- Arrays: the controller's critic weights are one Float64 array `W_init` (3) instead of `W1_init`..
  `W3_init`, and the RLS matrix one symmetric 3 x 3 array `P_init` instead of the six `P11_init`..
  `P33_init`; the learned values are the outputs `W` (3) and `P` (3 x 3). A scenario gives an array
  parameter as a TOML list in row-major order (`P_init = [100.0, 0, 0, 0, 100.0, 0, 0, 0, 100.0]`); the
  master records arrays as columns `controller.W[1]`.. and `controller.P[1,1]`... Setting `P_init` with
  P[i,j] != P[j,i] is refused (fmi3Fatal, with one line naming the elements).
- Units as in FMI 2.0 (the same `UnitDefinitions`), with display units offered beside them: degrees for
  rad (`deg`), deg/s and rpm for rad/s, deg/s2 for rad/s2.
- The independent variable `time` [s] (value reference 0), which FMI 3.0 requires.
- Dependencies: `Output` and `InitialUnknown` carry the same direct feedthrough as the FMI 2.0 FMUs (by
  value reference; an array output depends on the union of its elements' inputs); the clocked outputs
  of `WmrSensor3` and `WmrController3` (below) are `Output`s only.
- Failure rules as in FMI 2.0: a failed step returns fmi3Discard with its logged cause and every later
  step is refused; a failure in initialisation, a refused set (an output, a fixed parameter after
  initialisation, an asymmetric `P_init`) is fmi3Fatal (pythonfmu3 turns an exception in any call but a step into fmi3Fatal),
  after which the instance must not be called again.
- State: fmi3GetFMUState/SetFMUState and serialisation, with the component's whole internal state.
- Sample clock (`WmrSensor3`, `WmrController3`): their 2 ms sample period is a periodic input clock
  `sample` (`intervalVariability="constant"`, `intervalDecimal="0.002"`, no shift: ticks at t0 + k 2 ms;
  value reference 19 in `WmrSensor3`, 90 in `WmrController3`, after every variable's), which clocks their
  inputs and outputs (`clocks`, variability discrete; clocked variables are no `InitialUnknown`);
  `CoSimulation` has `hasEventMode="true"`. An importer runs them one of two ways:
  - eventModeUsed = false (`fmusim`, FMPy's `simulate_fmu`): as the FMI 2.0 FMUs, one
    fixed step (`canHandleVariableCommunicationStepSize="false"`): they sample at the end of every
    communication step, refuse a step of another length than the first (fmi3Discard), and the clock is
    unused (fmi3SetClock is refused, fmi3Fatal).
  - eventModeUsed = true: they sample only at the clock's ticks. At a tick (after
    fmi3ExitInitializationMode the instance is in Event Mode already, later fmi3EnterEventMode):
    fmi3SetClock(`sample`, true), set the inputs, fmi3UpdateDiscreteStates (it takes the sample, unless
    a read of an output took it first), read the outputs, fmi3EnterStepMode; then fmi3DoStep with steps
    of any length up to the next tick, over which the outputs hold (a step past the next tick is refused,
    fmi3Discard). Ticked every 2 ms, the outputs are bit for bit those of the fixed-step 2 ms run. The
    tick at the start time takes no step: it recomputes the outputs from the current inputs and
    parameters, as initialization mode does (the importer may leave it out). A tick that is not 2 ms after
    the last sample, or a failed sample, returns fmi3Error from fmi3UpdateDiscreteStates with its logged
    cause; every later step is refused.
- Hosts: any FMI 3.0 host, Python or not (FMPy, this project's master, `fmusim`, OMSimulator, a C
  program): `binaries/x86_64-linux/<model>.so` is the C loader of the FMI 2.0 FMUs in its FMI 3.0 form,
  which finds or starts the Python interpreter and forwards every call to pythonfmu3's binary (see
  [hosts.md](hosts.md)); it also carries the clock calls pythonfmu3 lacks (fmi3SetClock, fmi3GetClock,
  eventModeUsed) to the slave. OMSimulator 2.1 knows no Clock: it reads `sample` as a Float64 (refused,
  fmi3Fatal, unless its result file leaves `sample` out) and, after a run of `WmrSensor3` or
  `WmrController3`, aborts freeing it twice (its own defect; `WmrPlant3` has no clock).
"""

_OUTSIDE = """## Running the FMUs outside this project

An FMU file is self-contained apart from Python itself: its `resources/` hold the slave script, a copy
of the component code under a package name unique to the build (`wmrfmu_<component>_<hash8>`), the
paper's constants (`paper_results.json`) and pythonfmu's Python part. Any FMI 2.0 host on Linux x86-64,
or on 64-bit Windows where the build had MinGW-w64 (`binaries/win64`; the FMI 3.0 FMUs are Linux only),
loads it, Python or not, with nothing set up; the machine needs, on Linux, the Python version the FMUs
were built with (its shared library and standard library only, no numpy), on Windows a 64-bit Python
3.11 or later (python.org's installer), and the environment variable `WMR_FMU_LIBPYTHON` selects
another: see [hosts.md](hosts.md#platform).
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
        return str(int(x)) if v.type in ("Integer", "Int32") else f"{x:g}"

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
    fmi3 = md.fmiVersion.startswith("3")
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
        vtype = v.type
        if fmi3 and v.dimensions:
            vtype += "[" + ",".join(str(d.start) for d in v.dimensions) + "]"
        if fmi3 and v.causality == "independent":
            caus = "independent"
        if fmi3 and v.type == "Clock":   # (FMPy reads no interval: the model description says it)
            caus = f"input clock ({v.intervalVariability})"
        elif fmi3 and v.clocks:
            caus += ", clocked by " + ", ".join(f"`{c.name}`" for c in v.clocks)
        lines.append(f"| `{v.name}` | {caus} | {vtype} | {v.unit or ''} | {start} | {_range(v)} | {meaning} |")
    return "\n".join(lines) + "\n"


def document(fmus: dict[str, Path]) -> str:
    parts = [_INTRO]
    for model in ("WmrPlant", "WmrSensor", "WmrController"):
        parts.append(interface_table(fmus[model]))
    parts.append(_OUTSIDE)
    return "\n".join(parts)


def document3(fmus: dict[str, Path]) -> str:
    """The FMI 3.0 FMUs' document (docs/fmu-interfaces-fmi3.md)."""
    parts = [_INTRO3]
    for model in ("WmrPlant3", "WmrSensor3", "WmrController3"):
        parts.append(interface_table(fmus[model]))
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    import argparse

    from .build import build_all

    ap = argparse.ArgumentParser(prog="python -m wmr_cosim.fmus.doc_tables", description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="write the Markdown here, e.g. docs/fmu-interfaces.md "
                    "(default: stdout)")
    ap.add_argument("--fmus", type=Path, default=None, help="folder of the built FMUs (default: build/fmus)")
    ap.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the FMUs (default 2)")
    args = ap.parse_args(argv)
    if args.fmi == 3:
        from .build import SLAVES3
        text = document3(build_all(args.fmus, models=tuple(SLAVES3)))
    else:
        text = document(build_all(args.fmus))
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
