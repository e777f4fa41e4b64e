"""Touchers (physics/contact.py) against closed forms, a second discretisation and physical limits."""

from __future__ import annotations

import itertools
import math
import re

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.special import erfcx

from thermoskin.physics import contact
from thermoskin.physics.contact import (
    HUMANS,
    MATERIALS,
    OBJECTS,
    SKIN,
    HumanTissue,
    Material,
    Reservoir,
    Solid,
    Toucher,
    geometric_grid,
    h_contact,
    h_natural_water,
    toucher,
)

A1 = 1e-4  # 1 cm², the tests' own contact area


def run(t: Toucher, T_g: float, G: float, seconds: float) -> np.ndarray:
    """``q_i`` per sample over ``seconds`` with the sheet held at ``T_g``."""
    n = round(seconds / t.t_s)
    return np.array([t.step(T_g, G) for _ in range(n)])


# -- materials and contact coefficient ---------------------------------------------------------

def test_materials_are_transcribed_from_their_tables():
    import ht.insulation as ins

    checked = 0
    for m in MATERIALS.values():
        key = re.search(r"'(.+)'", m.source)
        if "ht.insulation" in m.source:
            assert key is not None, m.name
            name = key.group(1)
            assert m.k == pytest.approx(ins.k_material(name), rel=1e-9), m.name
            assert m.rho == pytest.approx(ins.rho_material(name), rel=1e-9), m.name
            assert m.c == pytest.approx(ins.Cp_material(name), rel=1e-9), m.name
            checked += 1
    assert checked >= 18
    # water against IAPWS through CoolProp (a different implementation than physics.water)
    from CoolProp.CoolProp import PropsSI

    w = MATERIALS["water"]
    T = 293.15
    assert w.k == pytest.approx(PropsSI("L", "T", T, "P", 101325, "Water"), rel=1e-3)
    assert w.rho == pytest.approx(PropsSI("D", "T", T, "P", 101325, "Water"), rel=1e-3)
    assert w.c == pytest.approx(PropsSI("C", "T", T, "P", 101325, "Water"), rel=1e-3)


def test_every_class_has_materials_and_effusivities_order_the_classes():
    by_class: dict[str, list[float]] = {}
    for m in MATERIALS.values():
        by_class.setdefault(m.cls, []).append(m.effusivity)
    assert set(by_class) == set(contact.CLASSES) - {"human"}
    # metal >> glass-ceramic, water > plastic, wood > foam (textbook ordering)
    assert min(by_class["metal"]) > 4 * max(by_class["glass-ceramic"])
    assert min(by_class["glass-ceramic"]) > max(by_class["plastic"])
    assert np.median(by_class["plastic"]) > np.median(by_class["wood"])
    assert min(by_class["wood"]) > 3 * max(by_class["foam"])
    assert min(by_class["water"]) > max(by_class["plastic"])
    # skin effusivity inside in-vivo measurements (1100-1800: see SKIN's docstring)
    assert 1100 <= SKIN.effusivity <= 1800
    assert math.sqrt(237 * 2702 * 903) == pytest.approx(MATERIALS["aluminium"].effusivity)


def test_contact_coefficient_power_law():
    assert h_contact(contact.P_REF) == pytest.approx(contact.H_C_REF)
    assert h_contact(2 * contact.P_REF) / h_contact(contact.P_REF) == pytest.approx(2 ** 0.94)
    ps = [0.5e3, 1e3, 2e3, 5e3, 10e3, 50e3]
    hs = [h_contact(p) for p in ps]
    assert all(a < b for a, b in itertools.pairwise(hs))
    # a finger pad at 1 N keeps docs/model.md's fingertip conductance (0.045-0.055 W/K)
    assert 0.045 <= contact.G_contact(1.5e-4, 1.0 / 1.5e-4) <= 0.055
    for bad in (0.0, -1.0, math.nan, 1e6):
        with pytest.raises(ValueError, match="pressure"):
            h_contact(bad)
    with pytest.raises(ValueError, match="area"):
        contact.G_contact(0.0, 1e3)


def test_natural_convection_film_against_churchill_chu_with_coolprop():
    from CoolProp.CoolProp import PropsSI

    for T, H in ((22.5, 0.12), (62.5, 0.09), (7.5, 0.115)):
        Tk = T + 273.15
        P = 101325.0
        k = PropsSI("L", "T", Tk, "P", P, "Water")
        rho = PropsSI("D", "T", Tk, "P", P, "Water")
        mu = PropsSI("V", "T", Tk, "P", P, "Water")
        cp = PropsSI("C", "T", Tk, "P", P, "Water")
        beta = PropsSI("isobaric_expansion_coefficient", "T", Tk, "P", P, "Water")
        Pr = cp * mu / k
        Ra = 9.80665 * beta * 5.0 * H ** 3 / (mu / rho) ** 2 * Pr
        Nu = (0.825 + 0.387 * Ra ** (1 / 6) / (1 + (0.492 / Pr) ** (9 / 16)) ** (8 / 27)) ** 2
        assert h_natural_water(T, H) == pytest.approx(Nu * k / H, rel=0.02)
    # cold water hardly convects
    assert h_natural_water(7.5, 0.1) < 0.7 * h_natural_water(22.5, 0.1)


def test_geometric_grid():
    xs = geometric_grid(6e-3, 9, 1e-4)
    dx = np.diff(xs)
    assert xs[0] == 0.0 and xs[-1] == pytest.approx(6e-3)
    assert dx[0] == pytest.approx(1e-4)
    r = dx[1:] / dx[:-1]
    assert np.allclose(r, r[0]) and r[0] > 1
    assert geometric_grid(1e-3, 5, 1e-3) == pytest.approx([0, 0.25e-3, 0.5e-3, 0.75e-3, 1e-3])
    with pytest.raises(ValueError):
        geometric_grid(1e-3, 1, 1e-4)


# -- objects against closed forms ---------------------------------------------------------------

@pytest.mark.parametrize("name, L", [("oak", 0.02), ("glass", 0.02), ("pu_foam", 0.03), ("steel", 0.12)])
def test_semi_infinite_slab_at_perfect_contact(name, L):
    """A thick slab at 20 °C against a sheet held at 30 °C: ``q = -e A dT/sqrt(pi t)``."""
    m = MATERIALS[name]
    s = Solid([(m, L)], A1)
    s.reset(20.0)
    q = run(s, 30.0, 1e4, 30.0)
    t_mid = (np.arange(q.size) + 0.5) * s.t_s
    q_ref = -m.effusivity * A1 * 10.0 / np.sqrt(np.pi * t_mid)
    sel = t_mid >= 0.3
    assert np.max(np.abs(q[sel] / q_ref[sel] - 1)) < 0.03
    assert s.T_s == pytest.approx(30.0, abs=0.01)
    # the back face has not been reached (semi-infinite regime), and a finer grid converges
    assert s.T[-1] == pytest.approx(20.0, abs=0.3)
    f = Solid([(m, L)], A1, n_nodes=17, tau0=0.02)
    f.reset(20.0)
    qf = run(f, 30.0, 1e4, 30.0)
    assert np.max(np.abs(qf[sel] / q_ref[sel] - 1)) < 0.01


@pytest.mark.parametrize("name", ["oak", "porcelain", "steel"])
def test_semi_infinite_slab_through_a_contact_conductance(name):
    """Carslaw & Jaeger / Incropera eq. 5.60: ``q = h A dT exp(b²) erfc(b)``, ``b = h sqrt(alpha t)/k``."""
    m = MATERIALS[name]
    h = 500.0
    L = 8 * math.sqrt(m.diffusivity * 20.0)
    s = Solid([(m, L)], A1)
    s.reset(20.0)
    q = run(s, 30.0, h * A1, 20.0)
    t_mid = (np.arange(q.size) + 0.5) * s.t_s
    q_ref = -h * A1 * 10.0 * erfcx(h * np.sqrt(m.diffusivity * t_mid) / m.k)
    sel = t_mid >= 0.1
    assert np.max(np.abs(q[sel] / q_ref[sel] - 1)) < 0.03


def contact_pair(a: Toucher, b: Toucher, G: float,
                 seconds: float) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """Two touchers pressed together through ``G``, each implicit: the interface node solves
    ``G_eff,a (T_eff,a - T_c) + G_eff,b (T_eff,b - T_c) = 0``."""
    qa, Tc, energy = [], [], []
    for _ in range(round(seconds / a.t_s)):
        a.begin(G)
        b.begin(G)
        T_c = (a.G_eff * a.T_eff + b.G_eff * b.T_eff) / (a.G_eff + b.G_eff)
        qa.append(a.end(T_c))
        b.end(T_c)
        Tc.append(T_c)
        energy.append(a.energy() + b.energy())
    return np.array(qa), np.array(Tc), energy


@pytest.mark.parametrize("name", ["aluminium", "oak", "pu_foam", "glass"])
def test_two_semi_infinite_bodies_contact_temperature_and_flux(name):
    """Skin-like body at 33 °C on an object at 20 °C: ``T_c = (e1 T1 + e2 T2)/(e1 + e2)``."""
    m = MATERIALS[name]
    e1, e2 = SKIN.effusivity, m.effusivity
    a = Solid([(SKIN, 8 * math.sqrt(SKIN.diffusivity * 20))], A1)
    b = Solid([(m, 8 * math.sqrt(m.diffusivity * 20))], A1)
    a.reset(33.0)
    b.reset(20.0)
    E0 = a.energy() + b.energy()
    qa, Tc, energy = contact_pair(a, b, 1e6, 20.0)
    t_mid = (np.arange(qa.size) + 0.5) * a.t_s
    sel = t_mid >= 0.5
    Tc_ref = (e1 * 33.0 + e2 * 20.0) / (e1 + e2)
    assert np.max(np.abs(Tc[sel] - Tc_ref)) < 0.02 * 13.0
    q_ref = e1 * e2 / (e1 + e2) * A1 * 13.0 / np.sqrt(np.pi * t_mid)
    assert np.max(np.abs(qa[sel] / q_ref[sel] - 1)) < 0.03
    assert a.T_s == pytest.approx(b.T_s, abs=1e-3)
    assert max(abs(E - E0) for E in energy) < 1e-9 * abs(E0)


def test_finite_slab_long_time_equilibrium_is_the_energy_balance():
    """A 5 mm steel slab at 40 °C and a 2 J/K lumped body at 20 °C, both implicit, settle at
    the capacity-weighted mean; energy is conserved every step."""
    m = MATERIALS["steel"]
    L = 5e-3
    s = Solid([(m, L)], A1)
    s.reset(40.0)
    C_slab = m.rho * m.c * A1 * L
    C_b, T_b = 2.0, 20.0
    G = 0.05
    E0 = s.energy() + C_b * T_b
    worst = 0.0
    for _ in range(200_000):
        s.begin(G)
        # lumped body, backward Euler: C_b (T' - T)/dt = G_eff (T_eff - T')
        T_b = (C_b / s.t_s * T_b + s.G_eff * s.T_eff) / (C_b / s.t_s + s.G_eff)
        s.end(T_b)
        worst = max(worst, abs(s.energy() + C_b * T_b - E0))
    T_eq = (C_slab * 40.0 + C_b * 20.0) / (C_slab + C_b)
    assert sum(s.C) == pytest.approx(C_slab, rel=1e-12)
    assert T_b == pytest.approx(T_eq, abs=1e-3)
    assert max(s.T) - min(s.T) < 1e-3 and s.T_s == pytest.approx(T_eq, abs=1e-3)
    assert worst < 1e-9 * E0


def test_well_mixed_cup_exponential():
    """100 ml of water at 60 °C behind a thin film: ``T_w = T_g + (T0 - T_g) e^{-t/tau}``,
    ``tau = rho c V (1/G + R_wall + 1/(h A))``; then, released, it cools to the room with
    ``tau = C/G_amb``."""
    w = MATERIALS["water"]
    wall = MATERIALS["ldpe"]
    d, h, A, G = 0.05e-3, 800.0, 10e-4, 0.2
    res = Reservoir(100e-6, h_film=h, G_amb=0.0)
    cup = Solid([(wall, d)], A, reservoir=res)
    cup.reset(60.0)
    C = w.rho * w.c * res.volume
    tau = C * (1 / G + d / (wall.k * A) + 1 / (h * A))
    n = 60_000
    T_w = np.empty(n)
    for k in range(n):
        cup.step(20.0, G)
        T_w[k] = cup.T[-1]
    t = (np.arange(n) + 1) * cup.t_s
    ref = 20.0 + 40.0 * np.exp(-t / tau)
    assert np.max(np.abs(T_w - ref)) < 0.005 * 40.0
    # ambient loss alone (no contact)
    G_amb = 0.5
    cup = Solid([(wall, d)], A, reservoir=Reservoir(100e-6, h_film=h, G_amb=G_amb), T_back=22.0)
    cup.reset(60.0)
    tau_amb = sum(cup.C) / G_amb
    run(cup, 0.0, 0.0, 300.0)
    assert cup.T[-1] == pytest.approx(22.0 + 38.0 * math.exp(-300.0 / tau_amb), abs=0.02)
    assert cup.T_s == pytest.approx(cup.T[-1], abs=0.01)  # the wall follows the water


# -- human tissue ---------------------------------------------------------------------------------

def pennes_slab(w_b: float, k: float, L: float, h: float, T_out: float, T_art: float, q_met: float,
                x: np.ndarray) -> np.ndarray:
    """Steady Pennes in ``[0, L]``, convective surface (``h`` to ``T_out``), zero flux at ``L``:
    ``T = T_a' - B cosh(m (L - x))``, ``m = sqrt(w_b rho_b c_b / k)``,
    ``B = h (T_a' - T_out)/(h cosh(m L) + k m sinh(m L))``, ``T_a' = T_art + q_met/(w_b rho_b c_b)``."""
    wc = w_b * contact.RHO_BLOOD * contact.C_BLOOD
    m = math.sqrt(wc / k)
    Ta = T_art + q_met / wc
    B = h * (Ta - T_out) / (h * math.cosh(m * L) + k * m * math.sinh(m * L))
    return Ta - B * np.cosh(m * (L - x))


@pytest.mark.parametrize("part, T_start", [("finger", 30.0), ("finger", 33.0), ("palm", 35.5)])
def test_pennes_resting_state_against_the_analytic_profile(part, T_start):
    t = HumanTissue(part)
    t.reset(T_start)
    x = np.array(t.x)
    ref = pennes_slab(t.w_b, SKIN.k, HUMANS[part].depth, contact.H_ENV, contact.T_ENV, 37.0,
                      contact.Q_MET_SKIN, x)
    assert np.max(np.abs(np.array(t.T) - ref)) < 0.05
    assert t.T_s == pytest.approx(T_start, abs=1e-9)
    # a fine grid converges on the analytic profile
    f = HumanTissue(part, n_nodes=41)
    f.set_perfusion(t.w_b)
    prof = np.array(f.steady_state())
    assert np.max(np.abs(prof - pennes_slab(t.w_b, SKIN.k, HUMANS[part].depth, contact.H_ENV,
                                            contact.T_ENV, 37.0, contact.Q_MET_SKIN, np.array(f.x)))) < 0.005
    # and the rest is a steady state of the stepping (G = 0 holds the surface at T_start)
    run(t, 0.0, 0.0, 5.0)
    assert t.T_s == pytest.approx(T_start, abs=1e-9)


def test_pennes_deep_tissue_exponential_profile():
    """Tissue much deeper than ``1/m``: ``T = T_a' - (T_a' - T_s) e^{-m x}`` with
    ``T_s = (k m T_a' + h T_env)/(k m + h)``."""
    t = HumanTissue("palm", depth=60e-3, n_nodes=41, h_env=10.0)
    w_b = 5e-3
    t.set_perfusion(w_b)
    prof = np.array(t.steady_state())
    wc = w_b * contact.RHO_BLOOD * contact.C_BLOOD
    m = math.sqrt(wc / SKIN.k)
    assert m * 60e-3 > 10
    Ta = 37.0 + contact.Q_MET_SKIN / wc
    T_s = (SKIN.k * m * Ta + 10.0 * contact.T_ENV) / (SKIN.k * m + 10.0)
    assert prof[0] == pytest.approx(T_s, abs=0.01)
    assert np.max(np.abs(prof - (Ta - (Ta - T_s) * np.exp(-m * np.array(t.x))))) < 0.02


def test_perfusion_sets_the_resting_temperature():
    ws = []
    for T in (30.0, 32.0, 34.0, 36.0):
        t = toucher("finger", T)
        ws.append(t.w_b)
        assert t.T_s == pytest.approx(T, abs=1e-9) and t.truth["T_f_true"] == T
    assert all(a < b for a, b in itertools.pairwise(ws))
    # from vasoconstricted to vasodilated: a tenth to ten times IT'IS's average skin perfusion
    assert ws[0] > 0.1 * contact.W_B_SKIN and ws[-1] < 10 * contact.W_B_SKIN
    with pytest.raises(ValueError, match="T_start"):
        toucher("finger", 38.0)
    with pytest.raises(ValueError, match="out of reach"):
        toucher("finger", 26.0, T_env=27.0)  # colder than the room with no blood flow


def reference_tissue(t: HumanTissue, n_cells: int = 300):
    """Cell-centred, uniform, ``n_cells`` cells; exact in time (matrix exponential)."""
    L = t.x[-1]
    dx = L / n_cells
    k, rc = SKIN.k, SKIN.rho * SKIN.c
    wc = t.w_b * contact.RHO_BLOOD * contact.C_BLOOD
    a = k / dx ** 2 / rc

    def system(h: float, T_out: float):
        M = np.zeros((n_cells, n_cells))
        b = np.full(n_cells, (wc * 37.0 + contact.Q_MET_SKIN) / rc)
        for j in range(n_cells):
            M[j, j] -= wc / rc
            if j > 0:
                M[j, j - 1] += a
                M[j, j] -= a
            if j < n_cells - 1:
                M[j, j + 1] += a
                M[j, j] -= a
        g = 1.0 / (1.0 / h + dx / (2 * k)) / (rc * dx)  # surface cell to the outside
        M[0, 0] -= g
        b[0] += g * T_out
        return M, b

    def surface(T: np.ndarray, h: float, T_out: float) -> float:
        return (2 * k / dx * T[0] + h * T_out) / (2 * k / dx + h)

    return system, surface


def test_contact_and_recovery_against_a_fine_discretisation():
    """A finger at 33 °C on a sheet held at 24 °C for 10 s, then released for 60 s: surface
    temperature and heat against a 300-cell grid solved exactly in time."""
    t = toucher("finger", 33.0)
    G = t.truth["G_true"]
    A = t.area
    system, surface = reference_tissue(t)
    M0, b0 = system(contact.H_ENV, contact.T_ENV)
    T = np.linalg.solve(M0, -b0)
    assert surface(T, contact.H_ENV, contact.T_ENV) == pytest.approx(33.0, abs=0.05)
    Mc, bc = system(G / A, 24.0)
    dt = 0.5
    Tss_c = np.linalg.solve(Mc, -bc)
    Tss_0 = np.linalg.solve(M0, -b0)
    Pc, P0 = expm(Mc * dt), expm(M0 * dt)
    Ts_model, Ts_ref, q_model, q_ref = [], [], [], []
    steps = round(dt / t.t_s)
    for seg in range(140):
        on = seg < 20
        for _ in range(steps):
            q = t.step(24.0, G if on else 0.0)
        if on:
            T = Tss_c + Pc @ (T - Tss_c)
            Ts = surface(T, G / A, 24.0)
            q_ref.append(G * (Ts - 24.0))
            q_model.append(q)
        else:
            T = Tss_0 + P0 @ (T - Tss_0)
            Ts = surface(T, contact.H_ENV, contact.T_ENV)
        Ts_ref.append(Ts)
        Ts_model.append(t.T_s)
    Ts_model, Ts_ref = np.array(Ts_model), np.array(Ts_ref)
    assert np.max(np.abs(Ts_model - Ts_ref)) < 0.1
    assert np.max(np.abs(np.array(q_model) / np.array(q_ref) - 1)) < 0.03
    # the surface cooled by several kelvin, then recovers monotonically towards 33 °C
    assert Ts_model[19] < 30.0
    rec = Ts_model[20:]
    assert np.all(np.diff(rec) > 0) and 32.0 < rec[-1] < 33.0


def test_long_contact_hand_settles_by_perfusion_object_drifts_to_the_sheet():
    """An hour on a sheet held at 24 °C (10 ms steps: backward Euler's steady state does not
    depend on the step): the palm settles where its blood flow holds it (the analytic
    Pennes level with ``h = G/A`` and the sheet as the outside), a 10 mm oak board at the
    same start goes to the sheet's temperature. Perfusion of a cool palm takes tens of
    minutes (``rho c/(w_b rho_b c_b)`` is about 20 min)."""
    palm = toucher("palm", 33.0, t_s=0.01)
    G = palm.truth["G_true"]
    wood = Solid([(MATERIALS["oak"], 10e-3)], palm.area, t_s=0.01)
    wood.reset(33.0)
    T_g = 24.0
    T_hist_palm = []
    for _ in range(60):
        run(palm, T_g, G, 60.0)
        run(wood, T_g, G, 60.0)
        T_hist_palm.append(palm.T_s)
    ref = pennes_slab(palm.w_b, SKIN.k, HUMANS["palm"].depth, G / palm.area, T_g, 37.0,
                      contact.Q_MET_SKIN, np.array([0.0]))[0]
    assert palm.T_s == pytest.approx(ref, abs=0.05)
    assert abs(T_hist_palm[-1] - T_hist_palm[-6]) < 0.02    # settled over the last 5 min
    assert palm.T_s > T_g + 2.0 and palm.q_i > 0.1
    assert wood.T_s - T_g < 0.1 * (palm.T_s - T_g)           # drifted to the sheet
    assert wood.q_i < 0.05 * palm.q_i


def test_effusivity_orders_the_heat_drawn():
    """Same contact, same temperature difference: higher effusivity draws more heat."""
    q = {}
    for name, m in MATERIALS.items():
        s = Solid([(m, 30e-3)], A1)
        s.reset(22.0)
        q[name] = -run(s, 32.0, 500.0 * A1, 3.0).mean()
    names = list(MATERIALS)
    for a in names:
        for b in names:
            if MATERIALS[a].effusivity > 1.15 * MATERIALS[b].effusivity:
                assert q[a] > q[b], (a, b)
    assert q["aluminium"] > 2 * q["oak"] > 4 * q["pu_foam"]


def test_cold_can_pulls_for_long_wood_only_briefly():
    can = toucher("can_cold")
    wood = toucher("wood_block", T_start=5.0)
    G = can.truth["G_true"]
    qc = run(can, 24.0, G, 120.0)
    qw = run(wood, 24.0, G, 120.0)
    assert qc[-1] / qc[5000] > 0.95     # after 2 min the can still draws its heat of the 5th second
    assert qw[-1] / qw[5000] < 0.6      # the wood's surface has warmed
    assert -qc[-1] > 3 * -qw[-1]


# -- the per-sample interface ----------------------------------------------------------------

def test_step_equals_begin_end_and_q_is_the_surface_exchange():
    rng = np.random.default_rng(3)
    for kind in ("finger", "mug_hot", "aluminium_block"):
        a, b = toucher(kind), toucher(kind)
        for _ in range(3000):
            G = float(rng.choice([0.0, rng.uniform(0.01, 2.0)]))
            T_g = float(rng.uniform(10, 40))
            qa = a.step(T_g, G)
            b.begin(G)
            qb = b.end(T_g)
            assert qa == pytest.approx(qb, rel=1e-12, abs=1e-15)
            assert np.allclose(a.T, b.T, rtol=1e-12, atol=0.0)
            # q_i = G (T_s' - T_g) with the surface at the end of the sample (backward Euler)
            assert qa == pytest.approx(G * (a.T_s - T_g), rel=1e-9, abs=1e-12)


def test_heat_leaving_the_toucher_is_what_the_sheet_gets():
    """Energy balance per step: ``-(dE)`` = ``q_i t_s`` plus the sinks (objects without any: exact)."""
    t = toucher("steel_tool")
    E = t.energy()
    for _ in range(1000):
        q = t.step(35.0, 0.1)
        E_new = t.energy()
        assert E - E_new == pytest.approx(q * t.t_s, rel=1e-9, abs=1e-12)
        E = E_new


def test_large_contact_conductance_is_stable_and_bounded():
    """A hand on a cold sheet through 100 W/K: no oscillation, the surface stays between."""
    t = toucher("hand", 34.0)
    Ts = []
    for _ in range(2000):
        t.step(10.0, 100.0)
        Ts.append(t.T_s)
    Ts = np.array(Ts)
    assert np.all(np.isfinite(Ts)) and np.all(Ts >= 10.0) and np.all(Ts <= 37.0)
    assert np.all(np.diff(Ts) <= 1e-12)


def test_coupled_with_the_simulated_skin_at_1ms_matches_a_finer_step():
    """``begin`` / skin step with ``(G_eff, T_eff)`` / ``end``: the split at 1 ms against 0.1 ms."""
    from thermoskin.params import load_config
    from thermoskin.sim.skin import SimulatedSkin

    def simulate(kind: str, t_s: float, G: float) -> np.ndarray:
        cfg = load_config().replace(sampling={"t_s": t_s})
        skin = SimulatedSkin(cfg)
        skin.reset_equilibrium(24.0, 0.141, 20.0)
        tch = toucher(kind, t_s=t_s)
        out = []
        every = round(0.01 / t_s)
        for k in range(round(3.0 / t_s)):
            g = G if k * t_s >= 0.5 else 0.0
            tch.begin(g)
            T_g0 = skin.T_g
            skin.step(24.0, 0.141, 20.0, tch.G_eff, tch.T_eff)
            tch.end(0.5 * (T_g0 + skin.T_g))
            if (k + 1) % every == 0:
                out.append(skin.T_g)
        return np.array(out)

    for kind, G in (("palm", None), ("aluminium_block", 5.0)):
        G = toucher(kind).truth["G_true"] if G is None else G
        coarse, fine = simulate(kind, 1e-3, G), simulate(kind, 1e-4, G)
        swing = np.ptp(fine)
        assert swing > 0.5
        assert np.max(np.abs(coarse - fine)) < 0.02 * swing


# -- factory, presets, table --------------------------------------------------------------------

def test_toucher_factory_and_truth():
    for kind in contact.kinds():
        t = toucher(kind)
        tr = t.truth
        assert tr["kind"] == kind
        assert tr["toucher_true"] == ("human" if kind in HUMANS else "object")
        assert tr["class_true"] in contact.CLASSES
        assert t.T_s == pytest.approx(tr["T_f_true"])
        assert tr["G_true"] == pytest.approx(h_contact(tr["pressure_true"]) * tr["area_true"])
    t = toucher("palm", T_start=31.0, area=50e-4, pressure=3e3)
    assert t.area == 50e-4 and t.T_s == pytest.approx(31.0, abs=1e-9)
    assert t.truth["G_true"] == pytest.approx(h_contact(3e3) * 50e-4)
    assert toucher("water_bag").truth["material_true"] == "water"
    # the persons of finger.py give the resting temperature
    from thermoskin.physics.finger import PERSONS

    for person in PERSONS.values():
        t = toucher("finger", person.T_body)
        assert t.T_s == pytest.approx(person.T_body, abs=1e-9)
        assert t.truth["perfusion_true"] == t.w_b > 0
    assert toucher("can_cold").truth["contents_true"] == "water"


@pytest.mark.parametrize("args, match", [
    (("glove",), "unknown kind 'glove'"),
    (("finger", math.nan), "T_start"),
    (("oak", None, -1.0), "area"),
    (("oak", None, None, 0.0), "pressure"),
    (("finger", 33.0, None, 2e5), "pressure"),
    (("mug_hot", 500.0), "T_start"),
])
def test_toucher_bad_input_is_one_clear_error(args, match):
    with pytest.raises(ValueError, match=match):
        toucher(*args)


def test_object_validation():
    with pytest.raises(ValueError, match="liquid"):
        toucher("mug_hot", -5.0)
    s = Solid([(MATERIALS["oak"], 0.01)], A1)
    with pytest.raises(ValueError, match="no steady state"):
        s.steady_state()
    assert s.steady_state(G=0.1, T_g=30.0) == pytest.approx([30.0] * len(s.C))
    with pytest.raises(ValueError, match="area"):
        Solid([(MATERIALS["oak"], 0.01)], 0.0)
    with pytest.raises(ValueError, match="unknown material"):
        Solid([("granite", 0.01)], A1)
    with pytest.raises(ValueError, match="body part"):
        HumanTissue("foot")


def test_material_validation():
    with pytest.raises(ValueError, match="class"):
        Material("x", "stone", 1.0, 1.0, 1.0, "")
    with pytest.raises(ValueError, match="k = 0"):
        Material("x", "metal", 0.0, 1.0, 1.0, "")


def test_docstring_table_matches_the_presets():
    doc = contact.__doc__
    assert doc is not None
    num = r"\s+([\d.]+)"
    rows = re.findall(r"^    (\w+)\s+([\w-]+)" + num * 5 + "$", doc, re.M)
    assert {r[0] for r in rows} == set(HUMANS) | set(OBJECTS)
    for name, cls, e, T, A, p, G in rows:
        tr = toucher(name).truth
        assert tr["class_true"] == cls
        assert float(e) == pytest.approx(tr["effusivity_true"], rel=0.005, abs=0.5)
        assert float(T) == pytest.approx(tr["T_f_true"])
        assert float(A) == pytest.approx(tr["area_true"] * 1e4, rel=0.01)
        assert float(p) == pytest.approx(tr["pressure_true"] / 1e3, rel=0.01)
        assert float(G) == pytest.approx(tr["G_true"], rel=0.05)
