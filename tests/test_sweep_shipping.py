"""Studies on a cluster that shares no file system with the driver: the files a sweep reads travel with
the work (by content, once per worker), a worker of another build is refused, a killed worker costs only
its points, and the progress says the time left.

The cluster tests start a scheduler and workers as separate processes, each worker in its own mount
namespace (``unshare --mount``, as root) where the driver's folder of FMUs, scenario files and results,
the folder of the robot's built FMUs, the checkout's shipped scenario files and its built Reference FMUs
are each covered by an empty tmpfs: a worker that opened any of them by path would find nothing, and the
tests ask every worker to confirm it cannot see them.  The same sweep on a local cluster (same files by
path) must give the same table bit for bit.
"""
from __future__ import annotations

import json
import math
import os
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import pandas as pd
import pytest

from dask_support import free_port, stop
from wmr_cosim.paper import robot_system
from wmr_cosim.studies import System, cluster, shipment, sweep
from wmr_cosim.cosim.messages.errors import CosimError
from wmr_cosim.scenario_files import folder as scenarios_folder

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data"


pytestmark = pytest.mark.usefixtures("studies_run_the_session_fmus")


def _table(df: pd.DataFrame) -> pd.DataFrame:
    return df.drop(columns=["wall_s"])


# ---------------------------------------------------------------------- a system of Reference FMUs
def _dahlquist_system(folder: Path, stop: float = 1.0, step: float = 0.01, ks: list[float] | None = None) -> Path:
    """Dahlquist (x' = -k x) driven through a Feedthrough, in ``folder``: the FMUs copied there, the scenario
    in two files (``system.toml`` over ``common.toml``, its base), an input table for the Feedthrough's
    Int32 input, a reference CSV; returns the sweep file (``ks``, else 20 values of k; final value and integral of
    the Feedthrough's output, its RMSE against the reference (over the run), the input as recorded)."""
    from reference_fmus import fmu

    folder.mkdir(parents=True, exist_ok=True)
    for model in ("Dahlquist", "Feedthrough"):
        shutil.copy(fmu("fmi2", model), folder / f"{model}.fmu")
    (folder / "common.toml").write_text(
        f'[experiment]\nstart = 0.0\nstop = {stop}\nstep = {step}\n'
        '[instances.dq]\nfmu = "Dahlquist.fmu"\n[instances.ft]\nfmu = "Feedthrough.fmu"\n'
        '[[connections]]\nfrom = "dq.x"\nto = "ft.Float64_continuous_input"\n')
    (folder / "system.toml").write_text(
        'base = "common.toml"\n[inputs]\nfile = "drive.csv"\n'
        '[record]\nvariables = ["ft.Float64_continuous_output", "ft.Int32_output"]\n')
    (folder / "drive.csv").write_text("time,ft.Int32_input\n0,1\n0.5,3\n")
    # the reference covers the run (exp(-t) at eleven times from 0 to stop)
    (folder / "ref.csv").write_text("time,x\n" + "".join(f"{t * stop / 10:g},{math.exp(-t * stop / 10):.17g}\n"
                                                           for t in range(11)))
    grid = ", ".join(map(str, ks if ks is not None else [0.25 * (i + 1) for i in range(20)]))
    f = folder / "dq-sweep.toml"
    f.write_text(f'base = "system.toml"\n[grid]\n"dq.k" = [{grid}]\n'
                 '[metric.y_end]\nof = "final"\nvariable = "ft.Float64_continuous_output"\n'
                 '[metric.y_int]\nof = "integral"\nvariable = "ft.Float64_continuous_output"\n'
                 '[metric.y_err]\nof = "rmse"\nvariable = "ft.Float64_continuous_output"\nreference = "ref.csv"\n'
                 'column = "x"\n'
                 '[metric.drive]\nof = "final"\nvariable = "ft.Int32_output"\n')
    return f


# ---------------------------------------------------------------------- what travels (no cluster)
def test_the_shipment_holds_the_merged_documents_and_the_files_by_content(tmp_path):
    f = _dahlquist_system(tmp_path / "d")
    base = str(tmp_path / "d" / "system.toml")
    ship, blobs = shipment.pack([base, base], {"WmrPlant": Path("/nowhere/WmrPlant.fmu")}.get)
    assert list(ship.documents) == [base]
    doc = ship.documents[base]
    assert doc["experiment"]["stop"] == 1.0 and "base" not in doc          # the base chain merged
    assert set(ship.files) == {str(tmp_path / "d" / n) for n in ("Dahlquist.fmu", "Feedthrough.fmu", "drive.csv")}
    for path, sf in ship.files.items():
        data = Path(path).read_bytes()
        assert blobs[sf.sha256] == data and sf.size == len(data) and sf.name == Path(path).name
    assert ship.models == {}           # the robot's model is not named by this system: not sent
    assert ship.build == shipment.build() and f.is_file()


def test_the_worker_reads_the_cache_and_the_reasons_name_the_drivers_files(tmp_path):
    _dahlquist_system(tmp_path / "d")
    base = str(tmp_path / "d" / "system.toml")
    ship, blobs = shipment.pack([base], System().models)
    cache = tmp_path / "cache"
    assert shipment.store(cache, blobs, ship.names()) == (sum(map(len, blobs.values())), 0)
    assert shipment.store(cache, blobs, ship.names()) == (0, sum(map(len, blobs.values())))  # once only
    proto, back = ship.protocol(base, None, cache)
    fmu = proto.document["instances"]["dq"]["fmu"]
    assert fmu.startswith(str(cache)) and Path(fmu).read_bytes() == (tmp_path / "d" / "Dahlquist.fmu").read_bytes()
    assert proto.file == base and back(f"{fmu}: boom") == f"{tmp_path / 'd' / 'Dahlquist.fmu'}: boom"
    assert ship.documents[base]["instances"]["dq"]["fmu"] == str(tmp_path / "d" / "Dahlquist.fmu")  # unchanged
    (cache / ship.files[str(tmp_path / "d" / "drive.csv")].sha256 / "drive.csv").unlink()
    with pytest.raises(CosimError, match=r"drive.csv: not shipped to this worker"):
        ship.protocol(base, None, cache)


def test_a_damaged_file_is_refused_by_its_hash(tmp_path):
    with pytest.raises(CosimError, match="arrived damaged"):
        shipment.store(tmp_path, {"0" * 64: b"not the file"}, {"0" * 64: ["x.fmu"]})
    assert not any(tmp_path.iterdir())


def test_a_point_on_a_worker_of_another_build_is_a_failed_row_naming_both(tmp_path):
    ship = shipment.Shipment({"b.toml": {}}, {}, {}, "wmr-cosim 0.0.1 (sources 000000000000), FMPy 0.0.1")
    row, _ = sweep.run_point({"id": 0, "params": {}}, sweep.Study(ship, "b.toml"), tmp_path / "cache")
    assert row["status"] == "failed"
    assert row["reason"] == (f"this worker runs {shipment.build()}, the driver wmr-cosim 0.0.1 (sources "
                             "000000000000), FMPy 0.0.1: install the driver's version on every worker")


def test_the_build_changes_with_the_sources(tmp_path, monkeypatch):
    """The build names the sources' digest: the same version number with other code is another build."""
    import wmr_cosim

    ours = shipment.build()
    assert ours.startswith(f"wmr-cosim {wmr_cosim.version()} (sources ") and "FMPy " in ours
    copy = tmp_path / "wmr_cosim"
    shutil.copytree(Path(wmr_cosim.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "studies" / "sweep.py").write_text((copy / "studies" / "sweep.py").read_text() + "\n# changed\n")
    p = subprocess.run([sys.executable, "-c", "from wmr_cosim.studies import shipment; print(shipment.build())"],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert p.returncode == 0, p.stderr
    theirs = p.stdout.strip()
    assert theirs != ours and theirs.split(" (")[0] == ours.split(" (")[0]


def test_a_worker_of_another_build_is_refused_in_one_line():
    class Client:
        def run(self, fn):
            return {"tcp://10.0.0.2:4000": fn(), "tcp://10.0.0.3:4000": "wmr-cosim 0.0.9 (sources abc), FMPy 0.3"}

    with pytest.raises(CosimError) as exc:
        shipment.check_workers(Client(), "--scheduler tcp://10.0.0.1:8786")
    assert str(exc.value) == (f"--scheduler tcp://10.0.0.1:8786: worker tcp://10.0.0.3:4000 runs wmr-cosim 0.0.9 "
                              f"(sources abc), FMPy 0.3, this driver {shipment.build()}: install the driver's version "
                              "on every worker")


def test_progress_lines_in_a_log_give_the_time_left(monkeypatch, capsys):
    clock = iter([0.0, 10.0, 20.0, 30.0, 40.0])
    monkeypatch.setattr(sweep.time, "monotonic", lambda: next(clock))
    p = sweep.Progress("sweep", 40, 0, True)          # (pytest's stderr is no terminal: lines)
    p.update(0)
    p.update(1)
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["sweep: 1/40 points (0 failed), 10 s, about 6 min 30 s left",
                     "sweep: 2/40 points (1 failed), 20 s, about 6 min 20 s left"]
    assert sweep._duration(7300) == "2 h 1 min"
    q = sweep.Progress("sweep", 40, 0, None)          # not asked for, no terminal: nothing
    q.update(0)
    assert capsys.readouterr().err == ""


# ---------------------------------------------------------------------- workers that cannot see the driver's files
def _can_hide_folders() -> str | None:
    """Why the workers cannot be given their own mount namespace here, or None."""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return "workers in their own mount namespace need root and unshare"
    p = subprocess.run(["unshare", "--mount", "--propagation", "private", "sh", "-c",
                        "mount -t tmpfs tmpfs /mnt"], capture_output=True, text=True, timeout=30)
    return None if p.returncode == 0 else f"unshare --mount fails here: {p.stderr.strip()}"


@contextmanager
def hidden_cluster(tmp: Path, hide: list[Path], workers: int = 2) -> Iterator[str]:
    """A scheduler and ``workers`` workers, separate processes; each worker in its own mount namespace
    where every folder of ``hide`` is an empty tmpfs.  Yields the scheduler's address."""
    why = _can_hide_folders()
    if why:
        pytest.skip(why)
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "True", "DASK_TEMPORARY_DIRECTORY": str(tmp / "dask")}
    log = open(tmp / "cluster.log", "wb")
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard"], stdout=log, stderr=log, env=env)]
    try:
        mounts = " && ".join(f"mount -t tmpfs -o size=1M tmpfs {shlex.quote(str(h))}" for h in hide)
        for i in range(workers):
            cmd = shlex.join([sys.executable, "-m", "distributed.cli.dask_worker", addr, "--nthreads", "1",
                              "--no-dashboard", "--local-directory", str(tmp / f"worker{i}")])
            procs.append(subprocess.Popen(["unshare", "--mount", "--propagation", "private", "sh", "-c",
                                           f"{mounts} && exec {cmd}"], stdout=log, stderr=log, env=env))
        from distributed import Client
        with Client(addr, timeout="30s") as c:
            c.wait_for_workers(workers, timeout=60)
        yield addr
    finally:
        stop(procs, timeout=15)
        log.close()


@pytest.mark.slow
def test_a_sweep_of_reference_fmus_on_workers_that_cannot_see_its_files_equals_the_local_one(tmp_path, built_fmus):
    """Dahlquist through a Feedthrough, 20 values of k, on two workers whose file system shows none of the
    driver's files (FMUs, scenario files and their base, input table, the robot's FMUs, the shipped
    scenarios): every point ok, the table equal bit for bit to the same sweep on a local cluster; the
    FMUs crossed once per worker (sweep.json)."""
    f = _dahlquist_system(tmp_path / "driver")
    hide = [tmp_path / "driver", Path(next(iter(built_fmus.values()))).parent, scenarios_folder(),
            ROOT / "build" / "reference-fmus"]
    with cluster.Cluster(workers=2) as local:
        here = sweep.run_sweep(f, tmp_path / "driver" / "local", cluster=local, progress=False, system=robot_system())
    assert list(here["status"]) == ["ok"] * 20, here["reason"].tolist()
    assert list(here["drive"]) == [3] * 20                       # the input table was read
    with hidden_cluster(tmp_path, hide) as addr, cluster.Cluster(address=addr) as cl:
        probe = [str(tmp_path / "driver" / "Dahlquist.fmu"), str(tmp_path / "driver" / "system.toml"),
                 str(next(iter(built_fmus.values()))), str(scenarios_folder() / "paper" / "g1.toml")]
        assert all(os.path.exists(p) for p in probe)
        seen = [cl.client.run(os.path.exists, p) for p in probe]     # (a function every worker has)
        assert all(len(s) == 2 and not any(s.values()) for s in seen), seen
        there = sweep.run_sweep(f, tmp_path / "driver" / "remote", cluster=cl, progress=False, system=robot_system())
    pd.testing.assert_frame_equal(_table(there), _table(here), check_exact=True)
    cost = json.loads((tmp_path / "driver" / "remote" / "sweep.json").read_text())["shipping"]
    sizes = sum((tmp_path / "driver" / n).stat().st_size for n in ("Dahlquist.fmu", "Feedthrough.fmu", "drive.csv"))
    assert cost["bytes"] == sizes and len(cost["workers"]) == 2
    assert all(w["written"] == sizes for w in cost["workers"].values())


@pytest.mark.slow
def test_the_foam_sweep_on_workers_that_cannot_see_its_files_equals_the_local_one(tmp_path, built_fmus):
    """The paper's foam sweep (scenarios/sweep-foam.toml: friction change x onset, the G1 protocol learn,
    frozen, foam) cut to two points of the 12 s protocol of the tests, on workers that see neither the
    robot's FMUs nor any scenario file: the same table as on a local cluster, bit for bit."""
    import tomllib

    d = tmp_path / "driver"
    d.mkdir()
    (d / "g1-short.toml").write_text(f'base = "{scenarios_folder() / "paper" / "g1.toml"}"\n[experiment]\nstop = 12.0\n')
    spec = tomllib.loads((scenarios_folder() / "sweep-foam.toml").read_text())
    f = d / "sweep-foam.toml"
    f.write_text(f'base = "g1-short.toml"\nvariant = "{spec["variant"]}"\nseed = {spec["seed"]}\nsamples = 1\n'
                 f'metrics = {json.dumps(spec["metrics"])}\n[grid]\n"plant.foam_da1+plant.foam_da2" = [0.4, 1.2]\n'
                 '[random]\n"plant.foam_t_on" = { dist = "uniform", low = 7.0, high = 9.0 }\n')
    hide = [d, Path(next(iter(built_fmus.values()))).parent, scenarios_folder()]
    with cluster.Cluster(workers=2) as local:
        here = sweep.run_sweep(f, d / "local", cluster=local, progress=False, system=robot_system())
    assert list(here["status"]) == ["ok", "ok"], here["reason"].tolist()
    assert here["gamma_star"].notna().all()
    with hidden_cluster(tmp_path, hide) as addr, cluster.Cluster(address=addr) as cl:
        there = sweep.run_sweep(f, d / "remote", cluster=cl, progress=False, system=robot_system())
    pd.testing.assert_frame_equal(_table(there), _table(here), check_exact=True)


# ---------------------------------------------------------------------- a worker killed mid-sweep
def _kill_a_busy_worker(cl: cluster.Cluster, points: Path, killed: list[int]) -> None:
    """Once a first point is on disk, SIGKILL a worker that is running a point."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if points.is_dir() and any(points.glob("*.json")):
            pids = cl.client.run(os.getpid)
            busy = [w for w, keys in cl.client.processing().items() if keys and w in pids]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(pids[busy[0]])
                return
        time.sleep(0.02)


@pytest.mark.slow
def test_a_worker_killed_mid_sweep_costs_only_its_points(tmp_path):
    """SIGKILL to a worker while it runs a point: that point runs again on another worker, the sweep
    completes every point, and the table equals an undisturbed run's."""
    f = _dahlquist_system(tmp_path / "d", stop=40.0, step=1e-4, ks=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6])  # 400,000 steps each
    with cluster.Cluster(workers=2) as cl:
        calm = sweep.run_sweep(f, tmp_path / "calm", cluster=cl, progress=False, system=robot_system())
    killed: list[int] = []
    with cluster.Cluster(workers=2) as cl:
        t = threading.Thread(target=_kill_a_busy_worker, args=(cl, tmp_path / "hit" / "points", killed))
        t.start()
        hit = sweep.run_sweep(f, tmp_path / "hit", cluster=cl, progress=False, system=robot_system())
        t.join()
    assert killed, "no worker was busy to kill"
    assert list(hit["status"]) == ["ok"] * 6, hit["reason"].tolist()
    pd.testing.assert_frame_equal(_table(hit), _table(calm), check_exact=True)


def _die(tries: str, row, results, work):   # a measure that kills its worker (as a crashing FMU would)
    if row["point"] == 1:
        with open(tries, "a") as fh:
            fh.write(f"{os.getpid()}\n")
        os.kill(os.getpid(), signal.SIGKILL)


@pytest.mark.slow
def test_a_point_that_kills_its_worker_each_time_is_a_failed_row(tmp_path):
    """It runs twice, in two worker processes (once more after its worker died), then it is a failed row;
    the other points end ok."""
    import functools

    _dahlquist_system(tmp_path / "d")
    base = str(tmp_path / "d" / "system.toml")
    points = [{"id": i, "params": {"dq.k": k}} for i, k in enumerate((0.5, 1.0, 2.0))]
    tries = tmp_path / "tries"
    with cluster.Cluster(workers=2) as cl:
        rows = sweep.run_points(points, base, None, None, tmp_path / "out", cl, progress=False, system=System(),
                                measure=functools.partial(_die, str(tries)))
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert rows[1]["reason"] == "its worker died while running it, again when it was run on another"
    pids = tries.read_text().split()
    assert len(pids) == 2 and len(set(pids)) == 2
