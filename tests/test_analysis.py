"""The analysis of recorded runs on synthetic signals whose figures are known in closed form: the run
summary of Tables 2 and 3, the true tracking errors, the foam's onset, (52)/(53) and the other gains,
the fidelity cells, the distance to the paper's final positions, and the reading of a run folder."""
from __future__ import annotations

import math

import numpy as np
import pytest

from wmr_cosim.paper import analysis
from wmr_cosim.paper.analysis import (cruise_mask, cumulative_integral, disturbance_analysis, fidelity, foam_onset,
                                load_signals, position_error, run_summary, t_move, true_errors)
from wmr_cosim.components import paper

H = 0.002
V_STAR = paper.table1()["v_star"]


def _run(n: int = 11, **over: np.ndarray) -> dict[str, np.ndarray]:
    """A run of n samples every 2 ms with every signal run_summary reads; ``over`` replaces some."""
    t = np.arange(n) * H
    z = np.zeros(n)
    sig = {"time": t, "controller.e1": z + 0.1, "controller.e2": z - 0.2, "controller.edot1": z + 0.3,
           "controller.edot2": z + 0.4, "controller.t_goal": z - 1.0, "plant.x_A": np.linspace(0, 1, n),
           "plant.y_A": np.linspace(0, 2, n), "controller.W1": z + 1.0, "controller.W2": z + 2.0,
           "controller.W3": z + 3.0, "controller.v_A_d": z, "controller.u1": z + 1.0, "controller.u2": z - 2.0}
    sig.update(over)
    return sig


# --- small functions --------------------------------------------------------------------------------

def test_cumulative_integral_is_the_trapezoid_rule_from_the_first_sample():
    t = np.array([0.0, 1.0, 3.0, 4.0])
    f = np.array([1.0, 3.0, 5.0, -1.0])
    # trapezoids: (1+3)/2*1 = 2, (3+5)/2*2 = 8, (5-1)/2*1 = 2
    assert cumulative_integral(f, t).tolist() == [0.0, 2.0, 10.0, 12.0]
    assert cumulative_integral(np.array([4.0]), np.array([0.0])).tolist() == [0.0]
    # an integer signal integrates as floats
    assert cumulative_integral(np.array([1, 2]), np.array([0.0, 0.5])).tolist() == [0.0, 0.75]


def test_cruise_is_at_least_95_percent_of_v_star():
    v = np.array([0.0, 0.95 * V_STAR - 1e-12, 0.95 * V_STAR, V_STAR])
    assert cruise_mask({"controller.v_A_d": v}, V_STAR).tolist() == [False, False, True, True]


def test_t_move_is_the_first_time_the_desired_speed_reaches_the_fraction():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    sig = {"time": t, "controller.v_A_d": np.array([0.0, 0.01 * V_STAR - 1e-12, 0.01 * V_STAR, 0.0])}
    assert t_move(sig, V_STAR) == 2.0
    assert t_move(sig, V_STAR, fraction=0.001) == 1.0
    assert t_move({"time": t, "controller.v_A_d": np.zeros(4)}, V_STAR) is None


def test_foam_onset_is_the_last_sample_before_the_friction_changes():
    t = np.array([0.0, 0.5, 1.0, 1.5])
    assert foam_onset({"time": t, "plant.foam_level": np.array([0.0, 0.0, 0.2, 1.0])}) == 0.5
    assert foam_onset({"time": t, "plant.foam_level": np.array([1.0, 1.0, 1.0, 1.0])}) == 0.0
    assert foam_onset({"time": t, "plant.foam_level": np.zeros(4)}) == math.inf


def test_true_errors_use_the_plant_angles_and_speeds():
    sig = {"controller.alpha_d1": np.array([1.0, 2.0]), "controller.alpha_d2": np.array([3.0, 4.0]),
           "plant.alpha1": np.array([0.5, 0.5]), "plant.alpha2": np.array([1.0, 5.0]),
           "controller.alpha_dot_d1": np.array([2.0, 2.0]), "controller.alpha_dot_d2": np.array([1.0, 1.0]),
           "plant.alpha_dot1": np.array([1.0, 3.0]), "plant.alpha_dot2": np.array([0.0, 0.0])}
    e = true_errors(sig)
    assert {k: v.tolist() for k, v in e.items()} == {"e1": [0.5, 1.5], "e2": [2.0, -1.0],
                                                     "edot1": [1.0, -1.0], "edot2": [1.0, 1.0]}
    for missing in sig:
        assert true_errors({k: v for k, v in sig.items() if k != missing}) is None, missing


def test_position_error_is_the_distance_to_the_paper_final_position():
    gx, gy = paper.results()["final_positions"]["G1"]
    assert position_error("G1", [gx + 0.3, gy - 0.4]) == pytest.approx(0.5, rel=1e-12)
    assert position_error("G1", None) is None
    assert position_error("LINE", [1.0, 1.0]) is None      # the paper prints no final position for it


# --- run summary -------------------------------------------------------------------------------------

def test_run_summary_of_a_run_that_recorded_nothing():
    assert run_summary(None, (1.0, 2.0), status="failed") == {
        "rmse_e": None, "rmse_edot": None, "final_position": None, "t_goal": None, "diverged": True,
        "status": "failed", "samples": 0}
    assert run_summary(None, None)["status"] == "ok"


def test_run_summary_figures():
    n = 11
    v = np.zeros(n)
    v[6:] = V_STAR                         # cruising over the last 5 samples
    v[4] = 0.02 * V_STAR                   # moving from sample 4 (t = 8 ms)
    u1 = np.arange(n, dtype=float)         # 0 .. 10
    u2 = -2.0 * np.arange(n, dtype=float)  # 0 .. -20
    e1 = np.full(n, 0.1)
    e1[-1] = -0.7
    e2 = np.full(n, -0.2)
    e2[1], e2[-2] = 0.9, -0.8                    # (only the last sample is final)
    sig = _run(n, **{"controller.v_A_d": v, "controller.u1": u1, "controller.u2": u2, "controller.e1": e1,
                     "controller.e2": e2, "controller.t_goal": np.full(n, 0.016)})
    s = run_summary(sig, (4.0, 6.0))
    assert s["rmse_e"] == [pytest.approx(math.sqrt((10 * 0.01 + 0.49) / 11), rel=1e-12),
                           pytest.approx(math.sqrt((9 * 0.04 + 0.81 + 0.64) / 11), rel=1e-12)]
    assert s["rmse_edot"] == [pytest.approx(0.3), pytest.approx(0.4)]
    assert s["rmse_e_true"] is None and s["rmse_edot_true"] is None   # no plant angles recorded
    assert s["final_position"] == [1.0, 2.0]
    assert s["goal_distance"] == pytest.approx(5.0)                  # (4 - 1, 6 - 2)
    assert s["t_goal"] == 0.016
    assert s["diverged"] is False and s["status"] == "ok" and s["samples"] == n
    assert s["final_W"] == [1.0, 2.0, 3.0]
    assert s["cruise_u"] == [pytest.approx(8.0), pytest.approx(-16.0)]   # means of u over samples 6..10
    assert s["peak_u"] == [10.0, 20.0]
    assert s["final_e"] == [-0.7, -0.2] and s["final_abs_e"] == 0.7
    assert s["t_move"] == pytest.approx(4 * H)
    assert s["final_u"] == [10.0, -20.0]


def test_run_summary_without_goal_cruise_or_completion():
    sig = _run()
    s = run_summary(sig, None, status="stopped")
    assert "goal_distance" not in s and s["t_goal"] is None
    assert s["cruise_u"] is None and s["t_move"] is None
    assert s["diverged"] is True and s["status"] == "stopped"       # an incomplete run is not a result
    assert run_summary(sig, None)["diverged"] is False


def test_run_summary_true_rmse_from_the_plant_angles():
    n = 5
    z = np.zeros(n)
    sig = _run(n, **{"controller.alpha_d1": z + 1.0, "controller.alpha_d2": z + 2.0,
                     "plant.alpha1": z + 0.5, "plant.alpha2": z + 2.5,
                     "controller.alpha_dot_d1": z + 3.0, "controller.alpha_dot_d2": z,
                     "plant.alpha_dot1": z + 1.0, "plant.alpha_dot2": z + 4.0})
    s = run_summary(sig, None)
    assert s["rmse_e_true"] == [0.5, 0.5]
    assert s["rmse_edot_true"] == [2.0, 4.0]


# --- (52), (53) and the gains ------------------------------------------------------------------------

def _pair(n: int = 5001, t_on: float = 5.0, du: float = 0.3, dF: float = 0.3, s: tuple[float, float] = (1.0, 1.0),
          dt: float = H):
    """A frozen run and a foam run of n samples every dt: s = ``s`` and u = 2 held on the frozen one; from
    t_on the foam run's control is higher by du and the plant's disturbance is dF (both wheels)."""
    t = np.arange(n) * dt
    one, zero = np.ones(n), np.zeros(n)
    frozen = {"time": t, "controller.s1": s[0] * one, "controller.s2": s[1] * one, "controller.u1": 2 * one,
              "controller.u2": 2 * one, "plant.dF1": zero, "plant.dF2": zero, "plant.foam_level": zero}
    on = t > t_on
    foam = dict(frozen, **{"controller.u1": np.where(on, 2 + du, 2.0), "controller.u2": np.where(on, 2 + du, 2.0),
                           "plant.dF1": np.where(on, dF, 0.0), "plant.dF2": np.where(on, dF, 0.0),
                           "plant.foam_level": on.astype(float)})
    return frozen, foam


def test_disturbance_estimate_52_is_zero_before_the_onset():
    frozen, foam = _pair()
    d = disturbance_analysis(frozen, foam, Q=1.0, R=0.5)
    t = d["time"]
    assert d["t_F"] == pytest.approx(5.0)
    for du in d["dF_est"]:
        assert np.all(du[t <= 5.0] == 0.0) and np.allclose(du[t > 5.0], 0.3)
    assert d["dF_est_rms"] == pytest.approx(0.3)
    assert np.all(d["dF_true"][0] == foam["plant.dF1"]) and np.all(d["dF_true"][1] == foam["plant.dF2"])
    # before the onset no gain is defined: the curves are nan there, finite after
    for key in ("gamma_star_curve", "gamma_true_curve", "gain_incremental_curve"):
        assert np.all(np.isnan(d[key][t <= 5.0])) and np.all(np.isfinite(d[key][t > 5.002])), key


def test_no_gain_before_the_disturbance_even_where_the_runs_differ():
    """The incremental gain is undefined (nan, not inf) while no disturbance has acted, even where the foam
    run's output already differs from the frozen one's."""
    frozen, foam = _pair()
    foam["controller.s1"] = foam["controller.s1"] + 0.1
    d = disturbance_analysis(frozen, foam, Q=1.0, R=0.5)
    assert np.all(np.isnan(d["gain_incremental_curve"][d["time"] <= 5.0]))


def test_the_gains_53_on_two_different_disturbances():
    """The estimate (from the control, 0.3) and the injected disturbance (0.6) differ: gamma* and
    gamma_true have the same numerator and denominators in the ratio 0.3^2 : 0.6^2."""
    frozen, foam = _pair(du=0.3, dF=0.6, s=(0.5, 1.5))
    Q, R = 2.0, 0.25
    d = disturbance_analysis(frozen, foam, Q=Q, R=R)
    t = d["time"]
    u = foam["controller.u1"]
    cost = cumulative_integral(Q * (0.25 + 2.25) + R * 2 * u * u, t)
    den_hat = cumulative_integral(np.where(t > 5.0, 2 * 0.09, 0.0), t)
    den_true = cumulative_integral(2 * foam["plant.dF1"] ** 2, t)
    assert d["gamma_star"] == pytest.approx(math.sqrt(cost[-1] / den_hat[-1]), rel=1e-12)
    assert d["gamma_true"] == pytest.approx(math.sqrt(cost[-1] / den_true[-1]), rel=1e-12)
    assert d["gamma_star"] == pytest.approx(2 * d["gamma_true"], rel=2e-3)
    # |dz|^2 = R |du|^2 (s unchanged): gain = sqrt(R 2 du^2 / (2 dF^2)) = sqrt(R) du / dF
    assert d["gain_incremental"] == pytest.approx(math.sqrt(R) * 0.3 / 0.6, rel=2e-3)


def test_incremental_gain_weighs_the_change_of_s_by_Q():
    frozen, foam = _pair(du=0.0, dF=0.5)
    on = foam["time"] > 5.0
    foam["controller.s1"] = np.where(on, 1.4, 1.0)      # s1 changes by 0.4, s2 by -0.3, u not at all
    foam["controller.s2"] = np.where(on, 0.7, 1.0)
    d = disturbance_analysis(frozen, foam, Q=3.0, R=0.5)
    assert d["gain_incremental"] == pytest.approx(math.sqrt(3.0 * (0.16 + 0.09) / (2 * 0.25)), rel=2e-3)
    assert d["gamma_star"] is None and d["dF_est_rms"] == 0.0          # no control change: no estimate


def _quarter_pair() -> tuple[np.ndarray, dict, dict]:
    """Runs sampled every 0.25 s (exact in binary, so the windows' ends fall on samples), foam from 2 s."""
    frozen, foam = _pair(n=41, t_on=2.0, du=0.0, dF=0.0, dt=0.25)
    return foam["time"], frozen, foam


def test_the_foam_rise_window_is_open_at_its_start_and_closed_at_its_end():
    """The rise is the mean control change over (t_F + ramp + 0.5, t_F + ramp + 2.5]: with t_F = 2 s and
    ramp = 0.5 s, over (3, 5] s: the samples 3.25 .. 5.0."""
    t, frozen, foam = _quarter_pair()
    change = np.zeros_like(t)
    change[(t > 3.0) & (t <= 5.0)] = 1.0
    change[t == 5.0] = 9.0                               # the window's last sample
    change[t == 3.0] = 100.0                             # just before it
    change[t == 5.25] = 100.0                            # just after it
    foam["controller.u1"] = 2.0 + change
    foam["controller.u2"] = 2.0 - 0.5 * change
    d = disturbance_analysis(frozen, foam, Q=1.0, R=0.5, ramp=0.5)
    assert d["t_F"] == 2.0
    assert d["foam_rise"] == [pytest.approx((7 * 1.0 + 9.0) / 8), pytest.approx(-0.5 * 16.0 / 8)]


def test_the_edge_peak_window_is_closed_at_both_ends():
    """The edge peak is the largest |u| of either wheel within [t_F, t_F + 2 s], on the foam run and on
    the frozen one over the same samples."""
    t, frozen, foam = _quarter_pair()
    for at, want in ((2.0, 7.0), (4.0, 7.0), (3.0, 7.0), (1.75, 2.0), (4.25, 2.0)):
        u = np.where(t == at, -7.0, 2.0)
        d = disturbance_analysis(frozen, dict(foam, **{"controller.u2": u}), Q=1.0, R=0.5)
        assert d["edge_peak_u"] == want, at
        e = disturbance_analysis(dict(frozen, **{"controller.u1": u}), foam, Q=1.0, R=0.5)
        assert (e["edge_peak_u"], e["edge_peak_u_frozen"]) == (2.0, want), at


def test_no_foam_gives_no_onset_and_no_windows():
    frozen, _ = _pair(n=101)
    d = disturbance_analysis(frozen, dict(frozen), Q=1.0, R=0.5)
    assert d["t_F"] == math.inf
    assert d["foam_rise"] == [None, None] and d["edge_peak_u"] is None and d["edge_peak_u_frozen"] is None
    assert d["dF_est_rms"] is None and d["gamma_star"] is None and d["gamma_true"] is None


def test_runs_of_different_lengths_are_compared_over_the_shorter():
    frozen, foam = _pair(n=5001)
    short = {k: v[:4001] for k, v in frozen.items()}
    d = disturbance_analysis(short, foam, Q=1.0, R=0.5)
    assert len(d["time"]) == 4001 and d["time"][-1] == pytest.approx(8.0)
    d2 = disturbance_analysis(frozen, {k: v[:4001] for k, v in foam.items()}, Q=1.0, R=0.5)
    assert d2["gamma_star"] == pytest.approx(d["gamma_star"], rel=1e-12)


def test_a_diverged_run_gives_inf_without_warnings():
    frozen, foam = _pair(n=2001, t_on=1.0)
    foam["controller.u1"] = np.where(foam["time"] > 3.0, 1e300, foam["controller.u1"])
    with np.errstate(all="raise"):
        d = disturbance_analysis(frozen, foam, Q=1.0, R=0.5)
    assert d["gain_incremental"] is not None        # the last finite value, from before the overflow
    assert not np.all(np.isfinite(d["gamma_star_curve"][1:]))


def test_last_finite_value():
    assert analysis._last_finite(np.array([1.0, 2.0, np.nan, np.inf])) == 2.0
    assert analysis._last_finite(np.array([np.nan, -np.inf])) is None


# --- fidelity ----------------------------------------------------------------------------------------

def _paper_tasks(scale: float = 1.0) -> dict:
    return {t: {r: {"rmse_e": [scale * v[0], scale * v[1]], "rmse_edot": [scale * v[2], scale * v[3]]}
                for r, v in paper.rmse_table(t).items()} for t in paper.TASKS}


def test_fidelity_cells_name_task_run_cell_and_both_values():
    f = fidelity(_paper_tasks(2.0))
    assert f["n_cells"] == 32 == len(f["cells"])
    ref = paper.rmse_table("G2")["foam"]
    cells = [c for c in f["cells"] if c["task"] == "G2" and c["run"] == "foam"]
    assert [c["cell"] for c in cells] == ["e_1", "e_2", "e_dot_1", "e_dot_2"]
    for c, p in zip(cells, ref):
        assert c["paper"] == p and c["ours"] == pytest.approx(2 * p) and c["ratio"] == pytest.approx(2.0)
    assert {c["run"] for c in f["cells"]} == {"learn", "foam"}
    assert f["within_1_5"] == 0 and f["within_2_5"] == 32
    assert f["rms_log_factor"] == pytest.approx(2.0)


def test_fidelity_bounds_are_inclusive_both_ways():
    for scale, in15, in25 in ((1.5, 32, 32), (1 / 1.5, 32, 32), (2.5, 0, 32), (1 / 2.5, 0, 32),
                              (1.5 * (1 + 1e-9), 0, 32), (2.5 * (1 + 1e-9), 0, 0)):
        tasks = _paper_tasks(1.0)
        for t in tasks.values():
            for r in t.values():
                r["rmse_e"] = [x * scale for x in r["rmse_e"]]
                r["rmse_edot"] = [x * scale for x in r["rmse_edot"]]
        f = fidelity(tasks)
        # (the products of the table's values and the scale round: compare through the ratios)
        ratios = [c["ratio"] for c in f["cells"]]
        assert f["within_1_5"] == sum(1 / 1.5 <= r <= 1.5 for r in ratios)
        assert f["within_2_5"] == sum(1 / 2.5 <= r <= 2.5 for r in ratios)
        if scale in (2.5 * (1 + 1e-9), 1.5 * (1 + 1e-9)):
            assert (f["within_1_5"], f["within_2_5"]) == (in15, in25), scale


def test_fidelity_of_a_zero_rmse_is_a_cell_without_a_log_factor():
    tasks = _paper_tasks()
    tasks["G2"]["learn"]["rmse_edot"][1] = 0.0
    f = fidelity(tasks)
    zero = [c for c in f["cells"] if c["ratio"] == 0.0]
    assert len(zero) == 1 and zero[0]["cell"] == "e_dot_2"
    assert f["within_1_5"] == 31 and f["within_2_5"] == 31 and f["rms_log_factor"] is None


def test_fidelity_of_missing_or_diverged_runs():
    tasks = _paper_tasks()
    del tasks["G3"]["foam"]                                      # a run that is missing
    tasks["G1"]["learn"]["rmse_e"][0] = math.inf                 # a run that diverged
    tasks["LINE"]["learn"] = {"rmse_e": None, "rmse_edot": None}  # a run that recorded nothing
    f = fidelity(tasks)
    missing = [c for c in f["cells"] if c["ratio"] is None]
    assert len(missing) == 4 + 1 + 4
    assert all(c["ours"] is None for c in missing if c["task"] in ("G3", "LINE"))
    assert f["within_1_5"] == 32 - 9 and f["within_2_5"] == 32 - 9
    assert f["rms_log_factor"] is None                            # not a figure over fewer cells
    del tasks["G1"]
    assert fidelity(tasks)["n_cells"] == 32


# --- reading a run folder ----------------------------------------------------------------------------

def test_load_signals_reads_the_recording_and_names_fmi3_arrays_as_fmi2(tmp_path):
    dt = np.dtype([("time", float), ("controller.W[1]", float), ("controller.P[1,2]", float), ("plant.x_A", float)])
    data = np.zeros(3, dtype=dt)
    data["time"] = [0.0, 0.002, 0.004]
    data["controller.W[1]"] = [1.0, 2.0, 3.0]
    data["controller.P[1,2]"] = [4.0, 5.0, 6.0]
    np.save(tmp_path / "signals.npy", data)
    sig = load_signals(tmp_path)
    assert set(sig) == {"time", "controller.W[1]", "controller.P[1,2]", "plant.x_A", "controller.W1",
                        "controller.P12"}
    assert sig["controller.W1"].tolist() == [1.0, 2.0, 3.0] and sig["controller.P12"].tolist() == [4.0, 5.0, 6.0]
    assert load_signals(str(tmp_path))["time"].tolist() == [0.0, 0.002, 0.004]


def test_load_signals_aliases_only_names_that_end_in_an_index(tmp_path):
    """s[2].v[1] (an array element of an array of records) becomes s[2].v1; a name with a bracket that
    does not end in one gets no alias."""
    dt = np.dtype([("time", float), ("c.s[2].v[1,3]", float), ("c.x[1].y", float)])
    np.save(tmp_path / "signals.npy", np.zeros(2, dtype=dt))
    assert set(load_signals(tmp_path)) == {"time", "c.s[2].v[1,3]", "c.x[1].y", "c.s[2].v13"}


def test_load_signals_keeps_a_recorded_fmi2_name_over_the_alias(tmp_path):
    dt = np.dtype([("time", float), ("c.W1", float), ("c.W[1]", float)])
    data = np.zeros(1, dtype=dt)
    data["c.W1"], data["c.W[1]"] = 7.0, 8.0
    np.save(tmp_path / "signals.npy", data)
    assert load_signals(tmp_path)["c.W1"].tolist() == [7.0]


def test_load_signals_of_an_empty_or_missing_recording(tmp_path):
    assert load_signals(tmp_path) is None
    np.save(tmp_path / "signals.npy", np.zeros(0, dtype=[("time", float)]))
    assert load_signals(tmp_path) is None


def test_the_rise_window_follows_the_plants_default_ramp_unless_told():
    """Without ``ramp`` the window starts 0.5 s after the plant's default foam ramp (0.1 s) ends."""
    from wmr_cosim.components.plant import PlantParams

    frozen, foam = _pair(n=5001, t_on=2.0, du=0.0)
    t = foam["time"]
    step_up = np.where(t > 2.0 + 0.1 + 0.5 + 0.3, 1.0, 0.0)      # the control rises 0.3 s into the window
    foam["controller.u1"] = 2.0 + step_up
    default = disturbance_analysis(frozen, foam, Q=1.0, R=0.5)
    assert PlantParams().foam_ramp == 0.1
    assert default["foam_rise"] == disturbance_analysis(frozen, foam, Q=1.0, R=0.5, ramp=0.1)["foam_rise"]
    assert default["foam_rise"][0] == pytest.approx(1.7 / 2.0, abs=2e-3)   # on for 1.7 s of the 2 s window


def test_table1_analysis_uses_table1s_weights():
    frozen, foam = _pair(du=0.3, dF=0.6, s=(0.5, 1.5))
    t1 = paper.table1()
    want = disturbance_analysis(frozen, foam, Q=t1["Q"], R=t1["R"])
    got = analysis.table1_disturbance_analysis(frozen, foam)
    assert got["gamma_star"] == want["gamma_star"] and got["gain_incremental"] == want["gain_incremental"]
    assert got["gamma_star"] != disturbance_analysis(frozen, foam, Q=t1["R"], R=t1["Q"])["gamma_star"]


def test_fidelity_of_a_perfect_or_uniformly_smaller_reproduction():
    assert fidelity(_paper_tasks(1.0))["rms_log_factor"] == 1.0
    assert fidelity(_paper_tasks(0.5))["rms_log_factor"] == pytest.approx(2.0)


def test_divergence_is_one_line_naming_the_figure():
    """THE definition of 'diverged' (paper job, sweeps, `run` of a protocol): not ended 'ok', nothing
    recorded, a non-finite tracking error, or the larger |e_i| at the last sample above 1 rad."""
    from wmr_cosim.paper.analysis import divergence

    n = 5
    assert divergence(_run(n)) is None
    e1 = np.zeros(n)
    e1[-1] = -4.6
    assert divergence(_run(n, **{"controller.e1": e1})) == "|e1| = 4.6 rad at t = 0.008 s, above 1 rad"
    e1[-1], e1[1] = 1.0, 9.0                       # exactly 1 rad at the end, a large error before: not diverged
    assert divergence(_run(n, **{"controller.e1": e1})) is None
    ed = np.zeros(n)
    ed[2] = math.inf
    assert divergence(_run(n, **{"controller.edot2": ed})) == "edot2 is not finite"
    assert divergence(None) == "nothing was recorded"
    assert divergence(_run(n), "stopped") == "the run ended 'stopped'"
    assert run_summary(_run(n, **{"controller.e2": -e1 * 1.2}), None)["diverged"] is True
