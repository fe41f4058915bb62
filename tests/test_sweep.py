"""Sweeps and the gamma search on Dask: the file format, determinism whatever the number of workers,
restart, failures recorded, a real scheduler with two workers."""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from dask_support import free_port, stop
from wmr_cosim.studies import cluster, shipment, sweep, sweep_file, metrics as sweep_metrics
from wmr_cosim.paper import robot_measures
from wmr_cosim.cosim.messages.errors import CosimError, ScenarioError
from wmr_cosim.paper import robot_system

DATA = Path(__file__).parent / "data"


pytestmark = pytest.mark.usefixtures("studies_run_the_session_fmus")


def _sweep_file(tmp: Path, body: str, name: str = "sweep-test.toml") -> Path:
    f = tmp / name
    f.write_text(f'base = "{DATA / "short_protocol.toml"}"\n' + body)
    return f


SMALL = """
runs = ["learn"]
seed = 5
samples = 2
[grid]
"plant.foam_da1+plant.foam_da2" = [0.2, 0.6]
[random]
"controller.goal_x" = { dist = "uniform", low = 1.8, high = 2.2 }
"""


@pytest.fixture(scope="module")
def cluster2():
    with cluster.Cluster(workers=2) as cl:
        yield cl


def _study(tmp: Path, base: str, **kw) -> sweep.Study:
    """A study of ``base`` whose files lie in the cache ``tmp/cache`` (as a worker's, for run_point here)."""
    ship, blobs = shipment.pack([base], robot_system().models)
    shipment.store(tmp / "cache", blobs, ship.names())
    return sweep.Study(ship, base, **kw)


def _table(df: pd.DataFrame) -> pd.DataFrame:
    return df.drop(columns=["wall_s"])


def test_points_are_drawn_from_the_seed(tmp_path):
    spec = sweep_file.load_sweep(_sweep_file(tmp_path, SMALL))
    a, b = sweep_file.draw_points(spec), sweep_file.draw_points(spec)
    assert a == b and len(a) == 4
    assert [p["params"]["plant.foam_da1"] for p in a] == [0.2, 0.2, 0.6, 0.6]
    assert all(p["params"]["plant.foam_da1"] == p["params"]["plant.foam_da2"] for p in a)   # linked
    assert all(1.8 <= p["params"]["controller.goal_x"] <= 2.2 for p in a)
    spec.seed = 6
    assert sweep_file.draw_points(spec) != a


@pytest.mark.parametrize("body, field, reason", [
    ("colour = 1\n", "colour", "unknown key"),
    ("[random]\n\"plant.a5\" = { dist = \"gauss\" }\n", "random.plant.a5", "needs dist"),
    ("[random]\n\"plant.a5\" = { dist = [1, \"a\"] }\n", "random.plant.a5", "needs dist"),
    ("[random]\n\"plant.a5\" = { dist = \"uniform\", low = 1 }\n", "random.plant.a5.high", "missing"),
    ("[grid]\n\"plant.a5\" = []\n", "grid.plant.a5", "non-empty"),
    ("[grid]\n\"a5\" = [1]\n", "grid.a5", "instance.param"),
    ("samples = 0\n", "samples", "integer >= 1"),
    ('runs = ["learn", "nope"]\n', "runs", "'nope' is not a run"),
    # each parameter of a distribution a value the draw takes, refused before any folder is made
    ('[random]\n"plant.a5" = { dist = "uniform", low = "a", high = 2.0 }\n', "random.plant.a5.low", "finite number"),
    ('[random]\n"plant.a5" = { dist = "uniform", low = -inf, high = inf }\n', "random.plant.a5.low", "finite number"),
    ('[random]\n"plant.a5" = { dist = "uniform", low = -1e308, high = 1e308 }\n', "random.plant.a5.high",
     "high - low must be a finite number"),
    ('[random]\n"plant.a5" = { dist = "normal", mean = nan, std = 1.0 }\n', "random.plant.a5.mean", "finite number"),
    ('[random]\n"plant.a5" = { dist = "lognormal", mean = 0.0, sigma = -1 }\n', "random.plant.a5.sigma", "must be >= 0"),
    ('[random]\n"plant.a5" = { dist = "normal", mean = 0.0, std = true }\n', "random.plant.a5.std", "finite number"),
    ('[random]\n"plant.a5" = { dist = "choice", values = [] }\n', "random.plant.a5.values", "non-empty array"),
    ('[random]\n"plant.a5" = { dist = "choice", values = 3 }\n', "random.plant.a5.values", "non-empty array"),
    # the reading of the file and of its base (one TOML reader for every file kind)
    pytest.param("x = " + "[" * 5000 + "]" * 5000 + "\n", "", "nested too deeply", id="nested too deeply"),
])
def test_bad_sweep_files(tmp_path, body, field, reason):
    with pytest.raises(ScenarioError) as exc:
        sweep_file.load_sweep(_sweep_file(tmp_path, body))
    assert exc.value.field == field and reason in str(exc.value), str(exc.value)


def test_a_base_whose_name_the_system_cannot_look_up_is_one_line(tmp_path, capsys):
    """A base of 5,000 characters (beyond the system's name length): one line naming the file's base."""
    from wmr_cosim.cli import main

    f = tmp_path / "long.toml"
    f.write_text('base = "' + "b" * 5000 + '.toml"\n[grid]\n"plant.a5" = [1.0]\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "base" in err[0] and "cannot be read" in err[0], err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_point_that_changes_q_and_r_gets_gamma_star_with_its_own_weights(tmp_path):
    """(53) weighs s and u with the run's own Q and R: a point setting controller.Q = 3 and R = 0.2 gets
    gamma* computed from its signals with those weights, not with Table 1's."""
    from wmr_cosim.paper.analysis import disturbance_analysis, load_signals, table1_disturbance_analysis

    point = {"id": 0, "params": {"controller.Q": 3.0, "controller.R": 0.2}}
    study = _study(tmp_path, str(DATA / "short_protocol.toml"), keep_runs=True, measure=robot_measures.measure)
    row, kept = sweep.run_point(point, study, tmp_path / "cache")
    assert row["status"] == "ok", row["reason"]
    runs = tmp_path / "runs" / "00000"
    sweep._unpacked(kept, runs)
    frozen, foam = load_signals(runs / "frozen"), load_signals(runs / "foam")
    own = disturbance_analysis(frozen, foam, Q=3.0, R=0.2)
    assert row["gamma_star"] == own["gamma_star"] and row["gain_incremental"] == own["gain_incremental"]
    assert row["gamma_star"] != table1_disturbance_analysis(frozen, foam)["gamma_star"]


def test_same_results_with_one_or_two_workers_and_after_a_restart(tmp_path, cluster2):
    f = _sweep_file(tmp_path, SMALL)
    with cluster.Cluster(workers=1) as one:
        df1 = sweep.run_sweep(f, tmp_path / "one", cluster=one, progress=False, system=robot_system())
    df2 = sweep.run_sweep(f, tmp_path / "two", cluster=cluster2, progress=False, system=robot_system())
    assert (df1["status"] == "ok").all()
    pd.testing.assert_frame_equal(_table(df1), _table(df2))
    assert df1["learn.rmse_e1"].nunique() == 4      # the points differ
    # every column is the point's own, a parameter, a requirement's or the robot's (what a metric's name may
    # not be: sweep._columns)
    plans = {"learn": SimpleNamespace(requirements=[SimpleNamespace(name=r) for r in ("goal", "static")])}
    assert set(df1.columns) <= set(sweep._columns(sweep_file.load_sweep(f), plans))
    # interrupted: two points lost; started again: only those run, the table is the same
    pts = tmp_path / "two" / "points"
    stamps = {p.name: p.stat().st_mtime_ns for p in pts.iterdir()}
    (pts / "00001.json").unlink()
    (pts / "00003.json").unlink()
    df3 = sweep.run_sweep(f, tmp_path / "two", cluster=cluster2, progress=False, system=robot_system())
    pd.testing.assert_frame_equal(_table(df3), _table(df2))
    for name in ("00000.json", "00002.json"):
        assert (pts / name).stat().st_mtime_ns == stamps[name]
    back = pd.read_parquet(tmp_path / "two" / "results.parquet")
    pd.testing.assert_frame_equal(_table(back), _table(df3))
    assert (tmp_path / "two" / "results.csv").is_file()
    assert any((tmp_path / "two" / "figures").glob("*.png"))
    # another sweep into the same folder is refused
    g = _sweep_file(tmp_path, SMALL.replace("seed = 5", "seed = 9"), "other.toml")
    with pytest.raises(CosimError, match="another sweep"):
        sweep.run_sweep(g, tmp_path / "two", cluster=cluster2, progress=False, system=robot_system())


@pytest.mark.slow
def test_a_failing_point_is_recorded_and_the_sweep_goes_on(tmp_path, cluster2):
    f = _sweep_file(tmp_path, 'runs = ["learn"]\n[grid]\n"sensor.phase2" = [0.5, 1.5]\n')
    df = sweep.run_sweep(f, tmp_path / "out", cluster=cluster2, progress=False, system=robot_system())
    assert list(df["status"]) == ["ok", "failed"]
    assert "phase2" in df["reason"][1] and "maximum" in df["reason"][1]
    f = _sweep_file(tmp_path, 'runs = ["learn"]\n[grid]\n"controller.gamma" = [11.0, 0.25]\n', "div.toml")
    df = sweep.run_sweep(f, tmp_path / "div", cluster=cluster2, progress=False, system=robot_system())
    assert df["status"][0] == "ok" and df["status"][1] in ("diverged", "failed") and df["reason"][1]


@pytest.mark.slow
def test_gamma_search_finds_the_crossing(tmp_path):
    from wmr_cosim.paper.gamma import gamma_search

    r = gamma_search(DATA / "short_protocol.toml", tmp_path / "gs", grid=[4.0, 40.0], workers=2, progress=False)
    curve = r["curve"]
    assert r["bisected"] and r["monotone"]
    g = r["smallest_gamma"]
    assert g is not None and 4.0 < g <= 40.0
    below = [p for p in curve if p["gamma"] < g]
    assert below and not any(p["holds"] for p in below)
    best = next(p for p in curve if p["gamma"] == g)
    assert best["gamma_star"] <= g
    # bisection narrowed it to 1 %: the largest failing gamma is within 1 % of the answer
    assert max(p["gamma"] for p in below) >= 0.99 * g
    assert "plant.foam_da1 = 0.4" in r["note"]
    assert (tmp_path / "gs" / "gamma_search.png").is_file()


@pytest.mark.slow
def test_sweep_on_an_existing_scheduler_with_two_workers(tmp_path):
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "True",
           "DASK_TEMPORARY_DIRECTORY": str(tmp_path / "dask")}  # the scheduler's scratch folder
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, env=env)]
    try:
        time.sleep(1.0)
        for i in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", addr, "--nthreads", "1",
                                           "--no-dashboard", "--local-directory", str(tmp_path / f"w{i}")],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env))
        from distributed import Client
        with Client(addr, timeout="20s") as c:
            c.wait_for_workers(2, timeout=30)
            assert len(c.scheduler_info()["workers"]) == 2
        f = _sweep_file(tmp_path, SMALL)
        with cluster.Cluster(address=addr) as cl:
            df = sweep.run_sweep(f, tmp_path / "out", cluster=cl, progress=False, system=robot_system())
            workers_used = {w for w in cl.client.run(lambda: os.getpid()).values()}
        assert (df["status"] == "ok").all() and len(df) == 4
        assert len(workers_used) == 2
        # the CLI on the same scheduler: the points are done, the table is the same
        p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "sweep", str(f), "--out", str(tmp_path / "out"),
                            "--scheduler", addr], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr
        assert "4 points (4 ok)" in p.stdout
    finally:
        stop(procs)


@pytest.mark.slow
def test_cli_sweep_errors_are_one_line(tmp_path):
    f = _sweep_file(tmp_path, "colour = 1\n")
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "sweep", str(f)], capture_output=True, text=True)
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "colour" in p.stderr
    p = subprocess.run([sys.executable, "-m", "wmr_cosim.cli", "sweep", str(_sweep_file(tmp_path, SMALL, "s2.toml")),
                        "--scheduler", "tcp://127.0.0.1:1"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "cannot connect" in p.stderr and "Traceback" not in p.stderr


# ---------------------------------------------------------------------- archive limits in the workers
def _cli_in_process(*args: str) -> int:
    from wmr_cosim import cli

    return cli.main([str(a) for a in args])


def test_the_command_lines_archive_limits_reach_the_sweeps_workers(tmp_path, capsys):
    """`wmr-cosim --max-archive-size 1KiB sweep` refuses at once: the parent reads the base's FMUs (to check
    the parameters and metrics) with the limit, before any point.  And each point is submitted with the
    limit, its worker extracting with it: a point run with it fails with the refusal as its reason."""
    from wmr_cosim.cosim import limit_overrides

    f = _sweep_file(tmp_path, 'runs = ["learn"]\n[grid]\n"plant.foam_da1" = [0.4]\n')
    out = tmp_path / "out"
    code = _cli_in_process("--max-archive-size", "1KiB", "sweep", f, "--out", out, "--workers", "1", "--quiet")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "more than the limit of 1 KiB" in err[0] and not out.exists()
    with cluster.Cluster(workers=1) as cl:
        rows = sweep.run_points([{"id": 0, "params": {"plant.foam_da1": 0.4}}], str(DATA / "short_protocol.toml"),
                                None, ["learn"], out, cl, progress=False, archive_limits=limit_overrides("1KiB", None),
                                system=robot_system(), measure=None)
    assert [r["status"] for r in rows] == ["failed"]
    assert "refused: its entries unpack to" in rows[0]["reason"] and "more than the limit of 1 KiB" in rows[0]["reason"]


def test_the_command_lines_archive_limits_reach_the_gamma_searchs_workers(tmp_path, capsys):
    """`wmr-cosim --max-archive-size 1KiB gamma-search` sends the limit with every gamma: the point fails
    with the refusal, and no gamma holds."""
    import json

    out = tmp_path / "gs"
    code = _cli_in_process("--max-archive-size", "1KiB", "gamma-search", DATA / "short_protocol.toml", "--grid", "4",
                           "--out", out, "--workers", "1", "--quiet")
    assert code == 0, capsys.readouterr().err
    r = json.loads((out / "gamma_search.json").read_text())
    assert r["smallest_gamma"] is None and [p["status"] for p in r["curve"]] == ["failed"]
    assert "more than the limit of 1 KiB" in r["curve"][0]["reason"]


# ---------------------------------------------------------------------- metrics for any system
def _dahlquist_base(tmp: Path) -> Path:
    """A scenario of one Reference FMU, Dahlquist (x' = -k x, x(0) = 1), 1 s in steps of 0.01 s."""
    from reference_fmus import REF

    base = tmp / "dahlquist.toml"
    base.write_text(f'[experiment]\nstart = 0.0\nstop = 1.0\nstep = 0.01\n[instances.dq]\nfmu = "{REF / "fmi2" / "Dahlquist.fmu"}"\n'
                    '[record]\nvariables = ["dq.x"]\n')
    (tmp / "ref.csv").write_text("time,x\n" + "".join(f"{t / 10:g},{math.exp(-t / 10):.17g}\n" for t in range(11)))
    return base


DAHLQUIST_METRICS = """
metrics = ["x_end"]
[grid]
"dq.k" = [{ks}]
[metric.x_end]
of = "final"
variable = "dq.x"
[metric.x_int]
of = "integral"
variable = "dq.x"
[metric.x_half]
of = "first_crossing"
variable = "dq.x"
level = 0.5
[metric.x_err]
of = "rmse"
variable = "dq.x"
reference = "ref.csv"
column = "x"
[metric.x_settle]
of = "settling_time"
variable = "dq.x"
target = 0.0
band = 0.1
"""


def test_each_metric_against_its_definition():
    t = np.linspace(0.0, 1.0, 11)
    spec = lambda of, **kw: sweep_metrics.MetricSpec("m", of, "a.y", **kw)   # noqa: E731
    y = 2.0 * t
    assert sweep_metrics.value(spec("final"), t, y) == 2.0
    assert (sweep_metrics.value(spec("min"), t, y), sweep_metrics.value(spec("max"), t, y)) == (0.0, 2.0)
    assert sweep_metrics.value(spec("integral"), t, y) == pytest.approx(1.0, abs=1e-15)   # exact for a line
    assert sweep_metrics.value(spec("mean"), t, y) == pytest.approx(1.0, abs=1e-15)
    assert sweep_metrics.value(spec("rms"), t, np.full(11, -3.0)) == pytest.approx(3.0, abs=1e-15)
    assert sweep_metrics.value(spec("first_crossing", level=0.5), t, y) == pytest.approx(0.25, abs=1e-15)
    assert math.isnan(sweep_metrics.value(spec("first_crossing", level=5.0), t, y))
    assert sweep_metrics.value(spec("first_crossing", level=0.0), t, y) == 0.0
    decay = np.exp(-5.0 * t)   # |y| > 0.1 until t = ln(10) / 5 = 0.46 s: settled from the sample at 0.5 s
    assert sweep_metrics.value(spec("settling_time", target=0.0, band=0.1), t, decay) == 0.5
    assert math.isnan(sweep_metrics.value(spec("settling_time", target=3.0, band=0.1), t, decay))
    assert sweep_metrics.value(spec("rmse", against="a.z"), t, y, y + 0.1) == pytest.approx(0.1, abs=1e-15)
    ref = spec("rmse", reference=(np.array([0.0, 1.0]), np.array([0.0, 2.0])))   # the same line, coarser
    assert sweep_metrics.value(ref, t, y) == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("body, field, reason", [
    ('[metric.a]\nof = "median"\nvariable = "dq.x"\n', "metric.a.of", "unknown metric"),
    ('[metric.a]\nof = "first_crossing"\nvariable = "dq.x"\n', "metric.a.level", "needs level"),
    ('[metric.a]\nof = "rmse"\nvariable = "dq.x"\nreference = "ref.csv"\ncolumn = "y"\n', "metric.a.column",
     "ref.csv has no column 'y'"),
    ('[metric.a]\nof = "final"\nvariable = "dq.x"\nlevel = 1\n', "metric.a.level", "final takes no level"),
    ('sets = ["tidy"]\n', "sets", "named sets"),
])
def test_bad_metrics_are_one_line_naming_the_field(tmp_path, body, field, reason):
    base = _dahlquist_base(tmp_path)
    f = tmp_path / "s.toml"
    f.write_text(f'base = "{base.name}"\n' + body)
    with pytest.raises(ScenarioError) as exc:
        sweep_file.load_sweep(f)
    assert exc.value.field == field and reason in str(exc.value), str(exc.value)


def test_a_metric_over_a_variable_not_recorded_stops_the_sweep_before_any_point(tmp_path, capsys):
    """The variables are checked against what the base's runs record (their FMUs read) at the start: one
    line naming the file and the field, exit code 2, no point run."""
    from wmr_cosim.cli import main

    base = _dahlquist_base(tmp_path)
    f = tmp_path / "s.toml"
    f.write_text(f'base = "{base.name}"\n[grid]\n"dq.k" = [1.0]\n[metric.a]\nof = "final"\nvariable = "dq.der(x)"\n')
    assert main(["sweep", str(f), "--out", str(tmp_path / "out"), "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "metric.a.variable" in err[0] and "'dq.der(x)' is not recorded by run 'run'" in err[0]
    assert not (tmp_path / "out" / "points").exists()


def test_a_sweep_of_a_reference_fmu_measures_what_its_file_names(tmp_path, cluster2):
    """Dahlquist over 20 values of k: each metric of the results table equals its definition over the
    point's recorded signals, with its unit in sweep.json; the robot's set is not asked for."""
    base = _dahlquist_base(tmp_path)
    ks = [0.25 * (i + 1) for i in range(20)]
    f = tmp_path / "dq-sweep.toml"
    f.write_text(f'base = "{base.name}"\nkeep_runs = true\n' + DAHLQUIST_METRICS.format(ks=", ".join(map(str, ks))))
    df = sweep.run_sweep(f, tmp_path / "out", cluster=cluster2, progress=False, system=robot_system())
    assert list(df["status"]) == ["ok"] * 20 and list(df["dq.k"]) == ks
    assert "foam.rmse_e1" not in df.columns and "gamma_star" not in df.columns
    for i, row in df.iterrows():
        sig = np.load(tmp_path / "out" / "runs" / f"{i:05d}" / "run" / "signals.npy")
        t, x = sig["time"], sig["dq.x"]
        assert row["x_end"] == x[-1]
        assert row["x_int"] == pytest.approx(float(np.sum((x[1:] + x[:-1]) * np.diff(t)) / 2), rel=1e-14)
        assert row["x_err"] == pytest.approx(float(np.sqrt(np.mean((x - np.interp(t, np.linspace(0, 1, 11),
                                                                                  np.exp(-np.linspace(0, 1, 11))))
                                                                       ** 2))), rel=1e-12)
        below = np.flatnonzero(x <= 0.5)
        if len(below):
            j = below[0]
            assert t[j - 1] < row["x_half"] <= t[j]
        else:
            assert math.isnan(row["x_half"])
        outside = np.flatnonzero(np.abs(x) > 0.1)
        if abs(x[-1]) > 0.1:
            assert math.isnan(row["x_settle"])
        else:
            assert row["x_settle"] == t[outside[-1] + 1]
    assert (np.diff(df["x_end"]) < 0).all() and (np.diff(df["x_int"]) < 0).all()   # faster decay with k
    assert df["x_half"].notna().sum() >= 10 and 1 <= df["x_settle"].notna().sum() < 20
    units = json.loads((tmp_path / "out" / "sweep.json").read_text())["units"]
    assert units == {"x_end": None, "x_int": None, "x_half": "s", "x_err": None, "x_settle": "s"}


def test_a_point_whose_run_did_not_end_ok_is_failed_whatever_it_measures(tmp_path, monkeypatch):
    """The status of a point is the sweep's, not its measure's: a run that ended otherwise than "ok" (here
    stopped by an event) makes the point failed with that run's message, with the file's metrics too."""
    from types import SimpleNamespace

    from wmr_cosim import cosim

    ends = {"first": SimpleNamespace(status="ok", message="", requirements=[]),
            "second": SimpleNamespace(status="stopped", message="stopped by events[0] at t = 0.5 s", requirements=[])}
    monkeypatch.setattr(cosim, "run_protocol", lambda *a, **kw: ends)
    monkeypatch.setattr(shipment.Shipment, "protocol", lambda *a: (SimpleNamespace(resolver=None), str))
    measure = sweep_metrics.SweepMeasure((sweep_metrics.MetricSpec("x_end", "final", "dq.x", run="first"),))
    study = sweep.Study(shipment.Shipment({"base.toml": {}}, {}, {}, shipment.build()), "base.toml", measure=measure)
    row, _ = sweep.run_point({"id": 3, "params": {"dq.k": 1.0}}, study, tmp_path / "cache")
    assert row["status"] == "failed" and row["reason"] == "second: stopped by events[0] at t = 0.5 s"
    assert math.isnan(row["x_end"])   # (nothing recorded here: the fake runs wrote no signals)


def test_a_sweeps_table_has_each_requirements_robustness_and_verdict(tmp_path, cluster2):
    """Dahlquist (x' = -k x, x(0) = 1; the Reference FMU's explicit Euler of 0.1 s: x(1) = (1 - 0.1 k)^10)
    with the requirement "x stays above 0.3" over k: its robustness column is the lowest x - 0.3 recorded,
    its verdict column holds for k = 0.5 and 1 (x(1) = 0.599, 0.349) and is violated for 1.5 and 2."""
    base = _dahlquist_base(tmp_path)
    with open(base, "a") as f:
        f.write('[[requirements]]\nname = "above"\nformula = "dq.x > 0.3"\n')
    ks = [0.5, 1.0, 1.5, 2.0]
    sw = tmp_path / "req-sweep.toml"
    sw.write_text(f'base = "{base.name}"\nkeep_runs = true\nsets = []\n[grid]\n"dq.k" = [{", ".join(map(str, ks))}]\n')
    df = sweep.run_sweep(sw, tmp_path / "out", cluster=cluster2, progress=False, system=robot_system())
    assert list(df["status"]) == ["ok"] * 4
    for i, row in df.iterrows():
        x = np.load(tmp_path / "out" / "runs" / f"{i:05d}" / "run" / "signals.npy")["dq.x"]
        assert row["run.above.robustness"] == float(np.min(x - 0.3))
        assert row["run.above.robustness"] == pytest.approx((1 - 0.1 * row["dq.k"]) ** 10 - 0.3, abs=1e-12)
    assert list(df["run.above.verdict"]) == ["holds", "holds", "violated", "violated"]


# ---------------------------------------------------------------------- refused before anything runs
def _refused(capsys, tmp_path: Path, args: list, *words: str) -> str:
    """`wmr-cosim sweep ARGS` in this process: exit code 2, one line on stderr holding ``words``, no results
    folder (no cluster started: the checks come first)."""
    from wmr_cosim.cli import main

    out = tmp_path / "out"
    code = main(["sweep", *map(str, args), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert all(w in err[0] for w in words), err[0]
    assert not out.exists()
    return err[0]


def _metric_sweep(tmp: Path, metric: str, body: str = '[grid]\n"dq.k" = [1.0]\n') -> Path:
    base = _dahlquist_base(tmp)
    f = tmp / "s.toml"
    f.write_text(f'base = "{base.name}"\n{body}{metric}')
    return f


@pytest.mark.parametrize("csv, words", [
    ("time,x\n0,1\n0.5,nan\n1,0.37\n", ["ref.csv, line 3, column 'x'", "'nan' is not a finite number"]),
    ("time,x\n0,1\n0.5,0.6\ninf,0.37\n", ["ref.csv, line 4, column 'time'", "'inf' is not a finite number"]),
    ("time,x\n0,1\n0.5,\n1,0.37\n", ["ref.csv, line 3, column 'x'", "'' is not a finite number"]),
    ("time,x\n0,1\n0.5,0.61\n", ["its times (0 to 0.5 s) do not cover run 'run' (0 to 1 s)"]),   # half the run
    ("time,x\n0.2,1\n1,0.37\n", ["its times (0.2 to 1 s) do not cover run 'run' (0 to 1 s)"]),
    (b"time,x\n0,1\n0.5,\xff\n1,0.37\n", ["ref.csv: not a text file"]),
])
def test_a_reference_that_is_not_finite_numbers_over_the_whole_run_is_refused(tmp_path, capsys, csv, words):
    """The reference of an rmse is linear in its time, which must cover the run: a NaN, an infinite time,
    an empty cell, half the run, bytes that are not UTF-8 are one line naming the file, the line and the
    column, exit code 2, before the sweep starts (not an empty column or an RMSE against nonsense)."""
    f = _metric_sweep(tmp_path, '[metric.e]\nof = "rmse"\nvariable = "dq.x"\nreference = "ref.csv"\ncolumn = "x"\n')
    ref = tmp_path / "ref.csv"
    ref.write_bytes(csv) if isinstance(csv, bytes) else ref.write_text(csv)
    _refused(capsys, tmp_path, [f, "--workers", "1"], "s.toml: metric.e.reference", *words)


def test_a_reference_whose_name_the_system_cannot_look_up_is_one_line(tmp_path, capsys):
    """A reference named by 5,000 characters (beyond the system's name length): one line, exit code 2."""
    name = "r" * 5000 + ".csv"
    f = _metric_sweep(tmp_path, f'[metric.e]\nof = "rmse"\nvariable = "dq.x"\nreference = "{name}"\ncolumn = "x"\n')
    _refused(capsys, tmp_path, [f, "--workers", "1"], "s.toml: metric.e.reference", "cannot be read")


@pytest.mark.parametrize("name, sets, what", [
    ("status", "", "the point's own"), ("point", "", "the point's own"), ("reason", "", "the point's own"),
    ("wall_s", "", "the point's own"), ('"dq.k"', "", "a parameter of the sweep"),
    ('"run.above.verdict"', "", "a requirement's"), ('"run.above.robustness"', "", "a requirement's"),
    ("gamma_star", 'sets = ["robot"]\n', "the robot's set of metrics"),
    ('"run.rmse_e1"', 'sets = ["robot"]\n', "the robot's set of metrics"),
])
def test_a_metric_named_as_a_column_of_the_table_is_refused(tmp_path, capsys, name, sets, what):
    """A metric is a column of the results table: one named as a column the table has already (the point's
    status, a parameter, a requirement's verdict, the robot's metrics) would overwrite it."""
    f = _metric_sweep(tmp_path, f'[metric.{name}]\nof = "final"\nvariable = "dq.x"\n',
                      sets + '[grid]\n"dq.k" = [1.0]\n')
    with open(tmp_path / "dahlquist.toml", "a") as fh:
        fh.write('[[requirements]]\nname = "above"\nformula = "dq.x > 0.3"\n')
    _refused(capsys, tmp_path, [f, "--workers", "1"], "already a column of the results table", what)


@pytest.mark.parametrize("key, words", [
    ('[grid]\n"dq.kk" = [1.0, 2.0]\n', ["grid.dq.kk", "has no variable 'kk' (did you mean 'k'?)"]),
    ('[grid]\n"dq.k+dq.kk" = [1.0]\n', ["grid.dq.k+dq.kk", "has no variable 'kk'"]),
    ('[grid]\n"dqq.k" = [1.0]\n', ["grid.dqq.k", "no instance 'dqq' (did you mean 'dq'?)"]),
    ('[random]\n"dq.kk" = { dist = "normal", mean = 1.0, std = 0.1 }\n', ["random.dq.kk", "did you mean 'k'?"]),
    ('[grid]\n"dq.der(x)" = [1.0]\n', ["grid.dq.der(x)", "can be set"]),
])
def test_a_parameter_the_base_does_not_have_is_refused_before_any_point(tmp_path, capsys, key, words):
    """A grid or draw over a parameter the base's FMUs do not have (or cannot set) ran every point to
    "failed" and exited 0: now one line naming the field with the nearest name, exit code 2."""
    base = _dahlquist_base(tmp_path)
    f = tmp_path / "s.toml"
    f.write_text(f'base = "{base.name}"\nsets = []\n{key}')
    _refused(capsys, tmp_path, [f, "--workers", "1"], "s.toml:", *words)


def test_the_local_workers_temporary_folder_is_the_clusters_own(cluster2):
    """A worker killed mid-run cannot clean up its run's extracted FMUs: the local cluster's workers take
    their temporary folder (TMPDIR) inside the cluster's scratch folder, removed when it closes."""
    import tempfile

    assert cluster2.scratch is not None
    temps = cluster2.client.run(tempfile.gettempdir)
    assert len(temps) == 2 and all(Path(t) == cluster2.scratch for t in temps.values()), temps


@pytest.mark.parametrize("workers", ["0", "-1"])
def test_workers_below_one_are_refused_before_anything_starts(tmp_path, capsys, workers):
    """--workers 0 took one worker per core without a word, -1 hung and left Dask's scratch behind: now
    one line naming the option, exit code 2 (the session's temporary folder stays empty: tempdir_guard)."""
    base = _dahlquist_base(tmp_path)
    f = tmp_path / "s.toml"
    f.write_text(f'base = "{base.name}"\nsets = []\n[grid]\n"dq.k" = [1.0]\n')
    _refused(capsys, tmp_path, [f, "--workers", workers], f"--workers {workers}: must be a whole number >= 1")
    with pytest.raises(CosimError, match="--workers 0"):
        cluster.Cluster(workers=0)


def test_a_sweep_file_that_is_not_utf8_is_one_line(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_bytes(b'base = "x.toml"\n# \xff\xfe\n')
    _refused(capsys, tmp_path, [f], "s.toml: not a text file (TOML is UTF-8 text)")


def test_a_copied_sweep_file_finds_its_base_among_the_shipped_scenarios(tmp_path, capsys):
    """As `run` finds a copied scenario's base: the shipped sweep-foam.toml copied elsewhere sweeps the
    shipped paper/g1.toml; a base found nowhere is one line that says it is the base."""
    from wmr_cosim.scenario_files import folder

    copy = tmp_path / "my-sweep.toml"
    copy.write_text((folder() / "sweep-foam.toml").read_text())
    assert Path(sweep_file.load_sweep(copy).base) == (folder() / "paper" / "g1.toml").resolve()
    # a scenario of one's own over a shipped one, swept: its base found as `run` finds it, its FMUs read
    (tmp_path / "mine.toml").write_text('base = "paper/g1.toml"\n[experiment]\nstop = 5.0\n')
    copy.write_text('base = "mine.toml"\nruns = ["learn"]\n[grid]\n"plant.a5" = [1.0]\n')
    spec = sweep_file.load_sweep(copy)
    assert sweep._measure(spec, robot_system(), None)[0].runs == ("learn",)
    copy.write_text('base = "paper/nope.toml"\n[grid]\n"plant.a5" = [1.0]\n')
    _refused(capsys, tmp_path, [copy], "my-sweep.toml: base: 'paper/nope.toml': the base scenario is not found",
             "nor a shipped scenario")


def test_mean_and_rms_are_over_time_not_over_samples():
    """mean and rms weigh each sample by the time it covers (the trapezoidal rule over the run's duration),
    not each sample alike: on a grid dense at the start, with a short last step, y = sqrt(t) (y^2 = t,
    linear: the trapezoidal rule is exact) has the time-RMS sqrt(T / 2) and y = t the time-mean T / 2,
    while their sample averages are far off; the integral is T^2 / 2."""
    t = np.concatenate([np.linspace(0.0, 0.1, 51), np.linspace(0.2, 1.9, 18), [1.95]])   # T = 1.95 s
    T = t[-1] - t[0]
    spec = lambda of: sweep_metrics.MetricSpec("m", of, "a.y")   # noqa: E731
    assert sweep_metrics.value(spec("rms"), t, np.sqrt(t)) == pytest.approx(math.sqrt(T / 2), rel=1e-14)
    assert sweep_metrics.value(spec("mean"), t, t) == pytest.approx(T / 2, rel=1e-14)
    assert sweep_metrics.value(spec("integral"), t, t) == pytest.approx(T * T / 2, rel=1e-14)
    assert abs(math.sqrt(np.mean(t)) - math.sqrt(T / 2)) > 0.1 and abs(np.mean(t) - T / 2) > 0.1   # (the samples')
    # from a start other than 0: the duration, not the end time, divides
    s = t + 3.0
    assert sweep_metrics.value(spec("mean"), s, s - 3.0) == pytest.approx(T / 2, rel=1e-14)
    assert sweep_metrics.value(spec("rms"), s, np.sqrt(t)) == pytest.approx(math.sqrt(T / 2), rel=1e-14)
