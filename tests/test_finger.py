"""Finger contact model: conductance ramps, overlapping touches, presets, validation."""

from __future__ import annotations

import numpy as np
import pytest

from thermoskin.physics.finger import (
    PERSONS,
    RAMP_S,
    Person,
    Touch,
    contact_at,
    contact_profile,
    touch_conductance,
)

# persons of the tests' own, so that the expected values do not depend on the presets
P = {"a": Person("a", T_body=30.0, G_finger=0.04), "b": Person("b", T_body=36.0, G_finger=0.02)}


def test_presets_are_the_papers_three_persons_in_plausible_ranges():
    assert set(PERSONS) == {"man1", "woman1", "woman2"}
    for name, p in PERSONS.items():
        assert p.name == name
        assert 32.0 <= p.T_body <= 35.0
        assert 0.04 <= p.G_finger <= 0.06
    # they differ (the person-to-person spread of Fig. 18)
    assert len({(p.T_body, p.G_finger) for p in PERSONS.values()}) == 3


def test_ramp_constant_is_tens_of_ms():
    assert 0.01 <= RAMP_S <= 0.05


def test_single_touch_ramp_plateau_and_release():
    tc = Touch(t_on=1.0, duration=2.0, n_fingers=2, person="a")
    full = 2 * 0.04
    assert touch_conductance(tc, 0.5, P) == 0.0
    assert touch_conductance(tc, 1.0, P) == 0.0  # contact starts just after t_on
    assert touch_conductance(tc, 1.0 + RAMP_S / 2, P) == pytest.approx(full / 2, rel=1e-9)
    assert touch_conductance(tc, 1.0 + RAMP_S / 4, P) == pytest.approx(full / 4, rel=1e-9)
    assert touch_conductance(tc, 1.0 + RAMP_S, P) == pytest.approx(full, rel=1e-12)
    assert touch_conductance(tc, 2.0, P) == pytest.approx(full, rel=1e-12)
    assert touch_conductance(tc, 3.0 - RAMP_S / 2, P) == pytest.approx(full / 2, rel=1e-9)
    assert touch_conductance(tc, 3.0, P) == 0.0
    assert touch_conductance(tc, 3.5, P) == 0.0


def test_short_touch_is_a_triangle():
    d = RAMP_S  # shorter than press + release
    tc = Touch(t_on=0.0, duration=d, n_fingers=1, person="a")
    peak = touch_conductance(tc, d / 2, P)
    assert peak == pytest.approx(0.04 * 0.5, rel=1e-9)


def test_n_fingers_scales_conductance():
    g = [touch_conductance(Touch(0.0, 1.0, n, "b"), 0.5, P) for n in (1, 2, 3)]
    assert g == pytest.approx([0.02, 0.04, 0.06], rel=1e-12)


def test_contact_at_single_touch_returns_body_temperature():
    G, T_f, n = contact_at([Touch(0.0, 1.0, 3, "a")], 0.5, P)
    assert (G, T_f) == (pytest.approx(0.12), pytest.approx(30.0))
    assert T_f == pytest.approx(30.0)
    assert n == 3


def test_overlapping_touches_add_conductance_and_weight_temperature():
    touches = [Touch(0.0, 2.0, 2, "a"), Touch(1.0, 2.0, 1, "b")]
    G, T_f, n = contact_at(touches, 1.5, P)
    # 2 x 0.04 at 30 °C in parallel with 1 x 0.02 at 36 °C
    assert (G, n) == (pytest.approx(0.10), 3)
    assert T_f == pytest.approx((0.08 * 30.0 + 0.02 * 36.0) / 0.10)
    assert T_f == pytest.approx(31.2)
    assert n == 3
    # only the second touch after the first has ended
    G, T_f, n = contact_at(touches, 2.5, P)
    assert (G, T_f, n) == (pytest.approx(0.02), pytest.approx(36.0), 1)


def test_no_touch_gives_zero_conductance():
    G, _, n = contact_at([Touch(5.0, 1.0, 1, "a")], 1.0, P)
    assert G == 0.0 and n == 0
    assert contact_at([], 1.0, P)[0] == 0.0


def test_body_temperature_override():
    G, T_f, _ = contact_at([Touch(0.0, 1.0, 1, "a", T_body=33.3)], 0.5, P)
    assert (G, T_f) == (pytest.approx(0.04), pytest.approx(33.3))


def test_profile_agrees_with_pointwise_values():
    touches = [Touch(0.2, 0.5, 1, "a"), Touch(0.6, 0.3, 3, "b"), Touch(0.95, 0.02, 2, "a")]
    t = np.arange(0, 1.2, 1e-3)
    G, T_f, n = contact_profile(touches, t, P)
    ref = [contact_at(touches, float(tk), P) for tk in t]
    np.testing.assert_allclose(G, [r[0] for r in ref], rtol=0, atol=1e-15)
    on = G > 0
    np.testing.assert_allclose(T_f[on], np.array([r[1] for r in ref])[on], rtol=1e-14)
    np.testing.assert_array_equal(n, [r[2] for r in ref])
    # an unordered grid gives the same values
    perm = np.random.default_rng(0).permutation(t.size)
    G2, _, n2 = contact_profile(touches, t[perm], P)
    np.testing.assert_allclose(G2, G[perm], atol=1e-15)
    np.testing.assert_array_equal(n2, n[perm])


def test_touch_validation():
    for bad in (0, 4, True):
        with pytest.raises(ValueError, match="n_fingers"):
            Touch(0.0, 1.0, bad, "a")
    with pytest.raises(ValueError, match="duration"):
        Touch(0.0, 0.0, 1, "a")
    with pytest.raises(KeyError, match="unknown person"):
        contact_at([Touch(0.0, 1.0, 1, "nobody")], 0.5)
    with pytest.raises(ValueError, match="G_finger"):
        Person("x", 33.0, 0.0)


def test_conductance_override_and_objects():
    """``G`` replaces n_fingers G_finger; ``T_body`` makes an object; n_fingers 0 only with ``G``."""
    weak = Touch(0.0, 1.0, 1, "a", G=0.02)
    palm = Touch(0.0, 1.0, 0, "b", G=0.3)
    can = Touch(2.0, 1.0, 0, "a", T_body=15.0, G=0.1)
    assert touch_conductance(weak, 0.5, P) == pytest.approx(0.02, rel=1e-12)
    assert touch_conductance(weak, RAMP_S / 2, P) == pytest.approx(0.01, rel=1e-9)
    G, T_f, n = contact_at([palm], 0.5, P)
    assert (G, T_f, n) == (pytest.approx(0.3), pytest.approx(36.0), 0)  # person b's body, no finger
    G, T_f, n = contact_at([can], 2.5, P)
    assert (G, T_f, n) == (pytest.approx(0.1), pytest.approx(15.0), 0)
    # a can and a finger together: conductances in parallel
    G, T_f, n = contact_at([can, Touch(2.2, 1.0, 2, "a")], 2.5, P)
    assert (G, n) == (pytest.approx(0.18), 2)
    assert T_f == pytest.approx((0.1 * 15.0 + 0.08 * 30.0) / 0.18)
    touches = [weak, palm, can, Touch(2.4, 0.3, 3, "b", T_body=45.0)]
    t = np.arange(0.0, 3.5, 1e-3)
    Gp, T_fp, n_p = contact_profile(touches, t, P)
    ref = [contact_at(touches, float(tk), P) for tk in t]
    np.testing.assert_allclose(Gp, [r[0] for r in ref], rtol=0, atol=1e-15)
    on = Gp > 0
    np.testing.assert_allclose(T_fp[on], np.array([r[1] for r in ref])[on], rtol=1e-14)
    np.testing.assert_array_equal(n_p, [r[2] for r in ref])
    with pytest.raises(ValueError, match=r"n_fingers.*\(or 0 with G\)"):
        Touch(0.0, 1.0, 4, "a", G=0.1)
    with pytest.raises(ValueError, match=r"must be 1, 2 or 3$"):
        Touch(0.0, 1.0, 0, "a")
    with pytest.raises(ValueError, match=r"G = -0\.1"):
        Touch(0.0, 1.0, 1, "a", G=-0.1)
    with pytest.raises(ValueError, match="T_body = nan"):
        Touch(0.0, 1.0, 1, "a", T_body=float("nan"))
