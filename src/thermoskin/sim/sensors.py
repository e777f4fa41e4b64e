"""Thermocouple boards of the simulated skin: sensing-element lag, conversions, noise, hold.

Each channel (``T_w``, ``T_p``, ``T_a``) is a converter board reading one sensing element.
At sample ``k`` (``t_k = k t_s``), with ``x_k`` the true temperature there:

1. **Lag.** The element follows the true temperature with a first-order lag of time
   constant ``lag`` (s; 0 = none), integrated exactly for ``x`` held over each sample::

       y_0 = x_0,   y_{k+1} = a y_k + (1 - a) x_k,   a = exp(-t_s / lag)

   so a step of ``x`` from ``x_0`` to ``x_1`` at ``t_0`` reads, at the samples, exactly
   ``y(t) = x_1 + (x_0 - x_1) exp(-(t - t_0)/lag)``.
2. **Conversions.** The board converts at ``t_0 = 0`` and at ``t_j = j period + u_j``
   (``u_j`` uniform in ``[-jitter, jitter]``, independent), each taken at its nearest
   sample ``k_j = floor(t_j / t_s + 1/2)`` (the loop sees time on its sample grid);
   ``period = 0``: a conversion every sample.
3. **Reading.** A conversion at sample ``k`` reads
   ``r_k = q floor((y_k + b + noise_T n_k) / q + 1/2)`` with ``n_k`` standard normal,
   ``b = offset`` (K: the board's cold junction and the wire's tolerance, reading minus truth)
   and ``q = quantum_T`` (no rounding when ``q = 0``).
4. **Hold.** Between conversions the last reading is repeated and the channel is not
   fresh. ``fresh`` is a bit mask over the channels: ``T_w`` = 1, ``T_p`` = 2, ``T_a`` = 4
   (the link protocol's ``CH_W, CH_P, CH_A``).

A noise value is drawn for every sample, converted or not, so a board's readings are the
ideal (``period = 0``) board's readings at its conversion samples, and the noise sequence
does not depend on the period. Every channel has its own noise and jitter streams
(``SeedSequence(seed).spawn(6)``: noise of ``T_w, T_p, T_a``, then their jitter), so one
channel's readings do not depend on the others'. With the defaults (no lag, a conversion
every sample) a reading is ``quantise(x_k + noise_T n_k)`` with the noise of the earlier
``Sensors``: the same seeds give the same readings.

:meth:`Board.read` (per sample, plain floats) and :meth:`Board.read_array` (a whole log
from a reset) give the same numbers for the same samples.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from thermoskin.params import SensorParams

Array = NDArray[np.float64]

CHANNELS: tuple[str, str, str] = ("T_w", "T_p", "T_a")
FRESH_W, FRESH_P, FRESH_A = 1, 2, 4
"""``fresh`` bits of the three channels (as ``devices.protocol.CH_W, CH_P, CH_A``)."""
CHANNEL_BITS: dict[str, int] = {"T_w": FRESH_W, "T_p": FRESH_P, "T_a": FRESH_A}
FRESH_ALL = FRESH_W | FRESH_P | FRESH_A
BLOCK = 1024
"""Noise values drawn at a time on the per-sample path."""


def quantise(x: float, q: float) -> float:
    """Round to the nearest multiple of ``q`` (ties upward); ``q = 0``: unchanged."""
    return q * math.floor(x / q + 0.5) if q > 0.0 else x


def quantise_array(x: Array, q: float) -> Array:
    """Vectorised :func:`quantise` (a new array)."""
    x = np.asarray(x, dtype=float)
    return q * np.floor(x / q + 0.5) if q > 0.0 else x.copy()


class Board:
    """One thermocouple channel (see the module doc): lag, conversions, noise, quantum, hold.

    After :meth:`read`: ``value`` (the reading, °C) and ``fresh`` (the channel's bit if this
    sample converted, else 0).
    """

    __slots__ = ("_a", "_b", "_buf", "_j", "_jitter_rng", "_jitter_seed", "_lagged", "_next",
                 "_noise_rng", "_noise_seed", "_periodic", "_pos", "_y", "bit", "fresh", "jitter",
                 "k", "lag", "name", "noise_T", "offset", "period", "quantum_T", "t_s", "value")

    def __init__(self, name: str, *, period: float = 0.0, jitter: float = 0.0, lag: float = 0.0,
                 noise_T: float = 0.0, quantum_T: float = 0.0, t_s: float | None = None,
                 noise_seed: np.random.SeedSequence | None = None,
                 jitter_seed: np.random.SeedSequence | None = None, offset: float = 0.0) -> None:
        for what, val in (("period", period), ("jitter", jitter), ("lag", lag), ("noise_T", noise_T),
                          ("quantum_T", quantum_T)):
            if not (val >= 0.0 and math.isfinite(val)):
                raise ValueError(f"Board {name}: {what} = {val} must be a finite number >= 0")
        if not math.isfinite(offset):
            raise ValueError(f"Board {name}: offset = {offset} must be finite")
        if (period > 0.0 or lag > 0.0) and not (t_s is not None and t_s > 0.0):
            raise ValueError(f"Board {name}: a period or a lag needs the sample time t_s")
        if period > 0.0 and t_s is not None and period < t_s:
            raise ValueError(f"Board {name}: period = {period} s is shorter than t_s = {t_s} s")
        if period > 0.0 and not jitter < 0.5 * period:
            raise ValueError(f"Board {name}: jitter = {jitter} s must be below half the period "
                             f"({period} s)")
        self.name = name
        self.bit = CHANNEL_BITS.get(name, 0)
        self.period = float(period)
        self.jitter = float(jitter)
        self.lag = float(lag)
        self.noise_T = float(noise_T)
        self.quantum_T = float(quantum_T)
        self.offset = float(offset)
        self.t_s = float(t_s) if t_s is not None else math.nan
        self._periodic = self.period > 0.0
        self._lagged = self.lag > 0.0
        self._a = math.exp(-self.t_s / self.lag) if self._lagged else 0.0
        self._b = 1.0 - self._a
        self._noise_seed = noise_seed if noise_seed is not None else np.random.SeedSequence(0)
        self._jitter_seed = jitter_seed if jitter_seed is not None else np.random.SeedSequence(1)
        self.reset()

    def reset(self) -> None:
        """Back to sample 0: noise and jitter streams from their seeds, the element unset."""
        self._noise_rng = np.random.default_rng(self._noise_seed)
        self._jitter_rng = np.random.default_rng(self._jitter_seed)
        self._buf: list[float] = []
        self._pos = 0
        self._y = math.nan
        self.k = 0
        self._next = 0
        self._j = 0
        self.value = math.nan
        self.fresh = 0

    # -- noise -----------------------------------------------------------------------------
    def noise(self, n: int) -> Array:
        """The next ``n`` noise values, K (``noise_T`` times standard normal draws)."""
        buf, pos = self._buf, self._pos
        head = np.asarray(buf[pos:pos + n], dtype=float)  # left over from read()'s block
        self._pos = pos + head.size
        rest = self._noise_rng.standard_normal(n - head.size)
        return self.noise_T * np.concatenate([head, rest])

    # -- conversions -----------------------------------------------------------------------
    def _conversion_sample(self, j: int, u: float) -> int:
        return math.floor((j * self.period + u) / self.t_s + 0.5)

    def _advance(self, k: int) -> None:
        """Schedule the next conversion strictly after sample ``k`` (one jitter draw per instant)."""
        J = self.jitter
        j = self._j
        while True:
            j += 1
            u = self._jitter_rng.uniform(-J, J) if J > 0.0 else 0.0
            kn = self._conversion_sample(j, u)
            if kn > k:
                break
        self._j = j
        self._next = kn

    def conversions(self, n: int) -> NDArray[np.bool_]:
        """Which of the samples ``0..n-1`` convert (from a reset; consumes the jitter draws)."""
        conv = np.zeros(n, dtype=bool)
        if not self._periodic:
            conv[:] = True
            return conv
        if n == 0:
            return conv
        conv[0] = True
        m = math.floor((n * self.t_s + self.jitter) / self.period) + 2
        j = np.arange(1, m + 1, dtype=float)
        J = self.jitter
        u = self._jitter_rng.uniform(-J, J, size=m) if J > 0.0 else np.zeros(m)
        kj = np.floor((j * self.period + u) / self.t_s + 0.5).astype(np.int64)
        kj = kj[(kj > 0) & (kj < n)]
        conv[kj] = True
        return conv

    # -- readings --------------------------------------------------------------------------
    def read(self, x: float) -> float:
        """The reading at this sample of true temperature ``x`` (°C); sets ``fresh``; next sample."""
        k = self.k
        self.k = k + 1
        pos = self._pos
        buf = self._buf
        if pos >= len(buf):
            buf = self._noise_rng.standard_normal(BLOCK).tolist()
            self._buf = buf
            pos = 0
        self._pos = pos + 1
        if self._lagged:
            y = self._y
            if y != y:  # the element starts at the true temperature
                y = x
            self._y = self._a * y + self._b * x
        else:
            y = x
        if k < self._next:
            self.fresh = 0
            return self.value
        if self._periodic:
            self._advance(k)
        r = y + self.offset + self.noise_T * buf[pos]
        q = self.quantum_T
        if q > 0.0:
            r = q * math.floor(r / q + 0.5)
        self.value = r
        self.fresh = self.bit
        return r

    def lagged(self, x: Array) -> Array:
        """The element's temperature ``y`` for a whole log ``x`` from a reset (the lag recursion)."""
        x = np.asarray(x, dtype=float)
        if not self._lagged or x.size == 0:
            return x
        # y[k] = z[k-1], z[k] = b x[k] + a y[k]: the recursion of read(), term for term
        import scipy.signal  # only on the array path (1 s of import)

        y, _ = scipy.signal.lfilter([0.0, self._b], [1.0, -self._a], x, zi=[x[0]])
        return np.asarray(y)

    def read_array(self, x: Array) -> tuple[Array, NDArray[np.bool_]]:
        """Readings and fresh flags for a whole log ``x`` of true temperatures, from a reset."""
        x = np.asarray(x, dtype=float).ravel()
        n = x.size
        if self.k and (self._periodic or self._lagged):
            raise ValueError(f"Board {self.name}: read_array continues a log only on a board "
                             "without lag or period (reset first)")
        y = self.lagged(x)
        r = quantise_array(y + self.offset + self.noise(n), self.quantum_T)
        conv = self.conversions(n)
        if self._periodic and n:
            idx = np.maximum.accumulate(np.where(conv, np.arange(n), 0))
            r = r[idx]
        self.k += n
        if n:
            self.value = float(r[-1])
            self.fresh = self.bit if conv[-1] else 0
        return r, conv


class Sensors:
    """The three thermocouple boards of the skin from ``[sensor]``; ``t_s`` the sample time, s.

    Each channel has its noise (``noise_T_w`` etc., or ``noise_T``), its offset
    (``offset_T_w`` etc.), its lag and period; the quantum ``quantum_T`` is the converter's.

    Per sample: ``read(T_w, T_p, T_a)`` -> the three readings, and ``fresh`` (bit mask).
    Over a whole log from a reset: :meth:`read_arrays`. ``measure``/``measure_one`` are the
    same readings one channel at a time.
    """

    CHANNELS: tuple[str, ...] = CHANNELS
    BLOCK = BLOCK

    def __init__(self, sensor: SensorParams, t_s: float | None = None) -> None:
        self.sensor = sensor
        self.t_s = t_s
        self.noise_T = float(sensor.noise_T)
        self.quantum_T = float(sensor.quantum_T)
        seqs = np.random.SeedSequence(int(sensor.seed)).spawn(2 * len(CHANNELS))
        self.boards: dict[str, Board] = {
            ch: Board(ch, period=getattr(sensor, f"period_{ch}"), jitter=sensor.jitter,
                      lag=getattr(sensor, f"lag_{ch}"), noise_T=sensor.noise(ch),
                      quantum_T=self.quantum_T, t_s=t_s, noise_seed=seqs[i],
                      jitter_seed=seqs[len(CHANNELS) + i], offset=getattr(sensor, f"offset_{ch}"))
            for i, ch in enumerate(CHANNELS)}
        self._w, self._p, self._a = (self.boards[ch] for ch in CHANNELS)
        self.fresh = 0

    @property
    def ideal(self) -> bool:
        """No lag and a conversion every sample on every channel."""
        return all(b.period == 0.0 and b.lag == 0.0 for b in self.boards.values())

    def reset(self) -> None:
        """Every board back to sample 0 (the same noise and jitter as after construction)."""
        for b in self.boards.values():
            b.reset()
        self.fresh = 0

    def board(self, channel: str) -> Board:
        """The board of ``channel``; KeyError naming the known ones."""
        try:
            return self.boards[channel]
        except KeyError:
            raise KeyError(f"Sensors: unknown channel {channel!r} (known: {', '.join(CHANNELS)})") from None

    def read(self, T_w: float, T_p: float, T_a: float) -> tuple[float, float, float]:
        """One sample: the readings of the true ``T_w, T_p, T_a`` (°C); sets ``fresh``."""
        w, p, a = self._w, self._p, self._a
        r = (w.read(T_w), p.read(T_p), a.read(T_a))
        self.fresh = w.fresh | p.fresh | a.fresh
        return r

    def read_arrays(self, T_w: Array, T_p: Array, T_a: Array) -> tuple[Array, Array, Array, NDArray[np.int8]]:
        """A whole log from a reset: readings of the three channels and ``fresh`` (int8 mask)."""
        rw, cw = self._w.read_array(T_w)
        rp, cp = self._p.read_array(T_p)
        ra, ca = self._a.read_array(T_a)
        fresh = (cw * FRESH_W + cp * FRESH_P + ca * FRESH_A).astype(np.int8)
        return rw, rp, ra, fresh

    # -- one channel -----------------------------------------------------------------------
    def noise(self, channel: str, n: int) -> Array:
        """The next ``n`` noise values of a channel, K."""
        return self.board(channel).noise(n)

    def quantise(self, x: float) -> float:
        """Round to the nearest multiple of ``quantum_T`` (ties upward)."""
        return quantise(x, self.quantum_T)

    def quantise_array(self, x: Array) -> Array:
        """Vectorised :meth:`quantise`."""
        return quantise_array(x, self.quantum_T)

    def measure(self, channel: str, x: Array) -> Array:
        """Readings of a whole array of true values of one channel (from a reset)."""
        x = np.asarray(x, dtype=float)
        return self.board(channel).read_array(x)[0].reshape(x.shape)

    def measure_one(self, channel: str, x: float) -> float:
        """One reading of one channel (its next sample)."""
        return self.board(channel).read(x)
