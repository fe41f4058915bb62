"""Our FMUs and our exported system in third-party masters: the G1 learning system (Jacobi, identity
connections) exported as SSP and run by libcosim (from the SSP and through its API), ecos (in process and
through its command-line program, a non-Python host) and FMPy's simulate_ssp.  Each runs once per session
in a child process of its own (tests/interop.py); the tests share the results.

All of them are Jacobi masters (every input from the previous step's outputs).  How they differ from ours:
- libcosim counts time in integer nanoseconds: 25,000 steps to exactly 50 s; it records no initial row.
- ecos accumulates time in doubles (t_end 50.000000000015); ``step(n)`` takes exactly n steps, but its
  command line, like ``step_until(50)``, stops at 49.998 s (24,999 steps); its CSV holds 6 significant digits.
- FMPy's runner accumulates time too (``while time < stop``), starts every connector at 0.0 (no exchange of
  the initial outputs: the plant gets no torque over the first step), labels each row with the start of its
  step and records no initial row.
Our FMUs snap a time within 1e-9 of k h to k h, so the accumulated times change nothing: libcosim reproduces
our Jacobi run bit for bit; FMPy too in every controller signal (the plant's first step differs by the
missing initial torque, below 1e-6 m); ecos to its CSV's precision.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from cosim_support import G1
from wmr_cosim.components.metrics import run_metrics
from wmr_cosim import cosim
from wmr_cosim.cosim.plan.ssp import export_ssp
from interop import SIGNALS, run_peer

pytestmark = pytest.mark.slow  # six third-party masters, 50 s of G1 each

PEERS = ("ours", "libcosim", "libcosim_api", "ecos", "ecos_cli", "fmpy_ssp")
GOAL = (2.0, 5.0)


@pytest.fixture(scope="session")
def jacobi_reference(built_fmus, tmp_path_factory):
    """Our master's Jacobi run of scenarios/g1_learn.toml, and the same system exported as SSP."""
    sc = cosim.load(G1, lambda name: built_fmus.get(name))
    sc.algorithm = "jacobi"
    sc.record = list(SIGNALS)
    plan = cosim.resolve(sc)
    d = tmp_path_factory.mktemp("interop")
    res = cosim.run(plan, d / "ref", progress=False)
    assert res.status == "ok", res.message
    data = np.load(d / "ref" / "signals.npy")
    ssp = export_ssp(plan, d / "g1_jacobi.ssp")
    return {s: data[s] for s in SIGNALS}, ssp


@pytest.fixture(scope="session")
def peer_runs(jacobi_reference):
    """Every peer once, three at a time (each in its own process)."""
    _, ssp = jacobi_reference

    def one(peer):
        try:
            return peer, run_peer(peer, ssp, 50.0, 0.002)
        except Exception as exc:  # reported by the test of that peer
            return peer, exc

    with ThreadPoolExecutor(max_workers=3) as pool:
        return dict(pool.map(one, PEERS))


def _metrics(sig):
    return run_metrics(sig, GOAL)


@pytest.mark.parametrize("peer", PEERS)
def test_peer_reaches_the_goal_with_the_same_tracking(peer, peer_runs, jacobi_reference):
    ref, _ = jacobi_reference
    r = peer_runs[peer]
    if isinstance(r, Exception):
        raise r
    m, m0 = _metrics(r["signals"]), _metrics(ref)
    assert not m["diverged"]
    assert m["t_goal"] is not None and m["goal_distance"] < 0.03          # reached eps_G
    for a, b in zip(m["rmse_e"] + m["rmse_edot"], m0["rmse_e"] + m0["rmse_edot"]):
        assert a == pytest.approx(b, rel=0.02)                            # within 2 % of our Jacobi run
    assert np.hypot(*np.subtract(m["final_position"], m0["final_position"])) < 1e-4
    expected_steps = 24999 if peer == "ecos_cli" else 25000              # see the module docstring
    assert r["steps"] == expected_steps
    assert r["t_end"] == pytest.approx(50.0 - (0.002 if peer == "ecos_cli" else 0.0), abs=1e-9)


def test_our_run_of_the_archive_is_our_run_of_the_scenario(peer_runs, jacobi_reference):
    ref, _ = jacobi_reference
    ours = peer_runs["ours"]["signals"]
    for s in SIGNALS:
        assert np.array_equal(ours[s], ref[s]), s


@pytest.mark.parametrize("peer", ["libcosim", "libcosim_api", "fmpy_ssp"])
def test_jacobi_masters_reproduce_ours_bit_for_bit(peer, peer_runs, jacobi_reference):
    ref, _ = jacobi_reference
    sig = peer_runs[peer]["signals"]
    for s in SIGNALS:
        if peer == "fmpy_ssp" and s.startswith("plant."):
            # FMPy starts every connector at 0.0 where the others pass the initial outputs: the plant sees
            # no torque over the first step; the encoders do not notice, the controller's signals are equal
            assert np.allclose(sig[s], ref[s][1:], rtol=0, atol=1e-6) and not np.array_equal(sig[s], ref[s][1:]), s
        else:
            assert np.array_equal(sig[s], ref[s][1:]), s          # they record no initial row


@pytest.mark.parametrize("peer", ["ecos", "ecos_cli"])
def test_ecos_reproduces_ours_to_its_csv_precision(peer, peer_runs, jacobi_reference):
    ref, _ = jacobi_reference
    sig = peer_runs[peer]["signals"]
    n = len(sig["controller.e1"])
    for s in SIGNALS:
        assert np.allclose(sig[s], ref[s][1:n + 1], rtol=1e-5, atol=1e-6), s


def test_the_ecos_command_line_runs_our_fmus_with_an_empty_environment(peer_runs):
    """A non-Python host with nothing set up: the ecos program ran the archive (the peer test above checks
    its results) with only libtbb's folder in its environment, no LD_PRELOAD, no PATH or PYTHONHOME."""
    from interop import ecos_cli_env

    cmd, env, tmp = ecos_cli_env()
    try:
        assert set(env) <= {"LD_LIBRARY_PATH", "TMPDIR"}
    finally:
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)
    r = peer_runs["ecos_cli"]
    if isinstance(r, Exception):
        raise r
    assert r["steps"] == 24999
