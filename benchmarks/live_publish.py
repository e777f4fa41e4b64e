"""Cost of the live server in the parent process: one block of 1000 loop rows (1 s of loop
time at 1 kHz) decimated to 100 Hz and published, with no viewer and with one subscribed
viewer (a websocket client in a thread of this process, reading everything).

Prints one JSON object: medians and p99 over the blocks, µs per block and per message.

    python benchmarks/live_publish.py [--blocks 200] [--rate 100]
"""

from __future__ import annotations

import argparse
import json
import socket
import threading
import time

import numpy as np

from thermoskin.live import LiveServer
from thermoskin.params import Config


def block(k0: int, n: int = 1000) -> dict[str, np.ndarray]:
    k = np.arange(k0, k0 + n, dtype=float)
    rng = np.random.default_rng(k0)
    cols = {name: 20 + rng.standard_normal(n) for name in
            ("T_w", "T_p", "T_a", "v", "T_w_cmd", "T_p_cmd", "drive", "q_i_hat", "dq_i_hat", "q_i", "T_g",
             "T_w_true", "T_p_true")}
    cols.update(t=k * 1e-3, contact=((k % 5000) > 4000).astype(float), gap=np.zeros(n),
                fresh=np.full(n, 7.0), contact_true=np.zeros(n), n_fingers=np.zeros(n), fault=np.zeros(n))
    return cols


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def measure(live: LiveServer, blocks: list[dict[str, np.ndarray]]) -> dict[str, float]:
    times = []
    n0 = live.published
    for b in blocks:
        t0 = time.perf_counter()
        live.write_rows(b)
        times.append(time.perf_counter() - t0)
    us = np.array(times) * 1e6
    msgs = (live.published - n0) / len(blocks)
    return {"block_p50_us": float(np.median(us)), "block_p99_us": float(np.percentile(us, 99)),
            "messages_per_block": msgs, "per_message_us": float(np.median(us) / msgs) if msgs else 0.0}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--blocks", type=int, default=200)
    ap.add_argument("--rate", type=float, default=100.0)
    a = ap.parse_args()
    import websocket

    port = free_port()
    out: dict[str, object] = {"rate_hz": a.rate, "blocks": a.blocks, "rows_per_block": 1000,
                              "note": "shared 2-core machine: medians and p99"}
    with LiveServer("127.0.0.1", port, config=Config(), rate=a.rate, page=False) as live:
        out["no_viewer"] = measure(live, [block(i * 1000) for i in range(a.blocks)])
        ws = websocket.create_connection(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"])
        ws.recv()
        adv = json.loads(ws.recv())
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": c["id"]} for i, c in enumerate(adv["channels"])]}))
        got = [0]

        def read() -> None:
            try:
                while True:
                    ws.recv()
                    got[0] += 1
            except Exception:
                pass

        threading.Thread(target=read, daemon=True).start()
        time.sleep(0.3)
        out["one_viewer"] = measure(live, [block((a.blocks + i) * 1000) for i in range(a.blocks)])
        time.sleep(0.5)
        out["one_viewer"]["received"] = got[0]  # type: ignore[index]
        ws.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
