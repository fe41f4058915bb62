"""Benchmarks.  ``python benchmarks/bench.py NAME``; the last line printed is one JSON object of figures.

NAME:
    loop    the G1 50 s learning run (25,000 steps of 2 ms), median of several runs each (each run of the
            direct loop followed by one of the co-simulation, so that their ratio compares the same minutes):
            - the direct loop (FMI-free), recording every output: direct_s, direct_us_per_step (target <= 20 us);
            - the co-simulation of the three FMUs (Gauss-Seidel) recording what the analysis needs:
              cosim_s (the stepping loop, first step to last, recording included), cosim_setup_s
              (extraction, instantiation, initialisation), cosim_us_per_step (target <= 22 us),
              cosim_to_direct (target <= 1.3), the loop that ran (loop: the compiled one where a C compiler
              is at hand), the same through the generated Python loop, interleaved: cosim_python_s,
              cosim_python_us_per_step, cosim_python_to_direct; and, from a separate run of the Python loop
              that times every FMI call, master_us_per_fmu_step = (loop time - time inside FMI calls) / steps /
              FMUs (target <= 1.5 us);
            - the same co-simulation with a plain loop over the instances in place of the generated Python
              one (interleaved runs): cosim_plain_us_per_step, cosim_generated_us_per_step, generated_speedup;
            - the same co-simulation through the FMI 3.0 FMUs (WmrPlant3, WmrSensor3, WmrController3),
              interleaved with runs through the FMI 2.0 ones: cosim3_us_per_step, cosim2_us_per_step (the
              FMI 2.0 figure of the same runs) and cosim3_to_cosim2 (target <= 1.10).
    paper   the whole `wmr-cosim paper` job (4 tasks x 3 runs x 2 variants, analysis, figures, report),
            once, the FMUs already built: paper_s (target < 60 s on 2 cores).
    sweep   a 16-run sweep (scenarios/sweep-geometry.toml) through the Dask path with 1 and with 2 worker
            processes, interleaved (a new cluster each time), --repeats times: sweep_startup_s (cluster start-up, excluded), sweep_1w_s,
            sweep_2w_s (the fastest of each), sweep_speedup (target >= 1.8 on 2 cores), same_results; the FMUs
            shipped to each worker: ship_bytes_per_worker, ship_s_until_all_workers_hold (the driver's wall
            time, the slowest shipment), ship_write_s_per_worker (the slowest worker's writing into its cache),
            ship_all_written (each new worker wrote every byte into its cache).
    generic three C FMUs (the Reference FMUs Dahlquist -> Feedthrough -> Feedthrough, 100,000 steps of 0.1 ms,
            Gauss-Seidel) under ours, a plain loop on FMPy's FMU2Slave, libcosim and ecos (Jacobi, their
            only algorithm for an SSP), each creating, initialising and stepping the system and recording the
            three outputs: us_per_fmu_step per master (target: ours the fastest, <= 2 us), ours_loop (our
            stepping loop alone: the compiled loop where a C compiler is at hand; target < 0.2 us),
            ours_python / ours_python_loop (through the generated Python loop), ecos_pinned (one core),
            c_floor (benchmarks/floor_loop.c: the chain stepped by hand in C, the FMUs' own cost: the
            floor), floor_ratio (ours_loop / c_floor), ours_equals_fmpy_loop, ours_equals_python_loop,
            ours_equals_c_floor (bit for bit).
    container  a chain of Reference C FMUs (Dahlquist -> Feedthrough -> Feedthrough, 1,000,000 steps of 0.1 ms)
            exported as one FMU three ways, each run in FMPy's simulate_fmu (unpacked beforehand, 1,000 host
            steps): ours (export-fmu, Gauss-Seidel and Jacobi), FMPy's container_fmu (patched around its bugs:
            bench_container says how) and fmu-manipulation-toolbox's fmucontainer (sequential and parallel):
            wall_s (median of --repeats interleaved runs), ours_to_* (our wall time over theirs, the same
            algorithm; target <= 1), max_abs_diff (from `wmr-cosim run` of the scenario of the algorithm; ours
            0.0), max_abs_diff_from_the_other_algorithm (what tells the algorithms apart), build_s,
            validation_problems (fmpy.validation), algorithm (the run each equals: FMPy's is Gauss-Seidel on
            the chain, Jacobi on G1), ours_equal; the same figures under "g1" for G1 cut to 10 s (our three
            pythonfmu FMUs, 56 outputs of three types, 100 host steps).
    interop the G1 learning system (Jacobi, exported as SSP with the signals the comparison needs) under our
            master and third-party masters, each in a fresh process as its users run it, with its defaults
            (tests/interop.py): peers = wall seconds per master (median of up to 3 runs; creating the
            execution, initialisation and 25,000 steps, recording included; not importing the library):
            ours (load_ssp + resolve + cosim.run, signals.npy), libcosim (from_ssp_file, time-series
            observer), ecos (EcosSimulation, CSV writer, step(n)), fmpy_ssp (simulate_ssp), and ecos_pinned
            (ecos with its process pinned to one core); c_plant_s = ours with the C plant (WmrCPlant.fmu)
            in place of the Python plant.  Target: ours the fastest of the default runs, and within 10 % of
            ecos_pinned.
    archive the archive checks on our three FMUs: check_directory_ms (the directory's entries and declared
            sizes), check_verify_ms (also every entry decompressed and counted, as loading a model does),
            extract_ms (counted extraction), summed over the three FMUs, medians; lying_bomb_refused_ms (256 MiB
            of zeros whose directory declares 1 KiB, refused while extracting) and nothing_left.
    isolation  G1 in process, with the plant in a child process and with all three FMUs in child processes
            (isolate = true); G1 with the C plant in process and isolated (the C child: c_plant; the
            Python child: c_plant_py); the Reference FMUs Dahlquist into Feedthrough in process and with
            Dahlquist isolated (ref_c, ref_py); interleaved, on a quiet machine, then beside one and beside
            two CPU-bound processes the benchmark starts (quiet, loaded_1, loaded_2): us_per_step of each,
            isolated_us_per_fmu_step_overhead (targets: the plant under 10 us quiet and under 60 us
            loaded_1; a C FMU with the C child under 5 us quiet and under 40 us loaded_1), handoff (the
            steps the children's hand-off spun and blocked), same_results.
    scripting what scripting costs per step on G1 through the Python API (wmr_cosim.Simulation): plain_us_per_step
            (no hooks), noop_callback / get_callback (a per-step callback doing nothing / reading one
            variable), condition (one condition event that never fires), each with *_overhead_us_per_step
            over plain (medians of interleaved runs).
    requirements what monitoring requirements costs per step on G1 on foam (scenarios/g1_requirements.toml):
            plain_us_per_step (without them), three (its three requirements), look_ahead (one requirement
            looking 5 s ahead), each with *_overhead_us_per_step (medians of interleaved runs); and the
            monitor alone over the recorded signals: monitor_tracking_us_per_sample,
            monitor_look_ahead_us_per_sample.
    live    what serving a run live costs (docs/live.md): G1 (25,000 steps, the analysis' recording, as fast as
            possible) plain (no server), served live without a client, and served live with a client
            consuming the WebSocket stream, interleaved, medians of the whole run's wall time (set-up and the
            server's start and end included): plain_s, live_s, live_client_s, rows_received (by the client),
            overhead = live_client_s / plain_s - 1 (target <= 0.10), overhead_no_client.
    loader  what the FMUs' Python loader (binaries/linux64/<model>.so forwarding to pythonfmu's binary) costs:
            the sensor FMU stepped 25,000 times (setReal + doStep + getReal through ctypes, as a master does)
            once through the loader and once through pythonfmu's binary loaded directly, in one process,
            interleaved, best of the rounds: via_loader_us_per_step, direct_us_per_step, loader_overhead
            (ratio - 1; target <= 0.05).
    exit    normal process exits after hosting our FMUs (the use-after-free of pythonfmu's and pythonfmu3's
            binaries at exit, fmus/pyloader/wmr_pyfinder.h): exit_runs = for each FMI 3.0 FMU, how many of 50
            runs (PYTHONHASHSEED=random) of a plain FMPy script (simulate_fmu x3, then FMU3Slave x30,
            normal exit) exit 0 (target 50 of 50); valgrind_invalid = for each of our FMUs (FMI 2.0, 3.0,
            the C plant) the "Invalid read/write" reports of valgrind on a script that instantiates, frees
            and exits under PYTHONMALLOC=malloc (target 0; null without valgrind).  ``--repeats`` is not used.
    mutation  mutation testing with mutmut of components/, cosim/ and the analysis code against the fast
            tests covering each mutant (benchmarks/mutation.py says how): mutants, killed, kill_rate (also
            per area; target >= 0.90 on components and cosim), equivalent (listed with their reasons in
            benchmarks/mutation-equivalents.toml), minutes, survivors.  Results are kept in build/mutation/,
            so a second run re-tests only what changed.
    bugs    bugs of the kinds mutmut does not make (an integer index off by one, an off-by-one in a
            time expression k * h, one factor dropped from a product, a containment check weakened to its
            first element), planted one at a time in cosim/ and components/ (benchmarks/bug_kinds.py):
            population, bugs (a sample of 60, seed 1), killed, kill_rate, by_kind, survivors, minutes.

    me      G1 with the C plant as co-simulation and as Model Exchange (the master's CVODE; its RK4 at 1 ms),
            interleaved: cs_us_per_step, me_cvode_us_per_step, me_rk4_us_per_step, their ratios to the
            co-simulation (me_cvode_to_cs, me_rk4_to_cs), and me_*_pose_diff_m, the final pose's distance [m]
            from the co-simulation plant's.

    adaptive  step-size control against fixed steps on a case whose dynamics change speed: the two-mass
            oscillator of tests/coupling_fmus.py (two C FMUs, the coupling force with direct feedthrough)
            with a stiff one-sided contact (10^4 N/m beyond a 5 cm stretch, against 100 N/m of the coupling
            spring) that engages for short spells, 2 s recorded every 10 ms.  The reference: the fixed-step
            iterated coupling (linear inputs) at 10 us (ref_to_ode_m: its distance from the monolithic
            ODE solved by DOP853 at 1e-12).  For each coupling (gauss-seidel: one pass; iterated: Newton,
            linear inputs) and its stated accuracy (largest position error on the output grid: 1e-2 m and
            1e-4 m), the largest fixed step of 10 ms / 2^k and the loosest rtol = atol of 10^-k that reach
            it: *_fixed_steps, *_fixed_error_m, *_adaptive_accepted, *_adaptive_rejected,
            *_adaptive_error_m, *_steps_ratio = (accepted + rejected) / fixed steps (target <= 1/3),
            *_instance_steps_* (every FMU step, the adaptive's three per macro step and the iterations'
            included) and *_wall_s_* of both runs.  ``--repeats`` is not used.

    parallel  Jacobi over N C FMUs (the probe FMU of the tests, built with BURN_US: each step computes for
            1 ms, 1,000 steps, or for 50 us, 4,000 steps) in a chain, N = 2 and 4, in this process (stepped in
            threads) and isolated (each in a child process): serial (workers = 1) and stepped at once
            (workers = N), interleaved, medians; per KIND_N_BURN (threads_2_1ms, isolated_4_50us, ...):
            us_per_step_serial_..., us_per_step_..., speedup_... (target >= 1.8 for threads_2_1ms on 2 cores)
            and same_results_... (bit for bit); the same for Gauss-Seidel over two independent chains of two
            1 ms probes, stepped by levels in threads (threads_gauss_seidel_2_chains_1ms); cores.

    contract  the contract harness (tests/contract_*.py; benchmarks/contract.py) for ``--budget`` seconds
            (default 600) shared by its targets (``--target NAME`` for some): random examples of scenario,
            requirement, sweep and falsification documents, command lines and hostile bytes for the
            readers, each held to the contract; each new defect printed with its minimal example
            (shrunk by Hypothesis) and its evidence: examples (per target), examples_total,
            shrink_runs, defects (distinct), defects_by_target, defect_keys, seconds.  ``--repeats`` is
            not used.

``--against REV`` runs NAME in this checkout and in a worktree of commit REV, interleaved, ``--rounds``
fresh processes each of ``--repeats`` runs (benchmarks/against.py): each figure's median over the rounds for
both and their ratio, this / that.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import json
from typing import Any, Callable, Iterator
import platform
import statistics
import sys


def bench_loop(repeats: int, between: Callable[[], Any] | None = None) -> dict[str, float]:
    """The direct loop, ``repeats`` times; ``between`` runs after each repeat (bench_loop_all: a repeat
    of the co-simulation, so that cosim_to_direct compares runs of the same minutes)."""
    from wmr_cosim.components.direct_loop import run_direct

    run_direct(t_stop=2.0)  # warm up imports and caches
    walls, walls_norec = [], []
    steps = 0
    for _ in range(repeats):
        r = run_direct(t_stop=50.0, h=0.002, record=True)
        walls.append(r.wall_s)
        steps = r.steps
        walls_norec.append(run_direct(t_stop=50.0, h=0.002, record=False).wall_s)
        if between is not None:
            between()
    direct_s = statistics.median(walls)
    return {
        "steps": steps,
        "repeats": repeats,
        "direct_s": round(direct_s, 4),
        "direct_us_per_step": round(direct_s / steps * 1e6, 2),
        "direct_norecord_us_per_step": round(statistics.median(walls_norec) / steps * 1e6, 2),
        "direct_min_us_per_step": round(min(walls) / steps * 1e6, 2),
    }


#: What the analysis of a run needs (report, metrics, figures): recorded at every step.
ANALYSIS_RECORD = ["plant.x_A", "plant.y_A", "plant.beta", "plant.dF*", "controller.u*", "controller.dF_hat*",
                   "controller.W*", "controller.V_hat", "controller.s*", "controller.e*", "controller.P_norm",
                   "controller.v_A_d", "controller.beta_dot_d", "controller.profile", "controller.t_goal"]


@contextlib.contextmanager
def stepping_loop(python: bool) -> Iterator[None]:
    """Runs (in this process and the ones it starts) through the Python loop where ``python``, else through
    the compiled one where a C compiler is at hand (cosim/stepping/native.py: WMR_COSIM_LOOP)."""
    if python:
        os.environ["WMR_COSIM_LOOP"] = "python"
    try:
        yield
    finally:
        os.environ.pop("WMR_COSIM_LOOP", None)


def bench_cosim(repeats: int) -> dict[str, float]:
    from wmr_cosim import cosim
    from wmr_cosim.runner import resolve_model

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    sc = cosim.load(root / "scenarios" / "g1_learn.toml", resolve_model)
    sc.record = ANALYSIS_RECORD
    plan = cosim.resolve(sc)
    walls, setups, python_walls = [], [], []
    res = None
    loop_used = ""
    for _ in range(repeats):   # the compiled loop (where a compiler is at hand) and the Python loop, interleaved
        for python, times in ((False, walls), (True, python_walls)):
            with stepping_loop(python):
                res = cosim.run(plan, None, progress=False)
            if res.status != "ok":
                raise SystemExit(f"co-simulation failed: {res.message}")
            times.append(res.wall_s)
            if not python:
                setups.append(res.setup_s)
                loop_used = (res.stepping or {}).get("loop", "")
    # the master's own time per FMU and step: the loop's time minus the time inside the FMI calls, timed one
    # by one (through the Python loop: the timing wraps each call in Python, which the compiled loop would
    # then call back)
    with stepping_loop(python=True):
        timed = [cosim.run(plan, None, progress=False, timing=True) for _ in range(max(1, repeats // 2))]
    overhead = statistics.median((r.wall_s - r.fmi_s) / r.steps / len(plan.instances) * 1e6 for r in timed)
    cosim_s, python_s = statistics.median(walls), statistics.median(python_walls)
    return {"cosim_s": round(cosim_s, 4), "cosim_setup_s": round(statistics.median(setups), 4),
            "cosim_us_per_step": round(cosim_s / res.steps * 1e6, 2),
            "cosim_python_s": round(python_s, 4), "cosim_python_us_per_step": round(python_s / res.steps * 1e6, 2),
            "cosim_recorded_columns": len(res.columns), "loop": loop_used,
            "master_us_per_fmu_step": round(overhead, 3)}


def plain_algorithm():
    """Gauss-Seidel with its loop written as a plain loop over the instances, making the same raw ctypes
    calls as the generated one (Real connections only: what G1 needs): the yardstick that decides whether
    generating the loop pays for itself.  An algorithm object of its own (cosim.stepping.algorithm's interface)."""
    from wmr_cosim.cosim.stepping.generated import GaussSeidel
    from wmr_cosim.cosim.instances.failure import Call, Failure

    class PlainGaussSeidel(GaussSeidel):
        def compile(self):
            import ctypes

            ios, clock, done, check_inputs = self.ios, self.clock, self.done, self.check_inputs
            if any(io.other or io.feed or io.fast.terminated is not None for io in ios):
                raise ValueError("the plain loop covers Gauss-Seidel with Real connections only")
            t0, h = clock.start, clock.step
            T, H = ctypes.c_double(0.0), ctypes.c_double(h)
            items = [(io.name, io.fast.c, io.fast.set_real, io.fast.do_step, io.fast.get_real, io.in_vr,
                      io.fast.in_val, io.n_in, io.out_vr, io.out_val, io.n_out, io.copies, bool(io.n_out.value),
                      io.fast.set_tail, io.fast.step_tail, io.fast.get_tail) for io in ios]

            def loop(k0, k1):
                for k in range(k0, k1):
                    T.value = t0 + k * h
                    for (name, c, setr, dostep, getr, invr, inv, nin, outvr, outv, nout, copies, has_out,
                         st, dt, gt) in items:
                        if copies:
                            for pos, arr, i, f, o in copies:
                                v = arr[i] * f + o
                                if check_inputs and v - v != 0.0:
                                    return Failure(k, name, Call.NON_FINITE_INPUT, v)
                                inv[pos] = v
                            s = setr(c, invr, nin, inv, *st)
                            if s:
                                return Failure(k, name, Call.SET_REAL, s)
                        s = dostep(c, T, H, *dt)
                        if s:
                            return Failure(k, name, Call.DO_STEP, s)
                        if has_out:
                            s = getr(c, outvr, nout, outv, *gt)
                            if s:
                                return Failure(k + 1, name, Call.GET_REAL, s)
                    s = done(k + 1, False)
                    if s is not None:
                        return s
                return None
            return loop
    return PlainGaussSeidel()


def bench_plain(repeats: int) -> dict[str, float]:
    """G1 as in bench_cosim, with the plain loop in place of the generated one (interleaved runs)."""
    from wmr_cosim import cosim
    from wmr_cosim.cosim.stepping.generated import GaussSeidel
    from wmr_cosim.runner import resolve_model

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    sc = cosim.load(root / "scenarios" / "g1_learn.toml", resolve_model)
    sc.record = ANALYSIS_RECORD
    plan = cosim.resolve(sc)
    def generated() -> GaussSeidel:   # the generated Python loop (the compiled one is bench_cosim's)
        alg = GaussSeidel()
        alg.native = False
        return alg
    walls: dict[str, list[float]] = {"generated": [], "plain": []}
    for _ in range(repeats):
        for kind, make in (("generated", generated), ("plain", plain_algorithm)):
            walls[kind].append(cosim.run(plan, None, progress=False, algorithm=make()).wall_s)
    g, p = statistics.median(walls["generated"]), statistics.median(walls["plain"])
    return {"cosim_plain_us_per_step": round(p / plan.n_steps * 1e6, 2),
            "cosim_generated_us_per_step": round(g / plan.n_steps * 1e6, 2),
            "generated_speedup": round(p / g, 3)}


def bench_fmi3(repeats: int) -> dict[str, float]:
    """G1 through the FMI 3.0 FMUs and through the FMI 2.0 ones, runs interleaved (the machine's load
    drifts): the stepping loop's time per step, median of the repeats."""
    from wmr_cosim import cosim
    from wmr_cosim.runner import resolver

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    plans = {}
    for fmi in (2, 3):
        sc = cosim.load(root / "scenarios" / "g1_learn.toml", resolver(fmi))
        sc.record = ANALYSIS_RECORD
        plans[fmi] = cosim.resolve(sc)
    walls: dict[int, list[float]] = {2: [], 3: []}
    for _ in range(repeats):
        for fmi in (2, 3):
            res = cosim.run(plans[fmi], None, progress=False)
            if res.status != "ok":
                raise SystemExit(f"co-simulation (FMI {fmi}) failed: {res.message}")
            walls[fmi].append(res.wall_s)
    w2, w3 = statistics.median(walls[2]), statistics.median(walls[3])
    n = plans[2].n_steps
    return {"cosim3_us_per_step": round(w3 / n * 1e6, 2), "cosim2_us_per_step": round(w2 / n * 1e6, 2),
            "cosim3_to_cosim2": round(w3 / w2, 3)}


def bench_loop_all(repeats: int) -> dict[str, float]:
    # each repeat of the direct loop followed by one of the co-simulation: on a shared machine the load
    # drifts between two phases run one after the other by more than cosim_to_direct's margin
    cosim_runs: list[dict[str, Any]] = []
    figures = bench_loop(repeats, between=lambda: cosim_runs.append(bench_cosim(1)))
    steps = figures["steps"]

    def median(key: str, digits: int) -> float:
        return round(statistics.median(r[key] for r in cosim_runs), digits)
    cosim_s, python_s = median("cosim_s", 4), median("cosim_python_s", 4)
    figures.update({"cosim_s": cosim_s, "cosim_setup_s": median("cosim_setup_s", 4),
                    "cosim_us_per_step": round(cosim_s / steps * 1e6, 2), "cosim_python_s": python_s,
                    "cosim_python_us_per_step": round(python_s / steps * 1e6, 2),
                    "cosim_recorded_columns": cosim_runs[-1]["cosim_recorded_columns"],
                    "loop": cosim_runs[-1]["loop"], "master_us_per_fmu_step": median("master_us_per_fmu_step", 3)})
    figures["cosim_to_direct"] = round(figures["cosim_s"] / figures["direct_s"], 3)
    figures["cosim_python_to_direct"] = round(figures["cosim_python_s"] / figures["direct_s"], 3)
    figures.update(bench_plain(repeats))
    figures.update(bench_fmi3(repeats))
    return figures


def bench_paper(repeats: int) -> dict[str, float]:
    """The whole paper job (both variants, 24 runs, analysis, figures, report), once: paper_s."""
    import tempfile
    import time

    from wmr_cosim.paper.job import run_paper
    from wmr_cosim.runner import resolve_model

    for m in ("WmrPlant", "WmrSensor", "WmrController"):  # FMUs built beforehand, as a user has them
        resolve_model(m)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        r = run_paper(tmp, progress=False)
        paper_s = time.perf_counter() - t0
    f = r["metrics"]["fidelity"]
    return {"paper_s": round(paper_s, 2), "runs": 24, "within_1_5": f["within_1_5"],
            "rms_log_factor": round(f["rms_log_factor"], 4)}


def bench_sweep(repeats: int) -> dict[str, float]:
    """scenarios/sweep-geometry.toml (16 G1 learning runs of 50 s, random r, l1 and goal) through the Dask
    path with 1 and with 2 worker processes, ``repeats`` times interleaved, a new cluster each time (the
    fastest of each kept); cluster start-up timed apart; what shipping the FMUs to the workers cost
    (sweep.json)."""
    import json
    import tempfile
    import time

    from wmr_cosim.studies.cluster import Cluster
    from wmr_cosim.paper import robot_system
    from wmr_cosim.studies import run_sweep

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    f = root / "scenarios" / "sweep-geometry.toml"
    figures: dict[str, float] = {}
    tables = {}
    times: dict[int, list[float]] = {1: [], 2: []}
    shipping: list[dict] = []
    startups = []
    for _ in range(max(1, repeats)):
        for n in (1, 2):   # one cluster at a time: an idle one's scheduler would load the driver's core
            with tempfile.TemporaryDirectory() as tmp, Cluster(workers=n) as cl:
                startups.append(cl.startup_s)
                cl.client.run(lambda: __import__("wmr_cosim.cosim.runtime.execution"))  # imports warm
                t0 = time.perf_counter()
                df = run_sweep(f, tmp, cluster=cl, progress=False, system=robot_system())
                times[n].append(time.perf_counter() - t0)
                tables[n] = df.drop(columns=["wall_s"])
                shipping.append(json.loads((__import__("pathlib").Path(tmp) / "sweep.json").read_text())["shipping"])
    figures["sweep_startup_s"] = round(max(startups), 3)
    for n in (1, 2):
        figures[f"sweep_{n}w_s"] = round(min(times[n]), 3)
    figures["sweep_speedup"] = round(figures["sweep_1w_s"] / figures["sweep_2w_s"], 3)
    figures["runs"] = len(tables[1])
    figures["same_results"] = bool(tables[1].equals(tables[2]))
    # every cluster here is new: each worker writes the files into its cache once
    per_worker = [w for s in shipping for w in s["workers"].values()]
    figures["ship_bytes_per_worker"] = shipping[0]["bytes"]
    figures["ship_s_until_all_workers_hold"] = round(max(s["seconds"] for s in shipping), 4)
    figures["ship_write_s_per_worker"] = round(max(w["seconds"] for w in per_worker), 4)
    figures["ship_all_written"] = all(w["written"] == shipping[0]["bytes"] for w in per_worker)
    return figures


def bench_interop(repeats: int) -> dict[str, float]:
    """Ours, libcosim, ecos, FMPy's simulate_ssp (and ecos pinned) on the exported G1 Jacobi system."""
    import tempfile
    from pathlib import Path

    from wmr_cosim import cosim
    from wmr_cosim.cosim.plan.ssp import export_ssp
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from interop import SIGNALS, run_peer
    from wmr_cosim.runner import resolve_model

    root = Path(__file__).resolve().parents[1]
    n = max(1, min(repeats, 3))
    figures: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        archives = {}
        for key, scen in (("python", "g1_learn.toml"), ("c", "g1_c_plant.toml")):
            sc = cosim.load(root / "scenarios" / scen, resolve_model)
            sc.algorithm, sc.record = "jacobi", list(SIGNALS)
            archives[key] = export_ssp(cosim.resolve(sc), Path(tmp) / f"{key}.ssp")
        walls: dict[str, list[float]] = {}
        steps = {}
        for _ in range(n):  # interleaved, so that a slow phase of the machine hits every master alike
            for peer in ("ours", "libcosim", "ecos", "fmpy_ssp", "ecos_pinned"):
                r = run_peer(peer, archives["python"], 50.0, 0.002)
                walls.setdefault(peer, []).append(r["wall_s"])
                steps[peer] = r["steps"]
            c_signals = [x.replace("plant.x_A", "plant.pos_x").replace("plant.y_A", "plant.pos_y") for x in SIGNALS]
            walls.setdefault("c_plant", []).append(run_peer("ours", archives["c"], 50.0, 0.002, c_signals)["wall_s"])
    med = {k: round(statistics.median(v), 3) for k, v in walls.items()}
    figures["peers"] = {k: med[k] for k in ("ours", "libcosim", "ecos", "fmpy_ssp", "ecos_pinned")}
    figures["c_plant_s"] = med["c_plant"]
    figures["steps"] = steps
    figures["repeats"] = n
    default = {k: v for k, v in figures["peers"].items() if k != "ecos_pinned"}
    figures["ours_fastest"] = min(default, key=default.get) == "ours"
    figures["ours_to_ecos_pinned"] = round(med["ours"] / med["ecos_pinned"], 3)
    return figures


GENERIC_STEPS = 100_000
GENERIC_H = 1e-4


def _chain_scenario(tmp: str, name: str, steps: int, h: float, algorithm: str | None = None,
                    factor: float | None = None) -> Any:
    """Dahlquist (k = 0.5) -> Feedthrough -> Feedthrough (Reference FMUs, C, FMI 2.0, built from their sources
    by tests/reference_fmus.py), ``steps`` steps of ``h`` [s], the three outputs recorded: the file
    ``tmp/name``; ``algorithm`` (default Gauss-Seidel), ``factor`` of the second connection (default none)."""
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from reference_fmus import REF

    ref = REF / "fmi2"
    path = Path(tmp) / name
    path.write_text(f"""
[experiment]
stop = {steps * h!r}
step = {h!r}
""" + (f'algorithm = "{algorithm}"\n' if algorithm is not None else "") + f"""[instances.d]
fmu = "{ref / 'Dahlquist.fmu'}"
parameters = {{ k = 0.5 }}
[instances.f1]
fmu = "{ref / 'Feedthrough.fmu'}"
[instances.f2]
fmu = "{ref / 'Feedthrough.fmu'}"
[[connections]]
from = "d.x"
to = "f1.Float64_continuous_input"
[[connections]]
from = "f1.Float64_continuous_output"
to = "f2.Float64_continuous_input"
""" + (f"factor = {factor!r}\n" if factor is not None else "") + """[record]
variables = ["d.x", "f1.Float64_continuous_output", "f2.Float64_continuous_output"]
csv = false
""")
    return path


def _generic_scenario(tmp: str) -> Any:
    """The chain (:func:`_chain_scenario`), Gauss-Seidel, GENERIC_STEPS steps, a factor 2 on its second
    connection."""
    return _chain_scenario(tmp, "chain.toml", GENERIC_STEPS, GENERIC_H, factor=2.0)


def _fmpy_loop(plan: Any) -> tuple[float, Any]:
    """The same chain as a plain Gauss-Seidel loop on FMPy's FMU2Slave (its wrapper methods), recording the
    three outputs in a preallocated array."""
    import shutil
    import tempfile
    import time

    import numpy as np
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave

    t0 = time.perf_counter()
    fmus, dirs = {}, []
    for name, ip in plan.instances.items():
        d = extract(str(ip.model.path), unzipdir=tempfile.mkdtemp(prefix="wmr-bench-"))
        dirs.append(d)
        md = ip.model.md
        f = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=name)
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        for var, value in ip.parameters:
            f.setReal([var.vr], [value])
        f.enterInitializationMode()
        f.exitInitializationMode()
        fmus[name] = f
    vr = {n: {v.name: v.vr for v in ip.model.variables.values()} for n, ip in plan.instances.items()}
    d, f1, f2 = fmus["d"], fmus["f1"], fmus["f2"]
    x_vr, i1, o1 = [vr["d"]["x"]], [vr["f1"]["Float64_continuous_input"]], [vr["f1"]["Float64_continuous_output"]]
    i2, o2 = [vr["f2"]["Float64_continuous_input"]], [vr["f2"]["Float64_continuous_output"]]
    n, h = plan.n_steps, plan.scenario.step
    out = np.empty((n, 3))
    for k in range(n):
        t = k * h
        d.doStep(t, h)
        x = d.getReal(x_vr)[0]
        f1.setReal(i1, [x])
        f1.doStep(t, h)
        y1 = f1.getReal(o1)[0]
        f2.setReal(i2, [2.0 * y1])
        f2.doStep(t, h)
        out[k] = (x, y1, f2.getReal(o2)[0])
    wall = time.perf_counter() - t0
    for f in fmus.values():
        f.terminate()
        f.freeInstance()
    for dd in dirs:
        shutil.rmtree(dd, ignore_errors=True)
    return wall, out


def _c_floor(plan: Any, tmp: str) -> tuple[float, Any] | None:
    """The chain stepped by hand in C (benchmarks/floor_loop.c, built here with the system's compiler):
    (seconds of its stepping loop, the outputs), or None without a compiler."""
    import shutil
    import subprocess
    from pathlib import Path

    import fmpy
    import numpy as np
    from fmpy import extract

    cc = shutil.which(os.environ.get("CC") or "cc")
    if cc is None:
        return None
    here, work = Path(__file__).resolve().parent, Path(tmp)
    exe = work / "floor_loop"
    if not exe.is_file():
        subprocess.run([cc, "-O2", "-I", str(Path(fmpy.__file__).parent / "c-code"), str(here / "floor_loop.c"),
                        "-o", str(exe), "-ldl"], check=True, capture_output=True)
    vr = {n: {v.name: v.vr for v in ip.model.variables.values()} for n, ip in plan.instances.items()}
    lines = [f"{plan.n_steps} {plan.scenario.step!r}",
             f"{vr['d']['k']} {next(v for var, v in plan.instances['d'].parameters if var.name == 'k')!r}"]
    chain = [("d", -1, 1.0, "x"), ("f1", vr["f1"]["Float64_continuous_input"], 1.0, "Float64_continuous_output"),
             ("f2", vr["f2"]["Float64_continuous_input"], 2.0, "Float64_continuous_output")]
    for name, in_vr, factor, out in chain:
        ip = plan.instances[name]
        d = Path(extract(str(ip.model.path), unzipdir=str(work / f"floor-{name}")))
        ident = ip.model.md.coSimulation.modelIdentifier
        lines.append(f"{d / 'binaries' / 'linux64' / (ident + '.so')} {ip.model.md.guid} {(d / 'resources').as_uri()}/ "
                     f"{name} {in_vr} {factor!r} {vr[name][out]}")
    (work / "floor.cfg").write_text("\n".join(lines) + "\n")
    p = subprocess.run([str(exe), str(work / "floor.cfg"), str(work / "floor.bin")], capture_output=True, text=True,
                       check=True)
    return json.loads(p.stdout)["loop_s"], np.fromfile(work / "floor.bin").reshape(plan.n_steps, 3)


def bench_generic(repeats: int) -> dict[str, Any]:
    """Three C FMUs (Reference FMUs Dahlquist -> Feedthrough -> Feedthrough), 100,000 steps, under ours,
    a plain loop on FMPy's FMU2Slave, libcosim and ecos (also pinned to one core); us_per_fmu_step = wall
    time (creating the system, initialisation and stepping, recording included) / steps / 3, median of the
    repeats.  ``ours_loop`` is our stepping loop alone (RunResult.wall_s: the compiled loop where a C
    compiler is at hand), ``ours_python_loop`` the same through the generated Python loop, ``c_floor`` the
    chain stepped by hand in C (benchmarks/floor_loop.c: the FMUs' own cost and the calls, the floor of
    any master); ``floor_ratio`` = ours_loop / c_floor, ``whole_floor_ratio`` = ours / c_floor.  Targets:
    ours the fastest; ours_loop under 0.2 us."""
    import tempfile
    from pathlib import Path

    import numpy as np

    from wmr_cosim import cosim
    from wmr_cosim.cosim.plan.ssp import export_ssp
    from wmr_cosim.cosim.stepping import native
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from interop import run_peer

    n = max(1, min(repeats, 5))
    signals = ["d.x", "f1.Float64_continuous_output", "f2.Float64_continuous_output"]
    walls: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        plan = cosim.resolve(cosim.load(_generic_scenario(tmp)))
        ssp = export_ssp(plan, Path(tmp) / "chain.ssp")
        stop, h = plan.scenario.stop, plan.scenario.step
        results = {}
        for _ in range(n):  # interleaved, so that a slow phase of the machine hits every master alike
            for peer in ("ours", "ours_python", "libcosim", "ecos", "ecos_pinned"):
                with stepping_loop(python=peer == "ours_python"):   # (ours: Gauss-Seidel)
                    r = run_peer("ours" if peer == "ours_python" else peer, ssp, stop, h, signals)
                walls.setdefault(peer, []).append(r["wall_s"])
                if peer.startswith("ours"):
                    walls.setdefault("ours_loop" if peer == "ours" else "ours_python_loop", []).append(r["loop_s"])
                results[peer] = r
            wall, loop_out = _fmpy_loop(plan)
            walls.setdefault("fmpy_loop", []).append(wall)
            floor = _c_floor(plan, tmp)
            if floor is not None:
                walls.setdefault("c_floor", []).append(floor[0])
    per = {k: round(statistics.median(v) / plan.n_steps / 3 * 1e6, 3) for k, v in walls.items()}
    ours = results["ours"]["signals"]
    same = all(np.array_equal(ours[s][1:], loop_out[:, j]) for j, s in enumerate(signals))  # (ours: + t0 row)
    same_python = all(np.array_equal(ours[s], results["ours_python"]["signals"][s]) for s in signals)
    same_floor = floor is not None and all(np.array_equal(ours[s][1:], floor[1][:, j]) for j, s in enumerate(signals))
    default = {k: v for k, v in per.items() if k not in ("ours_loop", "ours_python_loop", "c_floor", "ours_python")}
    lib, why = native.library()
    return {"us_per_fmu_step": per, "steps": plan.n_steps, "repeats": n,
            "loop": native.NATIVE if lib is not None else f"{native.PYTHON} ({why})",
            "floor_ratio": round(per["ours_loop"] / per["c_floor"], 2) if "c_floor" in per else None,
            "whole_floor_ratio": round(per["ours"] / per["c_floor"], 2) if "c_floor" in per else None,
            "ours_fastest": min(default, key=default.get) == "ours",
            "ours_equals_fmpy_loop": bool(same), "ours_equals_python_loop": bool(same_python),
            "ours_equals_c_floor": bool(same_floor),
            "libcosim_steps": results["libcosim"]["steps"], "ecos_steps": results["ecos"]["steps"]}


CONTAINER_STEPS = 1_000_000
CONTAINER_H = 1e-4
CONTAINER_EVERY = 1000     # the scenario's steps per step of the host
CONTAINER_G1_STOP = 10.0   # G1 cut to 5,000 steps of 2 ms
CONTAINER_G1_EVERY = 50
#: The chain's recorded outputs.
CONTAINER_OUTPUTS = ("d.x", "f1.Float64_continuous_output", "f2.Float64_continuous_output")


def _fmt_name(column: str) -> str:
    """What fmucontainer names an output (it exposes every linked output as a local variable named
    instance.variable, so an output of that name would be a second variable of one name)."""
    return column.replace(".", "_")


def _container_scenario(tmp: str, algorithm: str) -> Any:
    """The chain (:func:`_chain_scenario`), its connections without a factor or an offset (which neither of
    the other containers applies), CONTAINER_STEPS steps."""
    return _chain_scenario(tmp, f"chain_{algorithm.replace('-', '_')}.toml", CONTAINER_STEPS, CONTAINER_H, algorithm)


def _container_g1(tmp: str, algorithm: str) -> Any:
    """G1 (scenarios/g1_learn.toml: our three pythonfmu FMUs, no factor, offset or unit conversion between
    them, every output recorded: Real, Integer and Boolean) cut to CONTAINER_G1_STOP s."""
    from pathlib import Path

    path = Path(tmp) / f"g1_{algorithm.replace('-', '_')}.toml"
    g1 = Path(__file__).resolve().parents[1] / "scenarios" / "g1_learn.toml"
    path.write_text(f"base = {str(g1)!r}\n[experiment]\nstop = {CONTAINER_G1_STOP!r}\nalgorithm = {algorithm!r}\n")
    return path


def _start(var: Any, value: Any) -> str:
    """A start value as a model description writes it for the variable's type."""
    if var.type == "Boolean":
        return "true" if value else "false"
    if var.type == "Real":
        return repr(float(value))
    return str(int(value)) if var.type in ("Integer", "Enumeration") else str(value)


def _fmpy_container(plan: Any, out: Any, columns: list[str]) -> Any:
    """The system through FMPy's ``fmpy.container_fmu``, serial (``parallelDoStep`` false, the components in
    the plan's order; its results equal our Gauss-Seidel run's, measured), its outputs the recorded
    ``columns``, the FMI 2.0 container it builds, patched around its bugs: its work folder made
    before ``create_container_fmu`` deletes it (it deletes it unconditionally); the FMI 2 type names ``Real``
    and ``Integer`` that it writes for connections (which its own runtime refuses: ``Float64`` and ``Int32``
    expected) replaced in resources/container.json and the FMU zipped again; ``ModelStructure`` filled (it
    writes none otherwise); a variable ``time`` first, as its runtime reads value reference 0 as the time
    (value reference k as the k-th variable of its configuration: without it every variable reads the one
    before)."""
    import json
    import shutil
    import uuid
    from pathlib import Path

    from fmpy import read_model_description
    from fmpy.container_fmu import Configuration
    from fmpy.container_fmu.cli import create_container_fmu
    from fmpy.container_fmu.config import Component, Connection
    from fmpy.model_description import CoSimulation, DefaultExperiment, ModelDescription, ModelVariable, Unknown

    comps = {n: Component(name=n, filename=ip.model.path, modelDescription=read_model_description(str(ip.model.path)))
             for n, ip in plan.instances.items()}

    def var(inst: str, name: str) -> Any:
        return next(v for v in comps[inst].modelDescription.modelVariables if v.name == name)

    md = ModelDescription(fmiVersion="2.0", modelName="FmpySystem", instantiationToken="{" + str(uuid.uuid4()) + "}")
    md.coSimulation = CoSimulation(modelIdentifier="container_fmu", fixedInternalStepSize=plan.scenario.step)
    md.defaultExperiment = DefaultExperiment(startTime="0.0", stopTime=repr(plan.scenario.stop),
                                             stepSize=repr(plan.scenario.step))
    mappings: dict[Any, Any] = {}
    params = []
    for n, ip in plan.instances.items():
        for v, value in ip.parameters:
            inner = var(n, v.name)
            p = ModelVariable(name=f"{n}.{v.name}", type=inner.type, causality="parameter", variability="fixed",
                              initial="exact", start=_start(inner, value))
            mappings[p] = [(comps[n], inner)]
            params.append(p)
    outs = []
    for column in columns:
        inst, name = column.split(".", 1)
        inner = var(inst, name)
        o = ModelVariable(name=column, type=inner.type, causality="output",
                          variability="continuous" if inner.type == "Real" else "discrete", initial="calculated")
        mappings[o] = [(comps[inst], inner)]
        outs.append(o)
    time = ModelVariable(name="time", type="Real", causality="independent", variability="continuous")
    md.modelVariables = [time, *params, *outs]     # (patch: its runtime reads value reference 0 as the time)
    md.outputs = [Unknown(index=len(params) + i + 2, variable=o, dependencies=[]) for i, o in enumerate(outs)]
    md.initialUnknowns = list(md.outputs)
    conns = [Connection(comps[c.src], [var(c.src, c.src_var.name)], comps[c.dst], [var(c.dst, c.dst_var.name)])
             for c in plan.connections]
    config = Configuration(parallelDoStep=False, modelDescription=md, components=list(comps.values()),
                           connections=conns, variableMappings=mappings)
    work = Path(out).with_suffix(".d")
    work.mkdir()                              # (patch: it deletes the folder first)
    create_container_fmu(config, work, Path(out))
    cfg = work / "resources" / "container.json"
    data = json.loads(cfg.read_text())
    for c in data["connections"]:           # (patch: the FMI 3 type names its runtime reads)
        c["variableType"] = {"Real": "Float64", "Integer": "Int32"}.get(c["variableType"], c["variableType"])
    cfg.write_text(json.dumps(data, indent=4))
    Path(out).unlink()
    shutil.make_archive(str(work), "zip", work)
    shutil.rmtree(work)
    Path(str(work) + ".zip").replace(out)
    return Path(out)


def _fmucontainer(plan: Any, folder: Any, sequential: bool, columns: list[str]) -> Any:
    """The system through fmu-manipulation-toolbox's ``fmucontainer`` (its Python API, as its JSON input
    describes a container): the FMUs in the plan's order (``sequential``: each stepped after the one before,
    Gauss-Seidel; else on the outputs of the step before, Jacobi, in one thread), the parameters as start
    values, the recorded ``columns`` exposed under :func:`_fmt_name`'s names."""
    import logging
    import shutil
    from pathlib import Path

    from fmpy import read_model_description
    from fmu_manipulation_toolbox.assembly import AssemblyNode

    folder = Path(folder)
    name = f"Fmt{'Sequential' if sequential else 'Parallel'}.fmu"
    node = AssemblyNode(name, step_size=plan.scenario.step, sequential=sequential, auto_link=False, auto_input=False,
                        auto_output=False, auto_parameter=False)
    for n, ip in plan.instances.items():        # one file per instance: the instance takes the file's name
        if not (folder / f"{n}.fmu").is_file():
            shutil.copyfile(ip.model.path, folder / f"{n}.fmu")
        node.add_fmu(f"{n}.fmu")
        md = {v.name: v for v in read_model_description(str(ip.model.path)).modelVariables}
        for v, value in ip.parameters:
            node.add_start_value(f"{n}.fmu", v.name, _start(md[v.name], value))
    for c in plan.connections:
        node.add_link(f"{c.src}.fmu", c.src_var.name, f"{c.dst}.fmu", c.dst_var.name)
    for column in columns:
        inst, var = column.split(".", 1)
        node.add_output(f"{inst}.fmu", var, _fmt_name(column))
    logging.disable(logging.WARNING)            # (one line per unconnected port of the Reference FMUs)
    try:
        node.make_fmu(folder)
    finally:
        logging.disable(logging.NOTSET)
    return folder / name


#: Each container and the algorithm of the scenario whose run it must equal; FMPy's container_fmu (serial)
#: steps every FMU, then passes the connections in order, each read after the one before was set: Jacobi on
#: G1 (measured), Gauss-Seidel on the chain (whose Feedthrough FMUs pass an input set to their output at
#: once): it is compared with the run it equals (None), the other figures with their own.
CONTAINER_ALGORITHMS = {"ours_gauss_seidel": "gauss-seidel", "ours_jacobi": "jacobi", "fmpy_container_fmu": None,
                        "fmucontainer_sequential": "gauss-seidel", "fmucontainer_parallel": "jacobi"}


def _containers(n: int, work: Any, scenario: Any, every: int) -> dict[str, Any]:
    """One system (``scenario(tmp, algorithm)`` its file) through the five containers of
    CONTAINER_ALGORITHMS, run ``n`` times each, interleaved, in FMPy's simulate_fmu (its output interval
    ``every`` steps of the scenario's): the figures of :func:`bench_container`."""
    import time

    import numpy as np
    from fmpy import extract, simulate_fmu
    from fmpy.validation import validate_fmu

    from wmr_cosim import cosim
    from wmr_cosim.cli import main as cli
    from wmr_cosim.runner import resolve_model

    refs, fmus, build_s = {}, {}, {}
    for alg in ("gauss-seidel", "jacobi"):
        sc = scenario(str(work), alg)
        with contextlib.redirect_stdout(sys.stderr):   # (the last line of stdout is the figures)
            assert cli(["run", str(sc), "--out", str(work / f"run-{alg}"), "--quiet"]) == 0
        refs[alg] = np.load(work / f"run-{alg}" / "signals.npy")[::every]
        key = "ours_" + alg.replace("-", "_")
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(sys.stderr), contextlib.redirect_stderr(io.StringIO()):   # (its note)
            assert cli(["export-fmu", str(sc), "--out", str(work / f"Ours_{key}.fmu")]) == 0
        build_s[key] = time.perf_counter() - t0
        fmus[key] = work / f"Ours_{key}.fmu"
    columns = list(refs["jacobi"].dtype.names[1:])
    plan = cosim.resolve(cosim.load(scenario(str(work), "gauss-seidel"), resolve_model))
    t0 = time.perf_counter()
    fmus["fmpy_container_fmu"] = _fmpy_container(plan, work / "FmpySystem.fmu", columns)
    build_s["fmpy_container_fmu"] = time.perf_counter() - t0
    (work / "fmt").mkdir()
    for seq in (True, False):
        key = "fmucontainer_sequential" if seq else "fmucontainer_parallel"
        t0 = time.perf_counter()
        fmus[key] = _fmucontainer(plan, work / "fmt", seq, columns)
        build_s[key] = time.perf_counter() - t0
    problems = {k: len(validate_fmu(str(f))) for k, f in fmus.items()}
    dirs = {k: extract(str(f), unzipdir=str(work / f"x-{k}")) for k, f in fmus.items()}
    walls: dict[str, list[float]] = {k: [] for k in fmus}
    diffs: dict[str, dict[str, float]] = {}
    stop, interval = plan.scenario.stop, every * plan.scenario.step
    for _ in range(n):   # interleaved, so that a slow phase of the machine hits every container alike
        for key, d in dirs.items():
            t0 = time.perf_counter()
            res = simulate_fmu(d, stop_time=stop, output_interval=interval)
            walls[key].append(time.perf_counter() - t0)
            for alg, ref in refs.items():
                assert len(res) == len(ref), (key, len(res), len(ref))
                diffs.setdefault(alg, {})[key] = max(float(np.max(np.abs(
                    res[col if key.startswith(("ours", "fmpy")) else _fmt_name(col)].astype(float)
                    - ref[col].astype(float)))) for col in columns)
    wall = {k: round(statistics.median(v), 4) for k, v in walls.items()}
    algorithms = {k: a or min(diffs, key=lambda alg: diffs[alg][k]) for k, a in CONTAINER_ALGORITHMS.items()}
    ratios = {"ours_to_fmpy_container_fmu": wall["ours_" + algorithms["fmpy_container_fmu"].replace("-", "_")]
              / wall["fmpy_container_fmu"],
              "ours_to_fmucontainer_sequential": wall["ours_gauss_seidel"] / wall["fmucontainer_sequential"],
              "ours_to_fmucontainer_parallel": wall["ours_jacobi"] / wall["fmucontainer_parallel"]}
    other = {"gauss-seidel": "jacobi", "jacobi": "gauss-seidel"}
    return {"steps": plan.n_steps, "host_steps": plan.n_steps // every, "outputs": len(columns),
            "wall_s": wall, **{k: round(v, 3) for k, v in ratios.items()},
            "algorithm": algorithms, "max_abs_diff": {k: diffs[alg][k] for k, alg in algorithms.items()},
            "max_abs_diff_from_the_other_algorithm": {k: diffs[other[alg]][k] for k, alg in algorithms.items()},
            "build_s": {k: round(v, 3) for k, v in build_s.items()}, "validation_problems": problems,
            "ours_equal": diffs["gauss-seidel"]["ours_gauss_seidel"] == 0.0 and diffs["jacobi"]["ours_jacobi"] == 0.0}


def bench_container(repeats: int) -> dict[str, Any]:
    """Two systems, each exported as one FMU five ways and run in one host, FMPy's ``simulate_fmu`` (each FMU
    unpacked once beforehand): the chain of Reference C FMUs (Dahlquist -> Feedthrough -> Feedthrough,
    1,000,000 steps of 0.1 ms, output interval 1,000 steps; its figures at the top level) and ``g1`` (G1 cut
    to 10 s: our three pythonfmu FMUs, 56 outputs of three types, output interval 50 steps).  The five: ours
    (``export-fmu``; Gauss-Seidel and Jacobi), FMPy's ``container_fmu`` (serial: Gauss-Seidel here; patched,
    see _fmpy_container) and fmu-manipulation-toolbox's ``fmucontainer`` (sequential: Gauss-Seidel; parallel
    in one thread: Jacobi).  wall_s: the median of interleaved runs of each (instantiation, initialisation,
    stepping and the host's recording); max_abs_diff: each one's largest difference from ``wmr-cosim run`` of
    the scenario of its algorithm, over every output at every host step (ours must be 0.0); ours_to_*: our
    wall time over theirs, for the same algorithm (target <= 1)."""
    import importlib.metadata
    import tempfile
    from pathlib import Path

    n = max(1, repeats)
    out: dict[str, Any] = {}
    for key, scenario, every in (("chain", _container_scenario, CONTAINER_EVERY),
                                 ("g1", _container_g1, CONTAINER_G1_EVERY)):
        with tempfile.TemporaryDirectory(prefix="wmr-bench-") as tmp:
            out[key] = _containers(n, Path(tmp), scenario, every)
    chain = out.pop("chain")
    return {**chain, "repeats": n, "g1": out["g1"],
            "ours_equal": chain["ours_equal"] and out["g1"]["ours_equal"],
            "versions": {d: importlib.metadata.version(d) for d in ("fmpy", "fmu-manipulation-toolbox")}}


def bench_archive(repeats: int) -> dict[str, float]:
    """The archive checks on our three FMUs (median of ``repeats``, summed over the three): from the directory
    only, with every entry decompressed and counted (what loading a model does), and the extraction; and the
    refusal of a lying bomb (256 MiB of zeros declared as 1 KiB)."""
    import shutil
    import struct
    import tempfile
    import time
    import zipfile
    from pathlib import Path

    from wmr_cosim.cosim.model.archive import check_archive, safe_extract
    from wmr_cosim.cosim.messages.errors import FmuLoadError
    from wmr_cosim.runner import resolve_model

    fmus = [resolve_model(m) for m in ("WmrPlant", "WmrSensor", "WmrController")]

    def timed(fn) -> float:
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return statistics.median(ts)

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)

        def extract_all() -> None:
            for i, f in enumerate(fmus):
                safe_extract(f, tmp / f"x{i}")
            for i in range(len(fmus)):
                shutil.rmtree(tmp / f"x{i}")

        figures = {"fmu_mb": round(sum(f.stat().st_size for f in fmus) / 1e6, 3),
                   "check_directory_ms": round(1e3 * timed(lambda: [check_archive(f, verify=False) for f in fmus]), 3),
                   "check_verify_ms": round(1e3 * timed(lambda: [check_archive(f) for f in fmus]), 3),
                   "extract_ms": round(1e3 * timed(extract_all), 3)}
        bomb = tmp / "bomb.fmu"
        with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", "<fmiModelDescription/>")
            with zf.open("zeros.bin", "w", force_zip64=True) as fh:
                for _ in range(256):
                    fh.write(bytes(1024**2))
        data = bytearray(bomb.read_bytes())
        for sig, size_at in ((b"PK\x01\x02", 24),):
            i = data.rfind(sig)
            struct.pack_into("<I", data, i + size_at, 1024)
        bomb.write_bytes(bytes(data))

        def refuse() -> None:
            try:
                safe_extract(bomb, tmp / "b")
            except FmuLoadError:
                return
            raise AssertionError("the bomb was extracted")

        figures["bomb_mb"] = round(bomb.stat().st_size / 1e6, 3)
        figures["lying_bomb_refused_ms"] = round(1e3 * timed(refuse), 3)
        figures["nothing_left"] = not (tmp / "b").exists()
    return figures


def bench_binary(repeats: int) -> dict[str, float]:
    """The reading of an FMU's binary (cosim/model/binary.py, what ``check`` and ``info`` do with a
    stranger's archive) on ELF files of 10,000 and 100,000 exported symbols: named ones (the FMI functions
    among them), and ones whose names all begin in the first 1 MB of a string table with no terminator
    before the FMI functions' names at its end (what made the reader that read each name quadratic:
    minutes at 100,000).  Median of ``repeats`` [ms]: each takes about 10 times as long for 10 times the
    symbols (linear)."""
    import time
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from elf_files import elf_file
    from wmr_cosim.cosim.model.binary import library_problem

    def timed(data: bytes) -> float:
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            library_problem(data, 2, "co-simulation", "linux")
            ts.append(time.perf_counter() - t0)
        return round(1e3 * statistics.median(ts), 3)

    figures: dict[str, float] = {}
    for n in (10_000, 100_000):
        names = b"\0" + b"".join(b"sym_%d\0" % i for i in range(n)) + b"fmi2Instantiate\0fmi2DoStep\0"
        starts = [1 + i for i, c in enumerate(names[1:]) if names[i] == 0][:n + 2]
        named = elf_file(names, [(at, 5) for at in starts])
        assert library_problem(named, 2, "co-simulation", "linux") is None
        figures[f"named_{n}_ms"] = timed(named)
        long = b"x" * 1_000_000 + b"\0fmi2Instantiate\0fmi2DoStep\0"
        figures[f"unterminated_{n}_ms"] = timed(elf_file(long, [(i * 10, 5) for i in range(n)] +
                                                         [(1_000_001, 5), (1_000_017, 5)]))
    return figures


#: The runs of the isolation benchmark: (scenario, ("instance" isolated | "*" every one | None), the child
#: that serves an isolated C FMU ("c" or "python")); the Reference FMUs' run is made by _reference_plan.
ISOLATION_RUNS: dict[str, tuple[str, str | None, str]] = {
    "none": ("g1_learn.toml", None, "c"), "plant": ("g1_learn.toml", "plant", "c"), "all": ("g1_learn.toml", "*", "c"),
    "c_none": ("g1_c_plant.toml", None, "c"), "c_plant": ("g1_c_plant.toml", "plant", "c"),
    "c_plant_py": ("g1_c_plant.toml", "plant", "python"),
    "ref_none": ("reference", None, "c"), "ref_c": ("reference", "d", "c"), "ref_py": ("reference", "d", "python")}


def _reference_plan(isolated: str | None) -> Any:
    """Dahlquist into Feedthrough (the Reference FMUs, FMI 2.0, C), 25,000 steps of 2 ms, both recorded;
    ``isolated``: the instance isolated (d, Dahlquist)."""
    from pathlib import Path

    from wmr_cosim import cosim
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from reference_fmus import fmu

    doc = {"experiment": {"start": 0.0, "stop": 50.0, "step": 0.002},
           "instances": {"d": {"fmu": str(fmu("fmi2", "Dahlquist")), "isolate": isolated == "d"},
                         "f": {"fmu": str(fmu("fmi2", "Feedthrough")), "isolate": isolated == "f"}},
           "connections": [{"from": "d.x", "to": "f.Float64_continuous_input"}],
           "record": {"variables": ["d.x", "f.Float64_continuous_output"]}}
    return cosim.resolve(cosim.parse(doc, "reference.toml"))


def _isolation_run(kind: str) -> Any:
    """One run of ISOLATION_RUNS[kind]: its result (failed runs end the benchmark)."""
    from wmr_cosim import cosim
    from wmr_cosim.runner import resolve_model

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    scenario, isolated, child = ISOLATION_RUNS[kind]
    if scenario == "reference":
        plan = _reference_plan(isolated)
    else:
        sc = cosim.load(root / "scenarios" / scenario, resolve_model)
        sc.record = ANALYSIS_RECORD
        plan = cosim.resolve(sc)
        for n, ip in plan.instances.items():
            ip.spec.isolate = isolated == "*" or isolated == n
    os.environ["WMR_COSIM_CHILD"] = child
    try:
        r = cosim.run(plan, None, progress=False)
    finally:
        os.environ.pop("WMR_COSIM_CHILD", None)
    if r.status != "ok":
        raise SystemExit(f"{kind}: {r.message}")
    return r


def _isolation_walls(repeats: int) -> tuple[dict[str, float], dict[str, dict], dict[str, dict[str, int]]]:
    """Each run of ISOLATION_RUNS, interleaved: the median wall [s] of each, its final values, and how the
    isolated runs' hand-off waited (steps spun and blocked, summed over the runs)."""
    walls: dict[str, list[float]] = {k: [] for k in ISOLATION_RUNS}
    finals: dict[str, dict] = {}
    waits: dict[str, dict[str, int]] = {k: {} for k, run in ISOLATION_RUNS.items() if run[1] is not None}
    for _ in range(max(1, repeats)):
        for kind in walls:
            r = _isolation_run(kind)
            walls[kind].append(r.wall_s)
            finals[kind] = r.final
            for mode, n in (r.summary.get("handoff") or {}).get("steps", {}).items():
                waits[kind][mode] = waits[kind].get(mode, 0) + n
    return {k: statistics.median(v) for k, v in walls.items()}, finals, waits


def bench_isolation(repeats: int) -> dict[str, Any]:
    """G1 (50 s, Gauss-Seidel, the analysis record) in process, with the plant isolated and with all three
    FMUs isolated (each in a child process); G1 with the C plant (WmrCPlant) in process and isolated, served
    by the C child (c_plant) and by the Python child (c_plant_py); the Reference FMUs Dahlquist into
    Feedthrough (25,000 steps) in process and with Dahlquist isolated, C child (ref_c) and Python child
    (ref_py); interleaved, medians; on a quiet machine, then beside one and beside two CPU-bound processes
    of its own (a busy loop, as a user's other work would be): isolated_us_per_fmu_step_overhead =
    (isolated wall - in-process wall) / steps / isolated FMUs (targets: the plant under 10 us quiet and
    under 60 us beside one busy process; a C FMU with the C child under 5 us quiet and under 40 us beside
    one); handoff: the steps whose answer the master waited for spinning and blocking; same_results (bit
    for bit, in every run, with each scenario's run in process)."""
    import subprocess

    steps = 25_000
    out: dict[str, Any] = {}
    finals: list[dict[str, dict]] = []
    for load, burners in (("quiet", 0), ("loaded_1", 1), ("loaded_2", 2)):
        busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(burners)]
        try:
            med, fin, waits = _isolation_walls(repeats)
        finally:
            for b in busy:
                b.kill()
                b.wait()
        finals.append(fin)

        def over(kind: str, base: str, n: int = 1) -> float:
            return round((med[kind] - med[base]) / steps / n * 1e6, 2)
        out[load] = {"us_per_step": {k: round(v / steps * 1e6, 2) for k, v in med.items()},
                     "isolated_us_per_fmu_step_overhead": {
                         "plant": over("plant", "none"), "all": over("all", "none", 3),
                         "c_plant": over("c_plant", "c_none"), "c_plant_py": over("c_plant_py", "c_none"),
                         "ref_c": over("ref_c", "ref_none"), "ref_py": over("ref_py", "ref_none")},
                     "handoff": waits}
    loads = ("quiet", "loaded_1", "loaded_2")
    over_ = {k: out[k]["isolated_us_per_fmu_step_overhead"]["plant"] for k in loads}
    c_over = {k: {c: out[k]["isolated_us_per_fmu_step_overhead"][c] for c in ("c_plant", "ref_c")} for k in loads}
    out["plant_overhead_us"] = over_
    out["quiet_under_10us"] = over_["quiet"] < 10.0
    out["loaded_1_under_60us"] = over_["loaded_1"] < 60.0
    out["c_fmu_overhead_us"] = c_over
    out["c_quiet_under_5us"] = all(v < 5.0 for v in c_over["quiet"].values())
    out["c_loaded_1_under_40us"] = all(v < 40.0 for v in c_over["loaded_1"].values())
    groups = {"none": ("none", "plant", "all"), "c_none": ("c_none", "c_plant", "c_plant_py"),
              "ref_none": ("ref_none", "ref_c", "ref_py")}
    out["same_results"] = all(f[k] == finals[0][ref] for f in finals for ref, ks in groups.items() for k in ks)
    out["cores"] = os.cpu_count()
    out["repeats"] = max(1, repeats)
    return out


def bench_loader(repeats: int) -> dict[str, float]:
    """The same sensor FMU through our loader and through pythonfmu's binary itself, in one process."""
    import ctypes
    import shutil
    import tempfile
    import time
    from pathlib import Path

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from wmr_cosim.fmus.build import REAL_BINARY
    from wmr_cosim.runner import resolve_model

    fmu = resolve_model("WmrSensor")
    n = 25000
    with tempfile.TemporaryDirectory() as tmp:
        md = read_model_description(str(fmu))
        dirs = {"via_loader": Path(extract(str(fmu), unzipdir=str(Path(tmp) / "loader"))),
                "direct": Path(extract(str(fmu), unzipdir=str(Path(tmp) / "direct")))}
        lib = dirs["direct"] / "binaries" / "linux64"
        shutil.copyfile(lib / REAL_BINARY, lib / "WmrSensor.so")  # pythonfmu's binary under the model's name
        ins = [v.valueReference for v in md.modelVariables if v.causality == "input"]
        outs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]
        runs = {}
        for key, d in dirs.items():
            f = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="WmrSensor", instanceName=key)
            f.instantiate(loggingOn=False)
            if key == "direct":  # this host does what the loader does: release pythonfmu's (empty) PyState,
                f.dll.finalizePythonInterpreter()  # or the process corrupts its heap at exit (wmr_pyfinder.h)
            f.setupExperiment(startTime=0.0)
            f.enterInitializationMode()
            f.exitInitializationMode()
            runs[key] = f
        best = {k: float("inf") for k in runs}
        t_step = 0
        for r in range(max(3, repeats)):
            for key, f in (list(runs.items()) if r % 2 == 0 else list(runs.items())[::-1]):  # alternate the order
                dll, c = f.dll, ctypes.c_void_p(f.component)
                set_real, do_step, get_real = dll.fmi2SetReal, dll.fmi2DoStep, dll.fmi2GetReal
                vin = (ctypes.c_uint * len(ins))(*ins)
                vout = (ctypes.c_uint * len(outs))(*outs)
                xin = (ctypes.c_double * len(ins))()
                xout = (ctypes.c_double * len(outs))()
                h = ctypes.c_double(0.002)
                t0 = time.perf_counter()
                for k in range(t_step, t_step + n):
                    xin[0] = xin[1] = 0.001 * k
                    set_real(c, vin, len(ins), xin)
                    do_step(c, ctypes.c_double(k * 0.002), h, 1)
                    get_real(c, vout, len(outs), xout)
                best[key] = min(best[key], time.perf_counter() - t0)
            t_step += n
        for f in runs.values():
            f.terminate()
            f.freeInstance()
    us = {k: v / n * 1e6 for k, v in best.items()}
    return {"steps": n, "rounds": max(3, repeats), "via_loader_us_per_step": round(us["via_loader"], 3),
            "direct_us_per_step": round(us["direct"], 3),
            "loader_overhead": round(us["via_loader"] / us["direct"] - 1.0, 4)}


_EXIT_RUN = r"""
import shutil, sys
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi3 import FMU3Slave
path = sys.argv[1]
for _ in range(3):
    simulate_fmu(path, stop_time=0.1, output_interval=0.002)
md = read_model_description(path)
d = extract(path)
for i in range(30):
    s = FMU3Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=f"i{i}")
    s.instantiate()
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.doStep(0.0, 0.002)
    s.terminate()
    s.freeInstance()
shutil.rmtree(d)
"""

_LOAD_FREE_EXIT = r"""
import shutil, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave
md = read_model_description(sys.argv[1])
d = extract(sys.argv[1])
cls = FMU3Slave if md.fmiVersion.startswith("3") else FMU2Slave
s = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
s.instantiate()
s.freeInstance()
shutil.rmtree(d)
"""


def bench_exit(repeats: int) -> dict[str, Any]:
    """Exit statuses of plain FMPy scripts on the FMI 3.0 FMUs; valgrind's invalid accesses per FMU."""
    import os
    import re
    import shutil
    import subprocess
    import tempfile
    from pathlib import Path

    from wmr_cosim.fmus import cplant_build
    from wmr_cosim.fmus.build import FMI_VERSION, build_all

    fmus = build_all(models=tuple(FMI_VERSION))
    runs: dict[str, int] = {}
    invalid: dict[str, int] | None = None
    with tempfile.TemporaryDirectory(prefix="wmr_bench_exit_") as tmp:
        env = {**{k: v for k, v in os.environ.items() if k != "PYTHONPATH"}, "TMPDIR": tmp,
               "PYTHONHASHSEED": "random"}
        for model in ("WmrPlant3", "WmrSensor3", "WmrController3"):
            runs[model] = sum(subprocess.run([sys.executable, "-c", _EXIT_RUN, str(fmus[model])], env=env,
                                             capture_output=True, timeout=600).returncode == 0 for _ in range(50))
        valgrind = shutil.which("valgrind")
        if valgrind:
            fmus["WmrCPlant"] = cplant_build.build_c_plant(Path(tmp) / "cplant")
            supp = Path(tmp) / "ldso.supp"   # glibc's SSE2 strncmp reading past a string in ld.so: not an error
            supp.write_text("{\n   ld.so is_dst\n   Memcheck:Addr8\n   fun:strncmp\n   fun:is_dst\n}\n")
            invalid = {}
            for model, path in fmus.items():
                log = Path(tmp) / f"{model}.valgrind"
                subprocess.run([valgrind, "--quiet", f"--suppressions={supp}", f"--log-file={log}", sys.executable,
                                "-c", _LOAD_FREE_EXIT, str(path)], env={**env, "PYTHONMALLOC": "malloc"},
                               capture_output=True, timeout=1200)
                invalid[model] = len(re.findall(r"Invalid (?:read|write|free)", log.read_text()))
    return {"exit_runs": {m: f"{n} of 50" for m, n in runs.items()}, "valgrind_invalid": invalid}


def bench_scripting(repeats: int) -> dict[str, float]:
    """What scripting costs per step on G1 (25,000 steps, the analysis' recording), medians of interleaved
    runs through the Python API: no hooks (the generated loop in long segments), a callback doing
    nothing, a callback reading one variable with Run.get, a condition event that never fires."""
    from wmr_cosim import Simulation

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    sim = Simulation.load(root / "scenarios" / "g1_learn.toml")
    sim.document["record"] = {"variables": ANALYSIS_RECORD, "csv": False}
    cond = Simulation(sim.document).event(when="plant.x_A < -100 and t > 1", action="stop")
    kinds = {"plain": lambda: sim.run(), "noop_callback": lambda: sim.run(on_step=lambda r: None),
             "get_callback": lambda: sim.run(on_step=lambda r: r.get("plant.x_A")),
             "condition": lambda: cond.run()}
    walls: dict[str, list[float]] = {k: [] for k in kinds}
    steps = 0
    for _ in range(repeats):
        for k, fn in kinds.items():
            r = fn()
            walls[k].append(r.summary["wall_s"])
            steps = r.steps
    us = {k: statistics.median(v) / steps * 1e6 for k, v in walls.items()}
    out = {f"{k}_us_per_step": round(v, 2) for k, v in us.items()}
    out.update({f"{k}_overhead_us_per_step": round(us[k] - us["plain"], 2) for k in kinds if k != "plain"})
    out["steps"] = steps
    return out


def bench_live(repeats: int) -> dict[str, Any]:
    """A run served live (wmr_cosim.live) against the same run plain, as fast as possible (see the module's
    docstring): interleaved plain, live without a client and live with a client reading the stream."""
    import threading
    import time as _time

    from websockets.sync.client import connect

    from wmr_cosim import Simulation
    from wmr_cosim.cosim import run as cosim_run
    from wmr_cosim.live import LiveOptions, run_live

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    sim = Simulation.load(root / "scenarios" / "g1_learn.toml")
    sim.document["record"] = {"variables": ANALYSIS_RECORD, "csv": False}
    plan = sim.check()
    received: list[int] = []

    def client(url: str) -> None:
        """Read the stream to its end (started once the server listens)."""
        def read() -> None:
            n = 0
            with connect(url.replace("http://", "ws://").rstrip("/") + "/api/stream", open_timeout=30) as ws:
                while json.loads(ws.recv())["type"] != "end":
                    n += 1
            received.append(n)
        threading.Thread(target=read, daemon=True).start()

    def timed(fn: Any) -> float:
        t0 = _time.perf_counter()
        r = fn()
        assert str(r.status) == "ok", r.message
        return _time.perf_counter() - t0

    kinds = {"plain": lambda: cosim_run(plan, None, progress=False),
             "live": lambda: run_live(plan, None, LiveOptions(), announce=lambda url: None),
             "live_client": lambda: run_live(plan, None, LiveOptions(), announce=client)}
    walls: dict[str, list[float]] = {k: [] for k in kinds}
    timed(kinds["plain"])   # (the FMUs built and cached, the loop compiled)
    for _ in range(max(3, repeats)):
        for k, fn in kinds.items():
            walls[k].append(timed(fn))
    med = {k: statistics.median(v) for k, v in walls.items()}
    return {"steps": plan.n_steps, "repeats": max(3, repeats), "plain_s": round(med["plain"], 3),
            "live_s": round(med["live"], 3), "live_client_s": round(med["live_client"], 3),
            "rows_received": int(statistics.median(received)) if received else 0,
            "overhead_no_client": round(med["live"] / med["plain"] - 1, 4),
            "overhead": round(med["live_client"] / med["plain"] - 1, 4)}


def bench_requirements(repeats: int) -> dict[str, Any]:
    """What monitoring requirements costs per step on G1 on foam (scenarios/g1_requirements.toml, 25,000
    steps, the analysis' recording), medians of interleaved runs through the Python API: without its
    requirements, with its three (torque, goal, tracking), and with the tracking one looking ahead 5 s
    (``always (|e| > 0.5 rad implies eventually[0,5] |e| < 0.05 rad)``: a window of 2,500 steps); and the
    monitor alone on those recorded signals (requirements.monitor.evaluate, no co-simulation)."""
    import time as _time

    import numpy as np

    from wmr_cosim import Simulation
    from wmr_cosim.cosim.model.units import KNOWN
    from wmr_cosim.cosim.requirements.formula import VarInfo, check
    from wmr_cosim.cosim.requirements.monitor import evaluate

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    base = Simulation.load(root / "scenarios" / "g1_requirements.toml")
    base.document["record"] = {"variables": ANALYSIS_RECORD, "csv": False}
    plain = Simulation({k: v for k, v in base.document.items() if k != "requirements"})
    ahead = Simulation({k: v for k, v in base.document.items() if k != "requirements"}).require(
        "settle", "always (abs(controller.e1) > 0.5 rad implies eventually[0,5] abs(controller.e1) < 0.05 rad)")
    kinds = {"plain": plain.run, "three": base.run, "look_ahead": ahead.run}
    walls: dict[str, list[float]] = {k: [] for k in kinds}
    steps, last = 0, None
    for _ in range(repeats):
        for k, fn in kinds.items():
            r = fn()
            walls[k].append(r.summary["wall_s"])
            steps = r.steps
            if k == "three":
                last = r
    us = {k: statistics.median(v) / steps * 1e6 for k, v in walls.items()}
    out: dict[str, Any] = {f"{k}_us_per_step": round(v, 2) for k, v in us.items()}
    out.update({f"{k}_overhead_us_per_step": round(us[k] - us["plain"], 2) for k in kinds if k != "plain"})
    assert last is not None
    sig = last.signals
    info = {n: VarInfo("Real", KNOWN["rad"] if n.endswith(("e1", "e2")) else KNOWN["N.m"])
            for n in ("controller.e1", "controller.e2", "controller.u1", "controller.u2")}
    alone = {}
    for name, text in (("tracking", "always[10,30] (abs(controller.e1) < 0.05 rad and abs(controller.e2) < 0.05 rad)"),
                       ("look_ahead", "always (abs(controller.e1) > 0.5 rad implies eventually[0,5] "
                                      "abs(controller.e1) < 0.05 rad)")):
        checked = check(text, info, 0.002, 50.0)
        t0 = _time.perf_counter()
        evaluate(name, checked, sig["time"], {n: np.asarray(sig[n]) for n in checked.variables}, 0.002)
        alone[name] = (_time.perf_counter() - t0) / len(sig) * 1e6
    out.update({f"monitor_{k}_us_per_sample": round(v, 2) for k, v in alone.items()})
    out["steps"] = steps
    return out


def bench_mutation(repeats: int) -> dict:
    """Mutation testing of components/, cosim/ and the analysis code (benchmarks/mutation.py)."""
    import mutation

    return mutation.run()


def bench_bugs(repeats: int) -> dict:
    """Bugs of the kinds mutmut does not make, a sample of 60 (benchmarks/bug_kinds.py)."""
    import bug_kinds

    return bug_kinds.run(sample=60, seed=1)


def bench_me(repeats: int) -> dict[str, Any]:
    """G1 (50 s learning run, Gauss-Seidel, the analysis record) with the C plant through its co-simulation
    interface and through its Model Exchange one under the master's CVODE and RK4 (1 ms steps, the
    co-simulation interface's own), runs interleaved: us_per_step of each (medians), me_cvode_to_cs and
    me_rk4_to_cs, and the final pose's distance from the co-simulation plant's [m]."""
    import numpy as np

    from wmr_cosim import cosim
    from wmr_cosim.runner import resolve_model

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    plans = {}
    for key, file, fields in (("cs", "g1_c_plant.toml", {}), ("me_cvode", "g1_c_plant_me.toml", {}),
                              ("me_rk4", "g1_c_plant_me.toml", {"solver": "rk4", "max_step": 0.001})):
        sc = cosim.load(root / "scenarios" / file, resolve_model)
        sc.record = ANALYSIS_RECORD
        for k, v in fields.items():
            setattr(sc.instances["plant"], k, v)
        plans[key] = cosim.resolve(sc)
    walls: dict[str, list[float]] = {k: [] for k in plans}
    final: dict[str, Any] = {}
    with __import__("tempfile").TemporaryDirectory() as tmp:
        for r in range(repeats):
            for key, plan in plans.items():
                out = __import__("pathlib").Path(tmp) / f"{key}_{r}"
                res = cosim.run(plan, out, progress=False)
                if res.status != "ok":
                    raise SystemExit(f"G1 ({key}) failed: {res.message}")
                walls[key].append(res.wall_s)
                sig = np.load(out / "signals.npy")
                final[key] = np.array([sig["plant.x_A"][-1], sig["plant.y_A"][-1]])
    n = plans["cs"].n_steps
    us = {k: statistics.median(w) / n * 1e6 for k, w in walls.items()}
    return {"steps": n, "cs_us_per_step": round(us["cs"], 2), "me_cvode_us_per_step": round(us["me_cvode"], 2),
            "me_rk4_us_per_step": round(us["me_rk4"], 2), "me_cvode_to_cs": round(us["me_cvode"] / us["cs"], 3),
            "me_rk4_to_cs": round(us["me_rk4"] / us["cs"], 3),
            "me_cvode_pose_diff_m": float(np.linalg.norm(final["me_cvode"] - final["cs"])),
            "me_rk4_pose_diff_m": float(np.linalg.norm(final["me_rk4"] - final["cs"]))}


def bench_adaptive(repeats: int) -> dict[str, Any]:
    """The step-size control against the fixed step on the two-mass oscillator with a stiff contact (see
    the module's docstring)."""
    import tempfile
    from pathlib import Path

    import numpy as np
    from scipy.integrate import solve_ivp

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from coupling_fmus import TwoMass, build_mass, two_mass_document

    from wmr_cosim import cosim
    from wmr_cosim.cosim.stepping import table as algorithms
    from wmr_cosim.cosim.stepping.generated import GaussSeidel
    from wmr_cosim.cosim.stepping.settings import AdaptiveSpec, IterationSpec
    from wmr_cosim.cosim.stepping.iterated import Iterated

    tm = TwoMass(x1=0.0, v1=3.0, kk=1e4, gap=0.05, h_int=1e-5)
    stop, interval = 2.0, 0.01
    linear = IterationSpec("newton", inputs="linear")
    grid = np.arange(round(stop / interval) + 1) * interval
    ode = solve_ivp(tm.rhs, (0.0, stop), [tm.x1, tm.v1, tm.x2, tm.v2], method="DOP853", rtol=1e-12, atol=1e-12,
                    dense_output=True, max_step=1e-3).sol(grid).T
    figures: dict[str, Any] = {"contact_fraction": float(np.mean(ode[:, 0] - ode[:, 2] > tm.gap))}
    with tempfile.TemporaryDirectory() as tmp:
        fmus = build_mass(Path(tmp) / "fmu")
        runs = [0]

        def run(alg: Any, step: float) -> tuple[np.ndarray, Any]:
            plan = cosim.resolve(cosim.parse(two_mass_document(fmus, tm, stop=stop, step=step), "two.toml"))
            runs[0] += 1
            out = Path(tmp) / f"run{runs[0]}"
            res = cosim.run(plan, out, progress=False, algorithm=alg)
            if res.status != "ok":
                raise SystemExit(f"the two-mass run failed: {res.message}")
            sig = np.load(out / "signals.npy")
            k = np.round(sig["time"] / interval)
            on_grid = sig[np.abs(sig["time"] - k * interval) < 1e-9]
            return on_grid, res

        ref, _ = run(Iterated(linear), 1e-5)
        z_ref = np.column_stack([ref["body.x"], ref["coupler.x"]])
        figures["ref_to_ode_m"] = float(np.max(np.abs(z_ref - ode[:, [0, 2]])))

        def error(sig: np.ndarray) -> float:
            return float(np.max(np.abs(np.column_stack([sig["body.x"], sig["coupler.x"]]) - z_ref)))

        for key, accuracy, fixed, coupling in (("gs", 1e-2, GaussSeidel, "gauss-seidel"),
                                               ("iterated", 1e-4, lambda: Iterated(linear), "iterated")):
            figures[f"{key}_accuracy_m"] = accuracy
            for k in range(12):
                h = interval / 2 ** k
                sig, res = run(fixed(), h)
                if error(sig) <= accuracy:
                    break
            steps = round(stop / h)
            figures[f"{key}_fixed_step_s"] = h
            figures[f"{key}_fixed_steps"] = steps
            figures[f"{key}_fixed_error_m"] = float(f"{error(sig):.4g}")
            st = res.summary.get("stepping") or {}
            figures[f"{key}_instance_steps_fixed"] = st.get("instance_steps", 2 * steps)
            figures[f"{key}_wall_s_fixed"] = round(res.wall_s, 3)
            for k in range(2, 9):
                tol = 10.0 ** -k
                spec = AdaptiveSpec(rtol=tol, atol=tol, coupling=coupling)
                sig, res = run(algorithms.make("adaptive", linear, spec), interval)
                if error(sig) <= accuracy:
                    break
            st = res.summary["stepping"]
            figures[f"{key}_adaptive_tolerance"] = tol
            figures[f"{key}_adaptive_accepted"] = st["accepted_steps"]
            figures[f"{key}_adaptive_rejected"] = st["rejected_steps"]
            figures[f"{key}_adaptive_error_m"] = float(f"{error(sig):.4g}")
            figures[f"{key}_adaptive_smallest_step_s"] = float(f"{st['smallest_step']:.4g}")
            figures[f"{key}_instance_steps_adaptive"] = st["instance_steps"]
            figures[f"{key}_wall_s_adaptive"] = round(res.wall_s, 3)
            figures[f"{key}_steps_ratio"] = round((st["accepted_steps"] + st["rejected_steps"]) / steps, 4)
            figures[f"{key}_steps_ratio_within_third"] = bool(figures[f"{key}_steps_ratio"] <= 1.0 / 3.0)
            figures[f"{key}_reached"] = bool(figures[f"{key}_adaptive_error_m"] <= accuracy
                                             and figures[f"{key}_fixed_error_m"] <= accuracy)
    return figures


def bench_parallel(repeats: int) -> dict[str, Any]:
    """Parallel Jacobi against serial Jacobi (see the module's docstring): probes that burn 1 ms and 50 us
    of CPU a step, 2 and 4 of them, in this process (stepped in threads) and in child processes; Gauss-Seidel
    by levels against serial Gauss-Seidel over two independent chains of 1 ms probes."""
    import tempfile
    from pathlib import Path

    import numpy as np

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from c_fmu_support import build_probe

    from wmr_cosim import cosim

    figures: dict[str, Any] = {}

    def against_serial(doc: dict[str, Any], n: int, steps: int, key: str, tmp: str) -> None:
        """``doc`` run with workers = 1 and n, interleaved: the figures of ``key``."""
        walls: dict[int, list[float]] = {1: [], n: []}
        rows: dict[int, bytes] = {}
        for r in range(max(1, repeats)):
            for w in (1, n) if r % 2 == 0 else (n, 1):
                doc["experiment"]["workers"] = w
                plan = cosim.resolve(cosim.parse(doc, "parallel.toml"))
                out = Path(tmp) / f"{key}w{w}r{r}"
                res = cosim.run(plan, out, progress=False)
                if res.status != "ok":
                    raise SystemExit(f"parallel bench ({key}, workers = {w}): {res.message}")
                walls[w].append(res.wall_s)
                rows[w] = np.load(out / "signals.npy").tobytes()
        serial, par = (statistics.median(walls[w]) / steps * 1e6 for w in (1, n))
        figures[f"us_per_step_serial_{key}"] = round(serial, 2)
        figures[f"us_per_step_{key}"] = round(par, 2)
        figures[f"speedup_{key}"] = round(serial / par, 3)
        figures[f"same_results_{key}"] = rows[1] == rows[n]

    with tempfile.TemporaryDirectory() as tmp:
        for burn, label, steps in ((1000, "1ms", 1000), (50, "50us", 4000)):
            probe = build_probe(Path(tmp) / f"fmu{burn}", "Burn", BURN_US=burn)
            for kind in ("threads", "isolated"):
                for n in (2, 4):
                    names = [f"p{i}" for i in range(n)]
                    doc = {"experiment": {"start": 0.0, "stop": steps * 0.001, "step": 0.001, "algorithm": "jacobi"},
                           "instances": {m: {"fmu": str(probe), "isolate": kind == "isolated"} for m in names},
                           "connections": [{"from": f"{a}.y", "to": f"{b}.u"} for a, b in zip(names, names[1:])],
                           "record": {"variables": [f"{m}.y" for m in names]}}
                    against_serial(doc, n, steps, f"{kind}_{n}_{label}", tmp)
            if burn == 1000:   # Gauss-Seidel: two independent chains a0 -> a1, b0 -> b1, by levels, in threads
                names = ["a0", "b0", "a1", "b1"]
                doc = {"experiment": {"start": 0.0, "stop": steps * 0.001, "step": 0.001,
                                      "algorithm": "gauss-seidel", "order": names},
                       "instances": {m: {"fmu": str(probe)} for m in names},
                       "connections": [{"from": "a0.y", "to": "a1.u"}, {"from": "b0.y", "to": "b1.u"}],
                       "record": {"variables": [f"{m}.y" for m in names]}}
                against_serial(doc, 2, steps, f"threads_gauss_seidel_2_chains_{label}", tmp)
    figures["cores"] = __import__("os").cpu_count()
    return figures


#: Options of the benchmarks that take more than --repeats (set by main).
OPTIONS: dict[str, Any] = {}


def bench_contract(repeats: int) -> dict[str, Any]:
    """The contract harness's long run (benchmarks/contract.py): --budget seconds over its targets."""
    import contract

    return contract.run(OPTIONS.get("budget") or 600.0, OPTIONS.get("targets"))


BENCHES = {"generic": bench_generic, "container": bench_container, "loop": bench_loop_all, "fmi3": bench_fmi3, "paper": bench_paper,
           "sweep": bench_sweep, "interop": bench_interop, "archive": bench_archive, "binary": bench_binary,
           "loader": bench_loader,
           "isolation": bench_isolation, "scripting": bench_scripting, "mutation": bench_mutation,
           "requirements": bench_requirements, "live": bench_live,
           "bugs": bench_bugs, "exit": bench_exit, "me": bench_me,
           "adaptive": bench_adaptive, "parallel": bench_parallel, "contract": bench_contract}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("name", choices=sorted(BENCHES))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--against", metavar="REV", help="run NAME here and in a worktree of commit REV, "
                    "interleaved: --rounds processes each, of --repeats runs (benchmarks/against.py)")
    ap.add_argument("--rounds", type=int, default=5, help="with --against: processes per tree")
    ap.add_argument("--budget", type=float, default=None, metavar="SECONDS",
                    help="contract: the time budget shared by the targets (default 600)")
    ap.add_argument("--target", dest="targets", action="append", default=None, metavar="NAME",
                    help="contract: run only this target of tests/contract_targets.py (repeat it for several)")
    args = ap.parse_args(argv)
    OPTIONS.update(budget=args.budget, targets=args.targets)
    try:
        if args.against:
            from against import against
            figures = against(args.name, args.against, args.rounds, args.repeats)
        else:
            figures = BENCHES[args.name](args.repeats)
    except ModuleNotFoundError as exc:
        from pathlib import Path

        top = (exc.name or "").split(".")[0]
        here = Path(__file__).resolve().parents[1]
        if not top or any((here / d / f"{top}.py").is_file() for d in ("benchmarks", "tests")):
            raise
        extra = "mutation" if top == "mutmut" else "bench"
        print(f"bench.py {args.name}: needs {top}: pip install -e \".[{extra}]\" (docs/benchmarks.md)",
              file=sys.stderr)
        return 2
    print(f"# {args.name} on {platform.python_implementation()} {platform.python_version()}, "
          f"{platform.machine()}", file=sys.stderr, flush=True)
    print(json.dumps({"bench": args.name, **figures}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
