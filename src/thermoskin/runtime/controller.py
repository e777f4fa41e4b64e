"""The loop body: every block of the skin, stepped once per sample.

The same object runs against the simulated skin, a serial device, or a benchmark::

    v       = pump.step(T_w, T_w_cmd)                 Sec. V: stop while T_w is above its command
    T_p_cmd = mpc.step(T_w, T_a, T_w_cmd)             eqs. 9-11
    drive   = inner.step(T_p, T_p_cmd, T_a)           PI on the Peltier drive (Table I), plus the
                                                      identified model's feed-forward if configured
    contact = estimator.step(t, T_w, T_p, v, T_a, T_w_cmd, fresh, drive)   eq. 8, Kalman filter,
                                                      detector (it feeds no control decision)

Plain floats in, plain floats out; the results stay as attributes for a recorder. The
readings it is given have passed :func:`thermoskin.logio.plausible.admit` (done by the loops,
before the supervisor): an implausible reading arrives as NaN and is held over.

Active sensing (``probe``, :class:`~thermoskin.control.probe.SetpointProbe`): while a
contact is on, the pump logic and the MPC get ``T_w_cmd`` plus the probe's offset
(``T_w_cmd_eff``); the estimator keeps ``T_w_cmd``.
"""

from __future__ import annotations

from thermoskin.control.inner import InnerLoop, model_feedforward
from thermoskin.control.mpc import Mpc
from thermoskin.control.probe import SetpointProbe
from thermoskin.control.pump import PumpLogic
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.params import Config


class SkinController:
    """Observer, detector, MPC, inner loop and pump logic of one skin."""

    __slots__ = ("T_p_cmd", "T_w_cmd_eff", "_t_det", "contact", "drive", "estimator", "inner", "mpc",
                 "probe", "pump", "v")

    def __init__(self, cfg: Config, probe: SetpointProbe | None = None, *,
                 estimate: bool = True, background_fits: bool = False) -> None:
        """``probe``: active sensing during a contact (module doc). ``estimate=False``:
        temperature control only (pump, MPC, inner loop), no estimator (``estimator`` is None,
        ``contact`` stays 0, so no probe either): a water loop of many patches, whose patches
        are estimated elsewhere (``estimation.patches``). ``background_fits``: the estimator's
        (:class:`~thermoskin.estimation.estimator.TouchEstimator`), for a realtime loop."""
        t_s = cfg.sampling.t_s
        self.probe = probe
        self.estimator = TouchEstimator(cfg, background_fits=background_fits) if estimate else None
        self.pump = PumpLogic(cfg.pump, t_s)
        self.mpc = Mpc(cfg.skin, cfg.control, t_s, v_on=cfg.pump.v_on)
        self.inner = InnerLoop(cfg.control, t_s, feedforward=model_feedforward(cfg.peltier_model))
        self.reset()

    def reset(self, T_p: float | None = None) -> None:
        """Start every block afresh; ``T_p`` seeds the MPC's previous command."""
        if self.estimator is not None:
            self.estimator.reset()
        self.pump.reset(on=True)
        self.mpc.reset(T_p)
        self.inner.reset(0.0)
        self.v = self.pump.v
        self.T_p_cmd = self.drive = 0.0
        self.T_w_cmd_eff = float("nan")
        self.contact = 0
        self._t_det = 0.0

    def step(self, t: float, T_w: float, T_p: float, T_a: float, T_w_cmd: float,
             fresh: int = 7, v_applied: float | None = None, drive_applied: float | None = None) -> None:
        """One sample of measurements (``fresh``: bitmask of the channels with a new reading,
        1 ``T_w``, 2 ``T_p``, 4 ``T_a``); sets ``v, drive, T_p_cmd, contact`` (and the blocks').

        ``v_applied``, ``drive_applied``: what the device applies from ``t`` on, where it says so
        (a serial device's SAMPLE): the estimator models the interval with those rather than
        with this step's commands, which reach the device a sample or more later (many on a
        busy host)."""
        cmd = T_w_cmd
        if self.probe is not None and self.contact:
            cmd = T_w_cmd + self.probe.offset(t - self._t_det)
        self.T_w_cmd_eff = cmd
        v = self.pump.step(T_w, cmd, bool(fresh & 1))
        self.v = v
        T_p_cmd = self.mpc.step(T_w, T_a, cmd, v > 0.0)
        self.T_p_cmd = T_p_cmd
        drive = self.inner.step(T_p, T_p_cmd, T_a)
        self.drive = drive
        # last: the estimator models the interval to come with the pump and the drive applied
        if self.estimator is not None:
            if v_applied is not None:
                v = v_applied
            if drive_applied is not None:
                drive = drive_applied
            contact = self.estimator.step(t, T_w, T_p, v, T_a, T_w_cmd, fresh, drive)
            if contact and not self.contact:
                self._t_det = t
            self.contact = contact

    def safe(self) -> None:
        """The safe outputs: Peltier drive 0, pump off."""
        self.drive = 0.0
        self.v = 0.0
