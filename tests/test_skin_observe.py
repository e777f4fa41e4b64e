"""The skin's per-patch estimation: inlet water through the pipes, cross-talk, simultaneous touches."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from thermoskin.physics.finger import Touch
from thermoskin.sim.scenarios import Scenario
from thermoskin.sim.skin_scenarios import SkinContact, SkinScenario
from thermoskin.skin.inlet import delayed, displacement, inlet_inputs
from thermoskin.skin.layout import Pipe, load_skin

ROOT = Path(__file__).resolve().parent.parent


def test_delay_is_the_pipe_length_over_the_flow():
    """At constant v the plug flow delays by L / (v t_s) samples; stopped, the inlet stands."""
    t_s, v, L = 1e-3, 0.1, 0.02
    x = displacement(np.full(1000, v), t_s)
    k = delayed(x, L)
    assert k[500] == 500 - round(L / (v * t_s))
    x2 = displacement(np.r_[np.full(300, v), np.zeros(200), np.full(500, v)], t_s)
    k2 = delayed(x2, L)
    assert np.all(k2[301:500] == k2[301])  # no water moves while the pump stands


def test_inlet_is_the_upstream_outlet_delayed_and_cooled():
    """Patch 2 of a loop gets patch 1's outlet reading, L/v later, cooled by exp(-age/tau)."""
    skin = load_skin(ROOT / "examples" / "forearm.toml")
    n, P = 2000, len(skin.patches)
    t_s = skin.cfg.sampling.t_s
    rng = np.random.default_rng(1)
    T_w = 24.0 + rng.normal(0, 0.1, (n, P))
    T_p = np.full((n, P), 25.0)
    v = np.full((n, P), 0.141)
    T_a = np.full((n, P), 20.0)
    T_in, _fr = inlet_inputs(skin, t_s, [T_w, np.full((n, P), math.nan)], T_p, v, T_a, None)
    lp = skin.loops[0]
    up, down = lp.patches[0], lp.patches[1]
    pipe: Pipe = lp.pipes[1]
    d = int(np.ceil(pipe.length / (0.141 * t_s) - 1e-9))
    k = 1500
    expect = 20.0 + (T_w[k - d, up] - 20.0) * math.exp(-d * t_s / pipe.tau_loss)
    assert T_in[k, down] == pytest.approx(expect, abs=1e-12)
    d0 = int(np.ceil(lp.pipes[0].length / (0.141 * t_s) - 1e-9))  # the tank through the supply pipe
    assert T_in[k, up] == pytest.approx(20.0 + 5.0 * math.exp(-d0 * t_s / lp.pipes[0].tau_loss), abs=1e-12)


def _short(skin, contacts, duration=22.0):
    base = Scenario("t", "test", duration=duration, T_w_cmd=24.0, T_a=20.0, pump="logic")
    return SkinScenario("t", "test", base, tuple(contacts))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from thermoskin.runtime.skin_loop import run_skin
    from thermoskin.skin.log import read_skin_log
    from thermoskin.skin.observe import observe_skin

    skin = load_skin(ROOT / "examples" / "forearm.toml")
    d1, d4 = "dorsal1", "dorsal4"
    up = _short(skin, [SkinContact(Touch(t_on=12.0, duration=2.5, n_fingers=3, person="man1"),
                                   patch=d1, position=0.015)])
    both = _short(skin, [SkinContact(Touch(t_on=12.0, duration=2.5, n_fingers=3, person="man1"), patch=d1,
                                     position=0.015),
                         SkinContact(Touch(t_on=12.3, duration=2.5, n_fingers=3, person="man1"), patch=d4,
                                     position=0.015)])
    out = {}
    for name, sc in (("up", up), ("both", both)):
        path = tmp_path_factory.mktemp(name) / "log.parquet"
        run_skin(skin, sc, path)
        log = read_skin_log(path, skin)
        truth = {k: log.cols.pop(k) for k in ("q_i", "contact_true", "position_true")}
        out[name] = (skin, observe_skin(log, skin, locate=False), truth)
    return out


def _during(obs, i, a, b):
    return [e for e in obs.events if e.patch == i and e.event.onset < b and e.event.release > a]


def test_upstream_touch_is_not_reported_downstream(runs):
    skin, obs, truth = runs["up"]
    assert truth["contact_true"][:, 0].any() and not truth["contact_true"][:, 1:].any()
    assert _during(obs, 0, 12.0, 14.5), "the touch on the upstream patch is reported"
    for i in skin.loops[0].patches[1:]:
        assert not _during(obs, i, 12.0, 16.0), f"{skin.patches[i].name}: the upstream touch echoed"


def test_simultaneous_touches_on_one_loop_each_on_its_patch(runs):
    skin, obs, truth = runs["both"]
    touched = {i for i in range(len(skin.patches)) if truth["contact_true"][:, i].any()}
    assert touched == {0, 3}
    for i in touched:
        assert _during(obs, i, 12.0, 15.0), f"{skin.patches[i].name}: its own touch is reported"
    for i in (1, 2):
        assert not _during(obs, i, 12.0, 16.0), f"{skin.patches[i].name}: untouched, reported"


def test_no_event_outside_the_touches_while_the_loops_chatter(runs):
    """No patch reports a contact outside its touch: with the pumps chattering from the start,
    the inlets of the downstream patches swing 0.1-0.4 K at every switch (the lumped node's
    misfit to that, ``skin_transport``, gave alarms at 7-10 s before it was corrected)."""
    for name in ("up", "both"):
        skin, obs, truth = runs[name]
        for e in obs.events:
            c = truth["contact_true"][:, e.patch].astype(bool)
            t = np.arange(len(c)) * skin.cfg.sampling.t_s
            span = (t >= e.event.onset - 0.5) & (t <= e.event.release + 0.5)
            assert c[span].any(), f"{name}: {e.name} reported at {e.event.onset:.2f} s, untouched then"
