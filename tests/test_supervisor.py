"""The safety supervisor, sample by sample (no I/O)."""

from __future__ import annotations

import math

import pytest

from thermoskin.devices import protocol as proto
from thermoskin.params import Config, ConfigError, load_config
from thermoskin.runtime import supervisor as sv


def sup(**safety: object) -> sv.Supervisor:
    return sv.Supervisor(Config().replace(safety=safety) if safety else Config())


def test_quiet_samples_pass_and_gate_passes_outputs() -> None:
    s = sup()
    for k in range(2000):
        assert s.check(k * 1e-3, 24.0 + 0.01 * math.sin(k), 30.0, 20.0) == sv.OK
    assert s.gate(0.3, 0.141) == (0.3, 0.141)


@pytest.mark.parametrize(("sample", "code"), [
    ((24.0, 45.0, 20.0, 0, 0, 0), sv.OVERTEMP),
    ((24.0, 2.0, 20.0, 0, 0, 0), sv.OVERTEMP),
    ((math.nan, 30.0, 20.0, 0, 0, proto.ST_OPEN_W), sv.TC_OPEN),
    ((41.0, 39.0, 20.0, 0, 0, 0), sv.TOUCH_TEMP),
    ((24.0, 30.0, 20.0, 0, proto.CH_W, 0), sv.STUCK),
    ((24.0, 30.0, 20.0, proto.CH_A, 0, 0), sv.STALE),
    ((24.0, 30.0, 20.0, 0, 0, proto.ST_WATCHDOG), sv.DEVICE),
])
def test_each_fault_trips_at_once_and_latches(sample: tuple, code: int) -> None:
    s = sup()
    assert s.check(0.0, 24.0, 30.0, 20.0) == sv.OK
    assert s.check(0.001, *sample) == code
    assert s.tripped and s.t_fault == 0.001 and s.detail
    assert s.gate(0.5, 0.141) == (0.0, 0.0)
    assert s.check(0.002, 24.0, 30.0, 20.0) == code  # latched: a good sample does not clear it
    s.reset()  # the explicit restart
    assert s.check(0.003, 24.0, 30.0, 20.0) == sv.OK and s.gate(0.5, 0.1) == (0.5, 0.1)


def test_short_nan_gap_held_over_lasting_one_trips() -> None:
    s = sup(max_nan_s=0.15)
    t = 0.0
    for _ in range(100):  # one bad thermocouple conversion: 0.1 s of NaN
        assert s.check(t, math.nan, 30.0, 20.0) == sv.OK
        t += 1e-3
    assert s.check(t, 24.0, 30.0, 20.0) == sv.OK
    t0 = t = t + 1e-3
    while s.check(t, 24.0, math.nan, 20.0) == sv.OK:
        t += 1e-3
        assert t - t0 < 0.2
    assert s.code == sv.NAN and t - t0 == pytest.approx(0.151, abs=1.5e-3)


def test_link_timeout() -> None:
    s = sup(link_timeout_s=0.05)
    assert s.link_lost(1.0, 0.04) == sv.OK
    assert s.link_lost(1.01, 0.051) == sv.LINK


def test_surface_estimate_network_is_less_conservative() -> None:
    cfg = Config()
    net = sv.Supervisor(cfg.replace(safety={"surface": "network"}))
    Rg, Rag = cfg.skin.R_g, cfg.skin.R_ag
    assert net.surface(41.0, 20.0) == pytest.approx((Rag * 41 + Rg * 20) / (Rg + Rag))
    assert net.check(0.0, 41.0, 39.0, 20.0) == sv.OK  # the sheet sits near the air
    assert sup().check(0.0, 41.0, 39.0, 20.0) == sv.TOUCH_TEMP


def test_device_fault_frame() -> None:
    s = sup()
    assert s.device_fault(0.5, "tc-open", math.nan) == sv.TC_OPEN


def test_safety_config_validated(tmp_path) -> None:
    with pytest.raises(ConfigError, match=r"safety\.T_touch_max = 70"):
        Config().replace(safety={"T_touch_max": 70})
    with pytest.raises(ConfigError, match=r"safety\.T_p_min"):
        Config().replace(safety={"T_p_min": 40.0, "T_p_max": 30.0})
    f = tmp_path / "c.toml"
    f.write_text("[safety]\nT_touch_max = 38.5\nsurface = 'network'\n")
    cfg = load_config(f)
    assert cfg.safety.T_touch_max == 38.5 and cfg.safety.surface == "network"


@pytest.mark.parametrize(("name", "code"), [("tc-open", sv.TC_OPEN), ("overtemp", sv.OVERTEMP),
                                            ("internal", sv.DEVICE), ("fault-9", sv.DEVICE)])
def test_device_fault_frames(name: str, code: int) -> None:
    """A FAULT frame from the device: its name's code (an unknown one is a device fault), the time,
    the value and the words latched; outputs zero."""
    s = sup()
    assert s.device_fault(1.25, name, 46.5) == code
    assert (s.code, s.t_fault, s.value, s.detail) == (code, 1.25, 46.5, f"device reported {name}")
    assert s.gate(0.5, 0.141) == (0.0, 0.0)


def test_link_lost_past_the_timeout_only() -> None:
    """No sample for exactly the timeout is not yet a loss; past it, a link fault with the age
    (s) as its value and in ms in its words; a fault already latched is kept."""
    s = sup(link_timeout_s=0.05)
    assert s.link_lost(1.0, 0.05) == sv.OK and not s.tripped
    assert s.link_lost(1.1, 0.0625) == sv.LINK
    assert (s.t_fault, s.value, s.detail) == (1.1, 0.0625, "no sample from the device for 62 ms")
    s = sup()
    s.device_fault(0.5, "overtemp", 50.0)
    assert s.link_lost(0.9, 10.0) == sv.OVERTEMP and s.detail == "device reported overtemp"


def test_channels_are_named_in_the_words() -> None:
    s = sup()
    assert s.check(0.0, 24.0, 30.0, 20.0, stale=proto.CH_W | proto.CH_A) == sv.STALE
    assert s.detail == "no new thermocouple reading (channels T_w,T_a)" and s.value == 5.0
    s = sup()
    assert s.check(0.0, 24.0, 30.0, 20.0, stuck=proto.CH_P) == sv.STUCK
    assert s.detail == "thermocouple reading frozen (channels T_p)"
    assert sv._channels(0) == "" and sv._channels(7) == "T_w,T_p,T_a"


@pytest.mark.parametrize(("sample", "code", "value", "detail"), [
    ((0.0, 30.0, 20.0, 0, 0, proto.ST_OPEN_P), sv.TC_OPEN, 0.0, "open thermocouple flagged by the device"),
    ((24.0, 40.25, 20.0, 0, 0, 0), sv.OVERTEMP, 40.25, "T_p = 40.25 degC outside [4, 40] degC"),
    ((40.5, 30.0, 20.0, 0, 0, 0), sv.TOUCH_TEMP, 40.5,
     "estimated surface 40.50 degC above the touch-safe limit 40 degC"),
    ((24.0, 30.0, 20.0, 0, proto.CH_P, 0), sv.STUCK, 2.0, "thermocouple reading frozen (channels T_p)"),
    ((24.0, 30.0, 20.0, proto.CH_W, 0, 0), sv.STALE, 1.0, "no new thermocouple reading (channels T_w)"),
    ((24.0, 30.0, 20.0, 0, 0, proto.ST_SAFE), sv.DEVICE, 16.0, "device in its safe state (status 0x0010)"),
])
def test_each_fault_latches_its_time_value_and_words(sample: tuple, code: int, value: float,
                                                     detail: str) -> None:
    s = sup()
    assert s.check(2.5, *sample) == code
    assert (s.code, s.t_fault, s.value, s.detail) == (code, 2.5, value, detail)
    s.reset()  # the explicit restart: nothing latched
    assert s.code == sv.OK and math.isnan(s.t_fault) and math.isnan(s.value) and s.detail == ""
    assert s.check(3.0, 24.0, 30.0, 20.0) == sv.OK


def test_the_limits_themselves_are_allowed() -> None:
    """T_p at either bound, the surface at its limit, NaN for exactly max_nan_s: no fault; past each, one."""
    s = sup()
    assert s.check(0.0, 24.0, 40.0, 20.0) == sv.OK and s.check(0.001, 24.0, 4.0, 20.0) == sv.OK
    assert s.check(0.002, 40.0, 30.0, 20.0) == sv.OK  # surface = T_w (pipe) = 40: at the limit
    s = sup(max_nan_s=0.25)
    assert s.check(1.0, math.nan, 30.0, 20.0) == sv.OK
    assert s.check(1.25, 24.0, math.nan, 20.0) == sv.OK  # 0.25 s of NaN: not more than allowed
    assert s.check(1.375, math.nan, 30.0, 20.0) == sv.NAN
    assert (s.t_fault, s.detail) == (1.375, "NaN readings for more than 0.25 s") and math.isnan(s.value)
    s = sup(max_nan_s=0.25)  # a good sample in between starts the count again
    for t, Tw in ((0.0, math.nan), (0.2, 24.0), (0.3, math.nan), (0.5, math.nan)):
        assert s.check(t, Tw, 30.0, 20.0) == sv.OK


def test_surface_estimate_and_stuck_switch() -> None:
    """The surface is the pipe's reading (``pipe``) or the network's no-touch sheet temperature
    (``network``: (R_ag T_w + R_g T_a) / (R_g + R_ag), written out); ``stuck_readings = 0`` turns
    the frozen-reading check off, 1 keeps it."""
    assert sup().surface(30.0, 20.0) == 30.0
    cfg = Config().replace(safety={"surface": "network"})
    Rg, Rag = cfg.skin.R_g, cfg.skin.R_ag
    assert sv.Supervisor(cfg).surface(30.0, 20.0) == pytest.approx((Rag * 30.0 + Rg * 20.0) / (Rg + Rag))
    assert sup(stuck_readings=0).check(0.0, 24.0, 30.0, 20.0, stuck=proto.CH_W) == sv.OK
    assert sup(stuck_readings=1).check(0.0, 24.0, 30.0, 20.0, stuck=proto.CH_W) == sv.STUCK


def test_a_lost_link_and_a_stop_trip_at_once_and_latch_the_first() -> None:
    """``link_error``: a ``link`` fault (7) at its time, the detail naming the cause; ``stop``: the
    safe outputs on request (9), not a fault of the skin. Whichever comes first is kept."""
    s = sup()
    assert s.check(0.0, 24.0, 30.0, 20.0) == sv.OK
    assert sv.LINK == 7 and sv.STOPPED == 9
    assert s.link_error(0.25, "port closed") == sv.LINK
    assert s.code == sv.LINK and s.t_fault == 0.25 and math.isnan(s.value)
    assert s.detail == "link lost: port closed" and s.gate(0.4, 0.1) == (0.0, 0.0)
    assert s.stop(0.5) == sv.LINK and s.t_fault == 0.25  # the first kept
    s = sup()
    assert s.stop(1.5) == sv.STOPPED
    assert s.code == sv.STOPPED and s.t_fault == 1.5 and math.isnan(s.value)
    assert s.detail == "stopped on request" and s.gate(0.4, 0.1) == (0.0, 0.0)
    assert s.link_error(2.0, "x") == sv.STOPPED and s.detail == "stopped on request"


def test_the_pipe_surface_does_not_need_the_air() -> None:
    """With the surface taken as the pipe's reading (the default), an air reading lost (NaN) or
    absurd changes nothing: the surface is ``T_w``."""
    s = sup()
    assert s.surface(24.5, math.nan) == 24.5 and s.surface(24.5, math.inf) == 24.5
