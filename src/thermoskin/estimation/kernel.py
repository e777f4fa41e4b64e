"""The compiled estimation kernel: Kalman filter on the network, then the two-sided contact detector.

One sample of one patch is :func:`step`; :func:`run` loops it over arrays inside compiled
code, so the live loop (one call per sample) and offline analysis (one call per log) run
the very same machine code and agree bit for bit. The readable reference of the same
algorithm is :mod:`thermoskin.estimation.reference`; the tests hold the two together.

Per sample (``t`` s, readings ``T_w, T_p, T_a`` °C, ``fresh`` bitmask: 1 ``T_w``, 2 ``T_p``,
4 ``T_a``; ``iv`` the row of the model tables for the pump velocity applied over the
coming interval)::

    ambient update (T_a fresh):  x_a += K_a (T_a - x_a[i_a]),  P_a -= K_a P_a[i_a, :]
    patch updates (T_w, T_p fresh): x += K (y - x[i]),          K = P[:, i] / (P[i, i] + R)
    outputs: q_i estimate x[2], its standard deviation sqrt(P[2, 2])
    detector (armed): u = (q - b) / (s sqrt(P_qq));  g+ = max(0, g+ + (u - k) t_s),
                      g- = max(0, g- + (-u - k) t_s); onset when g± > h
    predict: x_a = Phi_a x_a,  x = Phi x + Gamma x_a[0],  P = Phi P Phi' + Q

A stale reading (its fresh bit clear), a NaN or an infinity is no measurement: the model
predicts through it. The state of a patch is one float64 vector (offsets below); the
parameters another; nothing is allocated per sample.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# ---------------------------------------------------------------- state layout (one patch)
X = 0          # x: T_w, T_g, q_i, T_p, dT_p (5)
P = 5          # P: 5 x 5, row-major (25)
XA = 30        # x_a: T_a, T_as (2)
PA = 32        # P_a: 2 x 2 (4)
READY = 36     # 1 once the filter is initialised
GAPRUN = 37    # samples since the last valid pipe reading
MODE = 38      # detector: WARM, IDLE, CONTACT
NWARM = 39     # warm-up samples seen
B = 40         # baseline of the q_i estimate, W
VAR = 41       # variance scale of the standardised estimate
GP = 42        # CUSUM for a rise
GM = 43        # CUSUM for a fall
TQP = 44       # last time GP was zero, s
TQM = 45       # last time GM was zero, s
SIGN = 46      # sign of the contact (+1 heat in, -1 heat out)
ONSET = 47
DETECTED = 48
PEAK = 49      # largest signed change in the contact, W
SUM = 50
COUNT = 51
RUN = 52       # CUSUM for a release
TFB = 53       # last time it was zero, s
SINCE = 54     # samples since the onset was declared
TREL = 55      # time of the last release, s
LASTSIGN = 56  # sign of the last contact
DQ = 57        # output: q_i estimate minus baseline, W
Q = 58         # output: q_i estimate, W
SQ = 59        # output: its standard deviation, W
ARMED = 60     # detection armed (the set-point held)
NIN = 61       # samples within the arming band
CONTACT = 62   # output: 0/1
LEVEL = 63     # smoothed level of the contact, W
LVLMAX = 64    # its largest value, W
GAP = 65       # output: 1 while a reading is NaN (held over)
WBUF = 66      # warm-up buffer: NWB q values, then NWB standard deviations
NWB = 256
SCR = WBUF + 2 * NWB  # scratch: Phi P (25)
NSTATE = SCR + 25

WARM, IDLE, INCONTACT = 0, 1, 2

# ---------------------------------------------------------------- parameter layout
PR_TS = 0        # t_s, s
PR_RT = 1        # thermocouple variance, K^2
PR_AMB = 2       # ambient state read by the air sensor (0 or 1)
PR_K = 3         # k_drift, sigma
PR_H = 4         # h_on, sigma s
PR_KOFF = 5      # k_off, sigma
PR_FOFF = 6      # f_off
PR_HOFF = 7      # h_off, sigma s
PR_NWARM = 8     # warm-up samples
PR_WSTRIDE = 9   # stride of the warm-up buffer
PR_TREF = 10     # t_refractory, s
PR_TSETTLE = 11  # t_settle, s
PR_AB = 12       # baseline EMA weight per sample
PR_AS = 13       # variance EMA weight per sample
PR_NMAX = 14     # max contact in samples
PR_MAXGAP = 15   # max pipe-reading gap in samples
PR_P0Q = 16      # initial variance of q_i, W^2
PR_RG = 17       # R_g, K/W
PR_RAG = 18      # R_ag, K/W
PR_BAND = 19     # arm_band, K
PR_NARM = 20     # t_arm in samples
PR_KREL = 21     # k_rel, sigma
PR_ALVL = 22     # EMA weight of the contact level per sample
NPARAM = 24

# event fields
EV_ONSET, EV_DETECTED, EV_RELEASE, EV_DURATION, EV_SIGN, EV_PEAK, EV_MEAN, EV_ENERGY = range(8)
NEV = 8

# step result bits
C_CONTACT, C_STARTED, C_ENDED = 1, 2, 4


def new_state() -> np.ndarray:
    """A fresh (uninitialised) patch state."""
    st = np.zeros(NSTATE)
    st[TREL] = -1e300
    return st


@njit(cache=True, inline="always")
def _update(st, i, y, R):
    """Scalar measurement of state ``i``: ``K = P[:, i]/(P[i, i] + R)``, Joseph-free form."""
    S = st[P + 6 * i] + R
    e = y - st[X + i]
    inv = 1.0 / S
    for a in range(5):
        st[X + a] += st[P + 5 * a + i] * inv * e
    # P <- P - K P[i, :] with K = P[:, i]/S (symmetric): compute from a copy of row i
    r0 = st[P + 5 * i]
    r1 = st[P + 5 * i + 1]
    r2 = st[P + 5 * i + 2]
    r3 = st[P + 5 * i + 3]
    r4 = st[P + 5 * i + 4]
    for a in range(5):
        ka = st[P + 5 * a + i] * inv
        base = P + 5 * a
        st[base] -= ka * r0
        st[base + 1] -= ka * r1
        st[base + 2] -= ka * r2
        st[base + 3] -= ka * r3
        st[base + 4] -= ka * r4


@njit(cache=True, inline="always")
def _predict(st, F, G, QQ, u):
    """``x = Phi x + Gamma u``, ``P = Phi P Phi' + Q``."""
    x0, x1, x2, x3, x4 = st[X], st[X + 1], st[X + 2], st[X + 3], st[X + 4]
    for i in range(5):
        st[X + i] = (F[i, 0] * x0 + F[i, 1] * x1 + F[i, 2] * x2 + F[i, 3] * x3 + F[i, 4] * x4
                     + G[i] * u)
    for i in range(5):
        for j in range(5):
            acc = 0.0
            for m in range(5):
                acc += F[i, m] * st[P + 5 * m + j]
            st[SCR + 5 * i + j] = acc
    for i in range(5):
        for j in range(i, 5):
            acc = QQ[i, j]
            for m in range(5):
                acc += st[SCR + 5 * i + m] * F[j, m]
            st[P + 5 * i + j] = acc
            st[P + 5 * j + i] = acc


@njit(cache=True, inline="always")
def _ambient(st, Fa, Qa, y, fresh, R, idx):
    """Update the ambient filter with a fresh air reading (if any)."""
    if fresh:
        S = st[PA + 3 * idx] + R
        e = y - st[XA + idx]
        k0 = st[PA + idx] / S
        k1 = st[PA + 2 + idx] / S
        st[XA] += k0 * e
        st[XA + 1] += k1 * e
        r0, r1 = st[PA + 2 * idx], st[PA + 2 * idx + 1]
        st[PA] -= k0 * r0
        st[PA + 1] -= k0 * r1
        st[PA + 2] -= k1 * r0
        st[PA + 3] -= k1 * r1


@njit(cache=True, inline="always")
def _ambient_predict(st, Fa, Qa):
    a0, a1 = st[XA], st[XA + 1]
    st[XA] = Fa[0, 0] * a0 + Fa[0, 1] * a1
    st[XA + 1] = Fa[1, 0] * a0 + Fa[1, 1] * a1
    p00, p01, p10, p11 = st[PA], st[PA + 1], st[PA + 2], st[PA + 3]
    f00, f01, f10, f11 = Fa[0, 0], Fa[0, 1], Fa[1, 0], Fa[1, 1]
    m00 = f00 * p00 + f01 * p10
    m01 = f00 * p01 + f01 * p11
    m10 = f10 * p00 + f11 * p10
    m11 = f10 * p01 + f11 * p11
    st[PA] = m00 * f00 + m01 * f01 + Qa[0, 0]
    st[PA + 1] = m00 * f10 + m01 * f11 + Qa[0, 1]
    st[PA + 2] = m10 * f00 + m11 * f01 + Qa[1, 0]
    st[PA + 3] = m10 * f10 + m11 * f11 + Qa[1, 1]


@njit(cache=True, inline="always")
def _init(st, pr, T_w, T_p, T_a):
    """Start from the first valid readings: the network's no-touch sheet, no touch, still tank."""
    R = pr[PR_RT]
    Rg, Rag = pr[PR_RG], pr[PR_RAG]
    for i in range(25):
        st[P + i] = 0.0
    st[X] = T_w
    st[X + 1] = (T_w / Rg + T_a / Rag) / (1.0 / Rg + 1.0 / Rag)
    st[X + 2] = 0.0
    st[X + 3] = T_p
    st[X + 4] = 0.0
    st[P] = R
    st[P + 6] = R
    st[P + 12] = pr[PR_P0Q]
    st[P + 18] = R
    st[P + 24] = 1e-4
    st[XA] = T_a
    st[XA + 1] = T_a
    st[PA] = R
    st[PA + 1] = R
    st[PA + 2] = R
    st[PA + 3] = R
    st[READY] = 1.0
    st[GAPRUN] = 0.0


@njit(cache=True, inline="always")
def _end(st, t_release, ev):
    n = st[COUNT]
    sg = st[SIGN]
    mean = st[SUM] / n if n > 0 else 0.0
    dur = t_release - st[ONSET]
    ev[EV_ONSET] = st[ONSET]
    ev[EV_DETECTED] = st[DETECTED]
    ev[EV_RELEASE] = t_release
    ev[EV_DURATION] = dur
    ev[EV_SIGN] = sg
    ev[EV_PEAK] = sg * st[PEAK]
    ev[EV_MEAN] = sg * mean
    ev[EV_ENERGY] = sg * mean * dur
    st[MODE] = IDLE
    st[CONTACT] = 0.0
    st[TREL] = t_release
    st[LASTSIGN] = sg
    st[GP] = 0.0
    st[GM] = 0.0
    st[TQP] = t_release
    st[TQM] = t_release
    st[RUN] = 0.0


@njit(cache=True, inline="always")
def _detect(st, pr, t, ev):
    """The detector's sample; returns the step-result bits."""
    q = st[Q]
    sq = st[SQ]
    mode = st[MODE]
    ts = pr[PR_TS]
    if mode == WARM:
        n = int(st[NWARM])
        stride = int(pr[PR_WSTRIDE])
        if n % stride == 0:
            j = n // stride
            if j < NWB:
                st[WBUF + j] = q
                st[WBUF + NWB + j] = sq
        n += 1
        st[NWARM] = n
        st[B] += (q - st[B]) / n
        if n >= int(pr[PR_NWARM]):
            m = min((n - 1) // stride + 1, NWB)
            qs = st[WBUF:WBUF + m].copy()
            b = np.median(qs)
            zs = np.abs(qs - b) / st[WBUF + NWB:WBUF + NWB + m]
            s = 1.4826 * np.median(zs)
            if not s > 1e-6:
                s = 1e-6
            st[B] = b
            st[VAR] = s * s
            st[MODE] = IDLE
            st[TQP] = t
            st[TQM] = t
        st[DQ] = q - st[B]
        return 0
    b = st[B]
    s = math.sqrt(st[VAR])
    if mode == IDLE:
        u = (q - b) / (s * sq)
        k = pr[PR_K]
        gp = st[GP] + (u - k) * ts
        gm = st[GM] + (-u - k) * ts
        if gp < 0.0:
            gp = 0.0
        if gm < 0.0:
            gm = 0.0
        if t - st[TREL] < pr[PR_TREF]:  # no onset of the other sign right after a release
            if st[LASTSIGN] > 0:
                gm = 0.0
            else:
                gp = 0.0
        if gp == 0.0:
            st[TQP] = t
        if gm == 0.0:
            st[TQM] = t
        st[GP] = gp
        st[GM] = gm
        h = pr[PR_H]
        if gp > h or gm > h:
            sg = 1.0 if gp >= gm else -1.0
            st[MODE] = INCONTACT
            st[CONTACT] = 1.0
            st[SIGN] = sg
            st[ONSET] = st[TQP] if sg > 0 else st[TQM]
            st[DETECTED] = t
            d = sg * (q - b)
            st[PEAK] = d
            st[SUM] = d
            st[COUNT] = 1.0
            st[RUN] = 0.0
            st[TFB] = t
            st[LEVEL] = d
            st[LVLMAX] = d
            st[SINCE] = 0.0
            st[GP] = 0.0
            st[GM] = 0.0
            st[DQ] = q - b
            return C_CONTACT | C_STARTED
        if t - st[TREL] >= pr[PR_TSETTLE]:
            # idle and settled: learn the noise scale (clipped at 3 sigma, so that a rising
            # edge cannot inflate it) and, while there is no evidence of a touch, the baseline
            z = (q - b) / sq
            z2 = z * z
            v = st[VAR]
            if z2 > 9.0 * v:
                z2 = 9.0 * v
            st[VAR] = v + pr[PR_AS] * (z2 - v)
            if gp == 0.0 and gm == 0.0:
                b += pr[PR_AB] * (q - b)
                st[B] = b
        st[DQ] = q - b
        return 0
    # in contact: release by a CUSUM for the estimate falling below max(k_off sigma, f_off
    # times the contact's smoothed level), back-dated to where that evidence began
    sg = st[SIGN]
    d = sg * (q - b)
    st[DQ] = q - b
    if d > st[PEAK]:
        st[PEAK] = d
    st[SUM] += d
    st[COUNT] += 1.0
    st[SINCE] += 1.0
    lvl = st[LEVEL] + pr[PR_ALVL] * (d - st[LEVEL])
    st[LEVEL] = lvl
    if lvl > st[LVLMAX]:
        st[LVLMAX] = lvl
    sd = s * sq
    thr = pr[PR_KOFF] * sd
    f = pr[PR_FOFF] * st[LVLMAX]
    if f > thr:
        thr = f
    g = st[RUN] + ((thr - d) / sd - pr[PR_KREL]) * ts
    if g <= 0.0:
        g = 0.0
        st[TFB] = t
    st[RUN] = g
    if g > pr[PR_HOFF]:
        _end(st, st[TFB], ev)
        return C_ENDED
    if st[SINCE] >= pr[PR_NMAX]:  # a drift, not a touch: end it and take it as the baseline
        _end(st, t, ev)
        st[B] = q
        return C_ENDED
    return C_CONTACT


@njit(cache=True)
def step(st, pr, Phi, Gam, Qd, Phi_a, Q_a, t, T_w, T_p, T_a, T_w_cmd, iv, fresh, ev):
    """One sample of one patch; returns the step-result bits (contact, started, ended)."""
    R = pr[PR_RT]
    gap = not (math.isfinite(T_w) and math.isfinite(T_p) and math.isfinite(T_a))
    st[GAP] = 1.0 if gap else 0.0
    ok_w = (fresh & 1) != 0 and math.isfinite(T_w)
    ok_p = (fresh & 2) != 0 and math.isfinite(T_p)
    ok_a = (fresh & 4) != 0 and math.isfinite(T_a)
    if st[READY] == 0.0:
        if gap:
            return C_CONTACT if st[MODE] == INCONTACT else 0
        _init(st, pr, T_w, T_p, T_a)
    else:
        _ambient(st, Phi_a, Q_a, T_a, ok_a, R, int(pr[PR_AMB]))
        if ok_w:
            _update(st, 0, T_w, R)
            st[GAPRUN] = 0.0
        else:
            st[GAPRUN] += 1.0
        if ok_p:
            _update(st, 3, T_p, R)
    st[Q] = st[X + 2]
    pq = st[P + 12]
    st[SQ] = math.sqrt(pq) if pq > 0.0 else 1e-12
    # arming: once T_w has held within the band of its command (no command: at once)
    if st[ARMED] == 0.0:
        if T_w_cmd != T_w_cmd:
            st[ARMED] = 1.0
        elif math.isfinite(T_w) and abs(T_w - T_w_cmd) <= pr[PR_BAND]:
            st[NIN] += 1.0
            if st[NIN] >= pr[PR_NARM]:
                st[ARMED] = 1.0
        else:
            st[NIN] = 0.0
    code = 0
    if gap:  # a NaN reading: hold the detector (and a contact) over it
        code = C_CONTACT if st[MODE] == INCONTACT else 0
    elif st[ARMED] != 0.0:
        code = _detect(st, pr, t, ev)
    else:
        st[DQ] = st[Q] - st[B]
    # predict over the coming interval
    _ambient_predict(st, Phi_a, Q_a)
    _predict(st, Phi[iv], Gam[iv], Qd[iv], st[XA])
    if st[GAPRUN] > pr[PR_MAXGAP]:
        st[READY] = 0.0  # restart from the next valid readings
    return code


@njit(cache=True)
def run(st, pr, Phi, Gam, Qd, Phi_a, Q_a, t, T_w, T_p, T_a, T_w_cmd, iv, fresh,
        dq, q, sq, contact, events):
    """:func:`step` over arrays; fills ``dq, q, sq, contact`` and ``events``; returns the event count."""
    n = t.shape[0]
    ev = np.empty(NEV)
    ne = 0
    cap = events.shape[0]
    for k in range(n):
        c = step(st, pr, Phi, Gam, Qd, Phi_a, Q_a, t[k], T_w[k], T_p[k], T_a[k], T_w_cmd[k], iv[k],
                 fresh[k], ev)
        dq[k] = st[DQ]
        q[k] = st[Q]
        sq[k] = st[SQ]
        contact[k] = st[CONTACT]
        if c & C_ENDED:
            if ne < cap:
                events[ne, :] = ev
            ne += 1
    return ne


@njit(cache=True)
def finish(st, t, ev):
    """End a contact still open at ``t`` (the end of a log); True if one was."""
    if st[MODE] == INCONTACT:
        _end(st, t, ev)
        return True
    return False
