"""The batched simulation of a sweep: many points, one compiled loop over points and samples.

Each point (row ``i``) is one whole run of one configuration; the rows share a structure
(the number of samples ``n`` and the MPC's horizon ``H``) and nothing else: every
parameter is per row. Rows are independent, so they are shared out over the cores
(``prange``) and each row's numbers do not depend on the others'.

One sample ``k`` (``t = k t_s``) of a **closed-loop** row is, in order, what
:func:`thermoskin.runtime.closed_loop.run_closed_loop` does with the simulated plant
(:class:`~thermoskin.sim.plant.SimulatedPlant`, network skin, Peltier tank) and the loop
body (:class:`~thermoskin.runtime.controller.SkinController`)::

    T_w, T_p, T_a = boards(T_w_true, T_p_true, T_a_true[k])     sim.sensors: lag, noise, quantum, hold
    v       = pump(T_w, T_w_cmd)                               Sec. V, hysteresis and dwell
    T_p_cmd = mpc(T_w, T_a, T_w_cmd, T_p_cmd_prev)             eqs. 9-11 (fast path, else the box QP)
    drive   = inner(T_p, T_p_cmd, T_a)                         PI with conditional integration
    estimator.step(t, T_w, T_p, v, T_a, T_w_cmd, fresh, drive)  estimation.kernel (the same code)
    tank.step(drive, T_a_true, (T_p_true - T_w_true)/R_w(v))   physics.peltier, RK4 sub-steps
    skin.step(T_p_true, v, T_a_true, G_c[k], T_f[k])           eqs. 3-7, exact ZOH (sim.skin)

An **open-loop** row is :func:`thermoskin.sim.run.simulate` (the prescribed tank
``T_p(t)``, the pump logic on the measured ``T_w``) followed by
:func:`thermoskin.analysis.observe.observe` (the estimator over the log, no drive), fused into one
loop. The supervisor and the ``[plausible]`` screen of the live loop are not run: a
simulated reading is always plausible, and a sweep reports what the design does, not
when its safety limits would stop it.

Accumulated per row (nothing is stored per sample): the contacts (kernel event records),
``sum (T_w_true - T_w_cmd)^2`` from ``t_track`` on, the Peltier's electric energy
``sum P_elec t_s``, and ``dq_i_hat``'s sums over one-finger contact samples and over quiet
samples (from ``t_track`` on, no contact and none in the last ``T_QUIET`` s), for the SNR.
"""

from __future__ import annotations

import math

import numpy as np

from thermoskin._jit import njit, prange
from thermoskin.control.mpc import interval_ok
from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.physics.peltier import rk4_pair, tank_linear
from thermoskin.sim.skin import zoh_scalars
from thermoskin.sweep.qp import box_qp

# the plant's own arithmetic, compiled here (one source for the plant and the batch)
_tank_linear = njit(forceinline=True)(tank_linear)
_rk4_pair = njit(forceinline=True)(rk4_pair)
_zoh_scalars = njit(forceinline=True)(zoh_scalars)

# per-row scalar parameters (PS[i, :])
(S_TS, S_CW, S_CG, S_RG, S_RAW, S_RAG, S_RWON, S_RWOFF, S_VON, S_HALF, S_NDWELL,
 S_NMOD, S_SM, S_RM, S_KM, S_IMAX, S_CT, S_RTA, S_CS, S_RS, S_NSUB, S_DMIN, S_DMAX,
 S_KP, S_KITS, S_SPAN, S_FFMODE, S_FF0, S_FF1, S_FF2, S_FF3,
 S_TPMIN, S_TPMAX, S_K0, S_K1, S_K2, S_K3, S_IV0, S_IV1, S_IV2, S_IV3, S_IV4, S_IV5, S_IV6, S_IV7,
 S_NOISE, S_QUANT, S_LAGW, S_LAGP, S_LAGA, S_TTRACK, S_W0, S_G0, S_P0, S_SINK0, S_TPPREV0,
 S_CLOSED, S_NSTILL) = range(58)
NS = 58

# per-row results (R[i, :])
R_SSE, R_NTRACK, R_ENERGY, R_SUM1, R_N1, R_SUMQ, R_SUMQ2, R_NQ, R_NARMED, R_QPS, R_QPFALL, R_NEV = range(12)
NR = 12

# per-sample class of the truth (CLS[i, k])
CLS_OTHER, CLS_QUIET, CLS_ONE = 0, 1, 2


@njit(cache=True, forceinline=True)
def _zoh(ps, Rw, G, c):
    """``sim.skin.zoh_coefficients`` of the network (``physics.network.state_space``) into ``c``."""
    Cw, Cg, Rg, Raw, Rag = ps[S_CW], ps[S_CG], ps[S_RG], ps[S_RAW], ps[S_RAG]
    t_s = ps[S_TS]
    a = -(1 / Rw + 1 / Raw + 1 / Rg) / Cw
    b = 1 / (Rg * Cw)
    cc = 1 / (Rg * Cg)
    d = -(1 / Rg + 1 / Rag + G) / Cg
    B10, B11 = 1 / (Rw * Cw), 1 / (Raw * Cw)
    B21, B22, B23 = 1 / (Rag * Cg), 1 / Cg, G / Cg
    p11, p12, p21, p22, m11, m12, m21, m22 = _zoh_scalars(a, b, cc, d, t_s)
    # B = [[B10, B11, 0, 0], [0, B21, B22, B23]]
    c[0], c[1], c[2], c[3] = p11, p12, p21, p22
    c[4] = m11 * B10 + m12 * 0.0
    c[5] = m11 * B11 + m12 * B21
    c[6] = m11 * 0.0 + m12 * B22
    c[7] = m11 * 0.0 + m12 * B23
    c[8] = m21 * B10 + m22 * 0.0
    c[9] = m21 * B11 + m22 * B21
    c[10] = m21 * 0.0 + m22 * B22
    c[11] = m21 * 0.0 + m22 * B23


@njit(cache=True, forceinline=True)
def _read(x, y, k, ch, lag, noise_T, q, NOISE, CONV, last):
    """One board (``sim.sensors.Board.read``): returns ``(reading, fresh, new lag state)``."""
    if lag > 0.0:
        if y != y:
            y = x
        yy = y
        y = lag * y + (1.0 - lag) * x
    else:
        yy = x
    if CONV[ch, k] == 0:
        return last, 0, y
    r = yy + noise_T * NOISE[ch, k]
    if q > 0.0:
        r = q * math.floor(r / q + 0.5)
    return r, 1, y


_interval_ok = njit(cache=True, forceinline=True)(interval_ok)


@njit(cache=True, forceinline=True)
def _in_interval(ps, T_w, T_a, cmd, prev):
    """``Mpc._in_interval`` (:func:`thermoskin.control.mpc.interval_ok`, compiled)."""
    return _interval_ok(T_w, T_a, cmd, prev, ps[S_IV0], ps[S_IV1], ps[S_IV2], ps[S_IV3], ps[S_IV4],
                        ps[S_IV5], ps[S_IV6], ps[S_IV7], ps[S_TPMAX] - 1e-9, ps[S_TPMIN] + 1e-9)


@njit(cache=True)
def _row(ps, G_c, T_f, T_a_true, cmd, T_p_presc, cls, NOISE, CONV, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw,
         Kmat, Fmat, Pm, Pinv, res, events):
    """One whole run of one row (module doc); fills ``res`` and ``events``."""
    n = G_c.shape[0]
    t_s = ps[S_TS]
    closed = ps[S_CLOSED] != 0.0
    H = Kmat.shape[0]
    st = K.new_state()
    ev = np.zeros(K.NEV)
    c = np.zeros(12)
    # QP workspace
    W = np.zeros(H, dtype=np.int8)
    u = np.zeros(H)
    ustar = np.zeros(H)
    qv = np.zeros(H)
    M = np.zeros((H, H))
    rr = np.zeros(H)
    gg = np.zeros(H)
    idx = np.zeros(H, dtype=np.int64)
    ws_set = False
    # plant
    Tw, Tg = ps[S_W0], ps[S_G0]
    Tp, Ts = ps[S_P0], ps[S_SINK0]
    v_prev, G_prev = -1.0, -1.0
    # sensors
    lw = math.exp(-t_s / ps[S_LAGW]) if ps[S_LAGW] > 0.0 else 0.0
    lp = math.exp(-t_s / ps[S_LAGP]) if ps[S_LAGP] > 0.0 else 0.0
    la = math.exp(-t_s / ps[S_LAGA]) if ps[S_LAGA] > 0.0 else 0.0
    yw = yp = ya = math.nan
    rw = rp = ra = math.nan
    noise_T, quant = ps[S_NOISE], ps[S_QUANT]
    # pump
    on = True
    n_dwell = int(ps[S_NDWELL])
    held = n_dwell
    n_still = int(ps[S_NSTILL])
    still = n_still
    half, v_on = ps[S_HALF], ps[S_VON]
    # mpc, inner loop
    prev = ps[S_TPPREV0]
    integral = 0.0
    drive = 0.0
    ff_last = 0.0
    dmin, dmax, span = ps[S_DMIN], ps[S_DMAX], ps[S_SPAN]
    Tpmin, Tpmax = ps[S_TPMIN], ps[S_TPMAX]
    # tank constants
    nm, Sm, Rm, Km, Imax = ps[S_NMOD], ps[S_SM], ps[S_RM], ps[S_KM], ps[S_IMAX]
    Ct, Cs = ps[S_CT], ps[S_CS]
    gt, gs = 1.0 / ps[S_RTA], 1.0 / ps[S_RS]
    n_sub = int(ps[S_NSUB])
    h = t_s / n_sub
    sse = 0.0
    ntrack = 0.0
    energy = 0.0
    s1 = n1 = sq = sq2 = nq = narm = 0.0
    qps = 0.0
    qpfall = 0.0
    ne = 0
    cap = events.shape[0]
    t_track = ps[S_TTRACK]
    for k in range(n):
        t = k * t_s
        T_a_k = T_a_true[k]
        Tp_true = Tp if closed else T_p_presc[k]
        rw, fw, yw = _read(Tw, yw, k, 0, lw, noise_T, quant, NOISE, CONV, rw)
        rp, fp, yp = _read(Tp_true, yp, k, 1, lp, noise_T, quant, NOISE, CONV, rp)
        ra, fa, ya = _read(T_a_k, ya, k, 2, la, noise_T, quant, NOISE, CONV, ra)
        fresh = fw | (fp << 1) | (fa << 2)
        cm = cmd[k]
        # pump logic (control.pump.PumpLogic.step)
        if fw and not on:
            still += 1
        if held >= n_dwell:
            if on:
                if rw > cm + half:
                    on = False
                    held = 0
                    still = 0
            elif rw < cm - half and still >= n_still:
                on = True
                held = 0
        if held < n_dwell:
            held += 1
        if closed:
            # MPC (control.mpc.Mpc.step, on_stop = "solve")
            if math.isfinite(rw) and math.isfinite(ra) and math.isfinite(cm):
                if (not ws_set and _in_interval(ps, rw, ra, cm, prev)) or _box_ok(
                        Kmat, rw, ra, cm, prev, Tpmin, Tpmax):
                    if ws_set:
                        W[:] = 0
                        ws_set = False
                    u0 = ps[S_K0] * rw + ps[S_K1] * ra + ps[S_K2] * cm + ps[S_K3] * prev
                    u0 = min(max(u0, Tpmin), Tpmax)
                    prev = u0
                else:
                    for i in range(H):
                        qv[i] = (Fmat[i, 0] * rw + Fmat[i, 1] * ra + Fmat[i, 2] * cm
                                 + Fmat[i, 3] * prev)
                        ustar[i] = (Kmat[i, 0] * rw + Kmat[i, 1] * ra + Kmat[i, 2] * cm
                                    + Kmat[i, 3] * prev)
                    it = box_qp(Pm, Pinv, qv, ustar, Tpmin, Tpmax, W, u, M, rr, idx, gg)
                    ws_set = True
                    qps += 1.0
                    if it < 0:
                        qpfall += 1.0
                    prev = min(max(u[0], Tpmin), Tpmax)
            T_p_cmd = prev
            # inner loop (control.inner.InnerLoop.step)
            e = T_p_cmd - rp
            if e == e:
                mode = ps[S_FFMODE]
                if mode == 0.0:
                    ff = 0.0
                elif mode == 1.0:
                    ff = ps[S_FF0] * (T_p_cmd - ra) if ps[S_FF0] != 0.0 else 0.0
                else:
                    ff = (ps[S_FF0] * T_p_cmd - ps[S_FF1] * ra - ps[S_FF2]) / ps[S_FF3]
                if ff != ff:
                    ff = ff_last
                i_c = integral + ps[S_KITS] * e
                if i_c > span:
                    i_c = span
                elif i_c < -span:
                    i_c = -span
                p = ff + ps[S_KP] * e
                vv = p + i_c
                if (vv > dmax and e > 0.0) or (vv < dmin and e < 0.0):
                    vv = p + integral
                else:
                    integral = i_c
                if vv > dmax:
                    drive = dmax
                elif vv < dmin:
                    drive = dmin
                else:
                    drive = vv
                ff_last = ff
            drv = drive
        else:
            drv = math.nan
        iv = 1 if on else 0
        code = K.step(st, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, rw, rp, ra, cm, iv, drv, fresh, ev)
        if code & K.C_ENDED:
            if ne < cap:
                events[ne, :] = ev
            ne += 1
        # truth and metrics at t_k
        if t >= t_track:
            narm += 1.0
            cl = cls[k]
            dq = st[K.DQ]
            if cl == CLS_ONE:
                s1 += dq
                n1 += 1.0
            elif cl == CLS_QUIET:
                sq += dq
                sq2 += dq * dq
                nq += 1.0
            err = Tw - cm
            sse += err * err
            ntrack += 1.0
        # plant.apply(drive, v)
        Rw_v = ps[S_RWON] if on else ps[S_RWOFF]
        G = G_c[k]
        if closed:
            d = drive if drive < dmax else dmax
            if d < dmin:
                d = dmin
            i_m = d * Imax
            a11, a12, a21, a22, b1, b2 = _tank_linear(nm, Sm, Km, Rm, Ct, Cs, gt, gs, i_m, T_a_k,
                                                      (Tp - Tw) / Rw_v)
            x, y = Tp, Ts
            energy += nm * (Sm * i_m * (x - y) + i_m * i_m * Rm) * t_s
            x, y = _rk4_pair(x, y, a11, a12, a21, a22, b1, b2, h, n_sub)
            Tp_old = Tp
            Tp, Ts = x, y
        else:
            Tp_old = Tp_true
        vv = v_on if on else 0.0
        if vv != v_prev or G_prev != G:
            _zoh(ps, Rw_v, G, c)
            v_prev = vv
            G_prev = G
        w0 = Tw
        g0 = Tg
        Tf = T_f[k]
        Tw = c[0] * w0 + c[1] * g0 + c[4] * Tp_old + c[5] * T_a_k + c[6] * 0.0 + c[7] * Tf
        Tg = c[2] * w0 + c[3] * g0 + c[8] * Tp_old + c[9] * T_a_k + c[10] * 0.0 + c[11] * Tf
    if K.finish(st, (n - 1) * t_s, ev):
        if ne < cap:
            events[ne, :] = ev
        ne += 1
    res[R_SSE] = sse
    res[R_NTRACK] = ntrack
    res[R_ENERGY] = energy if closed else math.nan
    res[R_SUM1] = s1
    res[R_N1] = n1
    res[R_SUMQ] = sq
    res[R_SUMQ2] = sq2
    res[R_NQ] = nq
    res[R_NARMED] = narm
    res[R_QPS] = qps
    res[R_QPFALL] = qpfall
    res[R_NEV] = ne


@njit(cache=True, forceinline=True)
def _box_ok(Kmat, T_w, T_a, cmd, prev, lo, hi):
    """``Mpc._box_test``: the unconstrained optimum within eq. 11 over the whole horizon."""
    for i in range(Kmat.shape[0]):
        x = Kmat[i, 0] * T_w + Kmat[i, 1] * T_a + Kmat[i, 2] * cmd + Kmat[i, 3] * prev
        if x - hi > 0.0 or lo - x > 0.0:
            return False
    return True


@njit(cache=True, parallel=True)
def run_rows(PS, G_c, T_f, T_a_true, cmd, T_p_presc, cls, NOISE, CONV, mid, PR, Phi, Gam, Qi, Qc, Phi_a,
             Q_a, Rw, cid, Kmat, Fmat, Pm, Pinv, RES, EVENTS):
    """Every row (module doc), over the cores; ``mid[i]`` / ``cid[i]`` its estimator and MPC model."""
    for i in prange(PS.shape[0]):
        m = mid[i]
        j = cid[i]
        _row(PS[i], G_c[i], T_f[i], T_a_true[i], cmd[i], T_p_presc[i], cls[i], NOISE[i], CONV[i], PR[m],
             Phi[m], Gam[m], Qi[m], Qc[m], Phi_a[m], Q_a[m], Rw[m], Kmat[j], Fmat[j], Pm[j], Pinv[j],
             RES[i], EVENTS[i])
