"""Latency from the true release of a tap to its MQTT command arriving at a subscriber.

    python scripts/latency_bench.py                 # 40 taps, mosquitto if installed
    python scripts/latency_bench.py --taps 100 --qos 1 --broker mqtt://127.0.0.1:1883

The simulator records a scene of taps on the paper's desk (with ground truth). That recording
is replayed in real time (``--speed 1``) through the whole run loop (estimator, gesture
engine, dispatcher, MQTT action) to a broker, and a subscriber in *another process* stamps
each command's arrival. Sample time maps to the wall clock through the replay's pacer (both
sides use CLOCK_MONOTONIC via ``time.perf_counter``), so

    latency = arrival - wall time of the tap's true release (the last sample with finger force)

The target is p95 <= 40 ms. Prints the figures; exits 1 when the target is missed.
"""

from __future__ import annotations

import argparse
import json
import logging
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording_io import write_recording
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

TARGET_P95_MS = 40.0
TOPIC = "bench/lamp/set"
TAP_POINT_CM = (-20.0, -10.0)

SCENE = """\
name: latency
desk: kitamura2017
units: cm
quiet_s: 2.0
tail_s: 1.0
timeline:
  - tap: {{point: [{x}, {y}], peak_n: 6, wait_s: 0.6, repeat: {taps}}}
"""

LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  lamp: {{rect: [{x0}, {y0}, {x1}, {y1}]}}
bindings:
  - gesture: tap
    region: lamp
    do: {{mqtt: {{topic: {topic}, qos: {qos}, payload: {{state: TOGGLE, t: "{{{{ t }}}}"}}}}}}
"""

SUBSCRIBER = """\
import sys, time
import paho.mqtt.client as mqtt
host, port, topic, qos = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
def on_message(client, userdata, message):
    print(f"{time.perf_counter():.6f} {message.payload.decode()}", flush=True)
client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2)
client.on_connect = lambda c, u, f, r, p: c.subscribe(topic, qos=qos)
client.on_subscribe = lambda *a: print("READY", flush=True)
client.on_message = on_message
client.connect(host, port)
client.loop_forever()
"""


def true_releases(fn: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Sample times of the last sample of each touch (finger force > 0)."""
    touching = fn > 0
    ends = np.flatnonzero(touching[:-1] & ~touching[1:])
    return t[ends]


def start_broker(folder: Path) -> tuple[str, object]:
    """mosquitto on a free port if installed, else the embedded amqtt broker."""
    from hapticdesk.plugins.mqtt.broker import EmbeddedBroker, free_loopback_port

    program = shutil.which("mosquitto") or shutil.which("mosquitto", path="/usr/sbin")
    if program is None:
        broker = EmbeddedBroker().start()
        return broker.url, broker.stop
    port = free_loopback_port()
    config = folder / "mosquitto.conf"
    config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\n")
    process = subprocess.Popen([program, "-c", str(config)], stderr=subprocess.DEVNULL)
    time.sleep(0.3)

    def stop() -> None:
        process.terminate()
        process.wait(10)

    return f"mqtt://127.0.0.1:{port}", stop


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taps", type=int, default=40)
    parser.add_argument("--qos", type=int, default=2, choices=(0, 1, 2))
    parser.add_argument("--broker", help="mqtt://HOST:PORT (default: start one on loopback)")
    parser.add_argument("--speed", type=float, default=1.0, help="replay speed (1 = real time)")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    from hapticdesk.sim import load_scene, simulate

    folder = Path(tempfile.mkdtemp(prefix="hapticdesk-latency-"))
    profile = load_profile("kitamura2017")
    x, y = TAP_POINT_CM
    scene_file = folder / "scene.yaml"
    scene_file.write_text(SCENE.format(x=x, y=y, taps=args.taps))
    recording = simulate(profile, load_scene(scene_file), seed=0)
    rec_file = folder / "taps.npz"
    write_recording(rec_file, recording)
    releases = true_releases(recording.extra["true_fn"], recording.t)
    layout = folder / "layout.yaml"
    layout.write_text(
        LAYOUT.format(x0=x - 6, y0=y - 6, x1=x + 6, y1=y + 6, topic=TOPIC, qos=args.qos)
    )

    url, stop_broker = (args.broker, lambda: None) if args.broker else start_broker(folder)
    host, port = url.split("//")[1].rsplit(":", 1)
    sub = subprocess.Popen(
        [sys.executable, "-c", SUBSCRIBER, host, port, TOPIC, str(args.qos)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert sub.stdout is not None
        if sub.stdout.readline().strip() != "READY":
            print("the subscriber did not start", file=sys.stderr)
            return 2
        registry = load_registry(entry_points=False)
        scene = build_scene(
            layout,
            f"replay:{rec_file}",
            registry,
            speed=args.speed,
            overrides={"mqtt": {"broker": url}},
        )
        source = scene.source
        assert source.pacer is not None  # a replay plays on its sample clock
        report = Runtime(scene).run(handle_signals=False)
        sent = sum(lane.stats.ok for route in scene.dispatcher.routes for lane in route.lanes)
        arrivals: list[tuple[float, float]] = []
        deadline = time.monotonic() + 10
        while len(arrivals) < sent and time.monotonic() < deadline:
            line = sub.stdout.readline()
            if not line:
                break
            stamp, payload = line.split(" ", 1)
            arrivals.append((float(stamp), float(json.loads(payload)["t"])))
    finally:
        sub.terminate()
        sub.wait(10)
        stop_broker()  # type: ignore[operator]

    latencies, detection = [], []
    for arrived, t_event in arrivals:
        i = int(np.argmin(np.abs(releases - t_event)))
        if abs(releases[i] - t_event) > 0.3:
            continue  # not one of the taps (should not happen)
        latencies.append((arrived - source.pacer.wall_time(float(releases[i]))) * 1000)
        detection.append((t_event - releases[i]) * 1000)
    lat = np.array(latencies)
    print(f"broker {url}, QoS {args.qos}, replay speed {args.speed:g}")
    print(f"taps in the scene: {len(releases)}; recognised: {report.gestures.get('tap', 0)}; "
          f"commands received: {len(arrivals)} of {sent}")  # fmt: skip
    if len(lat) == 0:
        print("no command arrived")
        return 1
    det = np.array(detection)
    print(
        f"release -> tap decided (sample time): median {np.median(det):+.1f} ms, "
        f"min {det.min():+.1f}, max {det.max():+.1f}"
    )
    p50, p95 = np.percentile(lat, [50, 95])
    print(
        f"release -> command at the subscriber: p50 {p50:.1f} ms, p95 {p95:.1f} ms, "
        f"max {lat.max():.1f} ms, min {lat.min():.1f} ms (n = {len(lat)})"
    )
    ok = p95 <= TARGET_P95_MS and len(arrivals) == len(releases)
    print(f"target p95 <= {TARGET_P95_MS:g} ms and every tap delivered: {'PASS' if ok else 'FAIL'}")
    shutil.rmtree(folder, ignore_errors=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
