"""The compiled estimation kernel: Kalman filter on the network, then the two-sided contact detector.

One sample of one patch is :func:`step`; :func:`run` loops it over arrays inside compiled
code, so the live loop (one call per sample) and offline analysis (one call per log) run
the very same machine code and agree bit for bit. The readable reference of the same
algorithm is :mod:`thermoskin.estimation.reference`; the tests hold the two together.

Per sample (``t`` s, readings ``T_w, T_p, T_a`` °C, ``fresh`` bitmask: 1 ``T_w``, 2 ``T_p``,
4 ``T_a``; ``iv`` the row of the model tables for the pump velocity applied over the
coming interval)::

    ambient update (T_a fresh):  x_a += K_a (T_a - x_a[i_a]),  P_a -= K_a P_a[i_a, :]
    patch updates (T_w, T_p fresh), innovation e, its variance S = P[i, i] + R:
        g = P[i, q] / P[q, q]            the reading's sensitivity to a lasting change of q_i
        l± += ±Δ g e / (κ S) - Δ² g² / (2 κ S)     log-likelihood ratio of q_i + Δ (q_i - Δ)
        x += K e,  P -= K P[i, :],  K = P[:, i] / S
    detector (armed, idle): G± = max(0, G± + l±); onset when G± > h (Page's CUSUM), dated at
        argmax_tau (sum_{k>tau} g e/S)² / sum_{k>tau} g²/S within the CUSUM's window (the GLR
        over the change time; the readings' evidence kept in a ring buffer in the state)
    predict: x_a = Phi_a x_a,  x = Phi x + Gamma [x_a[0], drive],  P = Phi P Phi' + Q

This is Page's test on the Kalman filter's innovations for a step of the touch heat of
design size ``Δ`` (``detector.dq_design``): each fresh reading adds the evidence it
carries, weighted by how much it depends on ``q_i`` (a reading while the pump runs
carries little, one after the pump stood still a lot). While idle the filter's ``q_i``
follows only slow drift (``S_q_idle``), so a touch is not absorbed before it is seen;
at an onset the estimate jumps by the change the evidence points to and the filter
follows the contact (``S_q``) until the release. ``κ``, the innovations' scale against
their predicted variance, is tracked as a running median (1 when the model is right).

A stale reading (its fresh bit clear), a NaN or an infinity is no measurement: the model
predicts through it. The state of a patch is one float64 vector (offsets below); the
parameters another; nothing is allocated per sample.
"""

from __future__ import annotations

import math

import numba.core.options
import numpy as np

from thermoskin._jit import fetch_add, njit, prange, prefetch_w
from thermoskin.estimation.events import (  # the event record's layout
    EV_BD,
    EV_DETECTED,
    EV_DURATION,
    EV_ENERGY,
    EV_LAG,
    EV_MEAN,
    EV_ONSET,
    EV_PEAK,
    EV_RA,
    EV_RELEASE,
    EV_RP,
    EV_RW,
    EV_SIGN,
    NEV,
)
from thermoskin.estimation.model import RATE_TOL

# ---------------------------------------------------------------- state layout (one patch)
X = 0          # x: T_w, T_g, q_i, T_p, dT_p (5)
P = 5          # P: 5 x 5, row-major (25); symmetric, its upper triangle alone kept (_p_get)
XA = 30        # x_a: T_a, T_as (2)
PA = 32        # P_a: 2 x 2 (4)
READY = 36     # 1 once the filter is initialised
GAPRUN = 37    # samples since the last valid pipe reading
MODE = 38      # detector: WARM, IDLE, INCONTACT
NWARM = 39     # warm-up samples seen
B = 40         # baseline of the q_i estimate, W
KAPPA = 41     # scale of the innovations against their predicted standard deviation
QPRI = 42      # the q_i estimate before this sample's readings, W
RATEH = 43     # the reading rate the onset threshold HTH is for
BSH = 44       # the baseline's moves with the slow states, summed, W (the warm-up buffer's
#                values are kept less it: their median then stands where the baseline does)
TDOOR = 45     # the start of the last sudden change of the air (not its renewals), s
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
SGE = 72       # this sample's sum of g e / S
SGG = 73       # ... and of g^2 / S
RATE = 74      # fresh pipe readings per second (running mean of 1/interval)
CMD = 75       # the last set-point seen, degC
IVP = 76       # the last valid pump table row
# the paper's observer (eq. 8), q_hat = F1(s) T_w - F2(s) q_net, on interval means
E8N = 77       # samples averaged for its steady start
E8SW = 78      # running sums of T_w, q_net, T_a
E8SQ = 79
E8SA = 80
E8PW = 81      # the previous sample: T_w, T_p, T_a, pump row
E8PP = 82
E8PA = 83
E8PIV = 84
E8PREV = 85    # 1 once there is a previous sample
E8READY = 86
E8GAP = 87     # samples of the current NaN run
QIH = 88       # output: q_i_hat (eq. 8 + q_ag with T_w), W
F1Z0 = 89      # F1: state, input and output offsets
F1Z1 = 90
F1X0 = 91
F1Y0 = 92
F2Z0 = 93      # F2
F2X0 = 94
F2Y0 = 95
TLW = 96       # time of the last fresh pipe reading, s
TAMB = 97      # time of the last sudden change of the air, s
AGP = 98       # CUSUMs of the air sensor's innovations, up and down
AGM = 99
HTH = 102      # the onset threshold at the current reading rate
TFW = 103      # time of the last pipe reading flagged fresh (finite or not), s
RUNL = 100     # the release evidence CUSUM (dates the release)
TFBL = 101     # last time it was zero, s
CU = 104       # the onset CUSUMs, NCU of them, 4 fields each: statistic, last time it was
NCU = 6        # zero, and since then the sums of g e / S and g^2 / S (their ratio estimates
#                the change); designs +D, -D, +D_hi, -D_hi
MU = CU + 4 * NCU   # per onset CUSUM: mu, what remains in the filter's error of a unit step of
NMU = 5             # q_i at the CUSUM's last zero (the step's signature, Willsky and Jones);
#                     component a of CUSUM j's at MU + NCU a + j (the six side by side: one
#                     SIMD lane each in _mu_carry); see signature()
PHASE = MU + NMU * NCU  # samples since the last pump switch
PHDIR = PHASE + 1  # that switch: 0 to a lower water resistance (more flow), 1 to a higher
GHEAD = PHASE + 2       # the onset dating's ring buffer (idle, armed): the next entry written
GCNT = GHEAD + 1        # entries held (at most NGB)
GT0 = GHEAD + 2         # time of the first reading pooled in the newest entry, s
GOPEN = GHEAD + 3       # the newest entry, still pooling (3 fields as in GBUF): kept here, with
#                         the fields every sample reads, and written to GBUF once it is full
KUP = GOPEN + 3   # this sample's pipe and tank updates for the step signatures, 6 fields each:
#                   made (1/0), the gain K (5); applied to them with the prediction (_mu_carry);
#                   their gains on the bead (KUPM) further on
NPH = 64          # most phase bins of the pump-cycle correction, per direction
TPL = KUP + 12    # the correction: mean no-touch innovation of T_w per (direction, phase), K
GBUF = TPL + 2 * NPH    # NGB entries of 3: time of the last reading pooled, sums of g e/S, g^2/S
NGB = 256
WBUF = GBUF + 3 * NGB  # warm-up buffer: NWB q values
NWB = 256
UREC = WBUF + NWB  # traced (PR_TRACE): this sample's pipe and tank updates, NUR fields each:
NUR = 11               # made (1/0), innovation e, kappa^2 S, evidence (1/0), the gain K (5), the
#                        gain on the bead, and the bead's weight a in the reading
SWB = UREC + 2 * NUR   # traced: a pump-switch correction's x_Tw += c (x_Tp - x_Tw), its c, before
SWA = SWB + 1          # the updates and after them (0: none)
# what is learnt of the sensors from their readings (docs/model.md, Sensors that calibrate
# themselves): each channel's reading variance, its converter's step, the offset of the tank's
# readings against the pipe's (a slow state of the two-stage filter) and the evidence's dispersion
RW = SWA + 1       # the variance of a T_w reading, K^2 (noise and quantum), learnt
RP = RW + 1        # ... of a T_p reading
RA = RW + 2        # ... of a T_a reading
QW = RW + 3        # the smallest non-zero change between two fresh T_w readings (the converter's
QP = RW + 4        # step, if it has one), K; 1e300 before any change; T_p, T_a
QA = RW + 5
LYW = RW + 6       # the last fresh readings of T_w, T_p, T_a (NaN before the first)
LYP = RW + 7
LYA = RW + 8
TLP = RW + 9       # the time of the last fresh T_p reading, s
TLA = RW + 10      # ... of T_a
BD = RW + 11       # the offset of the T_p readings against the T_w readings beyond the configured
#                    ones (reading minus truth, K): a slow state of the two-stage filter
PBB = RW + 12      # the covariance of the two-stage filter's slow states (offset, lag): b b, b t,
PBT = RW + 13      # t t (K^2, K s, s^2)
PTT = RW + 14
VB = RW + 15       # 5: the patch state's sensitivity to an error of BD (dx/db, the two-stage
#                    filter's V: Friedland 1969)
RHO = VB + 5       # the onset evidence's dispersion over its model value (1 when the model fits)
WGE = RHO + 1      # this window's sums of g e/S and g^2/S, and where it began, s
WGG = RHO + 2
WT0 = RHO + 3
IRATE = RHO + 4    # the information on a step of q_i the readings bring, W^-2 per s (idle)
LINIT = RHO + 5    # 1 once what is learnt has its priors
RHON = RHO + 6     # the dispersion's windows seen
# the pipe thermocouple's bead: y = (1 - a) T_w + a m, m <- (1 - a) T_w + a m a sample (a first-order
# lag, a = exp(-t_s / tau)); m is a measurement-only state: nothing of the patch's depends on it,
# so the patch's covariance P is as without it, and m carries its own covariance with the state
XM = RHON + 1      # m, the bead's temperature through the last sample, degC
CM = XM + 1        # 5: its covariance with the patch state
PMM = CM + 5       # its variance
LAGA = PMM + 1     # a, the bead's weight a sample (0: no lag)
LAGT = LAGA + 1    # tau, the pipe thermocouple's lag, s: the two-stage filter's other slow state
VBM = LAGT + 1     # the bead's sensitivity to an error of BD (V_b's sixth component)
VT = VBM + 1       # 6: the state's (5) and the bead's sensitivity to an error of tau
WL1 = VT + 6       # the model's pipe rate through the lag once and twice, K/s: the reading's
WL2 = WL1 + 1      # sensitivity to tau is -WL2 (the lag's derivative, -s/(tau s + 1)^2)
MUM = WL2 + 1      # NCU: each onset CUSUM's step signature on the bead
KUPM = MUM + NCU   # this sample's gains on the bead of the pipe and the tank updates, and the a of
#                    the pipe's reading (for the signatures)
TINIT = KUPM + 3   # when the filter last started, s
SWIN = TINIT + 1   # the slow states' window: sums of s e/S and s^2/S for the offset and the lag,
#                    and where it began (their covariance is let go where a window's evidence
#                    says they are off by more than it allows)
LY2P = SWIN + 5    # the fresh T_p and T_a readings before the last (second differences)
LY2A = SWIN + 6
RSL = SWIN + 7     # NRS slots of the pipe reading variance's steps (the sum of their logarithms),
NRS = 4            # taken into it NRS - 1 slots late, dropped at a detection
RSI = RSL + NRS    # the slot being filled
RST0 = RSI + 1     # when it began, s
NRW = RST0 + 1     # the readings each variance's tracker has taken (T_w, T_p, T_a)
RHOB = NRW + 3     # the first NRB windows' z^2 over chi2(1)'s median, and a copy to sort
NRB = 16
WBD = RHOB + 2 * NRB  # the learnt offset and lag where the dispersion's window began
WLT = WBD + 1
IRN = WLT + 1      # the weight the information rate's mean has given its samples (1 - (1 - w)^n:
#                    its start's bias, taken off where it is read)
ARMLP = IRN + 1    # the arming: the T_w readings' mean over about ARM_TAU s, degC,
ARMREF = IRN + 2   # where it last settled, degC,
NSTEADY = IRN + 3  # and the samples it has held within ARM_STEADY x arm_band of that since
TXP = IRN + 4      # when a design onset CUSUM of the positive sign was last above PAIR_FLOOR of the
#                    threshold with no contact since, s (_pair_seen)
AHELD = IRN + 5    # 1 while the onsets are held after a sudden change of the air
ASL = IRN + 6      # the air estimate's rate of change, K/s (its mean over about ASL_TAU s),
AXL = IRN + 7      # the estimate at the last fresh air reading, degC,
ATL = IRN + 8      # and that reading's time, s
RHOS = IRN + 9     # the dispersion of the short windows (PR_RHOW) and of the long ones
RHOL = IRN + 10    # (PR_RHOWL): RHO is the larger
RHOLN = IRN + 11   # the long windows seen
WLGE = IRN + 12    # the long window's sums of g e/S and g^2/S, and the time they gathered, s
WLGG = IRN + 13
WLDT = IRN + 14
WLBD = IRN + 15    # the learnt offset and lag where the long window began
WLLT = IRN + 16
PHPREV = IRN + 17  # the pump's phase before the present one, samples
PBH = IRN + 18     # a slow board's last NPB fresh T_w readings (_noise_phase): the next slot,
PBN = IRN + 19     # how many there are,
PBQ = IRN + 20     # and NPB entries of (time s, reading degC, PHDIR, PHASE s, PHPREV s)
NPB = 32
RHOP = PBQ + 5 * NPB  # the dispersion of the pump's phases (_dispersion), the phase windows seen,
RHOPN = RHOP + 1
WPGE = RHOP + 2       # the present phase's sums of g e/S and g^2/S,
WPGG = RHOP + 3
WPOK = RHOP + 4       # and 1 while no contact has been seen in it
NSTATE = RHOP + 5

#: The long windows' tracker's least step in its logarithm, a window (the short one's is 0.03
#: a window of 0.4 s): a long window's 8 s are 20 short ones, and at 0.03 a dispersion its
#: first windows put high took minutes to come back (traced with a noise five times the
#: configured one, when the long windows were tried with every board)
RHOL_ETA = 0.1
#: The phase windows' tracker's least step in its logarithm, a window (about eight a second)
RHOP_ETA = 0.02
#: chi2(1)'s median: the trackers of a variance or a dispersion step up where a squared
#: standardised value is above it, down where below
CHI2_MEDIAN = 0.4549

#: Pipe readings a second from which a board is fast (``PR_RFAST``, the estimator's): its pipe
#: noise learnt from its innovations, the slow states' windows let go; below, a slow board's
FAST_READINGS = 200.0
#: A slow board's T_w reading is paired with the last one at the same point of the pump's
#: cycle (:func:`_noise_phase`, to within ``PR_PBTOL``) no further back than this, s
PB_REACH = 1.0
#: ... and from this long after the filter's start, s: the boards' rate known (from its first
#: readings a 1 kHz board's rose through slow ones', and the variance they moved flooded a
#: sheet 30 % lighter than configured with false alarms)
PB_START = 1.0
#: The arming's mean of the T_w readings: a first-order lag of this time constant (s), so that
#: the pump's ripple and the readings' noise do not break a hold (0.3 K off its command plus
#: 0.05 K of noise and the ripple broke it now and then, forever: the detector never armed).
ARM_TAU = 1.0
#: Where the sensors are learnt, the pump-cycle correction leaks to nought at this share of
#: its learning weight (a prior of no misfit): a level per direction of the switch is what a
#: T_p offset and the touch heat's baseline explain too (an offset's apparent heat changes
#: with the pump), and learnt by the table as well the three drifted together without bound
#: (a no-touch log of ideal boards: the baseline 0.4 W, the offset 17 mK after 20 min). A
#: pattern is learnt to 1/(1 + SWITCH_LEAK) of itself. (Learning the misfit less its level per
#: direction instead left too much of a skin's misfit: 7 false alarms in 8 logs of 4 min.)
SWITCH_LEAK = 0.1
#: ... and learns nothing this long after a contact's release (s): what the contact left in the
#: sheet (a cold object's, fading slower than the filter's estimate of it) is a misfit for
#: some seconds, which learnt read as the other sign once it had faded, and a half-threshold
#: positive CUSUM took the next cold touch for its end (the detection table's `cold`).
SWITCH_SETTLE = 10.0
#: The detector also arms once that mean has held within this fraction of ``arm_band`` of one
#: value for ARM_HOLD x ``t_arm``: a skin settled away from its command (a T_w board's offset
#: the controller did not see, or a command it cannot reach) is settled all the same.
ARM_STEADY = 0.2
ASL_TAU = 0.5    # the air estimate's rate is its mean over about this long, s (at 1 kHz its
#                  noise 0.01 K/s, with 10 Hz boards 0.02 K/s: lab boards, 5 min)
ARM_HOLD = 3.0

WARM, IDLE, INCONTACT = 0, 1, 2

# ---------------------------------------------------------------- parameter layout
PR_TS = 0        # t_s, s
PR_RT = 1        # thermocouple variance, K^2
PR_AMB = 2       # ambient state read by the air sensor (0 or 1)
PR_D = 3         # the smaller design change of q_i, W
PR_H = 4         # onset threshold, log-likelihood ratio
PR_KOFF = 5      # k_off, sigma
PR_FOFF = 6      # f_off
PR_HOFF = 7      # h_off, sigma s
PR_NWARM = 8     # warm-up samples
PR_WSTRIDE = 9   # stride of the warm-up buffer
PR_TREF = 10     # t_refractory, s
PR_TSETTLE = 11  # t_settle, s
PR_AB = 12       # baseline tracker step per sample (in standard deviations)
PR_UP = 13       # innovation-scale tracker: factor when |e|/sqrt(S) is above its median
PR_NMAX = 14     # max contact in samples
PR_MAXGAP = 15   # max pipe-reading gap in samples
PR_P0Q = 16      # initial variance of q_i, W^2
PR_RG = 17       # R_g, K/W
PR_RAG = 18      # R_ag, K/W
PR_BAND = 19     # arm_band, K
PR_NARM = 20     # t_arm in samples
PR_KREL = 21     # k_rel, sigma
PR_ALVL = 22     # EMA weight of the contact level per sample
PR_DOWN = 23     # innovation-scale tracker: factor when below its median
PR_S0 = 24       # standard deviation of the contact estimate over its filter's own sd
PR_CMAN = 25     # a tank innovation beyond this many sd is a manoeuvre
PR_TMAN = 26     # time over which a manoeuvre's jump is taken as a change of slope, s
PR_HSLOPE = 27   # onset threshold grows by this per e-fold of the pipe reading rate
PR_ARATE = 28    # weight per fresh reading of the reading-rate mean
PR_TCMD = 29     # a set-point change of dc makes the tank's slope uncertain by dc / this, s
# eq. 8: F1 = b(z)/a(z) of order 2, F2 of order 1 (Tustin), their DC gains, 1/R_aw, 1/R_ag
PR_F1B0, PR_F1B1, PR_F1B2, PR_F1A1, PR_F1A2, PR_F1DC = 30, 31, 32, 33, 34, 35
PR_F2B0, PR_F2B1, PR_F2A1, PR_F2DC = 36, 37, 38, 39
PR_IRAW = 40
PR_IRAG = 41
PR_NINIT = 42    # samples averaged for eq. 8's steady start
PR_MAXGAP8 = 43  # a NaN run longer than this restarts eq. 8
PR_AJUMP = 44    # a sudden change of the air lets its estimate go by this much, K
PR_TAMBH = 45    # no onset this long after a sudden change of the air, s
PR_KAIR = 46     # drift of the air CUSUM, standard deviations
PR_HAIR = 47     # its threshold
PR_TRETR = 48    # a contact begun this shortly before a sudden change of the air is withdrawn, s
PR_DHI = 49      # the larger design change of q_i, W
PR_VSW = 50      # pump-switch timing uncertainty (0: switches at the samples, as in the loop)
PR_ICW = 51      # 1/C_w, K/J
PR_NPH = 52      # phase bins of the pump-cycle correction of T_w (0: none)
PR_APH = 53      # its learning weight per no-touch reading
PR_TCONF = 54    # a contact released this soon after its detection, never confirmed, is withdrawn, s
PR_DLO = 55      # the design of the two CUSUMs that only date and size a weak step, W
PR_OSJ = 56      # 1: the whole state jumps at an onset (the step's signature); 0: q_i alone
                 # (the signatures are then not kept)
PR_HLO = 57      # the weak-step CUSUMs fire only this far above the onset threshold
PR_GLR = 58      # 1: an onset is dated by the GLR over the change time; 0: at the CUSUM's last zero
PR_GPOOL = 59    # a buffer entry pools the readings less than this after its first, s
PR_HMIN = 60     # the onset threshold's floor
PR_TRACE = 61    # 1: no detection; each update is recorded in the state (UREC), for the re-dating
PR_RW0 = 62      # the prior variance of a T_w reading (noise_T_w² + quantum_T²/12), K^2
PR_RP0 = 63      # ... of a T_p reading
PR_RA0 = 64      # ... of a T_a reading
PR_OFW = 65      # the configured offsets of the T_w, T_p, T_a readings, K (subtracted)
PR_OFP = 66
PR_OFA = 67
PR_BD0 = 68      # the learnt offset's starting value (0; the re-dating's filter: the live one's), K
PR_PB0 = 69      # its prior variance, K^2 (0: not learnt)
PR_SB = 70       # its random walk, K^2/s
PR_TAUR = 71     # the readings' variances are learnt over about this long, s (0: not learnt)
PR_LEARN = 72    # 1: learn (offset, variances, dispersion); 0: hold them (the re-dating's filter)
PR_RHOW = 73     # the dispersion's window, s (0: none)
PR_RHOETA = 74   # its tracker's least step (in its logarithm, a window)
PR_RHODB = 77    # the dispersion below this is taken as 1 (its tracker's own scatter)
PR_AIR = 78      # the information rate's weight per sample (t_s / its time constant)
PR_RMIN = 79     # a learnt variance stays within this factor of its prior, both ways
PR_RHOSET = 80   # the dispersion's windows begin this long after a release, s
PR_LAG0 = 81     # the pipe thermocouple's lag to start from (configured), s
PR_PT0 = 82      # its prior variance, s^2 (0: not learnt)
PR_ST = 83       # its random walk, s^2/s
PR_TAUMAX = 84   # the longest lag learnt, s
PR_DBMAX = 85    # the most a reading moves the learnt offset, K, and the lag, s
PR_DTMAX = 86
PR_LDELAY = 87   # the slow states learn from this long after the filter's start, s
PR_SWIN = 88     # the slow states' window, s
PR_RSLOT = 89    # the pipe reading variance's steps are gathered in slots this long, s
PR_RFAST = 90    # ... from pipe readings this many a second or more
PR_RHOPB = 91    # the dispersion is learnt once the offset's variance is below this, K^2,
PR_RHOPT = 92    # and the lag's below this, s^2
PR_RHODB_ = 93   # a dispersion window over which the offset moved more than this, K,
PR_RHODT = 94    # or the lag more than this, s, is not taken, in the filter's first PR_RHOEARLY s
PR_RHOEARLY = 95
PR_RHO0 = 96     # the dispersion before its third window
PR_RHOCAP = 97   # ... and at most this over its first windows (a touch among them)
PR_SLOWON = 98   # 1: the pipe thermocouple's bead and the slow states are carried (0: neither is:
                 # no lag, nothing learnt of them; the filter alone, as fast as before them)
PR_SLOWCU = 99   # the slow states do not learn while an onset CUSUM is above this fraction of
                 # its threshold (a touch's evidence building before its detection)
PR_QFINE = 100   # the slow states learn only while the T_w and T_p readings' converter steps are
                 # at most this, K (a coarser step is not dithered by the noise: its error, a
                 # sawtooth that follows the signal, was learnt as offsets swinging by 0.3 K)
PR_TPAIR = 101   # a negative onset this soon after positive evidence (TXP) is that touch's end, s
PR_RELN = 102    # a release needs its evidence over at least this many pipe readings
PR_ASLMAX = 103  # the air moving faster than this, K/s, is a sudden change (0: never)
PR_MEANMIN = 104  # a contact whose mean heat over it (its sign's way) is below this is withdrawn, W
PR_EMIN = 105    # ... or whose heat over it (mean times duration, its sign's way) is below this, J
PR_RHOWL = 106   # the dispersion's long window, s (0: none)
PR_PBTOL = 107   # a slow board's pipe reading paired at the same point of the pump's cycle to
#                  within this, s (0: its variance held at its prior; _noise_phase)
PR_RHOPH = 108   # 1: the dispersion also over the pump's phases (_dispersion), 0: not
PR_RELPH = 109   # 1: under a misfit locked to the pump's cycle a release spans two phases
                 # (_release_waits), 0: not
PR_DOORQ = 110   # 1: armed, through the air's hold from a door's start the estimate follows the
                 # sheet's heat as in a contact (process noise), 0: as between touches
NPARAM = 111

#: An onset CUSUM's excursion that came to no contact pairs with an onset of the other sign
#: once it rose above this fraction of the threshold (below it, noise's own excursions, about
#: one in e^(h/2) of them reaching it).
PAIR_FLOOR = 0.5

#: The slow states (offset, lag) are learnt from logs of this sample period or shorter only, s
#: (100 Hz and faster): at 50 Hz the pump switches between rows, and the model's misfit there
#: looked like an offset (0.1 K learnt where there was none).
SLOW_TS_MAX = 0.0100001
#: The slow states learn only while both converter steps are at most this many times the pipe
#: reading's configured sd (``PR_QFINE``).
QFINE_SD = 2.0


#: Rows of the per-sample outputs (:func:`run`, :func:`run_rows`).
NOUT = 10

# step result bits
C_CONTACT, C_STARTED, C_ENDED = 1, 2, 4

#: The entry points are compiled without numba's reference counting (``_nrt=False``): the
#: sample step allocates nothing, and the counts numba otherwise keeps on each array view it
#: takes (``Phi[iv]``, a patch's row ``ST[i]``; about a hundred atomic updates a sample that
#: its pruning leaves in this branchy code) cost more than the step itself: 1000 patches on
#: one core 625 -> 207-213 µs a tick (``benchmarks/patches.py --threads one``). ``_nrt`` is
#: numba's own option but not a documented one: a numba without it compiles the same code
#: with the counts (slower, the same results).
#:
#: Every function here lets LLVM fuse a product and a sum into one multiply-add (fast-math's
#: ``contract`` alone: one rounding instead of two; no other liberty, so the NaN tests and the
#: order of the sums stay): 178-183 -> 154-160 ns a sample on a 60 s log (same process,
#: alternating), the estimates within about 3e-12 W of the unfused code, the same contacts.
_CONTRACT = {"contract"}
_FAST: dict[str, object] = {"cache": True, "fastmath": _CONTRACT}
if hasattr(numba.core.options.DefaultOptions, "_nrt"):
    _FAST["_nrt"] = False
_inline = njit(forceinline=True, **_FAST)
"""The decorator of the sample step's parts: each compiled on its own (once for each set of
argument types), and inlined by LLVM where it is called (the function marked
``alwaysinline``). Numba's own inlining (``inline="always"``) gave code of the same size and
speed but copied the step's whole IR into each entry point that inlined it: 37 s to compile the
estimator on an empty cache instead of 12 s, 84 s for the parallel entry point instead of 3 s,
and its parfor pass then failed on that IR. So every entry point now inlines the step."""


@njit(cache=True)
def new_state() -> np.ndarray:
    """A fresh (uninitialised) patch state (compiled: the sweep's batch makes its own)."""
    st = np.zeros(NSTATE)
    st[TREL] = -1e300
    st[TXP] = -1e300
    st[KAPPA] = 1.0
    st[RATE] = 0.0
    st[TLW] = -1e300
    st[TFW] = -1e300
    st[TAMB] = -1e300
    st[TDOOR] = -1e300
    st[ATL] = -1e300
    st[CMD] = np.nan
    st[QIH] = np.nan
    st[ARMLP] = st[ARMREF] = np.nan
    st[QW] = st[QP] = st[QA] = 1e300
    st[LYW] = st[LYP] = st[LYA] = np.nan
    st[LY2P] = st[LY2A] = np.nan
    st[TLP] = st[TLA] = -1e300
    st[RHO] = st[RHOS] = st[RHOL] = st[RHOP] = 1.0
    return st


@_inline
def _tri(a, b):
    """Index of ``P[a, b]`` in a covariance held as a tuple of its upper triangle's 15 entries
    (row by row: ``P00 P01 P02 P03 P04 P11 P12 ... P44``), :func:`_p_get`."""
    lo, hi = (a, b) if a <= b else (b, a)
    return 5 * lo - lo * (lo - 1) // 2 + hi - lo


@_inline
def _p_get(st):
    """The covariance's upper triangle from the state, as a tuple (:func:`_tri`). ``P`` is
    symmetric, and only this triangle is kept up to date (15 stores instead of 25 at each update
    and prediction); nothing reads the lower one."""
    return (st[P], st[P + 1], st[P + 2], st[P + 3], st[P + 4], st[P + 6], st[P + 7], st[P + 8],
            st[P + 9], st[P + 12], st[P + 13], st[P + 14], st[P + 18], st[P + 19], st[P + 24])


@_inline
def _p_put(st, p):
    """:func:`_p_get` back: the tuple's 15 entries into the state's upper triangle."""
    st[P], st[P + 1], st[P + 2], st[P + 3], st[P + 4] = p[0], p[1], p[2], p[3], p[4]
    st[P + 6], st[P + 7], st[P + 8], st[P + 9] = p[5], p[6], p[7], p[8]
    st[P + 12], st[P + 13], st[P + 14] = p[9], p[10], p[11]
    st[P + 18], st[P + 19] = p[12], p[13]
    st[P + 24] = p[14]


@_inline
def _update(st, pr, i, y, p, eta, slow, learning, coarse):
    """Scalar measurement: the pipe's reading (``i`` 0) or the tank's (3), with the learnt variance
    of its readings; adds its evidence about a change of ``q_i``. ``p``: the covariance
    (:func:`_p_get`), returned updated; the pipe's and the tank's updates of a sample pass it
    from one to the other in registers, and the state takes it once. ``eta``: the weight of
    this reading in the variance's tracker (0: not learnt); ``slow``: the slow states learn from
    it; ``coarse``: a converter step too coarse to learn from (:func:`_coarse`, taken once a
    sample); ``learning`` (a constant where it is inlined): False for a patch with nothing learnt nor
    carried (:func:`fixed`), whose code then has neither the bead nor the slow states.

    The pipe's reading is its thermocouple's bead, ``y = (1 - a) T_w + a m`` (:data:`XM`), so
    its row of the covariance is ``r = (1 - a) P[0, :] + a c`` (``c`` the bead's covariance with
    the state) and ``S = (1 - a) r_0 + a r_m + R``; without a lag (``a`` 0) that is ``P[0, :]`` and
    ``P[0, 0] + R`` exactly, the filter as before.

    The offset of the tank's readings against the pipe's (``BD``) and the pipe thermocouple's lag
    (``LAGT``) are the slow states of a two-stage filter (Friedland 1969; Hsieh and Chen 1999):
    the patch filter runs as if they were known, ``V`` (:data:`VB`, :data:`VT`) carries the
    state's sensitivity to an error of each, ``s = C - H V`` the innovation's (``C``: 1 for the
    offset in a tank reading, the lag's derivative ``-WL2`` in a pipe reading, else 0), and each
    reading moves them by ``k e``, ``k = P_B s / (S + s' P_B s)``, and the state by ``-V k e``:
    the augmented filter's estimate, exactly for constant offsets (to first order in the lag)."""
    if learning:
        a = st[LAGA]
        c0, c1, c2, c3, c4 = st[CM], st[CM + 1], st[CM + 2], st[CM + 3], st[CM + 4]
        pmm = st[PMM]
        pbb, pbt, ptt = st[PBB], st[PBT], st[PTT]
    else:  # (all 0 in such a patch's state: its code the filter's alone)
        a = c0 = c1 = c2 = c3 = c4 = pmm = pbb = pbt = ptt = 0.0
    b1 = 1.0 - a
    # (a patch that learns nothing keeps its variances at their priors: read from its
    # parameters, one cache line fewer of its state a sample)
    if i == 0:
        R = _r_pipe(st) if learning else pr[PR_RW0]  # (learnt: at least its converter step's)
        if learning:
            yhat = b1 * st[X] + a * st[XM]
            sb = -(b1 * st[VB] + a * st[VBM])
            stau = -st[WL2] - (b1 * st[VT] + a * st[VT + 5])
        else:
            yhat = st[X]
            sb = stau = 0.0
    else:
        R = st[RP] if learning else pr[PR_RP0]
        yhat = st[X + 3]
        sb = 1.0 - st[VB + 3] if learning else 0.0
        stau = -st[VT + 3] if learning else 0.0
    # (not with a coarse converter: the slow states are not learnt from its readings, nor their
    # uncertainty taken into the innovations' variance, which drove the learnt noise down)
    sps = (sb * sb * pbb + 2.0 * sb * stau * pbt + stau * stau * ptt
           if learning and not coarse else 0.0)
    e = y - yhat
    kap = st[KAPPA]
    man = False
    if i == 3:
        Sf = p[12] + R + sps
        man = abs(e) > pr[PR_CMAN] * kap * math.sqrt(Sf)
        if man:
            # the tank manoeuvres (the drive jumped): let its slope go, as a fading-memory filter
            # does, and take no evidence about q_i from this reading
            p = (p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11],
                 p[12] + e * e, p[13], p[14] + (e / pr[PR_TMAN]) ** 2)
    # the reading's covariance with the state (its row of P), with the bead's, and its variance
    if i == 0 and learning:
        r0 = b1 * p[0] + a * c0
        r1 = b1 * p[1] + a * c1
        r2 = b1 * p[2] + a * c2
        r3 = b1 * p[3] + a * c3
        r4 = b1 * p[4] + a * c4
        rm = b1 * c0 + a * pmm
        S = b1 * r0 + a * rm + R
    elif i == 0:
        r0, r1, r2, r3, r4 = p[0], p[1], p[2], p[3], p[4]
        rm = 0.0
        S = r0 + R
    else:
        r0, r1, r2, r3, r4 = p[3], p[7], p[10], p[12], p[13]
        rm = c3
        S = r3 + R
    Sf = S + sps  # the innovation's variance with the slow states' uncertainty
    sS = math.sqrt(Sf)
    if not man:
        # evidence: the reading's sensitivity to a lasting change of q_i, g = P[i, q] / P[q, q]
        pqq = p[9]
        g = r2 / pqq if pqq > 0.0 else 0.0
        gS = g / (kap * kap * Sf)  # one division for both
        st[SGE] += gS * e
        st[SGG] += gS * g
        # the innovations' scale: running median of |e| / sqrt(S) (0.6745 for a unit normal)
        if abs(e) > 0.6745 * kap * sS:
            st[KAPPA] = kap * pr[PR_UP]
        else:
            st[KAPPA] = kap * pr[PR_DOWN]
            # not below 1 with a coarse converter: its readings hold still between steps, so
            # most innovations are nought and their median is no scale (kappa fell to 0.17 with
            # a 1/4 K step at 1 kHz, every reading's evidence taken 35 times over: a flood)
            if learning and st[KAPPA] < 1.0 and pr[PR_LEARN] != 0.0 and coarse:
                st[KAPPA] = 1.0
        if eta > 0.0 and i == 0:
            # the pipe reading's variance: its median tracker, e²/S at chi2(1)'s median 0.4549
            # (robust to the few large innovations of a pump switch), its steps into this slot
            l1 = math.log(1.0 + eta)
            st[RSL + int(st[RSI])] += l1 if e * e > CHI2_MEDIAN * Sf else -l1
    inv = 1.0 / S
    k0 = r0 * inv
    k1 = r1 * inv
    k2 = r2 * inv
    k3 = r3 * inv
    k4 = r4 * inv
    km = rm * inv
    if pr[PR_TRACE] != 0.0:  # the re-dating's detection-free filter keeps the update
        u = UREC if i == 0 else UREC + NUR
        st[u] = 1.0
        st[u + 1] = e
        st[u + 2] = kap * kap * Sf
        st[u + 3] = 0.0 if man else 1.0
        st[u + 4] = k0
        st[u + 5] = k1
        st[u + 6] = k2
        st[u + 7] = k3
        st[u + 8] = k4
        st[u + 9] = km
        st[u + 10] = a if i == 0 else 0.0
    # each onset CUSUM's step signature: what remains in the estimate's error of a step of
    # q_i at the CUSUM's last zero after this reading, mu <- (I - K H) mu: the gain kept, and
    # applied with the prediction (:func:`_mu_carry`)
    if _keeps_mu(st, pr):
        u = KUP if i == 0 else KUP + 6
        st[u] = 1.0
        st[u + 1] = k0
        st[u + 2] = k1
        st[u + 3] = k2
        st[u + 4] = k3
        st[u + 5] = k4
        if i == 0:
            st[KUPM] = km
            st[KUPM + 2] = a
        else:
            st[KUPM + 1] = km
    x0 = st[X] + k0 * e
    x1 = st[X + 1] + k1 * e
    x2 = st[X + 2] + k2 * e
    x3 = st[X + 3] + k3 * e
    x4 = st[X + 4] + k4 * e
    xm = st[XM] + km * e
    if not learning or pr[PR_SLOWON] == 0.0:  # no bead nor slow state: the filter alone
        st[X], st[X + 1], st[X + 2], st[X + 3], st[X + 4] = x0, x1, x2, x3, x4
        return (p[0] - k0 * r0, p[1] - k0 * r1, p[2] - k0 * r2, p[3] - k0 * r3, p[4] - k0 * r4,
                p[5] - k1 * r1, p[6] - k1 * r2, p[7] - k1 * r3, p[8] - k1 * r4,
                p[9] - k2 * r2, p[10] - k2 * r3, p[11] - k2 * r4,
                p[12] - k3 * r3, p[13] - k3 * r4,
                p[14] - k4 * r4)
    # the slow states' sensitivities through this update: V <- V - K (H V - C) = V + K s
    vb0 = st[VB] + k0 * sb
    vb1 = st[VB + 1] + k1 * sb
    vb2 = st[VB + 2] + k2 * sb
    vb3 = st[VB + 3] + k3 * sb
    vb4 = st[VB + 4] + k4 * sb
    vbm = st[VBM] + km * sb
    vt0 = st[VT] + k0 * stau
    vt1 = st[VT + 1] + k1 * stau
    vt2 = st[VT + 2] + k2 * stau
    vt3 = st[VT + 3] + k3 * stau
    vt4 = st[VT + 4] + k4 * stau
    vtm = st[VT + 5] + km * stau
    st[VB], st[VB + 1], st[VB + 2], st[VB + 3], st[VB + 4], st[VBM] = vb0, vb1, vb2, vb3, vb4, vbm
    st[VT], st[VT + 1], st[VT + 2], st[VT + 3], st[VT + 4], st[VT + 5] = vt0, vt1, vt2, vt3, vt4, vtm
    if slow and sps > 0.0 and not man and e * e < 64.0 * Sf:
        # (an outlier, beyond 8 sd, is no evidence of either)
        # the slow states learnt from this reading (held during a contact), and the state moved
        # as the filter would stand had its readings been corrected by them all along
        # the window's evidence on each, for the fading of their covariance (_slow_window)
        st[SWIN] += sb * e / Sf
        st[SWIN + 1] += sb * sb / Sf
        st[SWIN + 2] += stau * e / Sf
        st[SWIN + 3] += stau * stau / Sf
        hb = pbb * sb + pbt * stau
        ht = pbt * sb + ptt * stau
        kb = hb / Sf
        kt = ht / Sf
        db = kb * e
        dt = kt * e
        # each reading moves them by at most PR_DBMAX, PR_DTMAX: the lag's effect is linear in
        # it only for small changes, and the filter's start (its state settling) can ask for
        # large ones; a reading so limited is taken as that share of one (its information)
        f = 1.0
        if abs(db) > pr[PR_DBMAX]:
            f = pr[PR_DBMAX] / abs(db)
        if abs(dt) > pr[PR_DTMAX] and pr[PR_DTMAX] / abs(dt) < f:
            f = pr[PR_DTMAX] / abs(dt)
        db *= f
        dt *= f
        st[PBB] = pbb - f * kb * hb
        st[PBT] = pbt - f * kb * ht
        st[PTT] = ptt - f * kt * ht
        st[BD] += db
        tau = st[LAGT] + dt
        tau = 0.0 if tau < 0.0 else (pr[PR_TAUMAX] if tau > pr[PR_TAUMAX] else tau)
        dt = tau - st[LAGT]
        st[LAGT] = tau
        st[LAGA] = math.exp(-pr[PR_TS] / tau) if tau > 0.0 else 0.0
        # the estimate of q_i moves with them (what it had taken of their errors): so does its
        # no-touch baseline
        st[B] -= vb2 * db + vt2 * dt
        st[BSH] -= vb2 * db + vt2 * dt
        x0 -= vb0 * db + vt0 * dt
        x1 -= vb1 * db + vt1 * dt
        x2 -= vb2 * db + vt2 * dt
        x3 -= vb3 * db + vt3 * dt
        x4 -= vb4 * db + vt4 * dt
        xm -= vbm * db + vtm * dt
    st[X], st[X + 1], st[X + 2], st[X + 3], st[X + 4] = x0, x1, x2, x3, x4
    st[XM] = xm
    # the bead's covariances: c <- c - K r_m, P_mm <- P_mm - k_m r_m
    st[CM] = c0 - k0 * rm
    st[CM + 1] = c1 - k1 * rm
    st[CM + 2] = c2 - k2 * rm
    st[CM + 3] = c3 - k3 * rm
    st[CM + 4] = c4 - k4 * rm
    st[PMM] = pmm - km * rm
    # P <- P - K r' with K = r/S (P symmetric); on the upper triangle alone (15 products, not 25)
    return (p[0] - k0 * r0, p[1] - k0 * r1, p[2] - k0 * r2, p[3] - k0 * r3, p[4] - k0 * r4,
            p[5] - k1 * r1, p[6] - k1 * r2, p[7] - k1 * r3, p[8] - k1 * r4,
            p[9] - k2 * r2, p[10] - k2 * r3, p[11] - k2 * r4,
            p[12] - k3 * r3, p[13] - k3 * r4,
            p[14] - k4 * r4)


@_inline
def _predict(st, F, G, QQ, u, w):
    """``x = Phi x + Gamma [u, w]``, ``P = Phi P Phi' + Q``.

    ``q_i`` and ``r_p`` are random walks: their rows of ``Phi`` are unit rows and of
    ``Gamma`` zero (:func:`thermoskin.estimation.model.build_tables` makes them exactly so),
    which this uses (rows 0, 1 and 3 of ``Phi`` only), with ``P`` symmetric: the 15 distinct
    entries are read and written, in its upper triangle (:func:`_p_get`).
    """
    x0, x1, x2, x3, x4 = st[X], st[X + 1], st[X + 2], st[X + 3], st[X + 4]
    a0, a1, a2, a3, a4 = F[0, 0], F[0, 1], F[0, 2], F[0, 3], F[0, 4]
    b0, b1, b2, b3, b4 = F[1, 0], F[1, 1], F[1, 2], F[1, 3], F[1, 4]
    c0, c1, c2, c3, c4 = F[3, 0], F[3, 1], F[3, 2], F[3, 3], F[3, 4]
    st[X] = a0 * x0 + a1 * x1 + a2 * x2 + a3 * x3 + a4 * x4 + G[0, 0] * u + G[0, 1] * w
    st[X + 1] = b0 * x0 + b1 * x1 + b2 * x2 + b3 * x3 + b4 * x4 + G[1, 0] * u + G[1, 1] * w
    st[X + 3] = c0 * x0 + c1 * x1 + c2 * x2 + c3 * x3 + c4 * x4 + G[3, 0] * u + G[3, 1] * w
    p00, p01, p02, p03, p04 = st[P], st[P + 1], st[P + 2], st[P + 3], st[P + 4]
    p11, p12, p13, p14 = st[P + 6], st[P + 7], st[P + 8], st[P + 9]
    p22, p23, p24 = st[P + 12], st[P + 13], st[P + 14]
    p33, p34 = st[P + 18], st[P + 19]
    p44 = st[P + 24]
    # rows 0, 1, 3 of Phi P
    m00 = a0 * p00 + a1 * p01 + a2 * p02 + a3 * p03 + a4 * p04
    m01 = a0 * p01 + a1 * p11 + a2 * p12 + a3 * p13 + a4 * p14
    m02 = a0 * p02 + a1 * p12 + a2 * p22 + a3 * p23 + a4 * p24
    m03 = a0 * p03 + a1 * p13 + a2 * p23 + a3 * p33 + a4 * p34
    m04 = a0 * p04 + a1 * p14 + a2 * p24 + a3 * p34 + a4 * p44
    m10 = b0 * p00 + b1 * p01 + b2 * p02 + b3 * p03 + b4 * p04
    m11 = b0 * p01 + b1 * p11 + b2 * p12 + b3 * p13 + b4 * p14
    m12 = b0 * p02 + b1 * p12 + b2 * p22 + b3 * p23 + b4 * p24
    m13 = b0 * p03 + b1 * p13 + b2 * p23 + b3 * p33 + b4 * p34
    m14 = b0 * p04 + b1 * p14 + b2 * p24 + b3 * p34 + b4 * p44
    m30 = c0 * p00 + c1 * p01 + c2 * p02 + c3 * p03 + c4 * p04
    m31 = c0 * p01 + c1 * p11 + c2 * p12 + c3 * p13 + c4 * p14
    m32 = c0 * p02 + c1 * p12 + c2 * p22 + c3 * p23 + c4 * p24
    m33 = c0 * p03 + c1 * p13 + c2 * p23 + c3 * p33 + c4 * p34
    m34 = c0 * p04 + c1 * p14 + c2 * p24 + c3 * p34 + c4 * p44
    # (Phi P) Phi' + Q, the distinct entries
    n00 = m00 * a0 + m01 * a1 + m02 * a2 + m03 * a3 + m04 * a4 + QQ[0, 0]
    n01 = m00 * b0 + m01 * b1 + m02 * b2 + m03 * b3 + m04 * b4 + QQ[0, 1]
    n03 = m00 * c0 + m01 * c1 + m02 * c2 + m03 * c3 + m04 * c4 + QQ[0, 3]
    n11 = m10 * b0 + m11 * b1 + m12 * b2 + m13 * b3 + m14 * b4 + QQ[1, 1]
    n13 = m10 * c0 + m11 * c1 + m12 * c2 + m13 * c3 + m14 * c4 + QQ[1, 3]
    n33 = m30 * c0 + m31 * c1 + m32 * c2 + m33 * c3 + m34 * c4 + QQ[3, 3]
    n02 = m02 + QQ[0, 2]
    n04 = m04 + QQ[0, 4]
    n12 = m12 + QQ[1, 2]
    n14 = m14 + QQ[1, 4]
    n23 = m32 + QQ[2, 3]
    n34 = m34 + QQ[3, 4]
    n22 = p22 + QQ[2, 2]
    n24 = p24 + QQ[2, 4]
    n44 = p44 + QQ[4, 4]
    st[P] = n00
    st[P + 1] = n01
    st[P + 2] = n02
    st[P + 3] = n03
    st[P + 4] = n04
    st[P + 6] = n11
    st[P + 7] = n12
    st[P + 8] = n13
    st[P + 9] = n14
    st[P + 12] = n22
    st[P + 13] = n23
    st[P + 14] = n24
    st[P + 18] = n33
    st[P + 19] = n34
    st[P + 24] = n44


@_inline
def _air_changed(st, pr, t):
    """A sudden change of the air at ``t`` (``TAMB``, which the detector's hold runs from); where
    no hold is on, the start of a door (``TDOOR``: not the renewals while the reading moves)."""
    if not t - st[TAMB] < pr[PR_TAMBH]:
        st[TDOOR] = t
    st[TAMB] = t


@_inline
def _ambient(st, pr, t, y, fresh, idx, learning):
    """Update the ambient filter with a fresh air reading (if any), with its learnt variance.

    A sudden change of the air (a door) is found by Page's CUSUM on the standardised
    innovations (drift ``PR_KAIR``, threshold ``PR_HAIR``, either sign): the air's estimate is
    then let go (its variance grows by ``PR_AJUMP``²) and the time is kept, for the detector
    to wait until the lagging sensor has caught up.
    """
    if fresh:
        R = st[RA] if learning else pr[PR_RA0]
        S = st[PA + 3 * idx] + R
        e = y - st[XA + idx]
        z = e / math.sqrt(S)
        k = pr[PR_KAIR]
        ap = st[AGP] + z - k
        am = st[AGM] - z - k
        st[AGP] = ap if ap > 0.0 else 0.0
        st[AGM] = am if am > 0.0 else 0.0
        if (st[AGP] > pr[PR_HAIR] or st[AGM] > pr[PR_HAIR]) and not (
                st[QA] < 1e299 and abs(e) < 2.0 * st[QA]):
            # (not a coarse converter's one step, the filter slow to take it in: with 1/16 K
            # boards such a "door" withdrew a touch just detected)
            st[PA] += pr[PR_AJUMP] * pr[PR_AJUMP]
            S = st[PA + 3 * idx] + R
            _air_changed(st, pr, t)
            st[AGP] = st[AGM] = 0.0
        k0 = st[PA + idx] / S
        k1 = st[PA + 2 + idx] / S
        st[XA] += k0 * e
        st[XA + 1] += k1 * e
        r0, r1 = st[PA + 2 * idx], st[PA + 2 * idx + 1]
        st[PA] -= k0 * r0
        st[PA + 1] -= k0 * r1
        st[PA + 2] -= k1 * r0
        st[PA + 3] -= k1 * r1
        # the air's rate: a sensor lagging the air more than configured reads a door as a ramp
        # the filter follows (no jump), while the sheet feels the air itself (G_a tau dT_as/dt
        # of heat no model has): the air moving that fast is a sudden change too
        dt = t - st[ATL]
        if dt > 0.0 and st[ATL] > -1e300:
            w = dt / ASL_TAU if dt < ASL_TAU else 1.0
            st[ASL] += w * ((st[XA] - st[AXL]) / dt - st[ASL])
            # (and faster than two of its converter's steps in that time: a coarse converter's
            # one step, the filter taking it in, read as the air moving)
            lim = 2.0 * st[QA] / ASL_TAU if st[QA] < 1e299 else 0.0
            if pr[PR_ASLMAX] > 0.0 and abs(st[ASL]) > max(pr[PR_ASLMAX], lim):
                _air_changed(st, pr, t)
        st[AXL] = st[XA]
        st[ATL] = t


_TINY = float(np.finfo(np.float64).tiny)
"""The smallest normal float64; below it (subnormal numbers) arithmetic is many times slower."""


@_inline
def _ftz(x):
    """``x``, or 0 where it is subnormal (``0 < |x| < tiny``); NaN stays NaN."""
    return 0.0 if 0.0 < abs(x) < _TINY else x


@_inline
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
    # the cross terms decay towards zero where the air's two states are not coupled, and
    # settle on a subnormal number (5e-323), on which every product is a slow microcode
    # assist: flushed to zero (the estimates do not change: measured bit for bit), one
    # sample costs 190 ns instead of 540 ns from then on
    st[PA + 1] = _ftz(m00 * f10 + m01 * f11 + Qa[0, 1])
    st[PA + 2] = _ftz(m10 * f00 + m11 * f01 + Qa[1, 0])
    st[PA + 3] = m10 * f10 + m11 * f11 + Qa[1, 1]


@_inline
def _learnt_init(st, pr):
    """What is learnt of the sensors at its priors (once: a restart after a gap keeps it)."""
    st[RW] = pr[PR_RW0]
    st[RP] = pr[PR_RP0]
    st[RA] = pr[PR_RA0]
    st[BD] = pr[PR_BD0]
    st[PBB] = pr[PR_PB0]
    st[RHO] = pr[PR_RHO0] if pr[PR_RHOW] > 0.0 and pr[PR_LEARN] != 0.0 else 1.0
    st[RHOS] = st[RHO]
    st[RHOL] = 1.0
    st[RHOP] = 1.0
    st[PBT] = 0.0
    st[PTT] = pr[PR_PT0]
    tau = pr[PR_LAG0]
    st[LAGT] = tau
    st[LAGA] = math.exp(-pr[PR_TS] / tau) if tau > 0.0 else 0.0
    st[LINIT] = 1.0


@_inline
def _init(st, pr, T_w, T_p, T_a):
    """Start from the first valid readings (offsets taken off): the network's no-touch sheet,
    no touch, still tank. The tank's state is its reading, so its sensitivity to an error of
    the learnt offset is 1 (``V = e_Tp``)."""
    if st[LINIT] == 0.0:
        _learnt_init(st, pr)
    R = st[RW]
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
    st[P + 18] = st[RP]
    st[P + 24] = 1e-4
    # the bead at the pipe's reading: its covariances those of T_w
    st[XM] = T_w
    for i in range(5):
        st[CM + i] = st[P + i]
    st[PMM] = R
    for i in range(5):
        st[VB + i] = 0.0
        st[VT + i] = 0.0
    st[VB + 3] = 1.0
    st[VBM] = 0.0
    st[VT + 5] = 0.0
    st[WL1] = st[WL2] = 0.0
    Ra = st[RA]
    st[XA] = T_a
    st[XA + 1] = T_a
    st[ATL] = -1e300  # the air's rate from the next reading
    st[PA] = Ra
    st[PA + 1] = Ra
    st[PA + 2] = Ra
    st[PA + 3] = Ra
    st[READY] = 1.0
    st[GAPRUN] = 0.0
    _mu_reset_all(st)
    _threshold(st, pr)


@_inline
def _eq8(st, pr, Rw, T_w, T_p, T_a, iv):
    """The paper's thermal exchange observer (eq. 8) with its ``q_ag`` correction, one sample.

    ``q_hat = F1(s) T_w - F2(s) q_net`` with ``F1 = D(s)/((R_g C_w s+1)(R_g C_g s+1))``,
    ``F2 = 1/(R_g C_w s+1)`` (Tustin), on the means over the interval ``[k-1, k]`` of
    ``T_w, T_p, T_a`` and ``q_net = (T_p - T_w)/R_w(v_{k-1}) - (T_w - T_a)/R_aw`` (eqs. 1, 3);
    ``q_i_hat = q_hat + (T_w - T_a)/R_ag``. The first ``n_init`` samples are averaged and the
    filters start in that steady state; a NaN sample is held over; a NaN run longer than
    ``max_gap`` restarts it. The same arithmetic as
    :class:`thermoskin.estimation.observer.ThermalExchangeObserver` (with multiply-adds fused:
    equal to about 2e-14 W).
    """
    if iv < 0 or not (math.isfinite(T_w) and math.isfinite(T_p) and math.isfinite(T_a)):
        st[E8GAP] += 1.0
        return
    if st[E8GAP] > pr[PR_MAXGAP8]:
        st[E8N] = st[E8SW] = st[E8SQ] = st[E8SA] = 0.0
        st[E8PREV] = 0.0
        st[E8READY] = 0.0
        st[QIH] = np.nan
    st[E8GAP] = 0.0
    if st[E8PREV] == 0.0:
        st[E8PW], st[E8PP], st[E8PA], st[E8PIV] = T_w, T_p, T_a, iv
        st[E8PREV] = 1.0
    pw, pp, pa, piv = st[E8PW], st[E8PP], st[E8PA], int(st[E8PIV])
    st[E8PW], st[E8PP], st[E8PA], st[E8PIV] = T_w, T_p, T_a, iv
    mw = 0.5 * (pw + T_w)
    mp = 0.5 * (pp + T_p)
    ma = 0.5 * (pa + T_a)
    qn = (mp - mw) / Rw[piv] - (mw - ma) * pr[PR_IRAW]
    if st[E8READY] == 0.0:
        n = st[E8N] + 1.0
        st[E8N] = n
        st[E8SW] += mw
        st[E8SQ] += qn
        st[E8SA] += ma
        aw, aq, aa = st[E8SW] / n, st[E8SQ] / n, st[E8SA] / n
        st[QIH] = pr[PR_F1DC] * aw - pr[PR_F2DC] * aq + (aw - aa) * pr[PR_IRAG]
        if n >= pr[PR_NINIT]:
            st[F1Z0] = st[F1Z1] = st[F2Z0] = 0.0
            st[F1X0] = aw
            st[F1Y0] = pr[PR_F1DC] * aw
            st[F2X0] = aq
            st[F2Y0] = pr[PR_F2DC] * aq
            st[E8READY] = 1.0
        return
    x = mw - st[F1X0]
    y = pr[PR_F1B0] * x + st[F1Z0]
    st[F1Z0] = pr[PR_F1B1] * x - pr[PR_F1A1] * y + st[F1Z1]
    st[F1Z1] = pr[PR_F1B2] * x - pr[PR_F1A2] * y
    y1 = st[F1Y0] + y
    x = qn - st[F2X0]
    y = pr[PR_F2B0] * x + st[F2Z0]
    st[F2Z0] = pr[PR_F2B1] * x - pr[PR_F2A1] * y
    y2 = st[F2Y0] + y
    st[QIH] = (y1 - y2) + (T_w - T_a) * pr[PR_IRAG]


@_inline
def _threshold(st, pr):
    """The onset threshold for the current reading rate: more readings a second are more
    chances of a false alarm, ``h = max(h_on + h_rate ln(readings/s), h_min)`` (no reading
    yet: one a sample), renewed only when the rate has moved by more than
    :data:`~thermoskin.estimation.model.RATE_TOL` since (a board's rate jitters in its last bits
    at every reading; the logarithm was 7 % of a sample); the floor because a CUSUM alarms on
    noise about once in ``e^h`` readings (Lorden 1971), and a few readings a second each carry
    much evidence."""
    rate = st[RATE] if st[RATE] > 0.0 else 1.0 / pr[PR_TS]
    rh = st[RATEH]
    if rh > 0.0 and abs(rate - rh) <= RATE_TOL * rh:
        return
    st[RATEH] = rate
    h = pr[PR_H] + pr[PR_HSLOPE] * math.log(rate if rate > 1.0 else 1.0)
    st[HTH] = h if h > pr[PR_HMIN] else pr[PR_HMIN]


@_inline
def _keeps_mu(st, pr):
    """Whether the step signatures are carried through this sample. They are read only by an
    onset's whole-state jump, so not kept without it (a skin's patches: ``PR_OSJ`` is fixed for
    a patch's life), and not while warming up or in contact: every way out of those modes
    (:func:`_end`, a withdrawal, the warm-up's end) restarts every CUSUM, signature included
    (:func:`_cusums_reset`), so what they would carry is never read."""
    return pr[PR_OSJ] != 0.0 and st[MODE] == IDLE


@_inline
def _mu_reset(st, j):
    """CUSUM ``j``'s step signature for a step of ``q_i`` now: all of it still to be learnt. A
    unit step of ``q_i`` is unchanged by this sample's updates (``mu[T_w] = mu[T_p] = 0``:
    their products with it add nothing, exactly), so whenever in the sample it was restarted,
    they are applied to it as to the others (:func:`_mu_updated`, :func:`_mu_carry`)."""
    for a_ in range(NMU):
        st[MU + NCU * a_ + j] = 0.0
    st[MU + NCU * 2 + j] = 1.0
    st[MUM + j] = 0.0


@_inline
def _mu_reset_all(st):
    """Every CUSUM's signature a unit step now."""
    for j in range(NCU):
        _mu_reset(st, j)


@_inline
def _mu_reading(u0, u1, u2, u3, u4, um, k0, k1, k2, k3, k4, km, rho):
    """A reading's update of a signature, ``mu - K rho`` (``rho``: its component at the reading;
    ``um`` and ``km`` the bead's)."""
    return u0 - k0 * rho, u1 - k1 * rho, u2 - k2 * rho, u3 - k3 * rho, u4 - k4 * rho, um - km * rho


@_inline
def _kup_gains(st):
    """This sample's pipe and tank gains for the signatures (:data:`KUP`), 5 each; a reading
    not made in the sample is a zero gain, which leaves every signature as it was (``u - 0 rho =
    u`` exactly)."""
    uw = st[KUP] != 0.0
    up = st[KUP + 6] != 0.0
    return ((st[KUP + 1] if uw else 0.0, st[KUP + 2] if uw else 0.0, st[KUP + 3] if uw else 0.0,
             st[KUP + 4] if uw else 0.0, st[KUP + 5] if uw else 0.0, st[KUPM] if uw else 0.0,
             st[KUPM + 2] if uw else 0.0),
            (st[KUP + 7] if up else 0.0, st[KUP + 8] if up else 0.0, st[KUP + 9] if up else 0.0,
             st[KUP + 10] if up else 0.0, st[KUP + 11] if up else 0.0, st[KUPM + 1] if up else 0.0))


@_inline
def _mu_readings(st, j, w, p):
    """CUSUM ``j``'s signature through this sample's pipe and tank updates (gains ``w``, ``p``
    from :func:`_kup_gains`): ``mu - K_w mu[T_w]``, then ``- K_p mu[T_p]``."""
    u0, u1, u2, u3, u4 = (st[MU + j], st[MU + NCU + j], st[MU + 2 * NCU + j], st[MU + 3 * NCU + j],
                          st[MU + 4 * NCU + j])
    um = st[MUM + j]
    aw = w[6]  # the pipe reading's bead weight: it reads (1 - a) mu[T_w] + a mu[bead]
    u0, u1, u2, u3, u4, um = _mu_reading(u0, u1, u2, u3, u4, um, w[0], w[1], w[2], w[3], w[4], w[5],
                                         (1.0 - aw) * u0 + aw * um)
    return _mu_reading(u0, u1, u2, u3, u4, um, p[0], p[1], p[2], p[3], p[4], p[5], u3)


@_inline
def _mu_updated(st, j):
    """CUSUM ``j``'s signature after this sample's updates (:data:`KUP`): for an onset, which
    comes before :func:`_mu_carry` applies them."""
    w, p = _kup_gains(st)
    return _mu_readings(st, j, w, p)


def signature(st: np.ndarray, j: int) -> np.ndarray:
    """CUSUM ``j``'s step signature in a patch's state ``st``: its ``NMU`` components
    (``T_w, T_g, q_i, T_p, dT_p``), a copy."""
    return st[MU + j:MU + NMU * NCU:NCU].copy()


@_inline
def _mu_carry(st, F):
    """The step signatures through this sample: its updates, ``mu <- (I - K H) mu`` for each
    (pipe, then tank: :data:`KUP`), then the model, ``mu <- Phi mu`` (rows 2 and 4 of ``Phi``
    are unit rows). One pass, each signature read and written once, the same arithmetic for all
    six (their components side by side: the compiler makes one vector of them, one lane each).
    A signature restarted in this sample, a unit step still, comes through the updates
    unchanged (:func:`_mu_reset`)."""
    # Phi's rows and the gains read once (the stores below could be to the same memory, for
    # all the compiler knows: it would read them again for every signature)
    a0, a1, a2, a3, a4 = F[0, 0], F[0, 1], F[0, 2], F[0, 3], F[0, 4]
    b0, b1, b2, b3, b4 = F[1, 0], F[1, 1], F[1, 2], F[1, 3], F[1, 4]
    c0, c1, c2, c3, c4 = F[3, 0], F[3, 1], F[3, 2], F[3, 3], F[3, 4]
    w, p = _kup_gains(st)
    la = st[LAGA]
    lb = 1.0 - la
    for j in range(NCU):
        u0, u1, u2, u3, u4, um = _mu_readings(st, j, w, p)
        st[MUM + j] = lb * u0 + la * um  # the bead through the sample (before the model's step)
        st[MU + j] = a0 * u0 + a1 * u1 + a2 * u2 + a3 * u3 + a4 * u4
        st[MU + NCU + j] = b0 * u0 + b1 * u1 + b2 * u2 + b3 * u3 + b4 * u4
        st[MU + 2 * NCU + j] = u2
        st[MU + 3 * NCU + j] = c0 * u0 + c1 * u1 + c2 * u2 + c3 * u3 + c4 * u4
        st[MU + 4 * NCU + j] = u4


@_inline
def _cusums_reset(st, t):
    """Every onset CUSUM back to zero at ``t``."""
    for j in range(NCU):
        o = CU + 4 * j
        st[o] = 0.0
        st[o + 1] = t
        st[o + 2] = 0.0
        st[o + 3] = 0.0
    _mu_reset_all(st)


@_inline
def _r_pipe(st):
    """The variance a pipe reading is taken with (:func:`_update`): the learnt one, at least its
    learnt converter step's ``q²/12``, learnt or not (a slow board's variance is not learnt: at
    its 0.02 K prior a 1/4 K step read as 10 sd, a contact of -3 W lasting 50 ms); once the
    warm-up has seen the readings (the common divisor of the first changes is no step yet: 0.16 K
    for a 1/128 K converter, taken, put the strong touches of a 10 Hz session a second late)."""
    r = st[RW]
    qw = st[QW]
    qq = qw * qw / 12.0 if qw < 1e299 and st[MODE] != WARM else 0.0
    return qq if qq > r else r


@_inline
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
    ev[EV_RW] = _r_pipe(st)  # (as the filter took it: the re-dating's filter holds it)
    ev[EV_RP] = st[RP]
    ev[EV_RA] = st[RA]
    ev[EV_BD] = st[BD]
    ev[EV_LAG] = st[LAGT]
    st[MODE] = IDLE
    st[CONTACT] = 0.0
    st[TREL] = t_release
    st[LASTSIGN] = sg
    _cusums_reset(st, t_release)
    st[RUN] = 0.0


@_inline
def _between(st, t_zero, t):
    """A change seen first after the reading at ``t_zero``: half a reading interval later
    (it came somewhere before the next reading), not after ``t``."""
    r = st[RATE]
    tc = t_zero + 0.5 / r if r > 0.0 else t_zero
    return tc if tc < t else t


@_inline
def _glr_push(st, pr, t, sge, sgg):
    """Keep a pipe reading's time and evidence ``(g e/S, g²/S)`` in the ring buffer: pooled
    into the newest entry if that began less than ``PR_GPOOL`` ago, else in a new entry (the
    oldest of ``NGB`` goes). The newest entry is pooled in ``GOPEN`` (beside the fields every
    sample reads; in the ring, a 1 kHz reading was a distant cache line each sample, a tenth
    of a patch's sample) and goes to its slot in the ring when the next begins."""
    if st[GCNT] > 0.0 and t - st[GT0] < pr[PR_GPOOL]:
        st[GOPEN] = t
        st[GOPEN + 1] += sge
        st[GOPEN + 2] += sgg
        return
    k = int(st[GHEAD])
    if st[GCNT] > 0.0:
        o = GBUF + 3 * (k - 1 if k > 0 else NGB - 1)
        st[o] = st[GOPEN]
        st[o + 1] = st[GOPEN + 1]
        st[o + 2] = st[GOPEN + 2]
    st[GOPEN] = t
    st[GOPEN + 1] = sge
    st[GOPEN + 2] = sgg
    st[GT0] = t
    # the slot this new entry goes to when it is full: unread for seconds, so out of the
    # caches; fetched now, as a hint, so that the write then does not wait for memory (every
    # patch of a skin writes in the same sample: 1000 patches, that sample took 80 us instead
    # of 63 us)
    o = GBUF + 3 * k
    prefetch_w(st, o)
    prefetch_w(st, o + 2)
    st[GHEAD] = k + 1 if k + 1 < NGB else 0
    if st[GCNT] < NGB:
        st[GCNT] += 1.0


@_inline
def _glr_entry_at(st, k, newest):
    """Offset of ring slot ``k``'s fields: ``GOPEN`` for the newest entry (slot ``newest``)."""
    return GOPEN if k == newest else GBUF + 3 * k


@njit(cache=True)
def glr_entry(st, back):
    """The ``back``-th newest entry of the onset dating's buffer (0: the one still pooling):
    time of its last reading, its sums of ``g e/S`` and ``g²/S``; NaNs if not held."""
    if back >= st[GCNT]:
        return np.nan, np.nan, np.nan
    head = int(st[GHEAD])
    newest = head - 1 if head > 0 else NGB - 1
    k = (newest - back) % NGB
    o = _glr_entry_at(st, k, newest)
    return st[o], st[o + 1], st[o + 2]


@_inline
def _glr_time(st, t_zero, sg, sum_ge, sum_gg):
    """The change time of a step of sign ``sg`` by the generalised likelihood ratio over it
    (Willsky and Jones 1976; Basseville and Nikiforov 1993, sec. 2.4): the time ``tau`` after
    which a step of free size explains the readings best, the maximiser of
    ``LLR(tau) = (sum_{k>tau} g e/S)² / (2 sum_{k>tau} g²/S)`` with ``sg sum g e/S > 0``. The
    candidates: the CUSUM's last zero ``t_zero`` (with its own sums ``sum_ge, sum_gg``) and the
    end of each buffer entry since; where the window is longer than the buffer, the part it
    no longer holds has ``t_zero`` as its only candidate (the CUSUM's dating). Of equal
    ratios, ``t_zero``, then the latest; equal within 1e-12 (relative), so that the rounding
    of the sums (summed in another order by the reference) does not choose between a
    candidate and one an entry of no evidence (g = 0) away."""
    best_t = t_zero
    best = sum_ge * sum_ge / sum_gg if sg * sum_ge > 0.0 and sum_gg > 0.0 else 0.0
    a = 0.0
    b = 0.0
    k = int(st[GHEAD])
    newest = k - 1 if k > 0 else NGB - 1
    for _ in range(int(st[GCNT])):
        k = k - 1 if k > 0 else NGB - 1
        o = _glr_entry_at(st, k, newest)
        tk = st[o]
        if tk <= t_zero:
            break
        if sg * a > 0.0 and b > 0.0:
            llr = a * a / b
            if llr > best * (1.0 + 1e-12):
                best = llr
                best_t = tk
        a += st[o + 1]
        b += st[o + 2]
    return best_t


@_inline
def _median_in_place(a, lo, m):
    """The median of ``a[lo:lo + m]``, as ``np.median`` gives it (NaN if any is NaN), sorting
    that part of ``a`` in place (insertion sort: ``m`` is at most :data:`NWB`, once a patch);
    allocates nothing, so that the kernel needs no reference counting."""
    for k in range(lo, lo + m):
        if a[k] != a[k]:
            return np.nan
    for k in range(lo + 1, lo + m):
        v = a[k]
        j = k - 1
        while j >= lo and a[j] > v:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = v
    h = lo + m // 2
    return a[h] if m % 2 == 1 else (a[h - 1] + a[h]) / 2.0


@_inline
def _irho(st, pr, learning=True):
    """The weight of the onset evidence: ``1/rho``, 1 where ``rho`` is within its dead band
    (``rho`` 1 where nothing is learnt)."""
    rho = (st[RHO] if learning else 1.0) / pr[PR_RHODB]
    return 1.0 / rho if rho > 1.0 else 1.0


@_inline
def _track(r, a, b, eta):
    """A dispersion tracker's step at a window's end (``a = sum g e/S``, ``b = sum g²/S``): up by
    ``eta`` in its logarithm where the window's ``z² = a²/b`` is above ``r`` times chi2(1)'s
    median, else down; at least 1e-3."""
    r = r * math.exp(eta if a * a > CHI2_MEDIAN * r * b else -eta)
    return r if r > 1e-3 else 1e-3


@_inline
def _rho_of(st):
    """The dispersion the detector takes: the largest of the short windows', the long ones' and
    the pump's phases'."""
    r = st[RHOS] if st[RHOS] > st[RHOL] else st[RHOL]
    return r if r > st[RHOP] else st[RHOP]


@_inline
def _moved(st, pr, t, bd0, lt0):
    """Whether the slow states moved over a dispersion window (from ``bd0``, ``lt0``) in the
    filter's first ``PR_RHOEARLY`` s: learning them, its own transient, not the model's misfit
    (such a window is not taken)."""
    return t - st[TINIT] < pr[PR_RHOEARLY] and (abs(st[BD] - bd0) > pr[PR_RHODB_]
                                                or abs(st[LAGT] - lt0) > pr[PR_RHODT])


@_inline
def _dispersion(st, pr, t, sge, sgg, on, coarse):
    """The onset evidence's dispersion ``rho`` and the information rate, while no contact is
    seen (``on``). Where the model fits the readings (the innovations white, their variances
    right) the evidence a window of ``PR_RHOW`` s gathers, ``z² = (sum g e/S)² / sum g²/S``, is
    chi2(1); where it does not (an unmodelled lag, a skin unlike its configuration, coarse
    converters) the innovations are coloured and ``z²`` is ``rho`` chi2(1). ``rho`` is the
    median of ``z²`` over chi2(1)'s (0.4549) over the first :data:`NRB` windows (6 s), then
    tracks it in steps of ``max(PR_RHOETA, 1/(n+1))`` in its logarithm at the ``n``-th window.
    The same ``z²`` is tracked over windows of ``PR_RHOWL`` s (coarse converters) and over each
    phase of the pump's cycle (``PR_RHOPH``, fast boards: steps ``max(RHOP_ETA, 1/(n+1))``);
    ``rho`` is the largest of the three (:func:`_rho_of`). The information rate, ``sum g²/S`` a
    second over ``rho``, is what the one-finger SNR is figured from."""
    if st[PHASE] == 0.0:
        # the pump switched: the phase window that ended, where no contact was seen in it and
        # the board is fast (a misfit locked to the pump's cycle, positive in one phase and
        # negative in the next, cancels within the short windows; the CUSUMs gather it a phase
        # at a time)
        b = st[WPGG]
        if st[WPOK] != 0.0 and b > 0.0 and st[RATE] >= pr[PR_RFAST] and pr[PR_RHOPH] != 0.0:
            n = st[RHOPN]
            st[RHOPN] = n + 1.0
            eta = 1.0 / (n + 1.0) if 1.0 / (n + 1.0) > RHOP_ETA else RHOP_ETA
            st[RHOP] = _track(st[RHOP], st[WPGE], b, eta)
            st[RHO] = _rho_of(st)
        st[WPGE] = st[WPGG] = 0.0
        st[WPOK] = 1.0
    if not on:
        st[WGE] = st[WGG] = 0.0
        st[WT0] = t
        st[WBD] = st[BD]
        st[WLT] = st[LAGT]
        st[WPOK] = 0.0
        return
    st[WPGE] += sge
    st[WPGG] += sgg
    st[IRATE] += pr[PR_AIR] * (sgg * _irho(st, pr) / pr[PR_TS] - st[IRATE])
    st[IRN] += pr[PR_AIR] * (1.0 - st[IRN])
    st[WGE] += sge
    st[WGG] += sgg
    st[WLGE] += sge
    st[WLGG] += sgg
    st[WLDT] += pr[PR_TS]
    if pr[PR_RHOWL] > 0.0 and st[WLDT] >= pr[PR_RHOWL]:
        # the long window: a misfit slower than the short windows (a tank held on one coarse
        # step while it drifts within it) gathers in the CUSUMs over seconds. It gathers while
        # no contact is seen and goes on over a contact (touches every few seconds left few
        # stretches of 8 s without one: its tracker hardly moved). Its own tracker, from 1
        # (the model's), steps max(RHOL_ETA, 1/(n + 1)) in its logarithm; a window over which
        # the slow states moved in the filter's first seconds is not taken (as the short ones).
        # Only where a converter's step is coarse (:func:`_coarse`): taken with every board,
        # the touches the detector missed filled the long windows, and the tracker rose with
        # them (a noise five times the configured one: 71 of 76 touches found, then 55); and
        # only from fast boards (PR_RFAST readings a second: a 10 Hz board's few readings a
        # window widened the detector where the short windows did not, a lab's strong touches
        # found 0.3 s later)
        b = st[WLGG]
        if (b > 0.0 and not _moved(st, pr, t, st[WLBD], st[WLLT]) and st[RATE] >= pr[PR_RFAST]
                and coarse):
            n = st[RHOLN]
            st[RHOLN] = n + 1.0
            eta = 1.0 / (n + 1.0) if 1.0 / (n + 1.0) > RHOL_ETA else RHOL_ETA
            st[RHOL] = _track(st[RHOL], st[WLGE], b, eta)
            st[RHO] = _rho_of(st)
        st[WLGE] = st[WLGG] = st[WLDT] = 0.0
        st[WLBD] = st[BD]
        st[WLLT] = st[LAGT]
    if t - st[WT0] >= pr[PR_RHOW]:
        a, b = st[WGE], st[WGG]
        # a window over which the slow states moved in the filter's first seconds (learning
        # them: its own transient, not the model's misfit) is not taken
        if b > 0.0 and not _moved(st, pr, t, st[WBD], st[WLT]):
            n = int(st[RHON])
            st[RHON] = n + 1.0
            if n < NRB:  # the first NRB windows: their median (a few seconds, robust), from
                # the third on (before: its prior, PR_RHO0, detector.rho_prior)
                st[RHOB + n] = a * a / (CHI2_MEDIAN * b)
                for j in range(n + 1):
                    st[RHOB + NRB + j] = st[RHOB + j]
                r = _median_in_place(st, RHOB + NRB, n + 1) if n >= 2 else st[RHOS]
                r = r if r < pr[PR_RHOCAP] else pr[PR_RHOCAP]  # (a touch in the first windows)
            else:  # then a tracker of it
                eta = 1.0 / (n + 1.0) if 1.0 / (n + 1.0) > pr[PR_RHOETA] else pr[PR_RHOETA]
                r = _track(st[RHOS], a, b, eta)
            r = r if r > 1e-3 else 1e-3
            st[RHOS] = r
            st[RHO] = _rho_of(st)
        st[WGE] = st[WGG] = 0.0
        st[WT0] = t
        st[WBD] = st[BD]
        st[WLT] = st[LAGT]


@_inline
def _detect(st, pr, t, ev, learning):
    """The detector's sample; returns the step-result bits."""
    q = st[Q]
    sq = st[SQ]
    mode = st[MODE]
    if mode == WARM:  # the filter settles; the baseline is the median of its estimate
        n = int(st[NWARM])
        stride = int(pr[PR_WSTRIDE])
        if n % stride == 0:
            j = n // stride
            if j < NWB:  # (less the baseline's moves so far: see BSH)
                st[WBUF + j] = q - st[BSH]
        n += 1
        st[NWARM] = n
        st[B] += (q - st[B]) / n
        if n >= int(pr[PR_NWARM]):
            m = min((n - 1) // stride + 1, NWB)
            # the median of the estimates as they would stand now: the slow states learnt
            # meanwhile moved the estimate and the running mean, not the values kept (a lag
            # learnt from 0.10 to 0.12 s over the warm-up moved them 0.25 W: a baseline that far
            # off, a contact of the other sign at once)
            st[B] = _median_in_place(st, WBUF, m) + st[BSH]
            st[MODE] = IDLE
            _cusums_reset(st, t)
        st[DQ] = q - st[B]
        return 0
    b = st[B]
    if mode == IDLE:
        # Page's CUSUMs for a change of q_i by +-D and +-D_hi (the design sizes): each sample's
        # log-likelihood ratio D sum(g e/S) - D² sum(g²/S)/2 from the readings' evidence
        sge, sgg = st[SGE], st[SGG]
        if pr[PR_GLR] != 0.0 and (sgg > 0.0 or st[TLW] == t):
            _glr_push(st, pr, t, sge, sgg)  # a pipe reading: kept for dating an onset
        # no onset of the other sign after a release (a withdrawn contact's sign is 0: none)
        hold_other = t - st[TREL] < pr[PR_TREF] and st[LASTSIGN] != 0.0
        hold_all = t - st[TAMB] < pr[PR_TAMBH]  # the air changed: its sensor catches up first
        if not hold_all and st[AHELD] != 0.0:
            # the hold over: the CUSUMs start again, without the air's transient
            st[AHELD] = 0.0
            _cusums_reset(st, t)
        h = st[HTH]
        # the evidence's dispersion (:func:`_dispersion`): where the model does not fit the
        # readings the CUSUMs take the evidence as that much less (a quasi-likelihood), so that
        # noise alarms no more often than the threshold is for, and a touch needs that much more
        irho = _irho(st, pr, learning)
        fire = -1
        best = 0.0
        quiet = True
        for j in range(NCU):
            o = CU + 4 * j
            D = pr[PR_D] if j < 2 else (pr[PR_DHI] if j < 4 else pr[PR_DLO])
            sgj = 1.0 if j % 2 == 0 else -1.0
            g = st[o] + (sgj * D * sge - 0.5 * D * D * sgg) * irho
            if hold_other and sgj != st[LASTSIGN]:
                g = 0.0
            if g <= 0.0:
                # dated at a pipe reading (between readings nothing is learnt) or where the
                # evidence fell back to zero
                if st[o] > 0.0 or st[TLW] == t:
                    st[o + 1] = t
                    _mu_reset(st, j)
                st[o] = 0.0
                st[o + 2] = st[o + 3] = 0.0
            else:
                st[o] = g
                st[o + 2] += sge
                st[o + 3] += sgg
                if j >= 4:  # the weak-step CUSUMs date and size, and fire only further up
                    hl = h + pr[PR_HLO]
                    if g > hl and g - hl > best:
                        best = g - hl
                        fire = j
                    continue
                quiet = False
                if g > h and g - h > best:
                    best = g - h
                    fire = j
        if hold_all:
            # while the air's sensor catches up the CUSUMs gather their evidence but do not
            # fire (zeroed, they let a touch in the hold pass as no evidence, and the baseline
            # and the slow states learnt it: a flood of false alarms when the hold ended)
            fire = -1
            st[AHELD] = 1.0
        if fire >= 0:
            # of the three CUSUMs of its sign (designs D, D_hi, D_lo), the one whose step (at
            # its last zero, of the size its evidence points to) explains the readings best,
            # sum(g e/S)²/sum(g²/S): a large step seen by the smaller design's CUSUM is dated
            # where noise began to gather before the touch, and a weak one, which the
            # design-D CUSUM lost and found again, dated late
            o = CU + 4 * fire
            bestl = st[o + 2] * st[o + 2] / st[o + 3] if st[o + 3] > 0.0 else 0.0
            for k in range(fire % 2, NCU, 2):
                o2 = CU + 4 * k
                if k != fire and st[o2] > 0.0 and st[o2 + 3] > 0.0:
                    l2 = st[o2 + 2] * st[o2 + 2] / st[o2 + 3]
                    if l2 > bestl:
                        bestl = l2
                        fire = k
            o = CU + 4 * fire
            sg = 1.0 if fire % 2 == 0 else -1.0
            D = pr[PR_D] if fire < 2 else (pr[PR_DHI] if fire < 4 else pr[PR_DLO])
            # the change the evidence since the CUSUM left zero points to, sum(g e/S)/sum(g²/S);
            # the whole state takes it as a step at that time would have left it: jump mu (q_i
            # the jump, and the sheet and pipe what the filter has not yet seen of the step;
            # correcting q_i alone left them behind, the filter then drove q_i past the touch
            # to catch up, and the contact's level, set too high, released a tap early)
            jump = st[o + 2] / st[o + 3] if st[o + 3] > 0.0 else sg * D
            if sg * jump < D:
                jump = sg * D
            if pr[PR_OSJ] != 0.0:
                mu = _mu_updated(st, fire)
                um = jump * mu[5]  # the bead's part
                for a_ in range(5):
                    ua = jump * mu[a_]
                    st[X + a_] += ua
                    for b_ in range(a_, 5):  # P's upper triangle (_p_get)
                        st[P + 5 * a_ + b_] += 0.25 * ua * jump * mu[b_]
                    st[CM + a_] += 0.25 * ua * um
                st[XM] += um
                st[PMM] += 0.25 * um * um
            else:
                st[X + 2] += jump
                st[P + 12] += 0.25 * jump * jump
            if sg < 0.0 and t - st[TXP] < pr[PR_TPAIR]:
                # the end of a warm touch too weak to detect, whose evidence came to no contact
                # (_pair_seen): the sheet and the pipe take the change (their error, the heat
                # the touch left in them), q_i stays at its baseline, and there is no contact;
                # what follows is as after that touch's release (no negative onset for
                # t_refractory, the baseline and the slow states settle first)
                st[TREL] = t
                st[LASTSIGN] = 1.0
                _q_at(st, b)
                st[TXP] = -1e300
                _cusums_reset(st, t)
                _r_drop(st)
                return 0
            q = st[X + 2]
            st[Q] = q
            st[MODE] = INCONTACT
            st[CONTACT] = 1.0
            st[SIGN] = sg
            # dated by the GLR over the change time within the CUSUM's window (at its last
            # zero if off): noise or a slow drift that lifted the CUSUM before the touch and
            # never let it fall back to zero no longer dates the onset early
            tau = st[o + 1]
            if pr[PR_GLR] != 0.0:
                tau = _glr_time(st, tau, sg, st[o + 2], st[o + 3])
            st[ONSET] = _between(st, tau, t)
            st[DETECTED] = t
            d = sg * (q - b)
            st[PEAK] = d
            st[SUM] = d
            st[COUNT] = 1.0
            st[RUN] = 0.0
            st[TFB] = t
            st[RUNL] = 0.0
            st[TFBL] = t
            st[LEVEL] = d
            st[LVLMAX] = d
            st[SINCE] = 0.0
            _cusums_reset(st, t)
            _r_drop(st)
            st[TXP] = -1e300
            st[DQ] = q - b
            return C_CONTACT | C_STARTED
        _pair_seen(st, pr, t, h)
        if quiet and t - st[TREL] >= pr[PR_TSETTLE]:
            # no evidence of a touch: the baseline follows the estimate (a running median)
            step_b = pr[PR_AB] * sq
            b += step_b if q > b else -step_b
            st[B] = b
        st[DQ] = q - b
        return 0
    # in contact: release by a CUSUM for the estimate falling below max(k_off sd, f_off
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
    sd = pr[PR_S0] * st[KAPPA] * sq
    thr = pr[PR_KOFF] * sd
    f = pr[PR_FOFF] * st[LVLMAX]
    if f > thr:
        thr = f
    g = st[RUN] + ((thr - d) / sd - pr[PR_KREL]) * pr[PR_TS]
    if g <= 0.0:
        g = 0.0
        st[TFB] = t
    st[RUN] = g
    # the readings' evidence for the touch heat back at its baseline b rather than at its
    # mean level b + sg L over the contact: the log-likelihood ratio of the two, anchored at
    # them and not at the estimate (which, following the contact, has taken part of the fall
    # before the test sees it; the largest level, noisy, set the test too high); where it
    # last was zero dates the release better than the estimate, which lags
    lm = st[SUM] / st[COUNT]
    L = lm if lm > pr[PR_D] else pr[PR_D]
    Dr = -sg * L
    gl = st[RUNL] + Dr * st[SGE] - 0.5 * Dr * (2.0 * (b - st[QPRI]) + sg * L) * st[SGG]
    if gl <= 0.0:
        if st[RUNL] > 0.0 or st[TLW] == t:
            st[TFBL] = t
        gl = 0.0
    st[RUNL] = gl
    if g > pr[PR_HOFF]:
        # no reading since the detection favoured the contact's level over the baseline (the
        # release evidence never fell back to zero)
        unconfirmed = st[TFBL] == st[DETECTED] and t - st[DETECTED] < pr[PR_TCONF]
        if not unconfirmed and _release_waits(st, pr, t):
            return C_CONTACT
        t_rel = _between(st, st[TFBL], t) if st[DETECTED] <= st[TFBL] < st[TFB] else st[TFB]
        if unconfirmed or lm < pr[PR_MEANMIN] or lm * (t_rel - st[ONSET]) < pr[PR_EMIN]:
            # and it ended at once: the onset was noise, not a touch; withdraw it (no event);
            # so too a contact whose heat over it came to nothing (10 Hz boards: the filter's
            # recovery from a touch taken for a new one, a tap of 0.01 W or of the other sign),
            # or to less than the weakest design touch's over the shortest tap (a skin 30 %
            # lighter than configured: contacts of 0.2 W over 16-120 ms, 3-26 mJ, at 1 kHz)
            st[MODE] = IDLE
            st[CONTACT] = 0.0
            _q_at(st, b)
            st[P + 12] += 0.25 * lvl * lvl
            st[RUN] = 0.0
            _cusums_reset(st, t)
            if not unconfirmed:
                # (what follows is as after a release: the filter settles from the onset's
                # jump before the baseline and the dispersion learn; but no sign waits)
                st[TREL] = t
                st[LASTSIGN] = 0.0
            return 0
        _end(st, t_rel, ev)
        # the touch has gone: the estimate goes back to its baseline, free to correct itself
        _q_at(st, b)
        st[P + 12] += 0.25 * lvl * lvl
        return C_ENDED
    if st[SINCE] >= pr[PR_NMAX]:  # a drift, not a touch: end it and take it as the baseline
        _end(st, t, ev)
        st[B] = q
        return C_ENDED
    return C_CONTACT


@_inline
def _q_at(st, b):
    """The ``q_i`` estimate set to ``b`` (its baseline), no longer a function of the slow
    states (the offset, the lag)."""
    st[X + 2] = b
    st[VB + 2] = st[VT + 2] = 0.0
    st[Q] = b
    st[DQ] = 0.0


@_inline
def _pair_seen(st, pr, t, h):
    """When a positive design onset CUSUM (``D``, ``D_hi``) was last above ``PAIR_FLOOR h``
    (:data:`TXP`), for :func:`_detect`'s pairing: a warm touch too weak to be detected leaves
    its heat in the filter's other states (the sheet, the pipe), and their error reads as a
    fall of the touch heat once it ends (with a lab's 10 Hz boards, contacts of the negative
    sign 0.2-4 s after the ends of the one-finger touches missed). Only this way round: a
    negative excursion paired with a positive onset would, now and then, take a real touch
    (the common one) for a cold object's end. Nor within ``t_refractory + t_pair`` of a cold
    contact's release: the positive evidence of its end goes on past the hold, and the next
    cold touch was taken for its pair."""
    if pr[PR_TPAIR] == 0.0:
        return
    if st[LASTSIGN] < 0.0 and t - st[TREL] < pr[PR_TREF] + pr[PR_TPAIR]:
        return  # the tail of a cold contact's end (held for t_refractory, then rising still)
    floor = PAIR_FLOOR * h
    if st[CU] > floor or st[CU + 8] > floor:
        st[TXP] = t


@_inline
def _coarse(st, pr):
    """Whether a converter step of the T_w or the T_p readings is known and coarser than
    ``PR_QFINE`` (the slow states do not learn from such readings). Either alone: a tank held
    still on one 1/4 K step has no step known, and with both asked for the coarse pipe's
    dispersion never began (no information rate: no SNR line for such boards)."""
    qw, qp = st[QW], st[QP]
    return (pr[PR_QFINE] < qw < 1e299) or (pr[PR_QFINE] < qp < 1e299)


@_inline
def _release_waits(st, pr, t):
    """Whether a release whose CUSUM is over ``h_off`` waits: its evidence (since the CUSUM was
    last zero, ``TFB``) not yet over ``PR_RELN`` pipe readings (a slow board's one reading off,
    its noise or a reading dated at the wrong side of a pump switch, ends no touch); nor, where
    the model's misfit is locked to the pump's cycle (the phases' dispersion above its dead
    band, a fast board: ``PR_RELPH``), over the last whole phase and this one. There a pulse
    swings the estimate by as much as a fingertip's touch (a 0.3 s pipe bead learnt at 0.18 s:
    +0.46 to -0.05 W at one 50 ms pulse), and one dip would end a touch that goes on; a touch
    that has ended keeps its evidence through the next phase (the release is dated where the
    evidence began, not where it is taken)."""
    if (t - st[TFB]) * st[RATE] < pr[PR_RELN]:
        return True
    # (the phases' dispersion stays at 1, within the dead band, where it is not gathered)
    return (pr[PR_RELPH] != 0.0 and st[RHOP] > pr[PR_RHODB] and st[RATE] >= pr[PR_RFAST]
            and t - st[TFB] < (st[PHASE] + st[PHPREV]) * pr[PR_TS])


@_inline
def _slow_learnt(st, pr):
    """Whether the slow states are learnt (their variances below ``PR_RHOPB``, ``PR_RHOPT``):
    from then the dispersion's windows are taken and the pump-cycle correction learns."""
    return st[PBB] <= pr[PR_RHOPB] and st[PTT] <= pr[PR_RHOPT]


@_inline
def _building(st, pr):
    """Whether the detector's evidence of an onset builds: idle, and an onset CUSUM above
    ``PR_SLOWCU`` of the onset threshold (as the last sample left them)."""
    if st[MODE] != IDLE:
        return False
    lim = pr[PR_SLOWCU] * st[HTH]
    for j in range(NCU):  # noqa: SIM110 (a loop, not a generator, in compiled code)
        if st[CU + 4 * j] > lim:
            return True
    return False


@_inline
def _switch_correction(st, pr, Rw, iv_old, iv, slot):
    """A log coarser than the loop: the pump switched (table row ``iv_old`` to ``iv``) somewhere
    in the last interval, not at its end; the water brought (T_p - T_w)(1/R_w,new - 1/R_w,old)
    t_s / C_w times a uniform fraction of it more: half of it, ``x_Tw += c (x_Tp - x_Tw)``, and
    its sd (0.29) as variance. Traced (``PR_TRACE``): ``c`` kept in ``st[slot]``."""
    c = 0.5 * (1.0 / Rw[iv] - 1.0 / Rw[iv_old]) * pr[PR_TS] * pr[PR_ICW]
    if pr[PR_TRACE] != 0.0:
        st[slot] = c
    half = (st[X + 3] - st[X]) * c
    st[X] += half
    st[VB] += (st[VB + 3] - st[VB]) * c
    st[VT] += (st[VT + 3] - st[VT]) * c
    st[P] += (pr[PR_VSW] * 2.0 * half) ** 2


@_inline
def step(st, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive, fresh, ev,
         learning=True):
    """One sample of one patch; returns the step-result bits (contact, started, ended). An
    entry point (``TouchEstimator.step``, a sample from Python) and, inlined, the body of every
    loop below, the sweep's batch and the re-dating's trace.

    ``iv`` and ``drive``: the pump's table row and the Peltier drive applied over the coming
    interval (``iv = -1``: the pump's velocity is unknown, a NaN); ``Qi`` / ``Qc``: the
    process-noise tables while idle and in contact; ``Rw`` the water's resistance per row.
    ``learning`` False (a constant in the loops that inline this, ``*_fixed``): the step of a
    patch with nothing learnt nor carried (:func:`fixed`), its code without any of it; the
    same results as with True for such a patch, bit for bit.
    """
    st[KUP] = st[KUP + 6] = 0.0  # no update for the step signatures yet
    if pr[PR_TRACE] != 0.0:  # the trace's records of this sample
        st[UREC] = st[UREC + NUR] = st[SWB] = st[SWA] = 0.0
    _eq8(st, pr, Rw, T_w, T_p, T_a, iv)
    iv_old = -1  # the pump's row before a switch whose correction waits for this row's reading
    v_known = iv >= 0
    if v_known:
        if iv != int(st[IVP]) and pr[PR_VSW] > 0.0 and st[READY] != 0.0:
            if (fresh & 1) != 0 and math.isfinite(T_w) and 1.5 * pr[PR_TS] < t - st[TFW] < 1e299:
                # a slow board's reading (the last, NaN or not, came rows ago), new in the same
                # row as the switch: the controller switched on that reading, so it was taken
                # before the switch: it updates the state as it stood, the correction after it
                iv_old = int(st[IVP])
            else:
                _switch_correction(st, pr, Rw, int(st[IVP]), iv, SWB)
        if iv != int(st[IVP]):
            st[PHPREV] = st[PHASE]
            st[PHASE] = 0.0
            st[PHDIR] = 0.0 if Rw[iv] < Rw[int(st[IVP])] else 1.0
        else:
            st[PHASE] += 1.0
        st[IVP] = iv
    else:
        iv = int(st[IVP])
        st[PHASE] += 1.0
    if (fresh & 1) != 0:
        st[TFW] = t
    gap = st[E8GAP] > 0.0
    st[GAP] = 1.0 if gap else 0.0
    st[SGE] = st[SGG] = 0.0
    st[QPRI] = st[X + 2]
    # the readings' converter steps (each channel's smallest change between fresh readings);
    # the tank's and the air's reading variances from their own second differences (both
    # change smoothly: what a second difference holds is the noise, 6 R); the pipe's, which
    # the pump kinks at every switch, from its innovations (_update) where its board is fast,
    # and where it is slow from the change since its reading at the same point of the pump's
    # cycle (_noise_phase), as from its innovations while no contact is seen and none has just
    # ended (a touch's change over a cycle is no noise); not from a log coarser than the loop
    # (PR_VSW: its pump switched somewhere in a row's interval, and the point of the cycle is
    # known only to a row: a 100 Hz log's noise came out high, its touches found later)
    learn_r = learning and pr[PR_LEARN] != 0.0 and pr[PR_TAUR] > 0.0
    if learning and (fresh & 1) != 0:
        if (learn_r and pr[PR_PBTOL] > 0.0 and pr[PR_VSW] == 0.0 and st[RATE] < pr[PR_RFAST]
                and st[READY] != 0.0 and t - st[TINIT] >= PB_START and v_known
                and st[MODE] != INCONTACT and t - st[TREL] >= pr[PR_TSETTLE]):
            _noise_phase(st, pr, t, T_w)
        _quantum(st, QW, LYW, T_w)
    if learning and (fresh & 2) != 0:
        if learn_r:
            _noise2(st, pr, RP, PR_RP0, QP, LYP, LY2P, T_p, t - st[TLP])
        _quantum(st, QP, LYP, T_p)
    if learning and (fresh & 4) != 0:
        if learn_r:
            _noise2(st, pr, RA, PR_RA0, QA, LYA, LY2A, T_a, t - st[TLA])
        _quantum(st, QA, LYA, T_a)
    # a converter step too coarse to learn the slow states from (the steps as they now stand)
    coarse = learning and _coarse(st, pr)
    # the configured offsets off the readings (the learnt one of the tank's at its update)
    T_w_raw = T_w
    T_w = T_w - pr[PR_OFW]
    T_a = T_a - pr[PR_OFA]
    # the pipe reading's variance from its innovations, while no contact is seen and none has
    # just ended, taken NRS slots late (_r_slots): the innovations of a touch not yet detected
    # (with slow boards, a second or so) are dropped at its detection, not taken for noise
    # and only from fast readings (PR_RFAST a second and more; a slow board's: _noise_phase)
    learn = (learning and pr[PR_LEARN] != 0.0 and pr[PR_TAUR] > 0.0 and st[MODE] != INCONTACT
             and t - st[TREL] >= pr[PR_TSETTLE] and st[RATE] >= pr[PR_RFAST])
    if learning and pr[PR_LEARN] != 0.0 and t - st[RST0] >= pr[PR_RSLOT]:
        _r_slots(st, pr, t)
    # the slow states (offset, lag) learn while no contact is seen and none has just ended, and
    # not while the filter settles after its start
    slow = (learning and pr[PR_LEARN] != 0.0 and st[MODE] != INCONTACT and t - st[TREL] >= pr[PR_TSETTLE]
            and t - st[TINIT] >= pr[PR_LDELAY] and st[QW] <= pr[PR_QFINE] and st[QP] <= pr[PR_QFINE])
    # nor while the detector's evidence builds (an onset CUSUM above a fraction of its
    # threshold): the readings between a touch's onset and its detection are the touch's, and
    # learnt they moved the lag and the offset, whose error then read as heat at each pump
    # switch (a flood the hold during contacts kept); the window goes on without them
    learn_slow = slow and not _building(st, pr)
    if st[READY] == 0.0:
        if gap:
            return C_CONTACT if st[MODE] == INCONTACT else 0
        _init(st, pr, T_w, T_p - pr[PR_OFP] - (pr[PR_BD0] if st[LINIT] == 0.0 else st[BD]), T_a)
        st[TINIT] = t
        st[TLP] = t
        st[TLA] = t
    else:
        upd_a = (fresh & 4) != 0 and math.isfinite(T_a)
        _ambient(st, pr, t, T_a, upd_a, int(pr[PR_AMB]), learning)
        if learning and upd_a:
            st[TLA] = t
        if st[TAMB] == t and st[MODE] == INCONTACT and t - st[DETECTED] < pr[PR_TRETR]:
            # the "contact" just begun was the air changing: withdraw it (no event)
            st[MODE] = IDLE
            st[CONTACT] = 0.0
            st[X + 2] = st[B]
            st[VB + 2] = st[VT + 2] = 0.0  # q_i set: no longer a function of the slow states
            _cusums_reset(st, t)
        upd_w = (fresh & 1) != 0 and math.isfinite(T_w)
        upd_p = (fresh & 2) != 0 and math.isfinite(T_p)
        # read whether or not a reading comes (read only where one does, the fresh sample's
        # code spilled more: 1000 patches on one core 1.0-1.025x, 1461 instructions against 1420)
        p = _p_get(st)
        if upd_w:
            y = T_w
            nph = int(pr[PR_NPH])
            if nph > 0:
                # the pump-cycle correction: the reading less the mean misfit at this phase of
                # the cycle, learned while no touch is detected; where the sensors are learnt,
                # against the predicted reading (through the bead), only from fast boards
                # and only once the slow states are learnt and where they may learn (they would
                # otherwise compete for the same misfit: the lag's and an offset's are locked
                # to the pump's cycle too), and held in a filter that holds what is learnt
                ph = int(st[PHASE])
                j = TPL + int(st[PHDIR]) * nph + (ph if ph < nph - 1 else nph - 1)
                c = st[j]
                if learning and (pr[PR_PB0] != 0.0 or pr[PR_PT0] != 0.0):
                    # (held while an onset's evidence builds, as the slow states are, and in
                    # the filter's first seconds, its own transient; leaking: SWITCH_LEAK)
                    if (learn_slow and st[RATE] >= pr[PR_RFAST] and _slow_learnt(st, pr)
                            and t - st[TINIT] >= pr[PR_RHOEARLY] and t - st[TREL] >= SWITCH_SETTLE):
                        a = st[LAGA]
                        w = pr[PR_APH]
                        st[j] = c + w * (T_w - (1.0 - a) * st[X] - a * st[XM] - c) - w * SWITCH_LEAK * c
                elif st[MODE] != INCONTACT and pr[PR_LEARN] != 0.0:  # (nothing learnt; held)
                    st[j] = c + pr[PR_APH] * (T_w - st[X] - c)
                y = T_w - c
            p = _update(st, pr, 0, y, p, _eta_w(pr, t - st[TLW]) if learn else 0.0, learn_slow,
                        learning, coarse)
            st[GAPRUN] = 0.0
            dt = t - st[TLW]
            if dt > 0.0:  # the board's rate: a running mean of 1/interval, first value as is
                r = 1.0 / dt
                st[RATE] = r if st[RATE] == 0.0 else st[RATE] + pr[PR_ARATE] * (r - st[RATE])
                _threshold(st, pr)
            st[TLW] = t
        else:
            st[GAPRUN] += 1.0
        if upd_p:
            p = _update(st, pr, 3, T_p - pr[PR_OFP] - (st[BD] if learning else pr[PR_BD0]), p, 0.0,
                        learn_slow, learning, coarse)
            if learning:
                st[TLP] = t
        if upd_w or upd_p:
            _p_put(st, p)
    if iv_old >= 0:
        _switch_correction(st, pr, Rw, iv_old, iv, SWA)
    if slow and t - st[SWIN + 4] >= pr[PR_SWIN]:
        _slow_window(st, pr, t)
    elif learning and not slow:
        for j in range(4):
            st[SWIN + j] = 0.0
        st[SWIN + 4] = t
    if learning and pr[PR_RHOW] > 0.0 and pr[PR_LEARN] != 0.0:
        # (not while the slow states are still far from learnt: the filter's own transient at
        # its start; but with a coarse converter, which they never learn from, at once)
        _dispersion(st, pr, t, st[SGE], st[SGG], not gap and st[MODE] != INCONTACT
                    and t - st[TAMB] >= pr[PR_TAMBH] and t - st[TREL] >= pr[PR_RHOSET]
                    and (_slow_learnt(st, pr) or coarse), coarse)
    st[Q] = st[X + 2]
    pq = st[P + 12]
    st[SQ] = math.sqrt(pq) if pq > 0.0 else 1e-12
    # a new set-point: the controller is about to drive the tank hard; let its slope go
    # and drop the evidence gathered so far (it was about the old regime)
    if T_w_cmd == T_w_cmd:
        dc = T_w_cmd - st[CMD]
        if st[CMD] == st[CMD] and abs(dc) > 1e-9:
            st[P + 24] += (dc / pr[PR_TCMD]) ** 2
            _cusums_reset(st, t)
        st[CMD] = T_w_cmd
    # arming (no command: at once): once the T_w readings' mean has held within the band of
    # their command for t_arm, or settled (within ARM_STEADY of the band) for ARM_HOLD x t_arm
    if st[ARMED] == 0.0:
        if T_w_cmd != T_w_cmd:
            st[ARMED] = 1.0
        elif math.isfinite(T_w_raw):
            _arm(st, pr, T_w_raw, T_w_cmd)
        else:
            st[NIN] = 0.0
    code = 0
    if gap:  # a NaN reading: hold the detector (and a contact) over it
        code = C_CONTACT if st[MODE] == INCONTACT else 0
    elif st[ARMED] != 0.0 and pr[PR_TRACE] == 0.0:
        code = _detect(st, pr, t, ev, learning)
    else:
        st[DQ] = st[Q] - st[B]
    # predict over the coming interval
    _ambient_predict(st, Phi_a, Q_a)
    # (and, armed, through the air's hold from a door's start, not its renewals: a sensor
    # lagging the air more than configured leaves the sheet a heat no model has, G_a tau dT_a/dt,
    # for as long as the door lasts; taken in slowly, as between touches, the estimate then came
    # back over seconds after the hold, read as a touch: it follows it as in a contact)
    door = pr[PR_DOORQ] != 0.0 and st[ARMED] != 0.0 and t - st[TDOOR] < pr[PR_TAMBH]
    Qd = Qc if st[MODE] == INCONTACT or door else Qi
    x0 = st[X]
    slow_on = learning and pr[PR_SLOWON] != 0.0
    if slow_on:
        _bead_predict(st)
    _predict(st, Phi[iv], Gam[iv], Qd[iv], st[XA], drive if drive == drive else 0.0)
    if slow_on:
        _slow_predict(st, pr, Phi[iv], x0)
    if _keeps_mu(st, pr):  # the step signatures, for the onset's whole-state jump
        _mu_carry(st, Phi[iv])
    if st[GAPRUN] > pr[PR_MAXGAP]:
        st[READY] = 0.0  # restart from the next valid readings
    return code


@_inline
def _arm(st, pr, T_w_raw, T_w_cmd):
    """One reading into the arming: its mean (a first-order lag, ARM_TAU), the hold within the
    band of the command, the hold of the mean itself; armed once either is long enough."""
    lp = st[ARMLP]
    a = pr[PR_TS] / ARM_TAU
    lp = T_w_raw if lp != lp else lp + (a if a < 1.0 else 1.0) * (T_w_raw - lp)
    st[ARMLP] = lp
    if abs(lp - T_w_cmd) <= pr[PR_BAND]:
        st[NIN] += 1.0
    else:
        st[NIN] = 0.0
    if abs(lp - st[ARMREF]) <= ARM_STEADY * pr[PR_BAND]:  # (a NaN: the first reading)
        st[NSTEADY] += 1.0
    else:
        st[ARMREF] = lp
        st[NSTEADY] = 0.0
    if st[NIN] >= pr[PR_NARM] or st[NSTEADY] >= ARM_HOLD * pr[PR_NARM]:
        st[ARMED] = 1.0


@_inline
def _quantum(st, iq, ily, y):
    """A channel's converter step: the greatest common divisor of the changes between its fresh
    readings (``st[iq]``; the last reading in ``st[ily]``), by Euclid's algorithm to within
    1e-9 K: a converter's readings are whole multiples of its step, so their changes are too,
    however far apart; a board without one (or a log's readings rounded to no common step)
    brings it below 1e-6 K at once."""
    if math.isfinite(y):
        d = abs(y - st[ily])
        if d > 1e-9:
            g = st[iq]
            if g >= 1e299:
                g = d
            else:
                a, b = (g, d) if g > d else (d, g)
                for _ in range(64):
                    if b <= 1e-9:
                        break
                    a, b = b, a % b
                g = a
            st[iq] = g
        st[ily] = y


@_inline
def _r_slots(st, pr, t):
    """The next slot of the pipe reading variance's steps: the oldest, ``NRS - 1`` slots of
    ``PR_RSLOT`` s back (1.5 s), taken into the variance (within its bounds), and begun afresh."""
    k = int(st[RSI]) + 1
    k = k if k < NRS else 0
    v = st[RSL + k]
    if v != 0.0:
        r = st[RW] * math.exp(v)
        q = st[QW]
        qq = q * q / 12.0 if q < 1e299 else 0.0
        lo = pr[PR_RW0] / pr[PR_RMIN]
        lo = lo if lo > qq else qq
        hi = pr[PR_RW0] * pr[PR_RMIN]
        st[RW] = lo if r < lo else (hi if r > hi else r)
    st[RSL + k] = 0.0
    st[RSI] = k
    st[RST0] = t


@_inline
def _r_drop(st):
    """A contact detected: the pipe reading variance's steps not yet taken were its onset's."""
    for j in range(NRS):
        st[RSL + j] = 0.0


@_inline
def _r_step(st, pr, R, up, eta, ipr0, iq):
    """A reading variance's median tracker, one step up (``up``) or down by ``1 + eta``, kept
    within ``PR_RMIN`` of its prior (``pr[ipr0]``) both ways and above its converter's step's
    ``q²/12`` (``st[iq]``)."""
    r = R * (1.0 + eta) if up else R / (1.0 + eta)
    q = st[iq]
    qq = q * q / 12.0 if q < 1e299 else 0.0
    lo = pr[ipr0] / pr[PR_RMIN]
    lo = lo if lo > qq else qq
    hi = pr[ipr0] * pr[PR_RMIN]
    return lo if r < lo else (hi if r > hi else r)


@_inline
def _noise2(st, pr, ir, ipr0, iq, iy1, iy2, y, dt):
    """A smooth channel's reading variance from its second differences: ``y - 2 y1 + y2`` of three
    fresh readings is ``6 R`` in variance where the temperature's curvature over them is small
    against the noise; its median tracker (chi2(1)'s median 0.4549), each reading weighed by
    :func:`_eta` of ``dt`` since the last. ``st[iy1]``, ``st[iy2]``: the last two readings
    (``iy1`` is the quantum's, moved on by :func:`_quantum`)."""
    if not math.isfinite(y):
        return
    y1, y2 = st[iy1], st[iy2]
    st[iy2] = y1
    if y1 == y1 and y2 == y2:
        d = y - 2.0 * y1 + y2
        st[ir] = _r_step(st, pr, st[ir], d * d > 6.0 * CHI2_MEDIAN * st[ir], _eta(st, pr, ir - RW + NRW, dt),
                         ipr0, iq)


@_inline
def _noise_phase(st, pr, t, y):
    """A slow board's pipe reading variance (fewer than ``PR_RFAST`` readings a second): the
    change ``y - y_j`` since the last reading ``y_j`` (within :data:`PB_REACH`) taken at the same
    point of the pump's cycle (the same direction of its last switch, the same time since it and
    the same length of the phase before, each to within ``PR_PBTOL``) is ``2 R`` in variance:
    the pipe's response to the pump, the same both times, cancels. Its median tracker (chi2(1)'s
    median 0.4549), each reading weighed by :func:`_eta`. A slow board's innovations hold the
    model's prediction over the interval as well (they gave 10-40 % below the noise), its
    second differences the pump's kinks (with 10 Hz boards the pump switches every 0.1-0.2 s:
    0.30 K for 0.049 K), and held at its prior (0.02 K) the variance of a board of 0.049 K left
    the filter's gain too high: the evidence 3.7 times as spread as white noise's and false
    alarms in minutes of no touch (the emulator's default boards)."""
    if not math.isfinite(y):
        return
    ts = pr[PR_TS]
    tol = pr[PR_PBTOL]
    dr = st[PHDIR]
    ph = st[PHASE] * ts
    pv = st[PHPREV] * ts
    n = int(st[PBN])
    h = int(st[PBH])
    for j in range(n):
        o = PBQ + 5 * ((h - 1 - j) % NPB)
        if t - st[o] > PB_REACH:
            break
        if st[o + 2] == dr and abs(st[o + 3] - ph) <= tol and abs(st[o + 4] - pv) <= tol:
            d = y - st[o + 1]
            st[RW] = _r_step(st, pr, st[RW], d * d > 2.0 * CHI2_MEDIAN * st[RW],
                             _eta(st, pr, NRW, t - st[TLW]), PR_RW0, QW)
            break
    o = PBQ + 5 * h
    st[o] = t
    st[o + 1] = y
    st[o + 2] = dr
    st[o + 3] = ph
    st[o + 4] = pv
    st[PBH] = (h + 1) % NPB
    st[PBN] = n + 1 if n < NPB else NPB


@_inline
def _eta_w(pr, dt):
    """A pipe reading's weight in its variance's tracker: the time since the last over the
    tracker's time constant, at most 0.01 (fast readings only: no start of its own)."""
    w = dt / pr[PR_TAUR]
    return w if w < 0.01 else 0.01


@_inline
def _eta(st, pr, icount, dt):
    """A reading's weight in its variance's tracker: the time since the channel's last reading
    over the tracker's time constant, at most 0.01 (a slow board's readings, each weighed so,
    still average about a hundred), and at first ``1/(n + 4)`` at its ``n``-th reading
    (``st[icount]``, counted here): a running median, learnt in a hundred readings, ten seconds
    of a 10 Hz board's, rather than the tracker's time constants."""
    n = st[icount]
    st[icount] = n + 1.0
    w = dt / pr[PR_TAUR]
    w = w if w < 0.01 else 0.01
    f = 1.0 / (n + 4.0)
    return f if f > w else w


@_inline
def _slow_window(st, pr, t):
    """The end of a slow-state window: where the readings since its start say an offset or a lag
    other than the learnt one, by more than three of its standard deviations (``(sum s e/S)²/sum
    s²/S > 9``), its variance is let go to the square of that difference (``sum s e/S / sum
    s²/S``, the window's least-squares estimate of the error): the learnt value was believed too
    well (a first-order filter's covariance shrinks before a lag far from its start is reached),
    and the next readings move it at once. Its covariance with the other is let go with it. At
    most (1 K)² for the offset and ``PR_TAUMAX``² for the lag (an absurd reading's window); a
    state whose prior variance is 0 (not learnt) stays as it is, and so do both with a slow
    board (fewer than ``PR_RFAST`` readings a second)."""
    # (from fast boards only, PR_RFAST readings a second and more: a slow board's few readings a
    # window, each holding the model's prediction over its interval, let them go again and again,
    # the offset's sd back to 0.3-0.5 K, the dispersion never learnt, false alarms)
    fast = st[RATE] >= pr[PR_RFAST]
    for j, o, cap, p0 in ((0, PBB, 1.0, pr[PR_PB0]), (2, PTT, pr[PR_TAUMAX] * pr[PR_TAUMAX], pr[PR_PT0])):
        a, b = st[SWIN + j], st[SWIN + j + 1]
        if p0 > 0.0 and fast and b > 0.0 and a * a > 9.0 * b:  # (a state not learnt: not let go)
            d = a / b
            v = d * d if d * d < cap else cap
            if v > st[o]:
                st[o] = v
                st[PBT] = 0.0
    for j in range(4):
        st[SWIN + j] = 0.0
    st[SWIN + 4] = t


@_inline
def _bead_predict(st):
    """The pipe thermocouple's bead through the sample, before the model's step (it follows the
    pipe's temperature at the sample's start): ``m <- (1 - a) T_w + a m``, its covariance with the
    state ``c <- Phi ((1 - a) P[:, 0] + a c)`` (rows 2 and 4 of ``Phi`` unit rows; ``P`` still the
    sample's posterior), its variance, and the slow states' sensitivities of it."""
    a = st[LAGA]
    b1 = 1.0 - a
    c0 = st[CM]
    v0 = b1 * st[P] + a * c0
    v1 = b1 * st[P + 1] + a * st[CM + 1]
    v2 = b1 * st[P + 2] + a * st[CM + 2]
    v3 = b1 * st[P + 3] + a * st[CM + 3]
    v4 = b1 * st[P + 4] + a * st[CM + 4]
    st[PMM] = b1 * v0 + a * (b1 * c0 + a * st[PMM])
    st[XM] = b1 * st[X] + a * st[XM]
    st[VBM] = b1 * st[VB] + a * st[VBM]
    st[VT + 5] = b1 * st[VT] + a * st[VT + 5]
    # c's rows 0, 1, 3 through Phi come in _slow_predict (Phi's rows read there once): v kept
    st[CM], st[CM + 1], st[CM + 2], st[CM + 3], st[CM + 4] = v0, v1, v2, v3, v4


@_inline
def _slow_predict(st, pr, F, x0):
    """The two-stage filter's prediction: the sensitivities ``V <- Phi V`` (of the offset and
    the lag), the bead's covariance ``c <- Phi c``; the slow states' random walks; and the lag's
    regressor, the model's pipe rate over the sample (``x0`` the pipe's temperature at its start)
    through the lag once and twice."""
    a0, a1, a2, a3, a4 = F[0, 0], F[0, 1], F[0, 2], F[0, 3], F[0, 4]
    b0, b1, b2, b3, b4 = F[1, 0], F[1, 1], F[1, 2], F[1, 3], F[1, 4]
    c0, c1, c2, c3, c4 = F[3, 0], F[3, 1], F[3, 2], F[3, 3], F[3, 4]
    for o in (VB, VT, CM):
        v0, v1, v2, v3, v4 = st[o], st[o + 1], st[o + 2], st[o + 3], st[o + 4]
        st[o] = a0 * v0 + a1 * v1 + a2 * v2 + a3 * v3 + a4 * v4
        st[o + 1] = b0 * v0 + b1 * v1 + b2 * v2 + b3 * v3 + b4 * v4
        st[o + 3] = c0 * v0 + c1 * v1 + c2 * v2 + c3 * v3 + c4 * v4
    ts = pr[PR_TS]
    if st[PBB] > 0.0:
        st[PBB] += pr[PR_SB] * ts
    if st[PTT] > 0.0:
        st[PTT] += pr[PR_ST] * ts
    la = st[LAGA]
    lb = 1.0 - la
    r = (st[X] - x0) / ts
    r = -1e3 if r < -1e3 else (1e3 if r > 1e3 else r)  # a pipe moves far slower than 1000 K/s
    w1 = la * st[WL1] + lb * r
    st[WL1] = w1
    st[WL2] = la * st[WL2] + lb * w1


@_inline
def _keep_event(events, ne, ev):
    """``events[ne] = ev``, element by element (a row view would need reference counting)."""
    for j in range(NEV):
        events[ne, j] = ev[j]


@njit(nogil=True, **_FAST)
def run(st, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive, fresh,
        out, events, ev, marks):
    """:func:`step` over arrays; fills ``out`` (rows: q_i_hat, dq_i_hat, q estimate, its sd,
    contact, gap, the sheet's estimated temperature T_g, their covariance, the learnt offset of
    the T_p readings beyond the configured one and its sd), ``events``
    (``ev``: a scratch event row) and ``marks`` (the rows where a contact started or ended:
    row, those step-result bits, the contact's onset; the re-dating's clock); returns the
    event count and the mark count. :func:`step` inlined (LLVM's inlining, which adds little to
    the compile; numba's own had cost another 20 s) rather than called a sample: 12 % faster
    then (170 against 193 ns)."""
    n = t.shape[0]
    ne = 0
    nm = 0
    cap = events.shape[0]
    cap_m = marks.shape[0]
    for k in range(n):
        c = step(st, pr, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t[k], T_w[k], T_p[k], T_a[k],
                 T_w_cmd[k], iv[k], drive[k], fresh[k], ev)
        _outputs(st, out, k)
        if c & (C_STARTED | C_ENDED):
            if nm < cap_m:
                marks[nm, 0] = k
                marks[nm, 1] = c & (C_STARTED | C_ENDED)
                marks[nm, 2] = st[ONSET]
            nm += 1
            if c & C_ENDED:
                if ne < cap:
                    _keep_event(events, ne, ev)
                ne += 1
    return ne, nm


@_inline
def _outputs(st, out, k):
    out[0, k] = st[QIH]
    out[1, k] = st[DQ]
    out[2, k] = st[Q]
    out[3, k] = st[SQ]
    out[4, k] = st[CONTACT]
    out[5, k] = st[GAP]
    out[6, k] = st[X + 1]
    out[7, k] = st[P + 7]
    out[8, k] = st[BD]  # the learnt offset of the T_p readings (beyond the configured), K
    pb = st[PBB]
    out[9, k] = math.sqrt(pb) if pb > 0.0 else 0.0


# ---------------------------------------------------------------- many patches
# ST[i] is patch i's state; its model (parameters and tables) is row mid[i] of PR and of the
# tables Phi[m, v], Gam[m, v], ..., Rw[m, v] (patches with the same parameters share one).

@_inline
def _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m):
    """Model ``m``'s parameters and tables (row ``m`` of each). The loops over patches take
    them again only where the model changes from one patch (or row) to the next, not at every
    patch: on one core 1000 patches tick 2.6-2.8 % faster (``benchmarks/patches.py --threads one
    --peer``, three runs), the results the same bit for bit."""
    return PR[m], Phi[m], Gam[m], Qi[m], Qc[m], Phi_a[m], Q_a[m], Rw[m]


def fixed(PR: np.ndarray) -> bool:
    """Whether every model in ``PR`` (one row a model) has nothing learnt nor carried of its
    sensors: no reading variance learnt (``PR_TAUR`` 0), no dispersion (``PR_RHOW`` 0), neither
    bead nor slow state (``PR_SLOWON`` 0), as ``estimation.model.fixed_sensors`` makes them (a
    skin's patch). Such patches are stepped by the ``*_fixed`` loops, whose step has none of that
    code: on one core 1000 patches tick in about 0.7 of the time (``benchmarks/patches.py``)."""
    return bool(PR.shape[0] == 0 or ((PR[:, PR_TAUR] == 0.0) & (PR[:, PR_RHOW] == 0.0)
                                     & (PR[:, PR_SLOWON] == 0.0)).all())


@_inline
def _step_many(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive,
               fresh, codes, EV, learning):
    m = mid[0] if ST.shape[0] > 0 else 0
    pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
    for i in range(ST.shape[0]):
        if mid[i] != m:  # the model's rows taken again only where it changes
            m = mid[i]
            pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
        codes[i] = step(ST[i], pr, F, G, Q1, Q2, Fa, Qa, R, t,
                        T_w[i], T_p[i], T_a[i], T_w_cmd[i], iv[i], drive[i], fresh[i], EV[i],
                        learning)


@njit(**_FAST)
def step_many(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive,
              fresh, codes, EV):
    """One sample of every patch: the readings are arrays over patches; ``codes[i]`` its bits,
    ``EV[i]`` its ended contact (where ``codes[i]`` has ``C_ENDED``). For a few patches, on one
    core (many go to :func:`step_many_parallel`); :func:`step` inlined, as there."""
    _step_many(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive,
               fresh, codes, EV, True)


@njit(**_FAST)
def step_many_fixed(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv,
                    drive, fresh, codes, EV):
    """:func:`step_many` for patches with nothing learnt nor carried (:func:`fixed`)."""
    _step_many(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv, drive,
               fresh, codes, EV, False)


#: Patches a thread claims at a time in :func:`step_many_parallel` (about 3 µs of work).
CHUNK = 16
#: int64 words between two ranges' claim words in ``claims`` (each on a cache line of its own).
CLAIM_STRIDE = 8
_LOW = (1 << 32) - 1


def claim_words(threads: int) -> np.ndarray:
    """The claim words :func:`step_many_parallel` needs for ``threads`` threads
    (``numba.get_num_threads()``)."""
    return np.zeros(max(1, threads) * CLAIM_STRIDE, dtype=np.int64)


@njit(parallel=True, **_FAST)
def step_many_parallel(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a, T_w_cmd, iv,
                       drive, fresh, codes, EV, claims):
    """:func:`step_many` with the patches shared out over the cores (the patches are
    independent, so the result is the same, bit for bit, whichever core steps which).

    Each thread owns a range of the patches, claimed :data:`CHUNK` at a time from its front;
    a thread done with its own takes what is left of the others' from their backs. So a core
    the host stalls alone in mid-tick (a shared machine's other work) costs the tick about half
    the stall, the other core taking over its patches, not the whole stall (a stall of every
    core at once, it cannot shorten); and without stalls each core steps the same patches every
    tick, their states still in its caches. Range ``r``'s claim
    word, ``claims[r * CLAIM_STRIDE]``, holds its front chunk (low 32 bits) and one past its back
    chunk (high 32 bits), claimed by one atomic add each (:func:`~thermoskin._jit.fetch_add`);
    ``claims`` has one word (and line) per range: as many as threads, :func:`claim_words`
    (fewer ranges than threads leave threads idle; more are stepped in turn; the name ``sched``
    is numba's own in a parallel loop)."""
    n = ST.shape[0]
    nw = _claims_open(claims, n)
    for w in prange(nw):
        s = 0
        while True:
            lo, hi, s = _claim(claims, w, s, n)
            if lo < 0:
                break
            m = mid[lo]
            pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
            for i in range(lo, hi):
                if mid[i] != m:
                    m = mid[i]
                    pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
                codes[i] = step(ST[i], pr, F, G, Q1, Q2, Fa, Qa, R, t, T_w[i], T_p[i], T_a[i],
                                T_w_cmd[i], iv[i], drive[i], fresh[i], EV[i], True)


@njit(parallel=True, **_FAST)
def step_many_parallel_fixed(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, t, T_w, T_p, T_a,
                             T_w_cmd, iv, drive, fresh, codes, EV, claims):
    """:func:`step_many_parallel` for patches with nothing learnt nor carried (:func:`fixed`).
    (Its loop written out as there: through an inlined helper, LLVM contracted the sums into
    fused multiply-adds otherwise than in :func:`step_many`, and the two parted by an ulp.)"""
    n = ST.shape[0]
    nw = _claims_open(claims, n)
    for w in prange(nw):
        s = 0
        while True:
            lo, hi, s = _claim(claims, w, s, n)
            if lo < 0:
                break
            m = mid[lo]
            pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
            for i in range(lo, hi):
                if mid[i] != m:
                    m = mid[i]
                    pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
                codes[i] = step(ST[i], pr, F, G, Q1, Q2, Fa, Qa, R, t, T_w[i], T_p[i], T_a[i],
                                T_w_cmd[i], iv[i], drive[i], fresh[i], EV[i], False)


@_inline
def _claims_open(claims, n):
    """Share ``n`` patches' chunks out into ranges, one a claim word; returns the range count."""
    nw = claims.shape[0] // CLAIM_STRIDE
    nch = (n + CHUNK - 1) // CHUNK
    for r in range(nw):
        claims[r * CLAIM_STRIDE] = (r * nch // nw) | (((r + 1) * nch // nw) << 32)
    return nw


@_inline
def _claim(claims, w, s, n):
    """Thread ``w``'s next chunk of the ``n`` patches, ``(lo, hi, s)``: its patches ``lo`` to
    ``hi - 1`` and the range it came from, ``s`` ranges on from its own (its own range from the
    front, then the others' from their backs); ``lo = -1`` when none is left."""
    nw = claims.shape[0] // CLAIM_STRIDE
    while s < nw:
        o = ((w + s) % nw) * CLAIM_STRIDE
        if s == 0:  # its own range, from the front
            old = fetch_add(claims, o, 1)
            c = old & _LOW
            if c < (old >> 32):
                return c * CHUNK, min((c + 1) * CHUNK, n), s
        else:  # another's, from the back
            old = fetch_add(claims, o, -(1 << 32))
            c = (old >> 32) - 1
            if c >= (old & _LOW):
                return c * CHUNK, min((c + 1) * CHUNK, n), s
        s += 1
    return -1, -1, s


@_inline
def _run_rows(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, patch, t, T_w, T_p, T_a, T_w_cmd, iv,
              drive, fresh, out, events, ev_patch, ev, learning):
    """:func:`run_rows`'s loop, ``learning`` a constant (:func:`step`)."""
    n = t.shape[0]
    ne = 0
    cap = events.shape[0]
    m = mid[0] if ST.shape[0] > 0 else 0
    pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
    for k in range(n):
        i = patch[k]
        if mid[i] != m:  # the model's rows taken again only where it changes
            m = mid[i]
            pr, F, G, Q1, Q2, Fa, Qa, R = _model(PR, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, m)
        st = ST[i]
        c = step(st, pr, F, G, Q1, Q2, Fa, Qa, R, t[k], T_w[k], T_p[k], T_a[k], T_w_cmd[k], iv[k],
                 drive[k], fresh[k], ev, learning)
        _outputs(st, out, k)
        if c & C_ENDED:
            if ne < cap:
                _keep_event(events, ne, ev)
                ev_patch[ne] = i
            ne += 1
    return ne


@njit(nogil=True, **_FAST)
def run_rows(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, patch, t, T_w, T_p, T_a, T_w_cmd, iv,
             drive, fresh, out, events, ev_patch, ev):
    """A long-format log (one row per sample and patch, in time order): each row steps its
    patch's state; fills ``out`` per row (as :func:`run`), ``events`` and ``ev_patch`` (the
    patch of each; ``ev`` a scratch event row); returns the event count. :func:`step` inlined
    (LLVM's inlining, which no longer lengthens the compile much): 149-157 ns a row against
    187-193 ns calling it (9 patches, the same outputs)."""
    return _run_rows(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, patch, t, T_w, T_p, T_a, T_w_cmd,
                     iv, drive, fresh, out, events, ev_patch, ev, True)


@njit(nogil=True, **_FAST)
def run_rows_fixed(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, patch, t, T_w, T_p, T_a, T_w_cmd,
                   iv, drive, fresh, out, events, ev_patch, ev):
    """:func:`run_rows` for patches with nothing learnt nor carried (:func:`fixed`)."""
    return _run_rows(ST, PR, mid, Phi, Gam, Qi, Qc, Phi_a, Q_a, Rw, patch, t, T_w, T_p, T_a, T_w_cmd,
                     iv, drive, fresh, out, events, ev_patch, ev, False)


@njit(**_FAST)
def finish(st, t, ev):
    """End a contact still open at ``t`` (the end of a log); True if one was."""
    if st[MODE] == INCONTACT:
        _end(st, t, ev)
        return True
    return False
