"""Many patches at once: one state row per patch, stepped by the compiled kernel in one loop.

A whole-body skin has hundreds of patches, each with its own pipe thermocouple, all
estimated every sample. :class:`PatchEstimators` keeps one state vector per patch (a row of
``ST``) and one model per distinct configuration (patches built alike share their discretised
tables and parameters), and steps every patch with :func:`kernel.step_many` (live, one
sample of every patch) or :func:`kernel.run_rows` (a long-format log, one row per sample and
patch). Each patch is exactly the one-patch :class:`~thermoskin.estimation.estimator.TouchEstimator`
(the same sample step, inlined into each entry point), which the tests check bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba
import numpy as np
from numpy.typing import NDArray

from thermoskin.estimation import kernel as K  # noqa: N812
from thermoskin.estimation.estimator import TouchEstimator
from thermoskin.estimation.events import ContactEvent
from thermoskin.params import Config

Array = NDArray[np.float64]


#: From this many patches on, a sample of every patch is shared out over the cores.
PARALLEL_FROM = 64


class PatchEstimators:
    """``n`` patches, each with the configuration ``configs[i]`` (or one for all).

    ``parallel`` (default: from :data:`PARALLEL_FROM` patches on) steps the patches of a
    sample on every core (numba's ``prange``); the patches are independent, so the results
    are the same either way.
    """

    def __init__(self, configs: Config | Sequence[Config], n: int | None = None,
                 t_s: float | None = None, parallel: bool | None = None) -> None:
        cfgs = [configs] * int(n or 1) if isinstance(configs, Config) else list(configs)
        if not cfgs:
            raise ValueError("PatchEstimators: no patch")
        self.n = len(cfgs)
        self.t_s = cfgs[0].sampling.t_s if t_s is None else float(t_s)
        models: dict[Config, int] = {}
        self.mid = np.array([models.setdefault(c, len(models)) for c in cfgs], dtype=np.int64)
        par = self.n >= PARALLEL_FROM if parallel is None else parallel
        # the parallel step's claim words, one a thread (numba's threads now)
        self._claims = K.claim_words(numba.get_num_threads()) if par else None
        self._models = [TouchEstimator(c, t_s=self.t_s) for c in models]
        self._ev = np.zeros(K.NEV)  # the kernels' scratch event row (as TouchEstimator's)
        self._stack()
        self.reset()

    def _stack(self) -> None:
        """Tables of every model, stacked (every model has the same pump velocities)."""
        vs = tuple(dict.fromkeys(v for m in self._models for v in m.tables.v_values))
        for m in self._models:
            if m.tables.v_values != vs:
                m._build(vs)
        self.v_values = self._models[0].tables.v_values
        self._iv = {v: i for i, v in enumerate(self.v_values)}
        tabs = [m.tabs for m in self._models]
        self._tabs = tuple(np.ascontiguousarray(np.stack([t[j] for t in tabs]))
                           for j in range(len(tabs[0])))
        self.PR = np.ascontiguousarray(np.stack([m.pr for m in self._models]))
        # patches with nothing learnt nor carried of their sensors (a skin's): the loops whose
        # step has none of that code (the same results, in about 0.7 of the time)
        fx = K.fixed(self.PR)
        self._step_many = K.step_many_fixed if fx else K.step_many
        self._step_many_parallel = K.step_many_parallel_fixed if fx else K.step_many_parallel
        self._run_rows = K.run_rows_fixed if fx else K.run_rows

    def reset(self) -> None:
        """Every patch afresh."""
        self.ST = np.stack([K.new_state() for _ in range(self.n)])
        self.codes = np.zeros(self.n, dtype=np.int64)
        self.EV = np.zeros((self.n, K.NEV))
        self.events: list[tuple[int, ContactEvent]] = []

    def index(self, v: Array) -> NDArray[np.int64]:
        """Table rows of the pump velocities ``v`` (-1 for NaN); new velocities get tables."""
        v = np.asarray(v, dtype=float)
        if v.size > 64:  # a long-format block: each distinct velocity looked up once
            u, inv = np.unique(v, return_inverse=True)
            if u.size < v.size:
                return self._rows(u)[inv.ravel()].reshape(v.shape)
        return self._rows(v)

    def _rows(self, v: Array) -> NDArray[np.int64]:
        """:meth:`index`, one velocity at a time."""
        out = np.empty(v.shape, dtype=np.int64)
        for i, x in enumerate(v.ravel().tolist()):
            j = self._iv.get(x)
            if j is None:
                if x != x:
                    j = -1
                else:
                    self._models[0]._index(x)
                    self._stack()
                    j = self._iv[x]
            out.flat[i] = j
        return out

    # ---------------------------------------------------------------- live
    def step(self, t: float, T_w: Array, T_p: Array, v: Array, T_a: Array,
             T_w_cmd: Array | None = None, fresh: Array | None = None,
             drive: Array | None = None) -> NDArray[np.int64]:
        """One sample of every patch (arrays over patches); returns the contact flags."""
        n = self.n
        cmd = np.full(n, math.nan) if T_w_cmd is None else np.asarray(T_w_cmd, dtype=float)
        drv = np.full(n, math.nan) if drive is None else np.asarray(drive, dtype=float)
        fr = np.full(n, 7, dtype=np.int64) if fresh is None else np.asarray(fresh, dtype=np.int64)
        self.tick(float(t), np.asarray(T_w, dtype=float), np.asarray(T_p, dtype=float),
                  np.asarray(T_a, dtype=float), cmd, self.index(v), drv, fr)
        for i in np.flatnonzero(self.codes & K.C_ENDED):
            self.events.append((int(i), ContactEvent.from_kernel(self.EV[i])))
        return self.codes & K.C_CONTACT

    def tick(self, t: float, T_w: Array, T_p: Array, T_a: Array, T_w_cmd: Array,
             iv: NDArray[np.int64], drive: Array, fresh: NDArray[np.int64]) -> None:
        """The kernel's sample of every patch, on arrays of the kernel's types as they are
        (``iv`` from :meth:`index`; nothing converted or checked): :meth:`step` without its
        conversions, for a caller that keeps its arrays ready. Bits in ``codes``, ended
        contacts in ``EV``."""
        if self._claims is None:
            self._step_many(self.ST, self.PR, self.mid, *self._tabs, t, T_w, T_p, T_a, T_w_cmd,
                            iv, drive, fresh, self.codes, self.EV)
        else:
            self._step_many_parallel(self.ST, self.PR, self.mid, *self._tabs, t, T_w, T_p, T_a,
                                     T_w_cmd, iv, drive, fresh, self.codes, self.EV, self._claims)

    def column(self, offset: int) -> Array:
        """One state field of every patch (e.g. ``kernel.DQ``)."""
        return self.ST[:, offset].copy()

    # ---------------------------------------------------------------- logs
    def run_rows(self, patch: Array, t: Array, T_w: Array, T_p: Array, v: Array, T_a: Array,
                 T_w_cmd: Array | None = None, fresh: Array | None = None, drive: Array | None = None
                 ) -> tuple[dict[str, Array], list[tuple[int, ContactEvent]]]:
        """A long-format log (one row per sample and patch, in time order), continuing from
        where the last call stopped: per-row columns and the contacts that ended (with their
        patch)."""
        p = np.ascontiguousarray(patch, dtype=np.int64)
        n = len(p)
        if n and (p.min() < 0 or p.max() >= self.n):
            raise ValueError(f"patch index out of range 0..{self.n - 1}")
        def f(x, fill):
            # contiguous and writeable (a read-only Arrow column would compile a second kernel)
            return np.full(n, fill) if x is None else np.require(x, dtype=float, requirements="CW")
        fr = (np.full(n, 7, dtype=np.int64) if fresh is None
              else np.ascontiguousarray(fresh, dtype=np.int64))
        out = np.empty((K.NOUT, n))
        events = np.empty((max(16, n // 50), K.NEV))
        ev_patch = np.empty(len(events), dtype=np.int64)
        ne = self._run_rows(self.ST, self.PR, self.mid, *self._tabs, p,
                        np.ascontiguousarray(t, dtype=float), f(T_w, math.nan), f(T_p, math.nan),
                        f(T_a, math.nan), f(T_w_cmd, math.nan), self.index(v), f(drive, math.nan), fr,
                        out, events, ev_patch, self._ev)
        new = [(int(ev_patch[i]), ContactEvent.from_kernel(events[i])) for i in range(min(ne, len(events)))]
        self.events.extend(new)
        cols = {"q_i_hat": out[0], "dq_i_hat": out[1], "sd": out[3], "contact": out[4].astype(np.int8),
                "gap": out[5].astype(np.int8), "T_g_hat": out[6], "cov_qg": out[7]}
        return cols, new

    def finish(self, t: float) -> None:
        """End every contact still open at ``t``."""
        for i in range(self.n):
            if K.finish(self.ST[i], t, self._ev):
                self.events.append((i, ContactEvent.from_kernel(self._ev)))
