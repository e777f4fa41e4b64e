"""A skin of many patches on shared water loops: the TOML description, loaded and validated.

The paper's prototype is one 30 x 10 mm patch fed by one tank; a whole-body skin has many
patches, and one tank, Peltier and pump feed several of them in series. A description::

    name = "forearm"
    [spatial]                 # optional: defaults of every patch's spatial model
    n_cells = 15              #   (physics.spatial.SpatialParams; length and width are the patch's)
    [pipe]                    # optional: defaults of every connecting pipe
    tau_loss = 100.0          #   s, a still parcel of water cools towards the air with this time constant

    [links.forearm]           # a body link; its surface unrolled: x along its axis, y around it
    length = 0.26             # m
    circumference = 0.22      # m
    origin = [0.0, 0.0]       # m, where its unrolled surface sits in the layout picture

    [loops.dorsal]            # one water loop: a tank with its Peltier and its pump
    patches = ["d1", "d2", "d3"]          # in the order the water passes them
    pipes = [0.2, 0.02, 0.02, 0.2]        # m: supply (tank to d1), d1 to d2, d2 to d3, return;
                                          #   or tables {length = 0.02, tau_loss = 60.0}
    feedback = "d3"           # the patch whose T_w the loop's controller holds (default: the last)
    tank = [-0.06, 0.05]      # m, the tank in the layout picture (default: left of the first link)
    [loops.dorsal.pump]       # overrides of the config's [pump], [peltier], [control] for this loop,
    v_on = 0.141              #   and of the water-flow keys of [skin] (A, V, d, L, R_w_flowing,
    [loops.dorsal.skin]       #   R_w_stopped, water, T_ref: eq. 1's R_w(v) is the loop's)
    R_w_flowing = 0.19

    [patches.d1]              # patches are numbered 0, 1, ... in the order of this file
    link = "forearm"
    centre = [0.05, 0.06]     # m, on the link's unrolled surface
    length = 0.03             # m, the pipe's length along the patch (the patch's length)
    width = 0.01              # m
    angle = 0.0               # deg, the pipe's direction (inlet to outlet) from the link's axis
    thermocouples = [0.03, 0.0]   # m from the inlet along the pipe; the first is the log's T_w,
                              #   the next T_w2, ...; default [length]: one at the outlet
    [patches.d1.skin]         # overrides of the network keys of [skin] (C_w, C_g, R_g, R_aw, R_ag)
    R_g = 12.0
    [patches.d1.spatial]      # overrides of [spatial] for this patch
    k_sheet = 250.0

**Sizes.** The config's ``[skin]`` network (Table I) is the paper's 30 x 10 mm patch. A patch
of pipe length ``l`` and width ``w`` scales it unless its own ``[skin]`` gives a key: the pipe's
quantities with the length, ``C_w``, ``1/R_g``, ``1/R_aw`` times ``l / 30 mm``; the sheet's with
the area, ``C_g``, ``1/R_ag`` times ``l w / (30 mm x 10 mm)``. The paper's patch is unchanged.

**Positions.** Along a patch's pipe, ``s`` (m) runs from the inlet (0) to the outlet
(``length``); on the link, the pipe runs through ``centre`` in the direction ``angle``, the
inlet at ``centre - length/2 (cos angle, sin angle)``. In the spatial model (cells along the
pipe, ``physics.spatial``) the outlet is the end ``x = 0`` (the ``inlet = "far"`` choice, with
the paper's thermocouple at the outlet).

Every bad value or key raises :class:`~thermoskin.params.ConfigError` with one line naming
the file and the key. :func:`single_skin` is the paper's single patch (``examples/single.toml``),
the default wherever no description is given.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from thermoskin.params import Config, ConfigError, SkinParams, check_kind, read_toml
from thermoskin.physics.spatial import SpatialParams

REF_LENGTH = 0.03
"""Pipe length of the paper's patch, m (the config's ``[skin]`` describes it)."""
REF_WIDTH = 0.01
"""Width of the paper's patch, m."""
NETWORK_KEYS = ("C_w", "C_g", "R_g", "R_aw", "R_ag")
"""``[skin]`` keys a patch may set."""
FLOW_KEYS = ("A", "V", "d", "L", "R_w_flowing", "R_w_stopped", "water", "T_ref")
"""``[skin]`` keys of the water flow (eq. 1's ``R_w(v)``): a loop's, not a patch's."""
LOOP_SECTIONS = ("pump", "peltier", "control", "skin")
PATCH_OWN_SPATIAL = ("length", "width", "inlet")
"""Spatial keys a description may not set in a ``[spatial]`` table (the patch's own, or fixed)."""
DEFAULT_TAU_LOSS = 100.0
"""Default cooling time constant of a still parcel in a connecting pipe, s: a silicone tube of
2/4 mm bore/outer diameter in still air (wall ``2 pi k / ln(r_o/r_i)`` with ``k`` = 0.2 W/(m K),
1.8 W/(m K); outside ``h pi d_o`` with ``h`` = 10 W/(m^2 K), 0.13 W/(m K); in series about
0.12 W/(m K)) holding ``rho c_p pi d^2 / 4`` = 13 J/(m K) of water: about 100 s."""

_TOP_KEYS = ("name", "links", "loops", "patches", "spatial", "pipe")
_LINK_KEYS = ("length", "circumference", "origin")
_LOOP_KEYS = ("patches", "pipes", "feedback", "tank", *LOOP_SECTIONS)
_PATCH_KEYS = ("link", "centre", "length", "width", "angle", "thermocouples", "skin", "spatial")
_PIPE_KEYS = ("length", "tau_loss")


@dataclass(frozen=True)
class Link:
    """A body link: its surface unrolled, ``length`` (m, along its axis) by ``circumference`` (m);
    ``origin`` (m) places it in the layout picture."""

    name: str
    length: float
    circumference: float
    origin: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class Pipe:
    """A connecting pipe: ``length`` (m) of the loop's bore, ``tau_loss`` (s) the cooling time
    constant of a parcel of water in it towards the air (``inf``: no loss).

    Plug flow at velocity ``v``: a parcel takes ``L / v`` to pass and leaves at
    ``T_a + (T_in - T_a) exp(-(L/v) / tau_loss)``.
    """

    length: float = 0.0
    tau_loss: float = DEFAULT_TAU_LOSS

    def delay(self, v: float) -> float:
        """Transit time at ``v`` (m/s), s: ``L / v``."""
        return self.length / v

    def attenuation(self, v: float) -> float:
        """Share of a parcel's excess over the air left at the far end: ``exp(-(L/v)/tau_loss)``."""
        return math.exp(-self.delay(v) / self.tau_loss)


@dataclass(frozen=True)
class Patch:
    """One patch: where it is, its pipe, its thermocouples, its physics (see the module doc)."""

    name: str
    index: int
    loop: int
    link: str
    centre: tuple[float, float]
    length: float
    width: float
    angle: float
    thermocouples: tuple[float, ...]
    skin: SkinParams
    spatial: SpatialParams

    @property
    def direction(self) -> tuple[float, float]:
        """Unit vector of the pipe (inlet to outlet) on the link's surface."""
        a = math.radians(self.angle)
        return math.cos(a), math.sin(a)

    def point_at(self, s: float) -> tuple[float, float]:
        """The point ``s`` m from the inlet along the pipe, on the link's surface, m."""
        dx, dy = self.direction
        h = s - 0.5 * self.length
        return self.centre[0] + h * dx, self.centre[1] + h * dy

    def locate(self, x: float, y: float) -> float | None:
        """``s`` (m from the inlet) of the point ``(x, y)`` on the link if it is on this patch, else None."""
        dx, dy = self.direction
        rx, ry = x - self.centre[0], y - self.centre[1]
        along = rx * dx + ry * dy
        across = -rx * dy + ry * dx
        h = 0.5 * self.length
        if abs(along) <= h + 1e-12 and abs(across) <= 0.5 * self.width + 1e-12:
            return min(max(along + h, 0.0), self.length)
        return None

    def corners(self) -> list[tuple[float, float]]:
        """The patch's rectangle on the link's surface, m (four corners, in order)."""
        dx, dy = self.direction
        h, w = 0.5 * self.length, 0.5 * self.width
        cx, cy = self.centre
        return [(cx + a * h * dx - b * w * dy, cy + a * h * dy + b * w * dx)
                for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]

    def cell_of(self, s: float) -> int:
        """The spatial model's cell at ``s`` m from the inlet (cell 0 at the outlet)."""
        N = self.spatial.n_cells
        x = 1.0 - s / self.length
        return min(max(math.floor(x * N), 0), N - 1)

    @property
    def tc_cells(self) -> tuple[int, ...]:
        """The cell of each thermocouple."""
        return tuple(self.cell_of(s) for s in self.thermocouples)


@dataclass(frozen=True)
class Loop:
    """One water loop: its tank, Peltier and pump (``cfg``'s ``[peltier]``, ``[pump]``,
    ``[control]`` and flow keys of ``[skin]``), the patches in the water's order, the pipes
    (``pipes[0]`` from the tank to the first patch, ``pipes[i]`` from patch ``i-1`` to ``i``,
    ``pipes[-1]`` back to the tank), the ``feedback`` patch, the tank's place in the picture."""

    name: str
    index: int
    patches: tuple[int, ...]
    pipes: tuple[Pipe, ...]
    feedback: int
    tank: tuple[float, float]
    cfg: Config


def tc_fresh_bit(j: int) -> int:
    """``fresh`` bit of a patch's thermocouple ``j`` in a skin's log (0: ``T_w``, bit 1 as on
    the single patch; ``T_w2, T_w3, ...``: 8, 16, ..., above the tank's 2 and the air's 4)."""
    return 1 if j == 0 else 4 << j


@dataclass(frozen=True)
class Skin:
    """A whole skin: links, loops and patches (``patches[i].index == i``); ``cfg`` the base config."""

    name: str
    source: str
    cfg: Config
    links: Mapping[str, Link]
    loops: tuple[Loop, ...]
    patches: tuple[Patch, ...]

    def patch(self, name: str | int) -> Patch:
        """A patch by name or index; ``KeyError`` naming the known ones."""
        if isinstance(name, int) and not isinstance(name, bool):
            if 0 <= name < len(self.patches):
                return self.patches[name]
            raise KeyError(f"{self.source}: no patch {name} (0 to {len(self.patches) - 1})")
        for p in self.patches:
            if p.name == name:
                return p
        raise KeyError(f"{self.source}: no patch {name!r} "
                       f"(known: {', '.join(p.name for p in self.patches)})")

    @property
    def n_thermocouples(self) -> int:
        """The most thermocouples any patch has (the log's ``T_w``, ``T_w2``, ...)."""
        return max(len(p.thermocouples) for p in self.patches)

    def log_columns(self) -> list[str]:
        """Columns of the long-format log: ``t,patch,T_w,T_p,v,T_a``, ``T_w2..``, truth, ``fresh``."""
        extra = [f"T_w{j}" for j in range(2, self.n_thermocouples + 1)]
        return ["t", "patch", "T_w", "T_p", "v", "T_a", *extra, "q_i", "contact_true", "position_true",
                "fresh"]


# ------------------------------------------------------------------------------ parsing


class _Where:
    """Error messages naming the file and the key."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, key: str, msg: str) -> ConfigError:
        return ConfigError(f"{self.source}: {key} {msg}")

    def bad(self, key: str, value: Any, must: str) -> ConfigError:
        return ConfigError(f"{self.source}: {key} = {_short(value)} {must}")

    def table(self, data: Any, key: str, known: tuple[str, ...] | None = None) -> dict[str, Any]:
        if not isinstance(data, dict):
            raise self.bad(key, data, "must be a table")
        if known is not None:
            for k in data:
                if k not in known:
                    raise self.error(f"{key}.{k}" if key else k,
                                     f"is not a known key (known: {', '.join(known)})")
        return data

    def number(self, value: Any, key: str, *, lo: float = -math.inf, hi: float = math.inf,
               lo_open: bool = False, unit: str = "", finite: bool = True) -> float:
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        x = float(value) if ok else math.nan
        if ok and not math.isnan(x) and (math.isfinite(x) or not finite) \
                and (x > lo if lo_open else x >= lo) and x <= hi:
            return x
        rng = f"{'>' if lo_open else '>='} {lo:g}" if lo > -math.inf else "finite"
        if hi < math.inf:
            rng += f" and <= {hi:g}"
        raise self.bad(key, value, f"must be a number {rng}" + (f" ({unit})" if unit else ""))

    def pair(self, value: Any, key: str) -> tuple[float, float]:
        if not (isinstance(value, list) and len(value) == 2):
            raise self.bad(key, value, "must be a pair of numbers [x, y] (m)")
        return (self.number(value[0], f"{key}[0]", unit="m"), self.number(value[1], f"{key}[1]", unit="m"))

    def name(self, value: Any, key: str) -> str:
        if not (isinstance(value, str) and value.strip()):
            raise self.bad(key, value, "must be a non-empty name")
        return value

    def section(self, base: Any, table: Any, key: str, allowed: tuple[str, ...] | None = None) -> Any:
        """``base`` (a parameter set) with the keys of ``table`` replaced, validated."""
        known = tuple(f.name for f in dataclasses.fields(base))
        t = self.table(table, key, allowed if allowed is not None else known)
        try:
            return dataclasses.replace(base, **t)
        except ConfigError as e:  # "skin.R_g = -1 is out of range ...": prefix the table's place
            sec = getattr(base, "section", "")
            head = key[:len(key) - len(sec)] if sec and key.endswith(sec) else f"{key}: "
            raise ConfigError(f"{self.source}: {head}{e}") from None


def _raise(e: Exception) -> Any:
    raise e


def _short(value: Any, limit: int = 40) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 4] + "...]"


def _scaled_skin(base: SkinParams, length: float, width: float, own: Mapping[str, Any]) -> SkinParams:
    """The config's network scaled to a patch of ``length x width`` (module doc), ``own`` keys kept."""
    lr = length / REF_LENGTH
    ar = length * width / (REF_LENGTH * REF_WIDTH)
    scaled = {"C_w": base.C_w * lr, "R_g": base.R_g / lr, "R_aw": base.R_aw / lr,
              "C_g": base.C_g * ar, "R_ag": base.R_ag / ar}
    if lr == 1.0 and ar == 1.0:
        scaled = {}
    return dataclasses.replace(base, **{k: v for k, v in scaled.items() if k not in own})


#: Most patches a skin may have (measured at this size: docs/skin.md, Limits).
MAX_PATCHES = 10_000


def parse_skin(data: Mapping[str, Any], source: str, cfg: Config | None = None) -> Skin:
    """A skin from the parsed TOML ``data`` (``source`` names it in messages); ``cfg`` the base
    config (default: the paper's). Raises :class:`ConfigError` (one line) on any bad key or value."""
    cfg = cfg if cfg is not None else Config()
    W = _Where(source)
    top = W.table(dict(data), "", _TOP_KEYS)
    name = W.name(top.get("name", Path(source).stem), "name")
    sp_default = cfg_spatial = SpatialParams()
    if "spatial" in top:
        tab = W.table(top["spatial"], "spatial")
        for k in tab:
            if k in PATCH_OWN_SPATIAL:
                raise W.error(f"spatial.{k}", "cannot be set here: "
                              + ("the pipe runs from inlet to outlet" if k == "inlet"
                                 else f"it is each patch's own key patches.NAME.{k}"))
        sp_default = W.section(cfg_spatial, tab, "spatial")
    pipe_default = Pipe()
    if "pipe" in top:
        tab = W.table(top["pipe"], "pipe", _PIPE_KEYS)
        pipe_default = _pipe(W, tab, "pipe", Pipe())

    # links
    links_t = W.table(top.get("links"), "links") if "links" in top else _raise(
        W.error("[links]", "is missing: a skin needs at least one body link"))
    if not links_t:
        raise W.error("[links]", "is empty: a skin needs at least one body link")
    links: dict[str, Link] = {}
    for lname, lt in links_t.items():
        key = f"links.{lname}"
        lt = W.table(lt, key, _LINK_KEYS)
        for req in ("length", "circumference"):
            if req not in lt:
                raise W.error(f"{key}.{req}", "is missing")
        links[lname] = Link(
            lname, W.number(lt["length"], f"{key}.length", lo=0.0, lo_open=True, unit="m"),
            W.number(lt["circumference"], f"{key}.circumference", lo=0.0, lo_open=True, unit="m"),
            W.pair(lt["origin"], f"{key}.origin") if "origin" in lt else (0.0, 0.0))

    # patches (their loop is filled in below)
    patches_t = W.table(top.get("patches"), "patches") if "patches" in top else _raise(
        W.error("[patches]", "is missing: a skin needs at least one patch"))
    if not patches_t:
        raise W.error("[patches]", "is empty: a skin needs at least one patch")
    if len(patches_t) > MAX_PATCHES:
        raise W.error("[patches]", f"holds {len(patches_t)} patches, more than a skin may have "
                      f"({MAX_PATCHES}: at that size a run takes about 2.6 GB and runs 500 times slower "
                      "than real time on two cores, docs/skin.md, Limits); split the skin")
    raw: list[dict[str, Any]] = []
    for i, (pname, pt) in enumerate(patches_t.items()):
        key = f"patches.{pname}"
        pt = W.table(pt, key, _PATCH_KEYS)
        for req in ("link", "centre"):
            if req not in pt:
                raise W.error(f"{key}.{req}", "is missing")
        link = W.name(pt["link"], f"{key}.link")
        if link not in links:
            raise W.bad(f"{key}.link", link, f"is not a link of this skin (links: {', '.join(links)})")
        centre = W.pair(pt["centre"], f"{key}.centre")
        Lk = links[link]
        if not (0.0 <= centre[0] <= Lk.length and 0.0 <= centre[1] <= Lk.circumference):
            raise W.bad(f"{key}.centre", list(centre), f"lies outside link {link!r} "
                        f"([0, {Lk.length:g}] x [0, {Lk.circumference:g}] m)")
        length = W.number(pt.get("length", REF_LENGTH), f"{key}.length", lo=0.0, hi=1.0, lo_open=True,
                          unit="m")
        width = W.number(pt.get("width", REF_WIDTH), f"{key}.width", lo=0.0, hi=1.0, lo_open=True, unit="m")
        angle = W.number(pt.get("angle", 0.0), f"{key}.angle", lo=-360.0, hi=360.0, unit="deg")
        tcs_raw = pt.get("thermocouples", [length])
        if not (isinstance(tcs_raw, list) and tcs_raw):
            raise W.bad(f"{key}.thermocouples", tcs_raw, "must be a non-empty list of positions "
                        "(m from the inlet)")
        tcs = tuple(W.number(s, f"{key}.thermocouples[{j}]", lo=0.0, hi=length,
                             unit=f"m from the inlet, the pipe is {length:g} m")
                    for j, s in enumerate(tcs_raw))
        if len(set(tcs)) != len(tcs):
            raise W.bad(f"{key}.thermocouples", tcs_raw, "has the same position twice")
        own_skin = W.table(pt.get("skin", {}), f"{key}.skin")
        for k in own_skin:
            if k in FLOW_KEYS:
                raise W.error(f"{key}.skin.{k}", "belongs to the water loop (eq. 1's R_w(v)): "
                              "set it in [loops.NAME.skin]")
        skin_p = W.section(_scaled_skin(cfg.skin, length, width, own_skin), own_skin, f"{key}.skin",
                           NETWORK_KEYS)
        own_sp = W.table(pt.get("spatial", {}), f"{key}.spatial")
        for k in own_sp:
            if k in PATCH_OWN_SPATIAL:
                raise W.error(f"{key}.spatial.{k}", "cannot be set here: "
                              + ("the pipe runs from inlet to outlet" if k == "inlet"
                                 else f"it is the patch's own key {key}.{k}"))
        try:
            sp = dataclasses.replace(sp_default, length=length, width=width)
        except ConfigError as e:
            raise ConfigError(f"{source}: {key}: {e}") from None
        sp = W.section(sp, own_sp, f"{key}.spatial")
        raw.append(dict(name=pname, index=i, link=link, centre=centre, length=length, width=width,
                        angle=angle, thermocouples=tcs, skin=skin_p, spatial=sp))
    index = {r["name"]: r["index"] for r in raw}

    # loops
    loops_t = W.table(top.get("loops"), "loops") if "loops" in top else _raise(
        W.error("[loops]", "is missing: a skin needs at least one water loop"))
    if not loops_t:
        raise W.error("[loops]", "is empty: a skin needs at least one water loop")
    owner: dict[int, str] = {}
    loops: list[Loop] = []
    for j, (lname, lt) in enumerate(loops_t.items()):
        key = f"loops.{lname}"
        lt = W.table(lt, key, _LOOP_KEYS)
        names = lt.get("patches")
        if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
            raise W.bad(f"{key}.patches", names, "must be a non-empty list of patch names")
        members = []
        for n in names:
            if n not in index:
                raise W.bad(f"{key}.patches", n, f"is not a patch of this skin (patches: {', '.join(index)})")
            if index[n] in owner:
                raise W.bad(f"{key}.patches", n, f"is already on loop {owner[index[n]]!r}: "
                            "a patch is on one loop, once")
            owner[index[n]] = lname
            members.append(index[n])
        n_p = len(members)
        pipes_raw = lt.get("pipes", [0.0] * (n_p + 1))
        if not (isinstance(pipes_raw, list) and len(pipes_raw) == n_p + 1):
            count = len(pipes_raw) if isinstance(pipes_raw, list) else "no list of"
            raise W.bad(f"{key}.pipes", pipes_raw, f"has {count} entries: needs {n_p + 1} "
                        f"(supply, {n_p - 1} between patches, return), each a length (m) or a table "
                        "{length, tau_loss}")
        pipes = tuple(_pipe(W, p, f"{key}.pipes[{i}]", pipe_default) for i, p in enumerate(pipes_raw))
        fb_name = lt.get("feedback", names[-1])
        if fb_name not in names:
            raise W.bad(f"{key}.feedback", fb_name, f"must be one of the loop's patches ({', '.join(names)})")
        lcfg = cfg
        for sec in LOOP_SECTIONS:
            if sec in lt:
                allowed = FLOW_KEYS if sec == "skin" else None
                if sec == "skin":
                    for k in W.table(lt[sec], f"{key}.skin"):
                        if k in NETWORK_KEYS:
                            raise W.error(f"{key}.skin.{k}", "belongs to the patches: set it in "
                                          "[patches.NAME.skin]")
                new = W.section(getattr(lcfg, sec), lt[sec], f"{key}.{sec}", allowed)
                try:
                    lcfg = dataclasses.replace(lcfg, **{sec: new})
                except ConfigError as e:
                    raise ConfigError(f"{source}: {key}: {e}") from None
        first = raw[members[0]]
        org = links[first["link"]].origin
        tank = W.pair(lt["tank"], f"{key}.tank") if "tank" in lt else (org[0] - 0.04, org[1] + 0.03 * (j + 1))
        loops.append(Loop(lname, j, tuple(members), pipes, index[fb_name], tank, lcfg))
    for r in raw:
        if r["index"] not in owner:
            raise W.error(f"patches.{r['name']}", "is on no loop: list it in one [loops.NAME] patches")
    loop_of = {p: lp.index for lp in loops for p in lp.patches}
    patches = tuple(Patch(loop=loop_of[r["index"]], **r) for r in raw)
    return Skin(name, source, cfg, links, tuple(loops), patches)


def _pipe(W: _Where, value: Any, key: str, default: Pipe) -> Pipe:
    if isinstance(value, dict):
        t = W.table(value, key, _PIPE_KEYS)
        length = W.number(t.get("length", default.length), f"{key}.length", lo=0.0, hi=100.0, unit="m")
        tau = W.number(t.get("tau_loss", default.tau_loss), f"{key}.tau_loss", lo=0.0, lo_open=True,
                       unit="s; inf for no loss", finite=False)
        return Pipe(length, tau)
    return Pipe(W.number(value, key, lo=0.0, hi=100.0, unit="m"), default.tau_loss)


def load_skin(path: str | Path | None = None, cfg: Config | None = None) -> Skin:
    """The skin described in the TOML file ``path`` (None: :func:`single_skin`) on config ``cfg``."""
    if path is None:
        return single_skin(cfg)
    data = read_toml(path, "layout file")
    check_kind(path, data, "layout")
    return parse_skin(data, str(Path(path)), cfg)


SINGLE = """\
# The paper's prototype: one 30 x 10 mm patch, its pipe fed straight from the tank (no
# connecting pipe), the thermocouple at the outlet. The default wherever no --skin is given.
name = "single"

[links.patch]
length = 0.05
circumference = 0.03

[loops.tank]
patches = ["patch"]
pipes = [0.0, 0.0]
tank = [-0.02, 0.015]

[patches.patch]
link = "patch"
centre = [0.025, 0.015]
length = 0.03
width = 0.01
thermocouples = [0.03]
"""
"""The text of ``examples/single.toml``."""


def single_skin(cfg: Config | None = None) -> Skin:
    """The paper's single patch (:data:`SINGLE`, the same as ``examples/single.toml``)."""
    return parse_skin(tomllib.loads(SINGLE), "single.toml", cfg)
