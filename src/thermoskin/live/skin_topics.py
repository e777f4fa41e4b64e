"""A skin's topics, live and recorded: per-patch signals, contact events with their patch, a scene.

``thermoskin run --skin LAYOUT.toml`` with ``--live`` and/or ``--record`` sends the same topics to
the Foxglove WebSocket and to the MCAP recording (one :class:`SkinMessages` each; the live one
decimated to ``--live-rate``, the recording's every sample)::

    /patch/NAME/sample    {t, T_w, [T_w2, ...], T_in, T_p, T_a, v, fresh}   thermoskin.PatchSample
    /patch/NAME/estimate  {t, q_i_hat, dq_i_hat, contact, gap}                thermoskin.Estimate
    /patch/NAME/truth     {t, q_i, contact_true, position_true}               simulator only
    /events               {t, kind, detail}   contact-on / contact-off with detail.patch, .sign
    /params               {t, config, skin}   the config and the skin's layout (mm, below)
    /skin/scene           foxglove.SceneUpdate (protobuf): every patch a box, lit in contact

``T_in`` is the inlet water the patch's estimator used (``skin_inlet``), ``T_p`` its loop's tank.
Contact events are never decimated; a ``contact-off`` carries the finished contact's figures
(``onset, detected, release, duration, sign, peak_dq, mean_dq, energy``).

**The scene.** Frame ``skin``: each link's unrolled surface is a flat grey slab at its layout
origin (x along the link, y around it, z up, metres), each patch a box ``length x width x 3 mm``
on it, turned by its ``angle``, labelled with its name; grey while idle, orange in a contact
bringing heat (sign +1), blue in one taking it (-1). The whole scene is sent at the start and
again at every contact change (entities replace those of the same ``id``), and is latched live
(a viewer that subscribes later gets the last one).

**The layout** on ``/params`` (``skin``) is what the live page draws: the links' rectangles and
every patch's four corners in the layout picture's millimetres (``skin_plot``'s coordinates).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from thermoskin.estimation.events import DETECTION_COLUMNS, ContactEvent
from thermoskin.live.messages import Decimator
from thermoskin.runtime.record import TOPIC_SCHEMAS
from thermoskin.skin.layout import Skin

SCENE_TOPIC = "/skin/scene"
FRAME = "skin"
#: Colours of a patch (r, g, b, a): idle, in a contact of sign +1, of sign -1; a link's slab.
IDLE = (0.55, 0.58, 0.62, 1.0)
WARM = (1.0, 0.5, 0.05, 1.0)
COLD = (0.15, 0.45, 1.0, 1.0)
SLAB = (0.85, 0.85, 0.85, 0.35)
THICK = 0.003
"""A patch box's height, m."""

_NUM = {"type": "number"}
_NUM_NULL = {"type": ["number", "null"]}
_INT = {"type": "integer"}

PATCH_TRUTH_SCHEMA: dict[str, Any] = {
    "title": "thermoskin.PatchTruth",
    "description": "the simulator's truth on one patch: q_i W, contact_true 0/1, position_true m from "
                   "its inlet",
    "type": "object",
    "properties": {"t": _NUM, "q_i": _NUM_NULL, "contact_true": _INT, "position_true": _NUM_NULL},
    "required": ["t"],
}


def patch_topic(name: str, kind: str) -> str:
    """``/patch/NAME/KIND`` (``sample``, ``estimate``, ``truth``)."""
    return f"/patch/{name}/{kind}"


def sample_schema(skin: Skin) -> dict[str, Any]:
    """``thermoskin.PatchSample`` for the skin's thermocouples."""
    props: dict[str, Any] = {"t": _NUM, "T_w": _NUM_NULL}
    for j in range(2, skin.n_thermocouples + 1):
        props[f"T_w{j}"] = _NUM_NULL
    props.update({"T_in": _NUM_NULL, "T_p": _NUM_NULL, "T_a": _NUM_NULL, "v": _NUM_NULL, "fresh": _INT})
    return {"title": "thermoskin.PatchSample",
            "description": "one patch's sample: its thermocouples, the inlet water its estimator used, its "
                           "loop's tank and air degC, the loop's pump m/s; null = no reading",
            "type": "object", "properties": props, "required": ["t"]}


def scene_schema() -> Any:
    """``foxglove.SceneUpdate``'s schema (protobuf, from ``foxglove-sdk``)."""
    from foxglove.messages import SceneUpdate

    return SceneUpdate.get_schema()


def skin_topics(skin: Skin, truth: bool = True) -> dict[str, Any]:
    """Every topic of a skin's run and its schema: a JSON schema (a dict) or, for the scene, a
    ``foxglove.Schema`` (protobuf)."""
    out: dict[str, Any] = {}
    ss = sample_schema(skin)
    for p in skin.patches:
        out[patch_topic(p.name, "sample")] = ss
        out[patch_topic(p.name, "estimate")] = TOPIC_SCHEMAS["/skin/estimate"]
        if truth:
            out[patch_topic(p.name, "truth")] = PATCH_TRUTH_SCHEMA
    out["/events"] = TOPIC_SCHEMAS["/events"]
    out["/params"] = TOPIC_SCHEMAS["/params"]
    out[SCENE_TOPIC] = scene_schema()
    return out


# ------------------------------------------------------------------------------ layout and scene

def layout(skin: Skin) -> dict[str, Any]:
    """The skin's layout for ``/params`` (module doc), mm."""
    mm = 1000.0

    def at(link: str, x: float, y: float) -> list[float]:
        ox, oy = skin.links[link].origin
        return [round((ox + x) * mm, 3), round((oy + y) * mm, 3)]

    return {
        "name": skin.name,
        "links": [{"name": k, "x": lk.origin[0] * mm, "y": lk.origin[1] * mm, "w": lk.length * mm,
                   "h": lk.circumference * mm} for k, lk in skin.links.items()],
        "patches": [{"name": p.name, "index": p.index, "link": p.link, "loop": skin.loops[p.loop].name,
                     "corners": [at(p.link, x, y) for x, y in p.corners()], "centre": at(p.link, *p.centre)}
                    for p in skin.patches],
        "loops": [{"name": lp.name, "patches": [skin.patches[i].name for i in lp.patches],
                   "tank": [lp.tank[0] * mm, lp.tank[1] * mm]} for lp in skin.loops],
    }


def scene(skin: Skin, t: float, signs: Any) -> bytes:
    """The scene (module doc) at ``t`` s with patch ``i`` in a contact of sign ``signs[i]`` (0: none),
    as an encoded ``foxglove.SceneUpdate``."""
    from foxglove.messages import (
        Color,
        CubePrimitive,
        Pose,
        Quaternion,
        SceneEntity,
        SceneUpdate,
        TextPrimitive,
        Timestamp,
        Vector3,
    )

    ns = max(0, round(t * 1e9))
    stamp = Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)
    up = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)

    def colour(c: tuple[float, float, float, float]) -> Any:
        return Color(r=c[0], g=c[1], b=c[2], a=c[3])

    ents = []
    for name, lk in skin.links.items():
        ox, oy = lk.origin
        ents.append(SceneEntity(timestamp=stamp, frame_id=FRAME, id=f"link/{name}", cubes=[CubePrimitive(
            pose=Pose(position=Vector3(x=ox + lk.length / 2, y=oy + lk.circumference / 2, z=-0.001),
                      orientation=up),
            size=Vector3(x=lk.length, y=lk.circumference, z=0.001), color=colour(SLAB))]))
    for p in skin.patches:
        ox, oy = skin.links[p.link].origin
        a = math.radians(p.angle)
        s = int(signs[p.index])
        c = WARM if s > 0 else COLD if s < 0 else IDLE
        x, y = ox + p.centre[0], oy + p.centre[1]
        pos = Vector3(x=x, y=y, z=THICK / 2)
        turn = Quaternion(x=0.0, y=0.0, z=math.sin(a / 2), w=math.cos(a / 2))
        ents.append(SceneEntity(
            timestamp=stamp, frame_id=FRAME, id=f"patch/{p.name}",
            cubes=[CubePrimitive(pose=Pose(position=pos, orientation=turn),
                                 size=Vector3(x=p.length, y=p.width, z=THICK), color=colour(c))],
            texts=[TextPrimitive(pose=Pose(position=Vector3(x=x, y=y + p.width, z=THICK),
                                           orientation=up),
                                 billboard=True, font_size=12.0, scale_invariant=True,
                                 color=colour((0.1, 0.1, 0.1, 1.0)), text=p.name)]))
    return SceneUpdate(entities=ents).encode()


# ------------------------------------------------------------------------------ messages

class SkinMessages:
    """A skin run's blocks as ``(topic, t, message)``: a message is a JSON-clean dict or, for the
    scene, bytes. Signals decimated to ``rate`` Hz of the loop clock (None: every sample); contact
    changes and the scene at once."""

    def __init__(self, skin: Skin, rate: float | None = None) -> None:
        self.skin = skin
        self.P = len(skin.patches)
        self.names = [p.name for p in skin.patches]
        self._dec = Decimator(rate) if rate is not None else None
        self.signs = np.zeros(self.P, dtype=np.int64)
        self._tc = [f"T_w{j}" for j in range(2, skin.n_thermocouples + 1)]
        self._topics = [(patch_topic(n, "sample"), patch_topic(n, "estimate"), patch_topic(n, "truth"))
                        for n in self.names]

    def start(self, t: float = 0.0) -> Iterator[tuple[str, float, Any]]:
        """The scene with no contact."""
        yield SCENE_TOPIC, t, scene(self.skin, t, self.signs)

    def messages(self, t: Any, cols: Mapping[str, Any], blk: Any) -> Iterator[tuple[str, float, Any]]:
        """One block: ``t`` (m), the log's ``(m, P)`` columns, the estimator's
        :class:`~thermoskin.skin.observe.SkinBlock`."""
        ch = blk.changes
        for j, c in enumerate(ch):
            name = self.names[c.patch]
            detail: dict[str, Any] = {"patch": name, "sign": c.sign}
            if not c.on and c.event is not None:
                detail.update(figures(c.event))
            elif not c.on:  # withdrawn by the detector (detector.t_confirm): no event
                detail["withdrawn"] = True
            self.signs[c.patch] = c.sign if c.on else 0
            yield "/events", c.t, {"kind": "contact-on" if c.on else "contact-off", "detail": detail}
            if j + 1 == len(ch) or ch[j + 1].t != c.t:  # one scene per row with changes
                yield SCENE_TOPIC, c.t, scene(self.skin, c.t, self.signs)
        t = np.asarray(t, dtype=float)
        keep = np.arange(len(t)) if self._dec is None else self._dec.select(t)
        if not len(keep):
            return
        ts = t[keep].tolist()
        sample = [("T_w", cols["T_w"])] + [(k, cols[k]) for k in self._tc if k in cols]
        sample += [("T_in", blk.T_in), ("T_p", cols["T_p"]), ("T_a", cols["T_a"]), ("v", cols["v"])]
        S = [(k, np.asarray(a, dtype=float)[keep].tolist()) for k, a in sample]
        fresh = blk.fresh_in[keep].tolist()
        est = blk.columns
        q, dq = est["q_i_hat"][keep].tolist(), est["dq_i_hat"][keep].tolist()
        con, gap = est["contact"][keep].tolist(), est["gap"][keep].tolist()
        truth = None
        if "q_i" in cols and np.isfinite(np.asarray(cols["q_i"], dtype=float)).any():
            truth = (np.asarray(cols["q_i"], dtype=float)[keep].tolist(),
                     np.asarray(cols["contact_true"])[keep].astype(np.int64).tolist(),
                     np.asarray(cols["position_true"], dtype=float)[keep].tolist()
                     if "position_true" in cols else None)
        for r, tr in enumerate(ts):
            for i in range(self.P):
                ts_, te, tt = self._topics[i]
                msg = {k: _f(v[r][i]) for k, v in S}
                msg["fresh"] = int(fresh[r][i])
                yield ts_, tr, msg
                yield te, tr, {"q_i_hat": _f(q[r][i]), "dq_i_hat": _f(dq[r][i]), "contact": int(con[r][i]),
                               "gap": int(gap[r][i])}
                if truth is not None:
                    yield tt, tr, {"q_i": _f(truth[0][r][i]), "contact_true": int(truth[1][r][i]),
                                   "position_true": _f(truth[2][r][i]) if truth[2] is not None else None}


def figures(e: ContactEvent) -> dict[str, Any]:
    """A finished contact's figures (:data:`~thermoskin.estimation.events.DETECTION_COLUMNS`), JSON-clean."""
    row = e.row()
    return {k: _num(row[k]) for k in DETECTION_COLUMNS}


def _f(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _num(v: Any) -> Any:
    if isinstance(v, float | np.floating):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v
