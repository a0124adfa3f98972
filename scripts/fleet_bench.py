"""A building full of desks: N simulated desks publishing through real mosquitto brokers.

    python scripts/fleet_bench.py       # N = 1 10 50 200, direct and bridged, QoS 2 and 1
    python scripts/fleet_bench.py --desks 3 --setups bridged --qos 2 --duration 3 --json

Each desk is hapticdesk's own publishing path: one :class:`~hapticdesk.plugins.mqtt.link.MqttLink`
per desk (its queue, QoS 2 handshake, persistent session and reconnects), publishing every
gesture the way the desk's event sink does (``hapticdesk/<desk>/action`` and
``hapticdesk/<desk>/event``). No estimator runs: the "light mode" drives each desk with a tap
every 0.5-2 s (uniformly random, ``--interval``), so a worker process holds many desks.

Brokers are started here on free loopback ports with temporary config files:

- ``direct``: desks and consumers on one mosquitto;
- ``bridged``: desks on a *floor* broker that bridges ``hapticdesk/#`` out at QoS 2 to a
  *building* broker, where the consumers are.

``--consumers`` paho clients (MQTT 5) share one subscription (``$share/fleet/hapticdesk/+/event``)
on the building broker, so the events are spread over them. Every event carries
(desk, seq, sent wall time); the consumers count

    delivered = distinct (desk, seq) received,  lost = sent - delivered,
    doubled = received - delivered,  latency = arrival - sent (one machine, one clock).

Each row also gives the offered rate (events/s), and the CPU the brokers and the desk workers
used during the publishing window (% of one core), to show where it saturates.
"""

from __future__ import annotations

import argparse
import getpass
import heapq
import json
import multiprocessing as mp
import os
import queue
import random
import resource
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

SHARE_GROUP = "fleet"
BRIDGE_TOPIC = "hapticdesk/#"
MAX_INFLIGHT = 0  # mosquitto: 0 is no limit


# --- brokers ----------------------------------------------------------------------------------


def mosquitto_program() -> str | None:
    # mosquitto lives in /usr/sbin, which is not on every user's PATH
    return shutil.which("mosquitto") or shutil.which("mosquitto", path="/usr/sbin:/usr/local/sbin")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Broker:
    """One mosquitto on a free loopback port with a generated config (and optional bridge)."""

    def __init__(self, folder: Path, name: str, *, bridge_to: int | None = None) -> None:
        self.folder = folder / name
        self.folder.mkdir(parents=True)
        self.name = name
        self.port = free_port()
        lines = [
            f"listener {self.port} 127.0.0.1",
            "allow_anonymous true",
            "persistence false",
            f"log_dest file {self.folder}/mosquitto.log",
            "log_type error",
            "log_type warning",
            f"user {getpass.getuser()}",  # as root mosquitto would switch to `mosquitto`
            "set_tcp_nodelay true",
            # a consumer that lags must not lose messages to the default limit of 1000
            "max_queued_messages 1000000",
            # no in-flight limit: mosquitto 2.0.11's quota (default 20) gives a slot back at
            # PUBREC and again at PUBCOMP but sends queued messages only at a PUBCOMP, and under
            # load messages queued for a consumer stopped moving (bridged, 1600 events/s: 5755
            # of 6340 never arrived; 515 of 7935 with a limit of 1000; none without a limit).
            # These brokers keep no sessions on disk, so nothing needs the quota at a restart
            # (a broker that does should set a large limit, not 0: see the README).
            f"max_inflight_messages {MAX_INFLIGHT}",
        ]
        if bridge_to is not None:
            lines += [
                "connection building",
                f"address 127.0.0.1:{bridge_to}",
                f"topic {BRIDGE_TOPIC} out 2",
                "remote_clientid floor-bridge",
                "cleansession false",  # the building keeps the bridge's session
                "try_private true",  # the building does not echo messages back
                "notifications false",
                "restart_timeout 1",
            ]
        self.config = self.folder / "mosquitto.conf"
        self.config.write_text("\n".join(lines) + "\n")
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        program = mosquitto_program()
        if program is None:
            raise SystemExit("fleet_bench: mosquitto is not installed (apt-get install mosquitto)")
        self.process = subprocess.Popen(
            [program, "-c", str(self.config)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        deadline = time.monotonic() + 10
        while True:
            with socket.socket() as s:
                s.settimeout(0.2)
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return
            if self.process.poll() is not None:
                err = self.process.stderr.read().decode() if self.process.stderr else ""
                raise RuntimeError(f"mosquitto ({self.name}) did not start: {err}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"mosquitto ({self.name}) did not open its port within 10 s")
            time.sleep(0.02)

    def cpu_s(self) -> float:
        """User + system CPU seconds used so far (from /proc; 0 where there is none)."""
        if self.process is None:
            return 0.0
        try:
            fields = Path(f"/proc/{self.process.pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            return 0.0
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None


def wait_bridge_up(floor: Broker, building: Broker, timeout: float = 10.0) -> None:
    """Block until a message published on the floor broker arrives on the building broker."""
    import paho.mqtt.client as mqtt

    arrived = threading.Event()
    sub = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv5)
    sub.on_message = lambda c, u, m: arrived.set()
    sub.connect("127.0.0.1", building.port)
    sub.subscribe("hapticdesk/_probe", qos=1)
    sub.loop_start()
    pub = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv5)
    pub.connect("127.0.0.1", floor.port)
    pub.loop_start()
    try:
        deadline = time.monotonic() + timeout
        while not arrived.is_set():
            if time.monotonic() > deadline:
                raise RuntimeError("the floor broker's bridge to the building did not come up")
            pub.publish("hapticdesk/_probe", b"1", qos=1)
            arrived.wait(0.2)
    finally:
        for c in (pub, sub):
            c.disconnect()
            c.loop_stop()


# --- consumers --------------------------------------------------------------------------------


class Consumers:
    """K paho clients (MQTT 5) sharing one subscription to every desk's events."""

    def __init__(self, port: int, count: int, qos: int) -> None:
        import paho.mqtt.client as mqtt

        self.received: list[tuple[str, int, float]] = []  # (desk, seq, latency s)
        self.per_consumer = [0] * count
        self._lock = threading.Lock()
        self._clients = []
        subscribed = [threading.Event() for _ in range(count)]
        for k in range(count):
            c = mqtt.Client(
                mqtt.CallbackAPIVersion.VERSION2,
                client_id=f"fleet-consumer-{k}",
                protocol=mqtt.MQTTv5,
            )
            c.on_message = self._on_message_for(k)
            c.on_subscribe = lambda cl, u, mid, rc, p, e=subscribed[k]: e.set()
            c.connect("127.0.0.1", port)
            c.subscribe(f"$share/{SHARE_GROUP}/hapticdesk/+/event", qos=qos)
            c.loop_start()
            self._clients.append(c)
        for e in subscribed:
            if not e.wait(10):
                raise RuntimeError("a consumer's shared subscription was not acknowledged")

    def _on_message_for(self, k: int) -> Any:
        def on_message(client: Any, userdata: Any, message: Any) -> None:
            now = time.time()
            event = json.loads(message.payload)
            with self._lock:
                self.received.append((event["desk"], event["seq"], now - event["sent"]))
                self.per_consumer[k] += 1

        return on_message

    def count(self) -> int:
        with self._lock:
            return len(self.received)

    def stop(self) -> None:
        for c in self._clients:
            c.disconnect()
            c.loop_stop()


# --- desks (in worker processes) --------------------------------------------------------------


def desk_name(i: int) -> str:
    return f"fleet-d{i:04d}"


def run_desks(
    desks: Sequence[int],
    port: int,
    qos: int,
    interval: tuple[float, float],
    duration: float,
    tag: str,
    ready: Any,
    go: Any,
    results: Any,
) -> None:
    """A worker: one MqttLink per desk, taps at random intervals for ``duration`` s, then flush."""
    from hapticdesk.plugins.mqtt.link import MqttLink
    from hapticdesk.plugins.mqtt.settings import MqttSettings

    links = {
        i: MqttLink(
            MqttSettings(host="127.0.0.1", port=port, client_id=f"{tag}-{desk_name(i)}", qos=qos)
        ).start()
        for i in desks
    }
    connected = all(link.wait_connected(60) for link in links.values())
    ready.put(connected)
    go.wait()
    rng = random.Random(desks[0] if desks else 0)
    start = time.time()
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    # each desk's next tap: a heap of (time, desk), one scheduler thread for the whole worker
    due = [(start + rng.uniform(0, interval[1]), i) for i in desks]
    heapq.heapify(due)
    sent = dict.fromkeys(desks, 0)
    late = 0.0
    while due:
        t, i = heapq.heappop(due)
        if t >= start + duration:
            continue
        wait = t - time.time()
        if wait > 0:
            time.sleep(wait)
        else:
            late = max(late, -wait)
        sent[i] += 1
        name = desk_name(i)
        # the same two messages the desk's event sink publishes for one gesture
        links[i].publish(f"hapticdesk/{name}/action", "lamp_tap", retain=False)
        links[i].publish(
            f"hapticdesk/{name}/event",
            {
                "t": round(t - start, 6),
                "gesture": "tap",
                "region": "lamp",
                "x": 0.1,
                "y": -0.05,
                "action": "lamp_tap",
                "desk": name,
                "seq": sent[i],
                "sent": time.time(),
            },
            retain=False,
        )
        heapq.heappush(due, (t + rng.uniform(*interval), i))
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    window = time.time() - start
    flushed = all(link.flush(60) for link in links.values())
    delivered = dropped = 0
    for link in links.values():
        link.close(timeout=5)
        delivered += link.stats.delivered
        dropped += link.stats.dropped
    results.put(
        {
            "sent": {desk_name(i): n for i, n in sent.items()},
            "cpu_s": (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime),
            "window_s": window,
            "flushed": flushed,
            "acked": delivered,
            "dropped": dropped,
            "late_s": late,
        }
    )


# --- one run ----------------------------------------------------------------------------------


@dataclass
class Row:
    setup: str
    qos: int
    desks: int
    messages: int  # events sent (each gesture also publishes an action message)
    delivered: int
    lost: int
    doubled: int
    p50_ms: float
    p95_ms: float
    max_ms: float
    offered_per_s: float
    broker_cpu_pct: float  # the busiest broker, % of one core during the window
    desk_cpu_pct: float  # all desk workers together, % of one core
    scheduler_late_ms: float  # how late the worst tap left its scheduler (desk side overload)
    consumers_used: int  # consumers that received at least one event
    unacked: int  # messages (events and actions) the desks' links never saw acknowledged
    consumers_cpu_pct: float  # the consumers (all in this process), % of one core


def run_once(
    setup: str,
    n: int,
    qos: int,
    *,
    duration: float,
    interval: tuple[float, float],
    consumers: int,
    workers: int,
    drain_s: float = 30.0,
) -> Row:
    """Start the broker(s), N desks and the consumers; publish for ``duration`` s; count."""
    folder = Path(tempfile.mkdtemp(prefix="fleet-bench-"))
    brokers: list[Broker] = []
    consumer_group: Consumers | None = None
    procs: list[Any] = []
    try:
        building = Broker(folder, "building")
        building.start()
        brokers.append(building)
        desk_port = building.port
        if setup == "bridged":
            floor = Broker(folder, "floor", bridge_to=building.port)
            floor.start()
            brokers.append(floor)
            wait_bridge_up(floor, building)
            desk_port = floor.port
        consumer_group = Consumers(building.port, consumers, qos)
        ctx = mp.get_context("spawn")
        ready, results, go = ctx.Queue(), ctx.Queue(), ctx.Event()
        groups = [list(range(n))[w::workers] for w in range(min(workers, n))]
        tag = f"fb{os.getpid()}-{random.randrange(1 << 30):x}"
        for g in groups:
            p = ctx.Process(
                target=run_desks,
                args=(g, desk_port, qos, interval, duration, tag, ready, go, results),
                daemon=True,
            )
            p.start()
            procs.append(p)
        if not all(ready.get(timeout=120) for _ in groups):
            raise RuntimeError("not every desk connected within 60 s")
        cpu0 = [b.cpu_s() for b in brokers]
        here0 = resource.getrusage(resource.RUSAGE_SELF)  # this process: the consumers
        go.set()
        outs = [results.get(timeout=duration + 180) for _ in groups]
        cpu1 = [b.cpu_s() for b in brokers]
        here1 = resource.getrusage(resource.RUSAGE_SELF)
        sent = {d: c for out in outs for d, c in out["sent"].items()}
        total = sum(sent.values())
        # wait for the last events to arrive (bounded: stop when nothing new comes for a while)
        last, quiet_since = -1, time.monotonic()
        while consumer_group.count() < total and time.monotonic() - quiet_since < drain_s:
            now = consumer_group.count()
            if now != last:
                last, quiet_since = now, time.monotonic()
            time.sleep(0.05)
        time.sleep(0.3)  # a doubled message would come right after the original
        received = list(consumer_group.received)
        window = max(out["window_s"] for out in outs)
    finally:
        if consumer_group is not None:
            consumer_group.stop()
        for p in procs:
            p.join(10)
            if p.is_alive():
                p.terminate()
        for b in reversed(brokers):
            b.stop()
        shutil.rmtree(folder, ignore_errors=True)
    keys = {(d, s) for d, s, _ in received}
    expected = {(d, s) for d, c in sent.items() for s in range(1, c + 1)}
    latency = np.array([lat for _, _, lat in received]) * 1000.0
    if expected - keys:
        print(f"fleet_bench: lost, e.g. {sorted(expected - keys)[:8]}", file=sys.stderr)
    return Row(
        setup=setup,
        qos=qos,
        desks=n,
        messages=total,
        delivered=len(keys & expected),
        lost=len(expected - keys),
        doubled=len(received) - len(keys),
        p50_ms=float(np.percentile(latency, 50)) if latency.size else float("inf"),
        p95_ms=float(np.percentile(latency, 95)) if latency.size else float("inf"),
        max_ms=float(latency.max()) if latency.size else float("inf"),
        offered_per_s=total / window if window > 0 else 0.0,
        broker_cpu_pct=100.0 * max(b - a for a, b in zip(cpu0, cpu1, strict=True)) / window,
        desk_cpu_pct=100.0 * sum(out["cpu_s"] for out in outs) / window,
        scheduler_late_ms=1000.0 * max(out["late_s"] for out in outs),
        consumers_used=sum(1 for c in consumer_group.per_consumer if c),
        unacked=2 * total - sum(out["acked"] for out in outs),
        consumers_cpu_pct=100.0
        * ((here1.ru_utime + here1.ru_stime) - (here0.ru_utime + here0.ru_stime))
        / window,
    )


# --- command line -----------------------------------------------------------------------------


def format_table(rows: Sequence[Row]) -> str:
    head = (
        "| setup | QoS | N | messages | lost | doubled | p50 ms | p95 ms | max ms | events/s "
        "| broker CPU | desks CPU |"
    )
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        lines.append(
            f"| {r.setup} | {r.qos} | {r.desks} | {r.messages} | {r.lost} | {r.doubled} "
            f"| {r.p50_ms:.1f} | {r.p95_ms:.1f} | {r.max_ms:.1f} | {r.offered_per_s:.0f} "
            f"| {r.broker_cpu_pct:.0f} % | {r.desk_cpu_pct:.0f} % |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--desks", type=int, nargs="+", default=[1, 10, 50, 200])
    setups = ["direct", "bridged"]
    parser.add_argument("--setups", nargs="+", choices=setups, default=setups)
    parser.add_argument("--qos", type=int, nargs="+", choices=[0, 1, 2], default=[2, 1])
    parser.add_argument("--duration", type=float, default=10.0, help="publishing window, s")
    parser.add_argument(
        "--interval", type=float, nargs=2, default=[0.5, 2.0], metavar=("MIN", "MAX"),
        help="seconds between one desk's taps, uniformly random (default 0.5 2)",
    )  # fmt: skip
    parser.add_argument("--consumers", type=int, default=3, help="shared-subscription consumers")
    parser.add_argument("--workers", type=int, default=4, help="processes holding the desks")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args(argv)
    if min(args.desks) < 1 or args.duration <= 0 or not 0 < args.interval[0] <= args.interval[1]:
        parser.error("--desks must be >= 1, --duration > 0, and 0 < MIN <= MAX for --interval")
    rows = []
    for qos in args.qos:
        for setup in args.setups:
            for n in args.desks:
                try:
                    row = run_once(
                        setup,
                        n,
                        qos,
                        duration=args.duration,
                        interval=(args.interval[0], args.interval[1]),
                        consumers=args.consumers,
                        workers=args.workers,
                    )
                except (RuntimeError, OSError, queue.Empty) as err:  # more desks than fit here
                    print(f"fleet_bench: {setup}, QoS {qos}, N = {n}: {err}", file=sys.stderr)
                    return 2
                rows.append(row)
                if not args.json:
                    print(format_table([row]).splitlines()[-1], flush=True)
    if args.json:
        print(json.dumps([asdict(r) for r in rows], indent=2))
    else:
        print()
        print(format_table(rows))
    return 0 if all(r.lost == 0 and (r.qos < 2 or r.doubled == 0) for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
