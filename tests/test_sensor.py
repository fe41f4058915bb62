"""The sensor chain against (42), (43) and the encoder's resolution."""
import json
import math

import numpy as np
import pytest
from scipy.linalg import expm as scipy_expm

from wmr_cosim.components.linalg import expm, zoh
from wmr_cosim.components.sensor import Sensor, SensorParams, filter_matrices

H = 0.002
Q = 2 * math.pi / (500 * 19.7)  # one count of wheel angle [rad]


def test_count_resolution():
    assert SensorParams().count_angle == pytest.approx(Q, rel=1e-15)
    assert Q == pytest.approx(6.378e-4, rel=1e-3)


def test_counts_are_floor_of_angle_with_phase():
    s = Sensor(phase1=0.0, phase2=0.5)
    s.reset(0.0, 0.0)
    out = s.step(H, 10.4 * Q, 10.4 * Q)
    assert out[6] == 10 and out[7] == 10     # floor(10.4), floor(10.9)
    out = s.step(H, 10.6 * Q, 10.6 * Q)
    assert out[6] == 10 and out[7] == 11     # wheel 2 is half a count out of phase
    out = s.step(H, -0.3 * Q, -0.3 * Q)
    assert out[6] == -1 and out[7] == 0


def test_increment_velocity_42():
    """(42): alpha_dot = 2 pi / (500 x 19.7 x h) INC, the mean speed over the step."""
    s = Sensor(phase1=0.5, phase2=0.5)
    s.reset(0.0, 0.0)
    w = 4.85  # rad/s
    incs = []
    for k in range(1, 2001):
        out = s.step(H, w * k * H, -w * k * H)
        incs.append((out[4], out[5]))
    inc = np.array(incs)
    quanta = inc[:, 0] / (Q / H)
    assert np.allclose(quanta, np.round(quanta), atol=1e-9)           # whole counts
    assert set(np.round(quanta).astype(int)) <= {15, 16}              # 4.85*0.002/Q = 15.2 counts
    assert inc[:, 0].mean() == pytest.approx(w, rel=1e-3)             # the mean is the true speed
    assert inc[:, 1].mean() == pytest.approx(-w, rel=1e-3)


def test_expm_matches_scipy():
    rng = np.random.default_rng(1)
    for scale in (0.01, 1.0, 30.0):
        a = rng.normal(size=(4, 4)) * scale
        assert np.allclose(expm(a), scipy_expm(a), rtol=1e-12, atol=1e-12)


def _poles(c2, c1, c0):
    disc = math.sqrt(c1 * c1 - 4 * c2 * c0)
    return (-c1 + disc) / (2 * c2), (-c1 - disc) / (2 * c2)


def test_normalised_filter_poles_and_dc_gain():
    p1, p2 = _poles(1e-4, 0.03, 1.0)
    assert p1 == pytest.approx(-38.197, rel=1e-4) and p2 == pytest.approx(-261.803, rel=1e-4)
    ad, bd = filter_matrices("normalised", H)
    A = np.array(ad).reshape(3, 3)[1:, 1:]
    B = np.array(bd)[1:]
    # DC gain: y_ss = (I - A)^-1 B = 1
    yss = np.linalg.solve(np.eye(2) - A, B)
    assert yss[0] == pytest.approx(1.0, rel=1e-12)


def test_printed_filter_has_dc_gain_1e4():
    ad, bd = filter_matrices("printed", H)
    A = np.array(ad).reshape(3, 3)[1:, 1:]
    B = np.array(bd)[1:]
    assert np.linalg.solve(np.eye(2) - A, B)[0] == pytest.approx(1e4, rel=1e-8)


@pytest.mark.parametrize("h", [0.002, 0.001, 0.005])
def test_filter_step_response_is_the_analytic_one(h):
    """A speed step through (43), normalised: y(t) = v (1 + (p2 e^{p1 t} - p1 e^{p2 t}) / (p1 - p2)),
    and the angle is its exact integral.  The increment velocity is a whole number of counts per step."""
    n_counts = 3
    v = n_counts * Q / h
    s = Sensor(phase1=0.5, phase2=0.5)
    s.reset(0.0, 0.0)
    p1, p2 = _poles(1e-4, 0.03, 1.0)
    for k in range(1, 200):
        t = k * h
        out = s.step(h, n_counts * Q * k, n_counts * Q * k)
        y = v * (1 + (p2 * math.exp(p1 * t) - p1 * math.exp(p2 * t)) / (p1 - p2))
        theta = v * (t + (p2 / p1 * (math.exp(p1 * t) - 1) - p1 / p2 * (math.exp(p2 * t) - 1)) / (p1 - p2))
        assert out[2] == pytest.approx(y, rel=1e-10, abs=1e-12)
        assert out[0] == pytest.approx(theta, rel=1e-10, abs=1e-12)
        assert out[4] == pytest.approx(v, rel=1e-12)


def test_angle_from_counts():
    s = Sensor(angle_source="counts", phase1=0.0, phase2=0.5)
    s.reset(0.2, 0.2)
    out = s.step(H, 0.2 + 100.2 * Q, 0.2 + 100.2 * Q)
    # the count angle is relative to the start and resolved to one count
    assert abs(out[0] - 100.2 * Q) < Q and abs(out[1] - 100.2 * Q) < Q
    assert out[0] / Q == pytest.approx(round(out[0] / Q), abs=1e-9)


def test_zoh_of_integrator():
    ad, bd = zoh([[0.0]], [[1.0]], 0.3)
    assert ad[0][0] == 1.0 and bd[0][0] == pytest.approx(0.3, rel=1e-15)


def test_step_change_recomputes_discretisation_and_state_round_trips():
    s = Sensor()
    s.reset(0.0, 0.0)
    for k in range(1, 300):
        s.step(H, 0.01 * k, 0.011 * k)
    st = s.get_state()
    a = [s.step(H * 0.5, 3.0 + 0.005 * k, 3.3 + 0.0055 * k) for k in range(1, 100)]
    s.set_state(st)
    b = [s.step(H * 0.5, 3.0 + 0.005 * k, 3.3 + 0.0055 * k) for k in range(1, 100)]
    assert a == b


def test_fused_multiply_add_is_rounded_once():
    """linalg's fma: a * b + c with one rounding (exact rational arithmetic as the reference)."""
    import random
    from fractions import Fraction

    from wmr_cosim.components.linalg import _fma_exact, fma
    e = 2.0 ** -30
    # (1 + e)(1 - e) - 1 = -e^2 exactly: an unfused product rounds e^2 away and gives 0
    assert (1 + e) * (1 - e) - 1.0 == 0.0
    for f in (_fma_exact, fma):
        assert f(1 + e, 1 - e, -1.0) == -(e * e)
    rng = random.Random(5)
    for _ in range(20000):
        a, b, c = (rng.choice((-1, 1)) * rng.random() * 10.0 ** rng.uniform(-20, 20) for _ in range(3))
        exact = Fraction(a) * Fraction(b) + Fraction(c)
        assert _fma_exact(a, b, c) == float(exact)


def test_filter_discretisation_keeps_its_bits():
    """The exact discretisation of (43) at 2 ms, bit for bit as the G1 runs have always used it (computed
    before with numpy's matrix product on an x86-64 with FMA; now in the standard library, the same on every
    machine): a change here changes every run in its last bits."""
    ad, bd = filter_matrices("normalised", H)
    assert [x.hex() for x in ad] == [
        "0x1.0000000000000p+0", "0x1.04a201294db36p-9", "0x1.ba6e9c62f8533p-20",
        "0x0.0p+0", "0x1.f78fafe864ce4p-1", "0x1.87a59a819caacp-10",
        "0x0.0p+0", "-0x1.de15a71b37beap+3", "0x1.1214a76072ff1p-1"]
    assert [x.hex() for x in bd] == ["0x1.82dc05ccf0348p-17", "0x1.0e0a02f36810dp-6", "0x1.de15a71b37b70p+3"]


def test_sensor_components_need_no_numpy():
    """The sensor (and the other components an FMU runs) import only the standard library."""
    import subprocess
    import sys
    code = ("import sys; sys.modules['numpy'] = None\n"
            "from wmr_cosim.components import sensor, plant, controller\n"
            "s = sensor.Sensor(); s.reset(0.0, 0.0); print(s.step(0.002, 0.01, 0.02)[2])")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    ref = Sensor()
    ref.reset(0.0, 0.0)
    assert float(p.stdout) == ref.step(H, 0.01, 0.02)[2]

def _drive(s: Sensor, n: int = 400, h: float = 0.002, w: float = 9.7) -> list[tuple[float, ...]]:
    return [s.step(h, w * h * (k + 1), 0.9 * w * h * (k + 1)) for k in range(n)]


def test_encoder_noise_is_off_by_default_and_bit_identical():
    ref = _drive(Sensor())
    assert _drive(Sensor(noise_std=0.0, noise_seed=7)) == ref


def test_encoder_noise_is_seeded_and_flips_counts_with_the_gaussian_probability():
    a, b = _drive(Sensor(noise_std=0.3, noise_seed=3)), _drive(Sensor(noise_std=0.3, noise_seed=3))
    assert a == b and a != _drive(Sensor()) and a != _drive(Sensor(noise_std=0.3, noise_seed=4))
    # a wheel at rest 0.3 counts below an edge: the count reads one more when the jitter exceeds 0.3 counts
    s = Sensor(noise_std=0.5, noise_seed=11)
    q = s.q
    s.reset(0.0, 0.0)
    alpha = (10.0 + 0.7) * q           # fractional position 0.7 of wheel 1 (phase1 = 0)
    n = 20_000
    up = sum(s.step(0.002, alpha, 0.0)[6] == 11 for _ in range(n)) / n
    p = 0.5 * math.erfc(0.3 / (0.5 * math.sqrt(2.0)))      # P(N(0, 0.5) > 0.3)
    assert up == pytest.approx(p, abs=4.0 * math.sqrt(p * (1 - p) / n))


def test_encoder_noise_state_round_trips():
    s = Sensor(noise_std=0.4, noise_seed=2)
    _drive(s, 50)
    st = s.get_state()
    rest = _drive(s, 50)
    s2 = Sensor(noise_std=0.4, noise_seed=2)
    s2.set_state(st)
    assert _drive(s2, 50) == rest


@pytest.mark.parametrize("kw", [{"noise_std": -0.1}, {"noise_std": math.nan}, {"noise_seed": 1.5},
                                {"noise_seed": -1}])
def test_encoder_noise_parameters_are_checked(kw):
    with pytest.raises(ValueError, match="sensor parameter noise_"):
        SensorParams(**kw)


def test_state_restored_into_a_new_sensor_carries_the_noise_generator_exactly():
    """The generator's whole state travels, including a normal deviate it holds back (random.gauss makes
    them in pairs): a fresh sensor given the state draws the same noise and measures the same."""
    s = Sensor(noise_std=0.4, noise_seed=3)
    _drive(s, 31)
    s._rng.gauss(0.0, 1.0)           # an odd number of draws: one deviate is held back
    st = s.get_state()
    assert st["rng"][2] is not None
    s2 = Sensor(noise_std=0.4, noise_seed=99)
    s2.set_state(json.loads(json.dumps(st)))
    assert s2._rng.getstate() == s._rng.getstate()
    assert s2.outputs() == s.outputs()
    assert _drive(s2, 40) == _drive(s, 40)


def test_a_state_with_or_without_a_noise_generator_restores_the_counts_of_any_sensor():
    """A sensor's state carries its generator only when it has noise; restored into a sensor of the other
    kind it sets the counts and the filter, and the generator (or its absence) stays the receiver's own."""
    noisy, quiet = Sensor(noise_std=0.4, noise_seed=2), Sensor()
    _drive(noisy, 30)
    _drive(quiet, 20)
    other_quiet, other_noisy = Sensor(), Sensor(noise_std=0.4, noise_seed=5)
    before = other_noisy._rng.getstate()
    other_quiet.set_state(noisy.get_state())
    other_noisy.set_state(quiet.get_state())
    assert other_quiet._rng is None and other_quiet.outputs() == noisy.outputs()
    assert other_noisy._rng.getstate() == before and other_noisy.outputs() == quiet.outputs()


def test_state_restored_into_a_new_sensor_before_its_first_step():
    """Restoring a state taken right after reset into a sensor that has already run makes its first step
    the same as the original's (the first step only initialises the filter)."""
    s = Sensor()
    s.reset(0.0, 0.0)
    st = s.get_state()
    other = Sensor()
    _drive(other, 10)
    other.set_state(st)
    assert _drive(other, 30) == _drive(s, 30)
