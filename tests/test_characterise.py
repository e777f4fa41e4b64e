"""What touched: the characteriser against touchers stepped by the finite-volume bodies of
physics.contact (an independent model: a grid, backward Euler, Pennes perfusion), the flow
kernel against its closed-form limits, the identifiability rules, the events table."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import erfc

from thermoskin.estimation.events import EVENT_COLUMNS, ContactEvent, write_events
from thermoskin.params import Config
from thermoskin.physics import contact as ct
from thermoskin.touch.characterise import (
    Characteriser,
    flux_kernel,
    no_touch_sheet,
    regressors,
    sheet_coupling,
)

BONDED = Config().replace(skin={"R_g": 1.0, "R_ag": 10.0})
"""A sheet bonded to the pipe, insulated from the air: the pipe moves it by 10/11."""
TABLE1 = Config()
"""The paper's skin: the sheet held by the air, the pipe moves it by 1/11."""


def touch(cfg: Config, kind: str, T0: float, probe_K: float, hold: float = 4.0, seed: int = 1,
          noise: float = 0.02) -> tuple[Characteriser, ContactEvent, dict[str, float]]:
    """A toucher of physics.contact held ``hold`` s on the sheet, the pipe's water stepped by
    ``±probe_K`` every second from 0.3 s on (the probe's square wave), the sheet in balance
    (``T_g = T_x + R_par q``, solved with the toucher's exact one-step response), the flow
    with white noise: the characteriser fed with it, the event, the truth."""
    t_s, t_on = 1e-3, 2.0
    t_off = t_on + hold
    t = np.arange(int((t_off + 1.0) / t_s)) * t_s
    T_a = np.full(len(t), 20.0)
    s = t - t_on - 0.3
    T_w = 24.0 + np.where((s >= 0) & (t < t_off), np.where((s % 2.0) < 1.0, probe_K, -probe_K), 0.0)
    R_par = sheet_coupling(cfg)
    T_x = no_touch_sheet(cfg, T_w, T_a)
    body = ct.toucher(kind, T0)
    G = body.truth["G_true"]
    q = np.zeros(len(t))
    for k in range(len(t)):
        on = t_on <= t[k] < t_off
        body.begin(G if on else 0.0)
        q[k] = body.G_eff * (body.T_eff - T_x[k]) / (1.0 + body.G_eff * R_par) if on else 0.0
        body.end(T_x[k] + R_par * q[k])
    dq = q + noise * np.random.default_rng(seed).standard_normal(len(t))
    ch = Characteriser(cfg)
    ch.feed(t, dq, T_w, T_a)
    ch.finish()
    ev = ContactEvent(onset=t_on, detected_at=t_on + 0.04, release=t_off, duration=hold,
                      sign=1 if q[int(3.0 / t_s)] > 0 else -1, peak_dq=float(np.abs(q).max()),
                      mean_dq=float(q[q != 0].mean()), energy=float(q.sum() * t_s))
    return ch, ev, body.truth


def test_flux_kernel_limits() -> None:
    """``F(x) = exp(x²) erfc(x)``: 1 at the start; the asymptote ``1/(x sqrt(pi)) (1 - 1/(2x²))``;
    a direct evaluation where it does not overflow."""
    assert flux_kernel(0.0, 5.0) == pytest.approx(1.0)
    assert flux_kernel(1.0, -1.0) == pytest.approx(1.0)  # before the onset
    x = 40.0
    asym = 1 / (x * math.sqrt(math.pi)) * (1 - 1 / (2 * x * x))
    assert flux_kernel(x, 1.0) == pytest.approx(asym, rel=1e-5)
    for x in (0.1, 0.7, 2.0):
        assert flux_kernel(x, 1.0) == pytest.approx(math.exp(x * x) * float(erfc(x)), rel=1e-12)


def test_duhamel_regressors_for_a_step_of_the_sheet() -> None:
    """``T_x`` stepping by ``d`` at ``τ_1``: superposition gives ``u_2 = T_x0 F(κ√τ) + d F(κ√(τ - τ_1))``."""
    kap, T0x, d, t1 = 0.8, 21.0, 0.6, 1.0
    tau = np.arange(0.025, 3.0, 0.05)
    T_x = np.where(tau >= t1, T0x + d, T0x)
    u1, u2 = regressors(kap, tau, T_x, T0x)
    np.testing.assert_allclose(u1, math.exp(0) * np.array([flux_kernel(kap, x) for x in tau]), rtol=1e-12)
    expect = T0x * u1 + d * np.where(tau >= t1, [flux_kernel(kap, x - t1) for x in tau], 0.0)
    np.testing.assert_allclose(u2, expect, atol=0.02 * d)  # the step falls within a bin


@pytest.mark.parametrize(("kind", "T0", "human"), [("finger", 31.0, True), ("wood_block", 22.0, False)])
def test_probe_on_a_bonded_sheet_identifies_temperature_and_conductance(kind: str, T0: float,
                                                                       human: bool) -> None:
    ch, ev, truth = touch(BONDED, kind, T0, probe_K=0.5)
    r = ch.characterise(ev)
    assert r.toucher == ("human" if human else "object")
    assert abs(r.T_f_hat - truth["T_f_true"]) <= 1.5
    assert abs(r.T_f_hat - truth["T_f_true"]) <= 3.0 * r.T_f_sd + 0.3
    assert r.G_hat == pytest.approx(truth["G_true"], rel=0.25)
    assert r.kind == "hold"


@pytest.mark.parametrize("cfg", [BONDED, TABLE1], ids=["bonded", "table1"])
def test_without_the_probe_temperature_and_conductance_are_not_identifiable(cfg: Config) -> None:
    """A still sheet shows only ``G' (T_0 - T_x)``: no ``T_f_hat``, no ``G_hat``; person or
    object is still told (from the effusivity the decay shows and the flow's sign)."""
    ch, ev, _ = touch(cfg, "finger", 31.0, probe_K=0.0)
    r = ch.characterise(ev)
    assert math.isnan(r.T_f_hat) and math.isnan(r.T_f_sd)
    assert math.isnan(r.G_hat) and math.isnan(r.G_sd)
    assert r.toucher == "human" and r.p_human >= 0.8


def test_the_papers_skin_cannot_separate_them_even_with_the_probe() -> None:
    """With the sheet held by the air the pipe's ±0.5 K moves it by ±0.045 K: too little."""
    ch, ev, _ = touch(TABLE1, "palm", 33.0, probe_K=0.5)
    r = ch.characterise(ev)
    assert math.isnan(r.T_f_hat)
    assert r.toucher == "human"


def test_a_cold_can_is_an_object_from_a_tap() -> None:
    """Heat out of the skin at 24 °C: no person's hand does that."""
    ch, ev, _ = touch(BONDED, "can_cold", 5.0, probe_K=0.0, hold=0.5)
    r = ch.characterise(ev)
    assert r.kind == "tap" and r.toucher == "object" and r.p_human < 0.05


def test_a_hot_mug_needs_the_probe() -> None:
    """A 55 °C mug (glass-ceramic, ``e`` 1585) through a small contact brings the heat of a
    33 °C hand (``e`` 1180) through a larger one: without the probe it passes for a person;
    with it, its temperature shows and it is an object."""
    ch, ev, _ = touch(BONDED, "mug_hot", 55.0, probe_K=0.0)
    assert ch.characterise(ev).toucher != "object"
    ch, ev, _ = touch(BONDED, "mug_hot", 55.0, probe_K=0.5)
    r = ch.characterise(ev)
    assert r.toucher == "object" and r.material == "glass-ceramic"


def test_a_live_call_knows_less_than_the_release() -> None:
    """At 0.25 s after the onset the kind is not known yet; at the release it is."""
    ch, ev, _ = touch(BONDED, "finger", 31.0, probe_K=0.5)
    early = ch.characterise(ev, at=0.25)
    assert early.kind == "" and early.t_used == pytest.approx(0.25)
    assert ch.characterise(ev).kind == "hold"


def test_annotated_events_table(tmp_path: Path) -> None:
    """Text columns as text, unidentified values as empty fields, numbers round-trip."""
    ch, ev, _ = touch(BONDED, "finger", 31.0, probe_K=0.0)
    e = ch.annotate(ev)
    write_events(tmp_path / "ev.csv", [e, ev])
    with open(tmp_path / "ev.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == list(EVENT_COLUMNS)
    assert rows[0]["kind"] == "hold" and rows[0]["toucher"] == "human"
    assert rows[0]["T_f_hat"] == "" and rows[0]["G_hat"] == ""  # not identifiable
    assert float(rows[0]["p_human"]) == e.p_human
    assert rows[1]["kind"] == "" and rows[1]["p_human"] == ""  # not characterised


def test_bins_are_the_means_of_their_samples_whatever_the_chunks() -> None:
    """:class:`thermoskin.touch.characterise.Bins`: each 50 ms bin is the mean of its finite samples
    (computed here by grouping the samples in plain Python), a bin with a signal all NaN is
    left out, and any chunking of the same samples gives the same bins, bit for bit."""
    from thermoskin.touch.characterise import BIN_S, Bins

    rng = np.random.default_rng(5)
    n = 3000
    t = np.arange(n) * 1e-3 + 0.0123
    x = [rng.normal(0.1, 0.05, n), 24.0 + rng.normal(0.0, 0.02, n), 20.0 + rng.normal(0.0, 0.02, n)]
    x[0][rng.random(n) < 0.05] = np.nan  # NaN samples are left out
    x[1][680:750] = np.nan  # all of bin 14 (0.70-0.75 s) in T_w: that bin goes
    groups: dict[int, list[list[float]]] = {}
    for i in range(n):
        groups.setdefault(math.floor(t[i] / BIN_S + 1e-9), [[], [], []])
        for j in range(3):
            if math.isfinite(x[j][i]):
                groups[math.floor(t[i] / BIN_S + 1e-9)][j].append(float(x[j][i]))
    expect = {k: [math.fsum(v) / len(v) for v in g] for k, g in groups.items() if all(g)}
    runs = []
    for cuts in ([], [1, 49, 50, 51, 1234, 2999], sorted(rng.choice(np.arange(1, n), 40, replace=False))):
        b = Bins()
        for s, e in zip([0, *cuts], [*cuts, n], strict=True):
            b.feed(t[s:e], x[0][s:e], x[1][s:e], x[2][s:e])
        b.finish()
        runs.append((list(b.idx), list(b.q), list(b.w), list(b.a)))
    assert runs[0] == runs[1] == runs[2]  # bit for bit
    idx, q, w, a = runs[0]
    assert idx == sorted(expect) and len(idx) == len(groups) - 1 and 14 not in idx
    got = np.array([q, w, a]).T
    want = np.array([expect[k] for k in idx])
    assert np.allclose(got, want, rtol=1e-14, atol=1e-15)


def test_box_moments_equal_quadrature_for_every_component_at_once() -> None:
    """``_box_moments`` (Stein's lemma on the softened box) against a dense quadrature of
    ``N(m, v)`` times ``B(x)``, with the boxes of several components broadcast against a grid of
    ``(m, v)``, as the posterior calls it."""
    from scipy.special import ndtr

    from thermoskin.touch.characterise import _box_moments

    trap = getattr(np, "trapezoid", None) or np.trapz  # numpy 1.26 has the old name only
    rng = np.random.default_rng(3)
    m = rng.normal(30.0, 8.0, (2, 4))
    v = np.exp(rng.normal(0.0, 1.5, (2, 4)))
    lo = np.array([10.0, 28.0, 45.0])[:, None, None]
    hi = np.array([20.0, 36.0, 70.0])[:, None, None]
    s = 0.7
    lM0, mean, var = _box_moments(m, v, lo, hi, s)
    assert lM0.shape == mean.shape == var.shape == (3, 2, 4)
    for c in range(3):
        for i in range(2):
            for j in range(4):
                sd = math.sqrt(v[i, j])
                x = np.linspace(m[i, j] - 12 * sd, m[i, j] + 12 * sd, 200_001)
                w = np.exp(-0.5 * (x - m[i, j]) ** 2 / v[i, j]) / math.sqrt(2 * math.pi * v[i, j])
                w = w * (ndtr((x - lo[c, 0, 0]) / s) - ndtr((x - hi[c, 0, 0]) / s))
                M0 = trap(w, x)
                if M0 < 1e-12:  # far outside the box: the weight is nil, the moments a fallback
                    continue
                mu = trap(w * x, x) / M0
                assert math.exp(lM0[c, i, j]) == pytest.approx(M0, rel=1e-6)
                assert mean[c, i, j] == pytest.approx(mu, rel=1e-7, abs=1e-7)
                assert var[c, i, j] == pytest.approx(trap(w * (x - mu) ** 2, x) / M0, rel=1e-5)
