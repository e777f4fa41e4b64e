"""Thermocouple boards: lag against its closed form, conversions and hold, jitter statistics,
the ideal-board identity, per-sample against array paths, configuration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from thermoskin.devices import protocol as proto
from thermoskin.params import Config, ConfigError, SensorParams, load_config
from thermoskin.sim.plant import SimulatedPlant
from thermoskin.sim.scenarios import SCENARIOS
from thermoskin.sim.sensors import FRESH_A, FRESH_P, FRESH_W, Board, Sensors

T_S = 1e-3


def per_sample(board: Board, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = np.empty(x.size)
    f = np.empty(x.size, dtype=bool)
    for k, xk in enumerate(x.tolist()):
        r[k] = board.read(xk)
        f[k] = board.fresh != 0
    return r, f


@pytest.mark.parametrize("t_s", [1e-3, 1e-2])
def test_lag_step_response_is_the_closed_form(t_s: float) -> None:
    tau = 0.7
    n0, n = 50, round(5.0 / t_s)
    x = np.where(np.arange(n) < n0, 20.0, 21.0)
    r, fresh = per_sample(Board("T_a", lag=tau, t_s=t_s), x)
    assert fresh.all()
    np.testing.assert_array_equal(r[:n0 + 1], 20.0)  # the reading at the step is the old value
    t = (np.arange(n) - n0) * t_s
    expected = 21.0 - np.exp(-t[n0:] / tau)  # y(t) = x1 + (x0 - x1) e^{-t/tau}
    np.testing.assert_allclose(r[n0:], expected, rtol=0, atol=1e-12)
    # one time constant after the step: 63.2 % of the way
    k = n0 + round(tau / t_s)
    assert r[k] - 20.0 == pytest.approx(1.0 - math.exp(-1.0), abs=1e-12)


def test_no_lag_reads_the_true_value() -> None:
    x = 24.0 + 0.01 * np.arange(100)
    r, _ = per_sample(Board("T_w", t_s=T_S), x)
    np.testing.assert_array_equal(r, x)


def test_defaults_are_the_old_sensors_draw_for_draw() -> None:
    """Same seeds, same draws: ``quantise(x + noise_T n)`` with channel i on spawn(3)[i]."""
    p = SensorParams(seed=7)
    x = {"T_w": 24.0 + 0.002 * np.arange(3000), "T_p": np.full(3000, 24.3),
         "T_a": 20.0 - 0.001 * np.arange(3000)}
    seqs = np.random.SeedSequence(7).spawn(3)
    q = p.quantum_T
    expected = {ch: q * np.floor((x[ch] + p.noise_T * np.random.default_rng(seqs[i]).standard_normal(3000))
                                 / q + 0.5) for i, ch in enumerate(("T_w", "T_p", "T_a"))}
    s = Sensors(p, T_S)
    got = [s.read(float(a), float(b), float(c))
           for a, b, c in zip(x["T_w"], x["T_p"], x["T_a"], strict=True)]
    want = np.column_stack([expected[c] for c in ("T_w", "T_p", "T_a")])
    np.testing.assert_array_equal(np.array(got), want)
    assert s.fresh == FRESH_W | FRESH_P | FRESH_A
    rw, rp, ra, fresh = Sensors(p, T_S).read_arrays(x["T_w"], x["T_p"], x["T_a"])
    np.testing.assert_array_equal(rw, expected["T_w"])
    np.testing.assert_array_equal(rp, expected["T_p"])
    np.testing.assert_array_equal(ra, expected["T_a"])
    assert np.all(fresh == 7)


def test_fresh_bits_are_the_protocols() -> None:
    assert (FRESH_W, FRESH_P, FRESH_A) == (proto.CH_W, proto.CH_P, proto.CH_A)


def test_hold_and_fresh_follow_the_period() -> None:
    n = 2000
    x = 24.0 + 0.5 * np.sin(np.arange(n) * T_S * 3.0)
    p = SensorParams(seed=3, period_T_w=0.1, period_T_p=0.0334, period_T_a=0.25)
    rw, rp, ra, fresh = Sensors(p, T_S).read_arrays(x, x, x)
    k = np.arange(n)
    # 10 Hz: every 100th sample; 30 Hz: the nearest sample of j * 33.4 ms (no ties); 4 Hz: every 250th
    conv_p = np.zeros(n, bool)
    conv_p[np.round(np.arange(60) * 33.4).astype(int)] = True
    for bit, conv in ((FRESH_W, k % 100 == 0), (FRESH_P, conv_p), (FRESH_A, k % 250 == 0)):
        np.testing.assert_array_equal((fresh & bit) != 0, conv)
    for r, conv in ((rw, k % 100 == 0), (ra, k % 250 == 0)):
        last = np.maximum.accumulate(np.where(conv, k, 0))
        np.testing.assert_array_equal(r, r[last])  # held between conversions
    # the board reads what the ideal board (same seed) reads at the conversion samples
    iw, ip, ia, ifresh = Sensors(SensorParams(seed=3), T_S).read_arrays(x, x, x)
    assert np.all(ifresh == 7)
    np.testing.assert_array_equal(rw[k % 100 == 0], iw[k % 100 == 0])
    np.testing.assert_array_equal(rp[conv_p], ip[conv_p])
    np.testing.assert_array_equal(ra[k % 250 == 0], ia[k % 250 == 0])


def test_ten_hz_jittered_lagged_board_is_the_ideal_board_at_its_conversions() -> None:
    n = 5000
    x = 20.0 + np.where(np.arange(n) > 1200, 1.0, 0.0) + 0.3 * np.sin(np.arange(n) * 2e-3)
    common = {"seed": 11, "lag_T_w": 0.05, "lag_T_p": 0.2, "lag_T_a": 1.0}
    board = Sensors(SensorParams(**common, period_T_w=0.1, period_T_p=0.1, period_T_a=0.1,
                                 jitter=0.004), T_S)
    ideal = Sensors(SensorParams(**common), T_S)
    b = board.read_arrays(x, x, x)
    i = ideal.read_arrays(x, x, x)
    for ch, bit in enumerate((FRESH_W, FRESH_P, FRESH_A)):
        conv = (b[3] & bit) != 0
        assert 48 <= conv.sum() <= 51
        np.testing.assert_array_equal(b[ch][conv], i[ch][conv])
        k = np.arange(n)
        np.testing.assert_array_equal(b[ch], b[ch][np.maximum.accumulate(np.where(conv, k, 0))])
    # each board jitters on its own stream: the three conversion patterns differ
    assert len({tuple(np.flatnonzero(b[3] & bit)) for bit in (1, 2, 4)}) == 3


def test_jitter_statistics() -> None:
    """Offsets of the conversion samples from the nominal grid against their exact distribution.

    With ``t_j = j P + u``, ``u ~ U(-J, J)``, J = 3 ms, and the nearest sample at 1 ms, the
    offset is ``floor(u / 1 ms + 1/2)``: -3 and 3 with probability 1/12, -2..2 with 1/6.
    """
    P, J = 0.01, 0.003
    n = 200_000
    board = Board("T_w", period=P, jitter=J, t_s=T_S, noise_seed=np.random.SeedSequence(5),
                  jitter_seed=np.random.SeedSequence(6))
    conv = np.flatnonzero(board.conversions(n))
    assert conv[0] == 0 and np.all(np.diff(conv) > 0)
    j = np.arange(1, len(conv))
    off = conv[1:] - 10 * j
    assert set(np.unique(off)) <= set(range(-3, 4))
    counts = np.array([np.sum(off == m) for m in range(-3, 4)])
    p = np.array([1, 2, 2, 2, 2, 2, 1]) / 12
    expected = p * off.size
    chi2 = float(np.sum((counts - expected) ** 2 / expected))
    assert chi2 < 22.46  # chi-square, 6 degrees of freedom, 0.999 quantile
    assert abs(off.mean()) < 4 * math.sqrt(19 / 6 / off.size)
    assert off.var() == pytest.approx(19 / 6, rel=0.05)  # sum m^2 p(m) = 19/6 samples^2
    r = np.corrcoef(off[:-1], off[1:])[0, 1]
    assert abs(r) < 4 / math.sqrt(off.size)  # independent instants, no random walk
    # without jitter: exactly the grid
    plain = Board("T_w", period=P, t_s=T_S)
    np.testing.assert_array_equal(np.flatnonzero(plain.conversions(n)), np.arange(0, n, 10))


def test_per_sample_and_array_paths_agree_exactly() -> None:
    n = 3000
    x = 24.0 + 0.4 * np.sin(np.arange(n) * 5e-3) + np.where(np.arange(n) > 900, 0.5, 0.0)
    p = SensorParams(seed=21, period_T_w=0.1, period_T_p=0.05, period_T_a=0.2, jitter=0.006,
                     lag_T_w=0.02, lag_T_a=1.0)
    s = Sensors(p, T_S)
    rows = [(*s.read(v, v + 0.3, v - 4.0), s.fresh) for v in x.tolist()]
    one = np.array(rows)
    s.reset()
    arr = s.read_arrays(x, x + 0.3, x - 4.0)
    for c in range(3):
        np.testing.assert_array_equal(one[:, c], arr[c])
    np.testing.assert_array_equal(one[:, 3].astype(int), arr[3])
    # and reset restarts the same sequence
    s.reset()
    assert s.read(x[0], x[0] + 0.3, x[0] - 4.0) == tuple(one[0, :3])
    with pytest.raises(ValueError, match="reset"):
        s.board("T_w").read_array(x)


def test_board_validation() -> None:
    with pytest.raises(ValueError, match="t_s"):
        Board("T_w", period=0.1)
    with pytest.raises(ValueError, match="half the period"):
        Board("T_w", period=0.1, jitter=0.05, t_s=T_S)
    with pytest.raises(ValueError, match="shorter than t_s"):
        Board("T_w", period=1e-4, t_s=T_S)
    with pytest.raises(ValueError, match="lag"):
        Board("T_w", lag=-1.0, t_s=T_S)


def test_sensor_config_ranges(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match=r"sensor\.jitter.*half of sensor\.period_T_a"):
        SensorParams(period_T_a=0.1, jitter=0.05)
    with pytest.raises(ConfigError, match=r"sensor\.lag_T_a = -1"):
        SensorParams(lag_T_a=-1.0)
    with pytest.raises(ConfigError, match=r"sensor\.period_T_w = 0\.0005.*sampling\.t_s"):
        Config().replace(sensor={"period_T_w": 0.0005})
    p = tmp_path / "s.toml"
    p.write_text("[sensor]\nperiod_T_w = 0.1\nperiod_T_p = 0.1\nperiod_T_a = 0.1\njitter = 0.003\n"
                 "lag_T_a = 1.0\n")
    cfg = load_config(p)
    assert (cfg.sensor.period_T_p, cfg.sensor.jitter, cfg.sensor.lag_T_a) == (0.1, 0.003, 1.0)
    d = SensorParams()
    assert (d.period_T_w, d.period_T_p, d.period_T_a, d.jitter, d.lag_T_w, d.lag_T_p, d.lag_T_a) == (0.0,) * 7


def test_plant_and_sim_device_carry_the_boards() -> None:
    from thermoskin.devices.sim_device import SimDevice

    cfg = Config().replace(sensor={"period_T_w": 0.1, "period_T_p": 0.1, "period_T_a": 0.05})
    sc = SCENARIOS["none"].with_duration(0.5)
    dev = SimDevice(cfg, sc)
    dev.open()
    got = []
    while not dev.done:
        s = dev.read_sample()
        assert s is not None
        got.append((s.t, s.fresh, s.T_w))
        dev.write_command(0.0, 0.141)
    fresh = np.array([g[1] for g in got])
    k = np.arange(len(got))
    np.testing.assert_array_equal(fresh, np.where(k % 100 == 0, 3, 0) | np.where(k % 50 == 0, 4, 0))
    # measure() twice in one sample: the sensors advance once
    plant = SimulatedPlant(cfg, sc)
    a = plant.measure()
    assert plant.measure() == a and plant.fresh == 7
